"""Both pinnae stitched into one head: the left as :func:`stitching.replace_pinna.replace_pinna` does, the right
by the same code on the head mirrored across the mid-sagittal plane (y -> -y), so that the right pinna, fitted as a
left one (the PPM is a left ear), goes in mirrored.

Millimetres, project frame (x front, y left, z up, origin at the interaural centre).
"""
from __future__ import annotations

import trimesh

from .replace_pinna import replace_pinna
from .seam import smooth_seam


def mirror_left_right(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh mirrored across the mid-sagittal plane (y -> -y), triangles rewound so normals stay outward."""
    return trimesh.Trimesh(mesh.vertices * [1.0, -1.0, 1.0], mesh.faces[:, ::-1], process=False)


def stitch_left(head: trimesh.Trimesh, pinna: trimesh.Trimesh, gap_mm: float = 1.5, head_source: str = "head mesh",
                pinna_source: str = "pinna mesh") -> trimesh.Trimesh:
    """``head`` with its left pinna replaced by ``pinna`` (both mm), the seam smoothed."""
    stitched = replace_pinna(head, pinna, gap_mm=gap_mm, head_source=head_source, pinna_source=pinna_source)
    return smooth_seam(stitched.mesh, stitched.origin == 2)


def stitch_both_ears(head: trimesh.Trimesh, left_pinna: trimesh.Trimesh, right_pinna_as_left: trimesh.Trimesh,
                     gap_mm: float = 1.5, head_source: str = "head mesh", left_source: str = "left pinna",
                     right_source: str = "right pinna") -> trimesh.Trimesh:
    """``head`` (mm) with both pinnae replaced: ``left_pinna`` at the left ear, and ``right_pinna_as_left`` (the
    right pinna mirrored into a left one, as its PPM fit is) mirrored back to the right ear. One closed surface.

    Raises
    ------
    stitching.errors.StitchError
        If either pinna does not rest on its ear or the cut leaves more than one hole.
    """
    with_left = stitch_left(head, left_pinna, gap_mm, head_source, left_source)
    mirrored = stitch_left(mirror_left_right(with_left), right_pinna_as_left, gap_mm,
                           f"{head_source} (mirrored for the right ear)", right_source)
    return mirror_left_right(mirrored)


def right_ear_scan_as_left(right_crop_path, subject: str, level: str, seed: int) -> trimesh.Trimesh:
    """The right ear's fixed defective scan as a left ear (mm, head frame mirrored y -> -y): the clean right crop
    (a file) mirrored and scanned at ``level`` of ppm/data/scan_defects.yaml with ``seed`` mixed with
    "<subject>_right", a draw of its own beside the left ear's ("<subject>"; ppm.align.defects.hard_scan_of)."""
    import tempfile  # noqa: PLC0415
    from pathlib import Path  # noqa: PLC0415

    from ppm.align.defects import hard_scan_of  # noqa: PLC0415

    with tempfile.TemporaryDirectory() as folder:
        mirrored = Path(folder) / "right_as_left.ply"
        mirror_left_right(trimesh.load(right_crop_path, process=False, force="mesh")).export(mirrored)
        return hard_scan_of(mirrored, f"{subject}_right", level, seed)[0]
