"""Where the personal-detail layer leaves an ear: the points still beyond 1 mm of a solved detailed head, by pinna
region, and why the layer did not take them.

    .venv/bin/python studies/detail_leftovers.py [--subject P067] [--condition ppm_detail|ppm_detail_hard]
                                                 [--evaluation evaluation/sonicom]

``ppm_detail`` (the layer on the clean crop): the clean scan target's points beyond 1 mm of the ``ppm_detail`` head.
``ppm_detail_hard`` (the layer on the fixed defective scan): the same clean points (the truth) against the
``ppm_detail_hard`` head, each marked seen when the defective scan has a point within ``SEEN_MM`` of it: a far point
the scan never saw keeps the PPM's shape by design (a hole, the cut-off part of the crop), a seen one is evidence
the layer did not take.

Reads the kept heads (``<evaluation>/steps/<subject>/<condition>/head.ply`` and the PPM head under it, ``ppm`` or
``ppm_hard``), the landmarks of the clean PPM fit (``fit_landmarks.json``, as the evaluation's regions) and the scan
targets made by the workflow (``results/<subject>/target/pinna_target.ply``, for the hard condition also
``results/<subject>/controls/hard/target/pinna_target.ply``). For the far points it prints: their regions; which way
they face (the y component of the scan's normal: + lateral, - medial, the lobule's back); how far the PPM's nearest
surface lies along the scan's normal (+ in front of the scan, - behind it); and how many fail the layer's normal
test (``normal_agreement_deg`` of ``ppm/data/personal_detail.yaml``) on the detailed head, i.e. pairs the layer
never trusts. Millimetres, project frame (x front, y left, z up). Last line: JSON.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from committed import SEEN_MM, require_workflow_files

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FAR_MM = 1.0
PPM_HEAD = {"ppm_detail": "ppm", "ppm_detail_hard": "ppm_hard"}


def _target(path: Path):
    from ppm.align.target import prepare_target  # noqa: PLC0415

    require_workflow_files(path)
    return prepare_target(path, side="left", segment=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P067")
    parser.add_argument("--condition", choices=sorted(PPM_HEAD), default="ppm_detail")
    parser.add_argument("--evaluation", type=Path, default=ROOT / "evaluation" / "sonicom")
    args = parser.parse_args()
    import trimesh  # noqa: PLC0415
    from scipy.spatial import cKDTree  # noqa: PLC0415

    from ppm.align.detail import DetailSettings  # noqa: PLC0415
    from reporting.kept_fit import kept_fit_landmarks  # noqa: PLC0415
    from reporting.pinna_regions import label_points  # noqa: PLC0415

    results = ROOT / "results" / args.subject
    truth = _target(results / "target" / "pinna_target.ply")
    store = args.evaluation / "steps" / args.subject
    heads = {name: store / name / "head.ply" for name in (PPM_HEAD[args.condition], args.condition)}
    for name, path in heads.items():
        if not path.is_file():
            sys.exit(f"{path}: missing; {args.subject}'s {name} head is not solved and kept yet")
    landmarks = kept_fit_landmarks(store / "ppm")
    if landmarks is None:
        sys.exit(f"{store / 'ppm'}: no fit_landmarks.json; run the evaluation once to keep them")
    points, normals = np.asarray(truth.points_mm), np.asarray(truth.normals)
    ppm, detailed = (trimesh.load(path, process=False, force="mesh") for path in heads.values())

    _, distance, triangle = trimesh.proximity.closest_point(detailed, points)
    far = distance > FAR_MM
    regions = label_points(points, landmarks)
    by_region = {str(r): int(n) for r, n in zip(*np.unique(regions[far], return_counts=True))}
    seen = np.ones(len(points), dtype=bool)
    if args.condition == "ppm_detail_hard":
        scan = _target(results / "controls" / "hard" / "target" / "pinna_target.ply")
        seen = cKDTree(np.asarray(scan.points_mm)).query(points)[0] <= SEEN_MM
    limit = np.cos(np.deg2rad(DetailSettings.packaged().normal_agreement_deg))
    fails_normal = np.einsum("ij,ij->i", detailed.face_normals[triangle[far]], normals[far]) < limit
    on_ppm = trimesh.proximity.closest_point(ppm, points[far])[0]
    along = np.einsum("ij,ij->i", on_ppm - points[far], normals[far])  # + the PPM in front of the scan
    medial = normals[far][:, 1] < -0.3
    lateral = normals[far][:, 1] > 0.3

    print(f"{args.subject} {args.condition}: {int(far.sum())} of {len(points)} clean scan points beyond {FAR_MM:g} mm "
          f"of the head; median distance {np.median(distance):.3f} mm")
    for region, count in sorted(by_region.items(), key=lambda item: -item[1]):
        inside = regions == region
        unseen = int(np.sum(far & inside & ~seen))
        note = f", {unseen} not seen by the defective scan" if args.condition == "ppm_detail_hard" else ""
        print(f"  {region:22s} {count:5d} of {int(inside.sum()):5d} ({100.0 * count / inside.sum():.1f} %){note}")
    if args.condition == "ppm_detail_hard":
        print(f"  seen by the defective scan (a point within {SEEN_MM:g} mm): {int(seen.sum())} of {len(points)}; "
              f"of the far points {int((far & seen).sum())} seen, {int((far & ~seen).sum())} not")
    print(f"  facing medially (the back): {int(medial.sum())}, the PPM's nearest surface "
          f"{np.median(along[medial]) if medial.any() else float('nan'):+.2f} mm along their normal (median)")
    print(f"  facing laterally (the front): {int(lateral.sum())}, the PPM's nearest surface "
          f"{np.median(along[lateral]) if lateral.any() else float('nan'):+.2f} mm along their normal (median)")
    print(f"  paired on the detailed head with a face turned beyond the layer's normal test: {int(fails_normal.sum())}")
    summary = {"subject": args.subject, "condition": args.condition, "far_points": int(far.sum()),
               "scan_points": int(len(points)), "distance_median_mm": round(float(np.median(distance)), 3),
               "far_by_region": by_region, "far_medial": int(medial.sum()), "far_lateral": int(lateral.sum()),
               "medial_offset_median_mm": round(float(np.median(along[medial])), 3) if medial.any() else None,
               "lateral_offset_median_mm": round(float(np.median(along[lateral])), 3) if lateral.any() else None,
               "fail_normal_test": int(fails_normal.sum())}
    if args.condition == "ppm_detail_hard":
        summary |= {"seen_points": int(seen.sum()), "far_seen": int((far & seen).sum()),
                    "far_unseen": int((far & ~seen).sum()),
                    "far_unseen_by_region": {r: int(np.sum(far & ~seen & (regions == r))) for r in by_region}}
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
