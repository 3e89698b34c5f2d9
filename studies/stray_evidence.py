"""Issues 54 and 56: does settling the scan's stray points onto their neighbours' surface bring a hard listener's ears
nearer? The placed hard listener's ears on each draw of its scans solved so far
(results/listeners/<subject>_hard_placed[_draw<N>]/: the PPM fits and the prepared whole ear scans, made by
benchmarks/new_listener.py --hard --placed [--draw N]), the packaged layer laid on each fit as the workflow lays it
(the whole scan joined with its reconstruction's fill of its holes), and again with ``outlier_sigmas`` set: the
scan's points that stand off its local surface by more than that many times its noise
(``ppm.align.scan_noise.stray_points``; outliers thrown near the surface, which the isolation test keeps) moved onto
the quadric through their other neighbours (``settle_strays``). Cutting them out with their faces instead was tried
first: on the first draw it took the seen parts farther (studies/results/stray_evidence/*_left_out_partial.txt).

Measured like studies/seen_unseen_error.py: the layered pinna's faces split into those the hard scan saw and those it
did not, each face centre to the head as scanned (area-weighted median / p95, mm, and the area share beyond
0.5 mm), and the points of the surface the layer pairs with (the scan and its fill,
``ppm.align.detail.evidence_surface``) to the head as scanned: how many lie beyond 1.5 mm, and how many of those the
test finds.

Run: .venv/bin/python studies/stray_evidence.py [--subject P143] [--sigmas 2.5 3]
Last line: JSON {listener: {side: {"strays": {...}, setting: split figures}}}.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "studies"))

#: A scan point farther than this from the head as scanned counts as an outlier here (mm): three times the hard
#: level's 0.5 mm noise.
FAR_MM = 1.5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--sigmas", type=float, nargs="*", default=[3.0])
    args = parser.parse_args()
    import bpy  # noqa: F401, PLC0415  (before pymeshlab)
    import trimesh  # noqa: PLC0415

    from ppm.align import prepare_target  # noqa: PLC0415
    from ppm.align.detail import DetailSettings, evidence_surface, personal_detail  # noqa: PLC0415
    from seen_unseen_error import MIRROR, STORE, split_errors  # noqa: PLC0415
    from stitching.reconstruction import layer_evidence  # noqa: PLC0415

    scanned_head = trimesh.load(STORE / f"{args.subject}_new" / "scanned" / "head.ply", process=False, force="mesh")
    listeners = sorted(path.name for path in (ROOT / "results" / "listeners").glob(f"{args.subject}_hard_placed*")
                       if (path / "align").is_dir())
    if not listeners:
        raise SystemExit("no placed hard listener to lay: run benchmarks/new_listener.py --hard --placed first")
    out = ROOT / "results" / "studies" / "stray_evidence"
    out.mkdir(parents=True, exist_ok=True)
    result: dict = {}
    for name in listeners:
        base = ROOT / "results" / "listeners" / name
        result[name] = {}
        for side in ("left", "right"):
            scan_path = base / "prepared" / f"ear_scan_{side}.ply"
            fit = trimesh.load(base / "align" / side / "aligned_pinna.ply", process=False, force="mesh")
            vertices, faces = np.asarray(fit.vertices), np.asarray(fit.faces)
            scan = prepare_target(scan_path, side=side, segment=False)
            # the scan and its fill, the same for every setting here; asked with the stray test on, it records the
            # scan's own noise for the test (the packaged layer does not read it)
            evidence = layer_evidence(scan, DetailSettings.packaged(outlier_sigmas=3.0))
            points = np.asarray(evidence_surface(evidence, DetailSettings.packaged())[0].vertices)  # what it pairs with
            in_head = points @ (MIRROR if side == "right" else np.eye(3))  # the fits' left-ear frame back to the head's
            far = trimesh.proximity.closest_point(scanned_head, in_head)[1] > FAR_MM
            rows = {"strays": {"points": len(points), f"beyond_{FAR_MM:g}mm": int(far.sum())}}
            print(f"{name} {side:5s}: {len(points)} evidence points (the scan and its fill), {int(far.sum())} beyond "
                  f"{FAR_MM:g} mm of the head as scanned", flush=True)
            for sigmas in [None, *args.sigmas]:
                label = "packaged" if sigmas is None else f"outlier_sigmas {sigmas:g}"
                settings = DetailSettings.packaged(**({} if sigmas is None else {"outlier_sigmas": sigmas}))
                if sigmas is not None:
                    stray = evidence_surface(evidence, settings)[1]
                    rows["strays"][label] = {"settled": int(stray.sum()), "of_far": int((stray & far).sum())}
                layer = personal_detail(vertices, faces, evidence, settings)
                layered = out / f"{name}_{side}_{label.replace(' ', '_')}.ply"
                trimesh.Trimesh(vertices + layer.displacement_mm, faces, process=False).export(layered)
                split = split_errors(layered, scan_path, scanned_head, side)
                rows[label] = split
                extra = "" if sigmas is None else (f" ({rows['strays'][label]['settled']} points settled, "
                                                   f"{rows['strays'][label]['of_far']} of the far ones)")
                print(f"  {label:18s}: seen {split['seen']['median_mm']:.3f} / {split['seen']['p95_mm']:.3f} mm, "
                      f"unseen {split['unseen']['median_mm']:.3f} / {split['unseen']['p95_mm']:.3f} mm{extra}",
                      flush=True)
            result[name][side] = rows
    print(json.dumps(result))


if __name__ == "__main__":
    main()
