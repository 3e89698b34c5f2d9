"""A head mesh for a band of low frequencies: the same surface remeshed with longer edges, graded by distance to
the pinna as the full mesh is, with the ear-canal sources' faces kept exactly (same element area and position, so
the source level is the same in every band). At a wavelength of 0.11-2.3 m (150 Hz-3 kHz) the full mesh's 1 mm
pinna is far finer than the sound needs; NumCalc's time per step falls with the element count
(``benchmarks/band_meshes.py``).

Millimetres, project frame (x front, y left, z up, origin at the interaural centre).
"""
from __future__ import annotations

import json
import logging
import os
from collections.abc import Sequence

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from mesh2hrtf_io.ear_canal import ear_canal_elements
from core.atomic import write_text_atomic
from ppm.mesh_io import write_mesh

from .errors import StitchError
from .remesh import Band, folded_faces, remesh_graded, remove_slivers

log = logging.getLogger(__name__)

#: Faces whose centroids lie this close (mm) to a source's centre are never remeshed.
KEEP_AROUND_SOURCE_MM = 5.0


def band_mesh(head: trimesh.Trimesh, source_faces: np.ndarray | Sequence[np.ndarray], pinna_points_mm: np.ndarray,
              bands: tuple[Band, ...], keep_mm: float = KEEP_AROUND_SOURCE_MM,
              source: str = "head") -> tuple[trimesh.Trimesh, np.ndarray | list[np.ndarray]]:
    """``head`` remeshed by distance to the pinna with ``bands`` (coarser than the full mesh's; a distance band whose
    edges are already as long is kept, so the band mesh is nowhere finer than the head), the faces within
    ``keep_mm`` of each source's centre untouched, slivers repaired away from them. ``source_faces``: the face
    indices of one source, or a list of them (one per ear). Returns the band mesh and the indices of the source
    faces in it (the same triangles, found again by their centroids), in the form they were given.

    Raises
    ------
    StitchError
        If the remesh breaks the surface, or the source faces did not survive unchanged (raise ``keep_mm``).
    """
    one = isinstance(source_faces, np.ndarray) and source_faces.ndim == 1
    sources = [np.asarray(source_faces, dtype=np.int64)] if one else [np.asarray(f, np.int64) for f in source_faces]
    centres = np.array([head.triangles_center[faces].mean(axis=0) for faces in sources])
    mesh = remesh_graded(head, pinna_points_mm, bands, keep_centre_mm=centres, keep_radius_mm=keep_mm,
                         coarsen_only=True)
    mesh = remove_slivers(mesh)
    tree = cKDTree(mesh.triangles_center)
    found = []
    for faces in sources:
        distance, index = tree.query(head.triangles_center[faces])
        if distance.max() > 1e-6 or not np.allclose(mesh.area_faces[index], head.area_faces[faces], rtol=1e-9):
            raise StitchError(f"{source}: the ear-canal source's faces moved by up to {distance.max():.2e} mm in the "
                              f"band mesh; keep more of their surroundings (keep_mm > {keep_mm:g})")
        found.append(np.sort(index))
    if not (mesh.is_watertight and mesh.is_winding_consistent):
        raise StitchError(f"{source}: the band mesh is not closed; use a smaller edge near the pinna")
    log.info("%s: band mesh %d -> %d faces (edges %s mm), source faces kept", source, len(head.faces),
             len(mesh.faces), [b.edge_mm for b in bands])
    return mesh, (found[0] if one else found)


def band_mesh_bands(distances_mm: Sequence[float | None], edges_mm: Sequence[float]) -> tuple[Band, ...]:
    """The remeshing bands of a band mesh: the full mesh's distances to the pinna (mm, None: the rest of the head)
    with the band's edge lengths, each allowed a surface deviation of a tenth of its edge (at least 0.05 mm)."""
    return tuple(Band(np.inf if distance is None else float(distance), float(edge), max(0.05, float(edge) / 10.0))
                 for distance, edge in zip(distances_mm, edges_mm))


def write_band_head(head_path: str | os.PathLike, pinna_path: str | os.PathLike, sides: Sequence[str],
                    bands: tuple[Band, ...], mesh_path: str | os.PathLike, sources_path: str | os.PathLike) -> dict:
    """The band mesh of the head at ``head_path`` (mm) and the faces of its ear-canal sources (``sides``: 'left',
    'right'; found on the full head by :func:`mesh2hrtf_io.ear_canal.ear_canal_elements` and kept), written
    atomically: the mesh to ``mesh_path``, ``{"sources": {side: [face, ...]}, ...}`` to ``sources_path``. The
    distances are to the left pinna crop at ``pinna_path`` and its mirror image (the right pinna's place)."""
    head = trimesh.load(head_path, process=False, force="mesh")
    pinna = np.asarray(trimesh.load(pinna_path, process=False, force="mesh").vertices)
    pinnae = np.vstack([pinna, pinna * np.array([1.0, -1.0, 1.0])]) if "right" in sides else pinna
    full = [ear_canal_elements(head, side, source=str(head_path)) for side in sides]
    mesh, kept = band_mesh(head, full, pinnae, bands, source=str(head_path))
    write_mesh(mesh_path, mesh.vertices, mesh.faces)
    summary = {"head": str(head_path), "elements_full": int(len(head.faces)), "elements": int(len(mesh.faces)),
               "edges_mm": [band.edge_mm for band in bands],
               "sources": {side: faces.tolist() for side, faces in zip(sides, kept)},
               "source_area_mm2": {side: round(float(mesh.area_faces[faces].sum()), 6) for side, faces in zip(sides, kept)},
               # pairs of faces creased beyond the full mesh's fold test, kept as they are: at a band's long edges
               # the helix rim's ridge can pass it without folding over (P143's ppm_detail_hard: up to 134 deg)
               "creased_faces": int(folded_faces(mesh).sum()),
               "max_dihedral_deg": round(float(np.degrees(mesh.face_adjacency_angles.max())), 1)}
    write_text_atomic(sources_path, json.dumps(summary, indent=1) + "\n")
    return summary
