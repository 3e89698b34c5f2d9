"""The ear-canal entrance element(s) that act as the reciprocal source of a BEM head mesh.

Frame: millimetres, +x front, +y left, +z up, origin at the interaural centre. A ray from the
interaural centre along +y (left) or -y (right) leaves the head through the blocked ear canal: its
first exit point lies in the canal or at its entrance, deep inside the concha, never on the tragus
or helix, which stand further out. The element hit there (and, to reach a minimum area, its
neighbours nearest to the hit) is the source.
"""
from __future__ import annotations

import numpy as np
import trimesh

from .errors import StitchError

SIDES = {"left": 1.0, "right": -1.0}


class EarCanalError(StitchError):
    """No usable ear-canal element: the head is not centred at the interaural axis or has no ear there."""


def ear_canal_elements(mesh: trimesh.Trimesh, side: str, min_area_mm2: float = 4.0,
                       source: str = "head mesh") -> np.ndarray:
    """Face indices of the ear-canal entrance on ``side`` ('left' or 'right'), at least ``min_area_mm2``."""
    if side not in SIDES:
        raise EarCanalError(f"side must be 'left' or 'right', got {side!r}")
    direction = np.array([0.0, SIDES[side], 0.0])
    locations, _, faces = mesh.ray.intersects_location([[0.0, 0.0, 0.0]], [direction])
    if len(faces) == 0:
        raise EarCanalError(f"{source}: a ray from the origin along {direction[1]:+.0f}·y leaves no surface; the head "
                            "must be in the project frame (origin at the interaural centre, +y left, millimetres)")
    first = int(np.argmin(np.linalg.norm(locations, axis=1)))
    hit, face = locations[first], int(faces[first])
    depth = abs(float(hit[1]))
    if not 40.0 <= depth <= 110.0:
        raise EarCanalError(f"{source}: the {side} ear canal was found {depth:.1f} mm from the interaural centre; "
                            "expected 40-110 mm: check the units (millimetres) and that the origin is the "
                            "interaural centre")
    if float(mesh.face_normals[face] @ direction) <= 0.0:
        raise EarCanalError(f"{source}: the {side} ear element faces inwards; fix the normals (outward) first")
    chosen = [face]
    if mesh.area_faces[face] < min_area_mm2:
        centres = mesh.triangles_center
        for candidate in np.argsort(np.linalg.norm(centres - hit, axis=1)):
            if int(candidate) in chosen or float(mesh.face_normals[candidate] @ direction) <= 0.0:
                continue
            chosen.append(int(candidate))
            if mesh.area_faces[chosen].sum() >= min_area_mm2:
                break
    return np.array(sorted(chosen), dtype=np.int64)
