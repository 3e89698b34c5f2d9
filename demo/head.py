"""A simple parametric head for demo subjects (millimetres, project frame: +x front, +y left, +z up,
origin at the interaural centre).

The head is an ellipsoid whose skin around each ear is bent onto the rim of the pinna that will be
mounted there, so the pinna's skin ring rests on the head as it does on a scanned one; the pinna is then
stitched in with the same code that replaces a scanned head's pinna (`stitching.replace_pinna`). The
right ear is the left one mirrored (y -> -y).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import trimesh
from matplotlib.path import Path as PolygonPath
from scipy.spatial import cKDTree

from stitching.both_ears import mirror_left_right, stitch_left
from stitching.loops import boundary_loops


@dataclasses.dataclass(frozen=True)
class HeadShape:
    """Semi-axes of the ellipsoid (mm) and the height of its centre above the interaural axis (mm)."""

    front_mm: float = 95.0
    side_mm: float = 76.0
    top_mm: float = 115.0
    centre_z_mm: float = 12.0
    #: skin within this distance (mm, side view) of the pinna rim is bent onto it, with a smooth fall-off
    blend_mm: float = 25.0
    #: icosphere subdivisions of the ellipsoid (5: about 4 mm edges)
    subdivisions: int = 5


def ellipsoid_head(shape: HeadShape = HeadShape()) -> trimesh.Trimesh:
    """A closed ellipsoid (outward normals) with the given semi-axes, centred at z = centre_z_mm."""
    sphere = trimesh.creation.icosphere(subdivisions=shape.subdivisions, radius=1.0)
    vertices = sphere.vertices * [shape.front_mm, shape.side_mm, shape.top_mm] + [0.0, 0.0, shape.centre_z_mm]
    return trimesh.Trimesh(vertices, sphere.faces, process=False)


def _smoothstep(t: np.ndarray) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def bend_skin_onto_rim(head: trimesh.Trimesh, rim_mm: np.ndarray, blend_mm: float) -> trimesh.Trimesh:
    """Move the left-side skin (y > 0) along y so that it passes through the rim points (n, 3): inside the
    rim (seen from the side, x-z) it takes the rim's interpolated y, outside it returns to the ellipsoid
    within ``blend_mm``."""
    vertices = np.array(head.vertices, dtype=float)
    rim_xz, rim_y = rim_mm[:, [0, 2]], rim_mm[:, 1]
    side = vertices[:, 1] > 0.0
    xz = vertices[side][:, [0, 2]]
    distance, nearest = cKDTree(rim_xz).query(xz, k=8)
    weights = 1.0 / np.maximum(distance, 1e-6) ** 2
    rim_height = (weights * rim_y[nearest]).sum(axis=1) / weights.sum(axis=1)
    inside = PolygonPath(rim_xz).contains_points(xz)
    pull = np.where(inside, 1.0, _smoothstep(1.0 - distance[:, 0] / blend_mm))
    vertices[np.flatnonzero(side), 1] = pull * rim_height + (1.0 - pull) * vertices[side][:, 1]
    return trimesh.Trimesh(vertices, head.faces, process=False)


def head_with_pinnae(pinna_left: trimesh.Trimesh, shape: HeadShape = HeadShape()) -> trimesh.Trimesh:
    """The parametric head with ``pinna_left`` (mm, open along the rim of its skin ring) stitched on the
    left and its mirror image on the right: one closed surface with outward normals."""
    rim = np.asarray(pinna_left.vertices)[boundary_loops(pinna_left)[0]]
    head = bend_skin_onto_rim(ellipsoid_head(shape), rim, shape.blend_mm)
    head = mirror_left_right(bend_skin_onto_rim(mirror_left_right(head), rim, shape.blend_mm))
    with_left = stitch_left(head, pinna_left, head_source="demo head", pinna_source="demo pinna")
    # mirrored, that pinna sits on the right and the left side is bare skin bent for the same rim
    return stitch_left(mirror_left_right(with_left), pinna_left, head_source="demo head", pinna_source="demo pinna")
