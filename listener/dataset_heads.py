"""Both-ear heads from a dataset that grades each head fine at one pinna per file (SONICOM as prepared for
Mesh2HRTF: ``head_graded_left.ply`` 0.7-1 mm at the left pinna and 7-9 mm at the right one, and the mirror
file). A scan of a new listener resolves both ears alike; these heads stand in for one.

Millimetres, the dataset's frame (x front, y left, z up).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

#: Where the two graded files are joined (mm along y): right of the mid-sagittal plane, left of the right ear.
SPLICE_Y_MM = -45.0


def both_ears_head(subject_dir: str | Path, splice_y_mm: float = SPLICE_Y_MM) -> trimesh.Trimesh:
    """The faces of ``head_graded_left.ply`` left of ``splice_y_mm`` and of ``head_graded_right.ply`` right of it,
    as one mesh (mm): both ears as finely resolved as the dataset has them. The two parts meet in an open seam,
    so this is a surface for finding the head frame and fitting the pinnae, not a closed BEM mesh."""
    subject_dir = Path(subject_dir)
    left = trimesh.load(subject_dir / "head_graded_left.ply", process=False, force="mesh")
    right = trimesh.load(subject_dir / "head_graded_right.ply", process=False, force="mesh")
    parts = [trimesh.Trimesh(left.vertices, left.faces[left.triangles_center[:, 1] > splice_y_mm], process=False),
             trimesh.Trimesh(right.vertices, right.faces[right.triangles_center[:, 1] <= splice_y_mm], process=False)]
    for part in parts:
        part.remove_unreferenced_vertices()
    head = trimesh.util.concatenate(parts)
    return trimesh.Trimesh(np.asarray(head.vertices), np.asarray(head.faces), process=False)
