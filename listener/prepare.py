"""A new listener's head scan prepared for the pipeline: in the project frame, closed, and both pinnae cut out.

Writes, atomically, into one folder laid out as a dataset's subject (millimetres, project frame):
``head.ply`` (closed), ``pinna_left_crop.ply``, ``pinna_right_crop.ply`` (in place; mirror for a left shape),
and ``frame.json`` (the frame found: :meth:`listener.head_frame.HeadFrame.as_dict`, and what was repaired).
Nothing is written unless every step succeeds.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import trimesh

from core.atomic import write_text_atomic
from ppm.errors import PpmError
from ppm.mesh_io import load_mesh, write_mesh

from .ears import pinna_crop
from .errors import ListenerError
from .head_frame import find_head_frame, settings
from .repair import check_holes, closed_head
from .units import UNIT_MM, infer_unit

OUTPUTS = ("head.ply", "pinna_left_crop.ply", "pinna_right_crop.ply", "frame.json")


def prepare_head(head_path: str | os.PathLike, out_dir: str | os.PathLike) -> dict:
    """Prepare the head scan at ``head_path`` (PLY/STL/OBJ, any pose, mm/cm/m) into ``out_dir``; returns the
    frame summary written to ``frame.json``.

    Raises
    ------
    ListenerError
        If the scan is unreadable, not a head with two ears, in inches, or cannot be closed.
    """
    head_path, out_dir = Path(head_path), Path(out_dir)
    try:
        scan = load_mesh(head_path)
    except PpmError as error:
        raise ListenerError(str(error)) from error
    unit = infer_unit(scan.vertices, tuple(settings()["units"]["head_diameter_mm"]), str(head_path))
    check_holes(trimesh.Trimesh(scan.vertices * UNIT_MM[unit], scan.faces, process=True), str(head_path))
    frame = find_head_frame(scan, str(head_path))
    head, repairs = closed_head(frame.apply(scan), str(head_path))
    crops = {side: pinna_crop(head, side, str(head_path)) for side in ("left", "right")}
    summary = {"head": str(head_path), **frame.as_dict(), "repairs": repairs,
               "elements": int(len(head.faces)),
               "pinna_crop_vertices": {side: int(len(crop.vertices)) for side, crop in crops.items()}}
    out_dir.mkdir(parents=True, exist_ok=True)
    write_mesh(out_dir / "head.ply", head.vertices, head.faces)
    for side, crop in crops.items():
        write_mesh(out_dir / f"pinna_{side}_crop.ply", crop.vertices, crop.faces)
    write_text_atomic(out_dir / "frame.json", json.dumps(summary, indent=1) + "\n")
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Bring a head scan (any pose, mm/cm/m) into the project frame, "
                                     "close it and cut out both pinnae.")
    parser.add_argument("head", type=Path, help="head scan: PLY, STL or OBJ with both ears")
    parser.add_argument("out", type=Path, help="folder for head.ply, pinna_*_crop.ply and frame.json")
    args = parser.parse_args(argv)
    try:
        summary = prepare_head(args.head, args.out)
    except ListenerError as error:
        parser.exit(2, f"error: {error}\n")
    print(json.dumps({key: summary[key] for key in ("unit", "kept_as_given", "rotation_deg", "left_canal_mm",
                                                     "right_canal_mm", "elements")}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
