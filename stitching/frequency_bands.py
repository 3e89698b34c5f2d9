"""A head mesh for a band of low frequencies: the same surface remeshed with longer edges, graded by distance to
the pinna as the full mesh is, with the ear-canal source's faces kept exactly (same element area and position, so
the source level is the same in every band). At a wavelength of 0.11-2.3 m (150 Hz-3 kHz) the full mesh's 1 mm
pinna is far finer than the sound needs; NumCalc's time per step falls with the element count
(``benchmarks/band_meshes.py``).

Millimetres, project frame (x front, y left, z up, origin at the interaural centre).
"""
from __future__ import annotations

import logging

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from .errors import StitchError
from .remesh import Band, remesh_graded, remove_slivers

log = logging.getLogger(__name__)

#: Faces whose centroids lie this close (mm) to the source's centre are never remeshed.
KEEP_AROUND_SOURCE_MM = 5.0


def band_mesh(head: trimesh.Trimesh, source_faces: np.ndarray, pinna_points_mm: np.ndarray,
              bands: tuple[Band, ...], keep_mm: float = KEEP_AROUND_SOURCE_MM,
              source: str = "head") -> tuple[trimesh.Trimesh, np.ndarray]:
    """``head`` remeshed by distance to the pinna with ``bands`` (coarser than the full mesh's), the faces within
    ``keep_mm`` of the source faces' centre untouched, slivers repaired away from them. Returns the band mesh and
    the indices of the source faces in it (the same triangles, found again by their centroids).

    Raises
    ------
    StitchError
        If the remesh breaks the surface, or the source faces did not survive unchanged (raise ``keep_mm``).
    """
    source_faces = np.asarray(source_faces, dtype=np.int64)
    centroids = head.triangles_center[source_faces]
    centre = centroids.mean(axis=0)
    mesh = remesh_graded(head, pinna_points_mm, bands, keep_centre_mm=centre, keep_radius_mm=keep_mm)
    mesh = remove_slivers(mesh)
    distance, index = cKDTree(mesh.triangles_center).query(centroids)
    if distance.max() > 1e-6 or not np.allclose(mesh.area_faces[index], head.area_faces[source_faces], rtol=1e-9):
        raise StitchError(f"{source}: the ear-canal source's faces moved by up to {distance.max():.2e} mm in the band "
                          f"mesh; keep more of their surroundings (keep_mm > {keep_mm:g})")
    if not (mesh.is_watertight and mesh.is_winding_consistent):
        raise StitchError(f"{source}: the band mesh is not closed; use a smaller edge near the pinna")
    log.info("%s: band mesh %d -> %d faces (edges %s mm), source faces kept", source, len(head.faces),
             len(mesh.faces), [b.edge_mm for b in bands])
    return mesh, np.sort(index)
