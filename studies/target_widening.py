"""Fitting again on the scan around the first fit (ppm.align.widen): what it changes on the clean crops and on the
evaluation's fixed hard scans, and why it is needed there (the segmentation leaves the lobule out of a scan seen
from the side).

    .venv/bin/python studies/target_widening.py --subject P143 [--subject P067]

Per subject, for the clean crop and the fixed hard scan (evaluation/sonicom/hard_scans/): the PPM (leave-one-out
template, results/templates/without_<subject>) fitted to the segmented target as before, the share of the scan
within reach of that fit that the segmentation left out (anywhere, and over the pinna: the packaged criterion), the share of the true lobule the scan and the segmented
target hold (a point within 2 mm), and, fitted again on the widened target (whether or not the packaged threshold
asks for it), distances to the clean crop (the truth) over the stitched region: truth -> fit and fit -> truth median
/ p95, over the parts the hard scan saw and never saw, and over the lobule (mm). Last line: JSON of every figure.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "studies"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", action="append", default=None)
    args = parser.parse_args()
    import bpy  # noqa: F401  (before pymeshlab)
    import numpy as np
    import trimesh

    from scipy.spatial import cKDTree

    from committed import SONICOM
    from ppm.align import align, prepare_target
    from ppm.align.widen import SAME_POINT_MM, WideningSettings, left_out_share, widened_target
    from ppm.model import PinnaModel
    from reporting.pinna_regions import landmark_positions_mm, label_points
    from reporting.stitched_region import region_distances, seen_by

    evaluation = ROOT / "evaluation" / "sonicom"
    widening = WideningSettings.packaged()
    figures: dict = {}
    for subject in args.subject or ["P143", "P067"]:
        template = ROOT / "results" / "templates" / f"without_{subject}"
        if not (template / "template_left.ply").is_file():
            raise SystemExit(f"{template}: no leave-one-out template; run the evaluation's build_template rule first")
        model = PinnaModel.from_template(template)
        crop = SONICOM / subject / "pinna_left_crop.ply"
        truth = prepare_target(crop)
        hard_path = evaluation / "hard_scans" / f"{subject}_hard_scan.ply"
        hard_scan = trimesh.load(hard_path, process=False, force="mesh")
        seen = seen_by(hard_scan.vertices, truth.points_mm)
        for scan_name, path in (("clean", crop), ("hard", hard_path)):
            target = prepare_target(path, side="left")
            first = align(model, target)
            guide = trimesh.Trimesh(first.vertices_mm, model.faces, process=False)
            if scan_name == "clean":
                # the lobule as the clean fit's landmarks say (the same labels for both scans)
                with tempfile.TemporaryDirectory() as folder:
                    guide.export(Path(folder) / "fit.ply")
                    landmarks = landmark_positions_mm(Path(folder) / "fit.ply", template / "landmarks.yaml")
                lobule = label_points(truth.points_mm, landmarks) == "lobule"
            widened = widened_target(target, first.vertices_mm, model.faces, widening.reach_mm)
            share = left_out_share(target, widened, first.vertices_mm, model.faces, widening.pinna_from_rim_mm)
            anywhere = float(np.mean(cKDTree(target.points_mm).query(widened.points_mm)[0] > SAME_POINT_MM))
            scan_holds = seen_by(target.scan.vertices, truth.points_mm[lobule]).mean()
            target_holds = seen_by(target.points_mm, truth.points_mm[lobule]).mean()
            row = {"left_out_share": round(share, 4), "left_out_anywhere_share": round(anywhere, 4),
                   "target_points": int(len(target.points_mm)),
                   "widened_points": int(len(widened.points_mm)), "lobule_in_scan": round(float(scan_holds), 3),
                   "lobule_in_target": round(float(target_holds), 3)}
            print(f"{subject} {scan_name}: the segmented target holds {len(target.points_mm)} points, the scan within "
                  f"{widening.reach_mm:g} mm of its fit {len(widened.points_mm)}: {100 * anywhere:.1f} % left out, "
                  f"{100 * share:.1f} % over the pinna (refit above {100 * widening.refit_above_share:g} %); of the "
                  "true lobule the scan holds "
                  f"{100 * scan_holds:.0f} %, the target {100 * target_holds:.0f} %", flush=True)
            for fit_name, fit in (("segmented target", first), ("widened target", align(model, widened))):
                distances = region_distances(truth, seen, guide, fit.vertices_mm, model.faces)
                surface = trimesh.Trimesh(fit.vertices_mm, model.faces, process=False)
                to_lobule = trimesh.proximity.closest_point(surface, truth.points_mm[lobule])[1]
                entry = {part: [round(distances[f"{part}_median_mm"], 3), round(distances[f"{part}_p95_mm"], 3)]
                         for part in ("truth_to_fit", "fit_to_truth", "seen", "unseen")}
                entry["lobule"] = [round(float(np.median(to_lobule)), 3), round(float(np.percentile(to_lobule, 95)), 3)]
                row[fit_name] = entry
                print(f"{subject} {scan_name} fitted to the {fit_name:16s} " + "  ".join(
                    f"{part} {m:.3f}/{p:.3f}" for part, (m, p) in entry.items()
                    if not (scan_name == "clean" and part in ("seen", "unseen"))), flush=True)
            figures[f"{subject}/{scan_name}"] = row
    print(json.dumps({"reach_mm": widening.reach_mm, "pinna_from_rim_mm": widening.pinna_from_rim_mm,
                      "refit_above_share": widening.refit_above_share,
                      "scans": figures}))


if __name__ == "__main__":
    main()
