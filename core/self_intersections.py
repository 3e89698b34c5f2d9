"""Where a triangle mesh passes through itself (any units): MeshLab's per-face intersection test through pymeshlab.
Used on the fitted PPM (ppm.align.report), on the personal-detail layer's pinna and on the remeshed head
(stitching.remesh): a boundary element mesh must not cross itself."""
from __future__ import annotations

import numpy as np


def self_intersecting_faces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Indices of the faces that cross another face of the same mesh; faces that only share an edge or a vertex do
    not count."""
    import pymeshlab  # noqa: PLC0415  (imported late: after bpy where both are used in one process)

    meshes = pymeshlab.MeshSet()
    meshes.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(vertices, np.float64),
                                   face_matrix=np.asarray(faces, np.int32)))
    meshes.compute_selection_by_self_intersections_per_face()
    return np.flatnonzero(meshes.current_mesh().face_selection_array())
