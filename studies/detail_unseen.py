"""What the personal-detail layer does where the defective scan saw nothing: the layer laid afresh on the PPM fit of
a subject's hard scan, and its displacements split by whether the clean crop (the truth) near each PPM vertex was
seen by the scan.

    .venv/bin/python studies/detail_unseen.py [--subject P067] [--set evidence_fade_mm=3 ...]

Reads what the workflow makes for the ``*_hard`` conditions: the PPM fit of the fixed defective scan
(``results/<subject>/controls/ppm_hard/align/aligned_pinna.blend``) and its prepared scan
(``results/<subject>/controls/hard/target/pinna_target.ply``); make them with ``.venv/bin/python -m snakemake
--cores 2 --configfile config/paper_sonicom.yaml -- results/<subject>/controls/ppm_hard/align/aligned_pinna.blend``.
The scan and the truth: ``evaluation/sonicom/hard_scans/<subject>_hard_scan.ply`` and the dataset's
``pinna_left_crop.ply``. A crop point is *seen* when a scan point lies within ``committed.SEEN_MM`` (2 mm) of it; each PPM vertex within
``NEAR_MM`` of the crop takes the mark of its nearest crop point. For the seen and the unseen vertices: how far the
layer moves them, their distance to the truth without and with the layer (median, p95), and the share the layer
takes more than 0.1 mm farther from the truth. The layer's settings are ``ppm/data/personal_detail.yaml``'s, with
``--set name=value`` (YAML values) replaced. Millimetres, project frame. Last line: JSON.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from committed import SEEN_MM, crop_seen_by_hard_scan, require_workflow_files, subject_parser

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
NEAR_MM = 5.0
FARTHER_MM = 0.1


def main() -> None:
    parser = subject_parser(__doc__.splitlines()[0])
    parser.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE",
                        help="a setting of ppm/data/personal_detail.yaml replaced (YAML value)")
    args = parser.parse_args()
    import yaml  # noqa: PLC0415

    overrides = {name: yaml.safe_load(value) for name, _, value in (item.partition("=") for item in args.set)}
    import bpy  # noqa: F401, PLC0415  (before anything that may load pymeshlab)
    import trimesh  # noqa: PLC0415
    from scipy.spatial import cKDTree  # noqa: PLC0415

    from ppm.align import prepare_target  # noqa: PLC0415
    from ppm.align.detail import DetailSettings, personal_detail  # noqa: PLC0415
    from ppm.model import PinnaModel  # noqa: PLC0415

    controls = ROOT / "results" / args.subject / "controls"
    blend, target_path = controls / "ppm_hard" / "align" / "aligned_pinna.blend", controls / "hard" / "target" / "pinna_target.ply"
    require_workflow_files(blend, target_path)
    model = PinnaModel.from_blend(str(blend))
    target = prepare_target(str(target_path), side="left", segment=False)
    posed = model.evaluate()
    moved = personal_detail(posed, model.faces, target, DetailSettings.packaged(**overrides)).displacement_mm
    crop, crop_seen = crop_seen_by_hard_scan(args.evaluation, args.subject)
    gap, nearest = cKDTree(crop.vertices).query(posed)
    truth = trimesh.proximity.ProximityQuery(crop)
    before = np.abs(truth.signed_distance(posed))
    after = np.abs(truth.signed_distance(posed + moved))
    figures = {"subject": args.subject, "settings": overrides, "seen_mm": SEEN_MM, "near_mm": NEAR_MM}
    for label, chosen in (("seen", (gap < NEAR_MM) & crop_seen[nearest]), ("unseen", (gap < NEAR_MM) & ~crop_seen[nearest])):
        row = {"vertices": int(chosen.sum()),
               "moved_median_mm": round(float(np.median(np.linalg.norm(moved[chosen], axis=1))), 3),
               "truth_median_mm": [round(float(np.median(d[chosen])), 3) for d in (before, after)],
               "truth_p95_mm": [round(float(np.percentile(d[chosen], 95)), 3) for d in (before, after)],
               "farther_percent": round(float(np.mean(after[chosen] > before[chosen] + FARTHER_MM) * 100), 1)}
        figures[label] = row
        print(f"{args.subject} {label:6} {row['vertices']:5d} PPM vertices: the layer moves them {row['moved_median_mm']:.3f} mm "
              f"(median); to the truth median {row['truth_median_mm'][0]:.3f} -> {row['truth_median_mm'][1]:.3f}, p95 "
              f"{row['truth_p95_mm'][0]:.3f} -> {row['truth_p95_mm'][1]:.3f} mm; {row['farther_percent']:.1f} % taken "
              f"more than {FARTHER_MM} mm farther", flush=True)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
