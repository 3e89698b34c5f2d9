"""Issue 54: could the other ear (mirrored, registered) serve as evidence where one ear's scan is blind?

    .venv/bin/python studies/other_ear_evidence.py --subject P143

For the evaluation's fixed hard scan of the left ear (results/<subject>/controls/hard/scan.ply) and its PPM fit
(controls/ppm_hard), the truth points of the region the stitch replaces that the scan never saw (no scan point within
2 mm) are measured against: the PPM fit, its layer (towards the whole scan), and the right ear mirrored onto the left
and registered to the left scan by rigid ICP (points, no scale), once as the right ear's own hard scan (the same
level, drawn as ``benchmarks/new_listener.py`` draws it: seed 19 with "<subject>_right") and once as its clean crop
(a listener whose other ear was scanned well). Also: how many of those unseen points the registered other ear's
scan saw (a point within 2 mm), and the distance there (the layer's too). Millimetres, head frame; last line JSON.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "studies"))
sys.path.insert(0, str(ROOT / "benchmarks"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    args = parser.parse_args()
    import bpy  # noqa: F401  (before pymeshlab)
    import numpy as np
    import trimesh

    from committed import SONICOM, require_workflow_files
    from ppm.align import prepare_target
    from layer_evidence import BEFORE
    from ppm.align.detail import DetailSettings, personal_detail
    from reporting.stitched_region import seen_by
    from new_listener import evaluation_hard_scan  # benchmarks/: the draw of the right ear the listener gets
    from stitching.both_ears import mirror_left_right, right_ear_scan_as_left
    from stitching.replace_pinna import under_pinna

    base = ROOT / "results" / args.subject / "controls"
    scan_path, fit_path = base / "hard" / "scan.ply", base / "ppm_hard" / "align" / "aligned_pinna.ply"
    require_workflow_files(scan_path, fit_path)
    truth = prepare_target(SONICOM / args.subject / "pinna_left_crop.ply")
    scan = trimesh.load(scan_path, process=False, force="mesh")
    fit = trimesh.load(fit_path, process=False, force="mesh")
    vertices, faces = np.asarray(fit.vertices), np.asarray(fit.faces)
    unseen = truth.points_mm[under_pinna(truth.points_mm, fit) & ~seen_by(scan.vertices, truth.points_mm)]
    right_crop = SONICOM / args.subject / "pinna_right_crop.ply"
    recipe = evaluation_hard_scan()
    others = {"the other ear's hard scan": right_ear_scan_as_left(right_crop, args.subject, recipe["level"],
                                                                  recipe["seed"]),
              "the other ear's clean crop": mirror_left_right(trimesh.load(right_crop, process=False, force="mesh"))}
    figures: dict[str, dict] = {"unseen_points": int(len(unseen))}

    def measure(name: str, surface: trimesh.Trimesh, covered: np.ndarray | None = None,
                layer: np.ndarray | None = None) -> np.ndarray:
        """Print and keep ``surface``'s distances over the unseen points; with ``covered`` (the points the surface
        saw) also the share and the median there, with ``layer``'s (the layer's distances) beside it."""
        distance = trimesh.proximity.closest_point(surface, unseen)[1]
        row = {"median_mm": round(float(np.median(distance)), 3), "p95_mm": round(float(np.percentile(distance, 95)), 3)}
        text = f"median / p95 {row['median_mm']:.3f} / {row['p95_mm']:.3f} mm"
        if covered is not None:
            row["covered_share"] = round(float(covered.mean()), 3)
            text += f"; it saw {100 * covered.mean():.0f} % of them"
            if covered.any():
                row["covered_median_mm"] = round(float(np.median(distance[covered])), 3)
                row["layer_there_median_mm"] = round(float(np.median(layer[covered])), 3)
                text += (f", {row['covered_median_mm']:.3f} mm there (median; the layer "
                         f"{row['layer_there_median_mm']:.3f})")
        figures[name] = row
        print(f"{args.subject} {name:30s} {text}", flush=True)
        return distance

    print(f"{args.subject}: {len(unseen)} truth points of the stitched region the left hard scan never saw")
    measure("PPM (ppm_hard)", fit)
    whole = prepare_target(scan_path, side="left", segment=False)
    # the layer as this study measured it (before the hole fill and fold smoothing became its defaults)
    layered = vertices + personal_detail(vertices, faces, whole, DetailSettings.packaged(**BEFORE)).displacement_mm
    layer_distance = measure("layer (whole scan)", trimesh.Trimesh(layered, faces, process=False))
    for name, other in others.items():
        moved, _, _ = trimesh.registration.icp(np.asarray(other.vertices), np.asarray(scan.vertices),
                                               max_iterations=60, reflection=False, scale=False)
        registered = trimesh.Trimesh(trimesh.transform_points(other.vertices, moved), other.faces, process=False)
        measure(name, registered, seen_by(registered.vertices, unseen), layer_distance)
    print(json.dumps({"subject": args.subject, **figures}))


if __name__ == "__main__":
    main()
