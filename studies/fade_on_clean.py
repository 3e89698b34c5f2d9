"""What the personal-detail layer's evidence fade changes where the scan is whole: the layer laid on the PPM fit of a
subject's clean crop with the shipped settings and with ``evidence_fade_mm`` set, and the two compared.

    .venv/bin/python studies/fade_on_clean.py [--subject P143] [--fade-mm 2]

Reads what the workflow makes for the ``ppm`` condition: the PPM fit of the clean crop
(``results/<subject>/align/aligned_pinna.blend``) and its prepared scan (``results/<subject>/target/pinna_target.ply``);
make them with ``.venv/bin/python -m snakemake --cores 2 --configfile config/paper_sonicom.yaml --
results/<subject>/align/aligned_pinna.blend``. Prints the share of the PPM's vertices whose displacement the fade
changes by more than 1 µm, how far the two layers differ (median, p99, max), and, for the PPM vertices within 5 mm of
the clean crop, each layer's distance to it (median, p95). Millimetres, project frame. Last line: JSON.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from committed import SONICOM, require_workflow_files, subject_parser

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = subject_parser(__doc__.splitlines()[0])
    parser.add_argument("--fade-mm", type=float, default=2.0, help="the evidence fade to compare with none (mm)")
    args = parser.parse_args()
    import bpy  # noqa: F401, PLC0415  (before anything that may load pymeshlab)
    import trimesh  # noqa: PLC0415

    from ppm.align import prepare_target  # noqa: PLC0415
    from ppm.align.detail import DetailSettings, personal_detail  # noqa: PLC0415
    from ppm.model import PinnaModel  # noqa: PLC0415

    results = ROOT / "results" / args.subject
    blend, target_path = results / "align" / "aligned_pinna.blend", results / "target" / "pinna_target.ply"
    require_workflow_files(blend, target_path)
    model = PinnaModel.from_blend(str(blend))
    if model.detail_weight:
        model.set_detail_weight(0.0)
    target = prepare_target(str(target_path), side="left", segment=False)
    posed = model.evaluate()
    plain = personal_detail(posed, model.faces, target, DetailSettings.packaged(evidence_fade_mm=None))
    faded = personal_detail(posed, model.faces, target, DetailSettings.packaged(evidence_fade_mm=args.fade_mm))
    difference = np.linalg.norm(plain.displacement_mm - faded.displacement_mm, axis=1)
    crop = trimesh.load(SONICOM / args.subject / "pinna_left_crop.ply", process=False, force="mesh")
    truth = trimesh.proximity.ProximityQuery(crop)
    near = np.abs(truth.signed_distance(posed)) < 5.0
    figures = {"subject": args.subject, "fade_mm": args.fade_mm, "vertices": len(posed),
               "changed_percent": round(float(np.mean(difference > 1e-3) * 100), 2),
               "difference_median_mm": round(float(np.median(difference)), 4),
               "difference_p99_mm": round(float(np.percentile(difference, 99)), 4),
               "difference_max_mm": round(float(difference.max()), 4)}
    print(f"{args.subject}: the {args.fade_mm:g} mm fade changes {figures['changed_percent']:.2f} % of the "
          f"{len(posed):,} PPM vertices by more than 1 µm; the layers differ by {figures['difference_median_mm']:.4f} "
          f"(median), {figures['difference_p99_mm']:.4f} (p99), {figures['difference_max_mm']:.4f} mm (max)")
    for label, layer in (("no fade", plain), (f"fade {args.fade_mm:g} mm", faded)):
        to_truth = np.abs(truth.signed_distance(posed + layer.displacement_mm))[near]
        key = "fade" if layer is faded else "plain"
        figures[f"{key}_truth_median_mm"] = round(float(np.median(to_truth)), 4)
        figures[f"{key}_truth_p95_mm"] = round(float(np.percentile(to_truth, 95)), 4)
        print(f"  {label:12} PPM vertices within 5 mm of the clean crop -> crop: median "
              f"{figures[key + '_truth_median_mm']:.4f}, p95 {figures[key + '_truth_p95_mm']:.4f} mm")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
