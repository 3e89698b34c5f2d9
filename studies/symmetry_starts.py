"""Which mirror-ICP start the head frame needs to polish (listener.head_frame.symmetry_plane): on each head with ears
in ../shared/data (SONICOM P039, P067, P143 with both ears finely resolved; CGTUB), the mirror RMS (mm) of the three
principal-axis starts after ICP and after the polish, and the ratio of each other start's ICP RMS to the best polished
RMS (symmetry.polish_within in listener/data/head_frame.yaml leaves a start unpolished above it).

Run: .venv/bin/python studies/symmetry_starts.py
Last line: JSON {head: {"icp_mm": [...], "polished_mm": [...], "others_over_best": [...], "best_is_lowest_icp": bool}}.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DATA = ROOT.parent / "shared" / "data"


def main() -> None:
    import bpy  # noqa: F401, PLC0415  (before pymeshlab)
    import trimesh  # noqa: PLC0415

    from listener import head_frame  # noqa: PLC0415
    from listener.dataset_heads import both_ears_head  # noqa: PLC0415

    config = head_frame.settings()
    heads = {name: lambda name=name: both_ears_head(DATA / "sonicom" / name) for name in ("P039", "P067", "P143")}
    heads["CGTUB"] = lambda: trimesh.load(DATA / "heads" / "cgtub_head_2mm.ply", process=False, force="mesh")
    result = {}
    for name, load in heads.items():
        mesh = load()
        head = trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), process=True)  # as find_head_frame
        samples = head_frame._surface_samples(head, config["concha"]["samples_per_mm2"])
        tree, subset, starts = head_frame.mirror_icp_planes(samples, config["symmetry"])
        icp = [rms for rms, _, _ in starts]
        polished = [head_frame._polish_plane(tree, subset, normal, offset)[2] for _, normal, offset in starts]
        best = int(np.argmin(polished))
        result[name] = {"icp_mm": [round(v, 3) for v in icp], "polished_mm": [round(v, 3) for v in polished],
                        "others_over_best": [round(icp[i] / polished[best], 2) for i in range(3) if i != best],
                        "polish_lowers_others_by": [round(1 - polished[i] / icp[i], 3) for i in range(3) if i != best],
                        "best_is_lowest_icp": best == int(np.argmin(icp))}
        print(f"{name}: after ICP {result[name]['icp_mm']} mm, polished {result[name]['polished_mm']} mm; the other "
              f"starts' ICP RMS {result[name]['others_over_best']} x the best polished, the polish lowers them by "
              f"{result[name]['polish_lowers_others_by']}", flush=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
