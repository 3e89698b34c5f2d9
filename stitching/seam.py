"""Smoothing the seam between head and pinna: a few Laplacian steps on the strip and the faces next to
it (pymeshlab, selected faces only), so the rim of the pinna's skin ring blends into the head skin."""
from __future__ import annotations

import numpy as np
import trimesh


def smooth_seam(mesh: trimesh.Trimesh, seam_faces: np.ndarray, rings: int = 2, steps: int = 3) -> trimesh.Trimesh:
    """Laplacian smoothing of the vertices of ``seam_faces`` (bool per face) grown by ``rings`` face rings."""
    import pymeshlab  # noqa: PLC0415

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(mesh.vertices, np.float64),
                               face_matrix=np.asarray(mesh.faces, np.int32),
                               f_scalar_array=np.asarray(seam_faces, np.float64)))
    ms.compute_selection_by_condition_per_face(condselect="fq > 0.5")
    for _ in range(rings):
        ms.apply_selection_dilatation()
    ms.apply_coord_laplacian_smoothing(stepsmoothnum=steps, selected=True, cotangentweight=True)
    out = ms.current_mesh()
    return trimesh.Trimesh(out.vertex_matrix(), out.face_matrix(), process=False)
