"""Both-ear heads from a dataset that grades each head fine at one pinna per file (SONICOM as prepared for
Mesh2HRTF: ``head_graded_left.ply`` 0.7-1 mm at the left pinna and 7-9 mm at the right one, and the mirror
file). A scan of a new listener resolves both ears alike; these heads stand in for one.

Millimetres, the dataset's frame (x front, y left, z up).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from stitching.loops import boundary_loops, bridge_loops
from stitching.remesh import Band, remesh_graded, repair_folds_and_slivers, repair_self_intersections, self_intersections

from .errors import ListenerError

#: The two graded files are cut across y (mm) with a gap between (right of the mid-sagittal plane, left of the
#: right ear, where both are meshed 2-9 mm), and the gap is bridged by one strip of triangles.
SPLICE_Y_MM = (-40.0, -52.0)


def both_ears_head(subject_dir: str | Path, splice_y_mm: tuple[float, float] = SPLICE_Y_MM) -> trimesh.Trimesh:
    """The faces of ``head_graded_left.ply`` left of ``splice_y_mm[0]`` and of ``head_graded_right.ply`` right of
    ``splice_y_mm[1]``, joined by a strip across the gap into one closed surface (mm): both ears as finely
    resolved as the dataset has them, as a scan of a new listener would have them.

    Raises
    ------
    ListenerError
        If the two parts do not each leave one loop at the cut, or the joined surface is not closed.
    """
    subject_dir = Path(subject_dir)
    left = trimesh.load(subject_dir / "head_graded_left.ply", process=False, force="mesh")
    right = trimesh.load(subject_dir / "head_graded_right.ply", process=False, force="mesh")
    parts = [trimesh.Trimesh(left.vertices, left.faces[left.triangles_center[:, 1] > splice_y_mm[0]], process=False),
             trimesh.Trimesh(right.vertices, right.faces[right.triangles_center[:, 1] < splice_y_mm[1]], process=False)]
    for part in parts:
        part.remove_unreferenced_vertices()
    loops = [boundary_loops(part) for part in parts]
    if any(len(found) != 1 for found in loops):
        raise ListenerError(f"{subject_dir}: cutting the graded heads at y = {splice_y_mm} mm left "
                            f"{[len(found) for found in loops]} boundary loops instead of one each")
    vertices = np.vstack([parts[0].vertices, parts[1].vertices])
    offset = len(parts[0].vertices)
    across = vertices * np.array([1.0, 0.0, 1.0])  # rungs measured across the gap's plane
    strip = bridge_loops(vertices, loops[0][0], loops[1][0] + offset, across)
    head = trimesh.Trimesh(vertices, np.vstack([parts[0].faces, parts[1].faces + offset, strip]), process=False)
    if self_intersections(head):
        head = repair_self_intersections(head)
    # the strip's triangles are long and thin: the skin within 15 mm of the gap is remeshed at 2.5 mm, folds and
    # slivers repaired (up to 0.5 mm off the surface there), so that the head is fit for BEM as a scan would be
    centres = head.triangles_center
    near_gap = centres[(centres[:, 1] >= splice_y_mm[1] - 4.0) & (centres[:, 1] <= splice_y_mm[0] + 4.0)]
    head = remesh_graded(head, near_gap, (Band(15.0, 2.5, 0.3),))
    head = repair_folds_and_slivers(head, sliver_rounds=6, max_deviation_mm=0.5)  # P143: 12 creased faces at the splice
    if not (head.is_watertight and head.is_winding_consistent and head.volume > 0):
        raise ListenerError(f"{subject_dir}: the two graded heads joined at y = {splice_y_mm} mm are not one closed, "
                            "outward surface")
    return head
