"""Where the personal-detail layer leaves a scan: the scan points still beyond 1 mm of a solved ``ppm_detail`` head,
by pinna region, and why the layer did not take them.

    .venv/bin/python studies/detail_leftovers.py [--subject P067] [--evaluation evaluation/sonicom]
                                                 [--target results/P067/target/pinna_target.ply]

Reads the kept heads (``<evaluation>/steps/<subject>/{ppm,ppm_detail}/head.ply``, the ones solved), the landmarks
of the fit that made the PPM head (``fit_landmarks.json``, as the evaluation's regions) and the subject's scan target
(made by the workflow: ``snakemake ... results/<subject>/target/pinna_target.ply``). For the far points it prints:
their regions; which way they face (the y component of the scan's normal: + lateral, - medial, the lobule's back);
how far the PPM's nearest surface lies along the scan's normal (+ in front of the scan, - behind it); and how many
fail the layer's normal test (``normal_agreement_deg`` of ``ppm/data/personal_detail.yaml``) on the detailed head,
i.e. pairs the layer never trusts. Millimetres, project frame (x front, y left, z up). Last line: JSON.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FAR_MM = 1.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P067")
    parser.add_argument("--evaluation", type=Path, default=ROOT / "evaluation" / "sonicom")
    parser.add_argument("--target", type=Path,
                        help="the scan target (default results/<subject>/target/pinna_target.ply)")
    args = parser.parse_args()
    import trimesh  # noqa: PLC0415

    from ppm.align.detail import DetailSettings  # noqa: PLC0415
    from ppm.align.target import prepare_target  # noqa: PLC0415
    from reporting.kept_fit import kept_fit_landmarks  # noqa: PLC0415
    from reporting.pinna_regions import label_points  # noqa: PLC0415

    target_path = args.target or ROOT / "results" / args.subject / "target" / "pinna_target.ply"
    if not target_path.is_file():
        sys.exit(f"{target_path}: missing; make it with `.venv/bin/python -m snakemake --cores 2 --configfile "
                 f"config/paper_sonicom.yaml -- results/{args.subject}/target/pinna_target.ply`")
    store = args.evaluation / "steps" / args.subject
    heads = {name: store / name / "head.ply" for name in ("ppm", "ppm_detail")}
    for name, path in heads.items():
        if not path.is_file():
            sys.exit(f"{path}: missing; {args.subject}'s {name} head is not solved and kept yet")
    landmarks = kept_fit_landmarks(store / "ppm")
    if landmarks is None:
        sys.exit(f"{store / 'ppm'}: no fit_landmarks.json; run the evaluation once to keep them")
    target = prepare_target(target_path, side="left", segment=False)
    points, normals = np.asarray(target.points_mm), np.asarray(target.normals)
    ppm = trimesh.load(heads["ppm"], process=False, force="mesh")
    detailed = trimesh.load(heads["ppm_detail"], process=False, force="mesh")

    _, distance, triangle = trimesh.proximity.closest_point(detailed, points)
    far = distance > FAR_MM
    regions = label_points(points, landmarks)
    by_region = {str(r): int(n) for r, n in zip(*np.unique(regions[far], return_counts=True))}
    limit = np.cos(np.deg2rad(DetailSettings.packaged().normal_agreement_deg))
    fails_normal = np.einsum("ij,ij->i", detailed.face_normals[triangle[far]], normals[far]) < limit
    on_ppm = trimesh.proximity.closest_point(ppm, points[far])[0]
    along = np.einsum("ij,ij->i", on_ppm - points[far], normals[far])  # + the PPM in front of the scan
    medial = normals[far][:, 1] < -0.3
    lateral = normals[far][:, 1] > 0.3

    print(f"{args.subject}: {int(far.sum())} of {len(points)} scan points beyond {FAR_MM:g} mm of the ppm_detail head")
    for region, count in sorted(by_region.items(), key=lambda item: -item[1]):
        total = int(np.sum(regions == region))
        print(f"  {region:22s} {count:5d} of {total:5d} ({100.0 * count / total:.1f} %)")
    print(f"  facing medially (the back): {int(medial.sum())}, the PPM's nearest surface "
          f"{np.median(along[medial]) if medial.any() else float('nan'):+.2f} mm along their normal (median)")
    print(f"  facing laterally (the front): {int(lateral.sum())}, the PPM's nearest surface "
          f"{np.median(along[lateral]) if lateral.any() else float('nan'):+.2f} mm along their normal (median)")
    print(f"  paired on the detailed head with a face turned beyond the layer's normal test: {int(fails_normal.sum())}")
    print(json.dumps({"subject": args.subject, "far_points": int(far.sum()), "scan_points": int(len(points)),
                      "far_by_region": by_region, "far_medial": int(medial.sum()), "far_lateral": int(lateral.sum()),
                      "medial_offset_median_mm": round(float(np.median(along[medial])), 3) if medial.any() else None,
                      "lateral_offset_median_mm": round(float(np.median(along[lateral])), 3) if lateral.any() else None,
                      "fail_normal_test": int(fails_normal.sum())}))


if __name__ == "__main__":
    main()
