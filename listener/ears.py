"""The pinnae of a head in the project frame, cut out as a dataset's pinna crops are.

Millimetres, project frame (x front, y left, z up, origin between the ear canals). The box follows the
SONICOM crops of ``../shared/data``: |x| < 50, |z| < 55, and beyond 50 mm from the mid-sagittal plane on the
ear's side. The right crop stays where it is (mirror y -> -y for a left-ear shape, as the PPM fit does).
"""
from __future__ import annotations

import numpy as np
import trimesh

from .errors import ListenerError

#: Half-widths of the crop box along x and z, and its inner face along |y| (mm).
CROP_X_MM, CROP_Z_MM, CROP_Y_MM = 50.0, 55.0, 50.0


def in_crop_box(points_mm: np.ndarray, side: str) -> np.ndarray:
    """Per point (n, 3; mm, project frame), whether it lies in the crop box of the ``side`` ('left'/'right') ear."""
    points = np.asarray(points_mm, dtype=np.float64)
    sign = {"left": 1.0, "right": -1.0}[side]
    return (np.abs(points[:, 0]) < CROP_X_MM) & (np.abs(points[:, 2]) < CROP_Z_MM) & (sign * points[:, 1] > CROP_Y_MM)


def pinna_crop(head: trimesh.Trimesh, side: str, source: str = "head mesh") -> trimesh.Trimesh:
    """The faces of ``head`` (mm, project frame) inside the crop box of the ``side`` ('left'/'right') ear, the
    largest connected part, as an open surface.

    Raises
    ------
    ListenerError
        If the box holds no part of the head large enough to be a pinna with its skin ring.
    """
    inside = in_crop_box(np.asarray(head.vertices)[head.faces].reshape(-1, 3), side).reshape(-1, 3).all(axis=1)
    faces = np.flatnonzero(inside)
    if len(faces) == 0:
        raise ListenerError(f"{source}: nothing of the head lies in the {side} ear's crop box; is the head in the "
                            "project frame (ear canals on the y axis)?")
    part = trimesh.Trimesh(head.vertices, head.faces[faces], process=False)
    components = trimesh.graph.connected_components(part.face_adjacency, nodes=np.arange(len(faces)))
    largest = faces[np.sort(max(components, key=len))]
    crop = trimesh.Trimesh(head.vertices, head.faces[largest], process=False)
    crop.remove_unreferenced_vertices()
    extent = np.ptp(np.asarray(crop.vertices), axis=0)
    if extent[0] < 40.0 or extent[2] < 40.0:
        raise ListenerError(f"{source}: the {side} ear's crop is only {extent[0]:.0f} x {extent[2]:.0f} mm (x, z); a "
                            "pinna with its skin ring is about 100 x 110 mm: the ear is missing from the scan")
    return crop
