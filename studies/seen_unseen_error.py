"""Where a hard listener's ears still miss (issue 54): each stitched pinna of the listeners whose hard ear scans were
placed by the head's frame (P143_hard_placed with the personal-detail layer, P143_hard_ppm_placed without it, and
P143_hard_oracle_placed, whose scans were completed by the truth where they were blind, and
P143_hard_blind_oracle_placed, the same with the scans' own heights kept where they saw; P143_hard_noise_placed, whose
layer ends at the scans' noise; P143_hard_supple_placed, whose layer goes a stage further; P143_hard_points_placed,
the supple end led by the scan's points), split into the faces the hard scan saw (a scan point within
reporting.coverage.SEEN_MM of the face's centre, the coverage report's rule) and the faces it did not, each face's
centre measured to the head as scanned (the solved reference head in the step store, the listener's frame, mm).
Area-weighted median / p95 and the share of area beyond 0.5 mm.

Needs the listeners' run folders (results/listeners/<name>/, made by benchmarks/new_listener.py --hard --placed
[--no-layer], --hard --oracle, --hard --noise-floor, --hard --supple-end and --hard --layer-variant points) and the
step store's scanned head.

With ``--draw N`` (N >= 1) the two listeners solved on the N-th other draw of the same hard recipe instead
(``<subject>_hard_placed_draw<N>``, the packaged layer, and ``<subject>_hard_points_placed_draw<N>``, the points layer:
``benchmarks/new_listener.py --hard --placed --draw N`` and ``--hard --layer-variant points --draw N``), split by
their own scans, and the oracle of that draw where it was solved (``<subject>_hard_oracle_placed_draw<N>``,
``--hard --oracle --draw N``).

Run: .venv/bin/python studies/seen_unseen_error.py [--subject P143] [--draw N]
Last line: JSON {listener: {side: {seen|unseen: {area_share, median_mm, p95_mm, share_over_0_5mm}}}}.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

STORE = ROOT / "benchmarks" / "results" / "new_listener" / "steps_dataset_grid" / "listeners"
#: The left-ear frame of the fits holds a right ear mirrored across the mid-sagittal plane (y -> -y).
MIRROR = np.diag([1.0, -1.0, 1.0])


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The ``q`` quantile (0-1) of ``values`` with each value counted by its ``weights`` (areas)."""
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, q * cumulative[-1])])


def split_errors(pinna_path: Path, scan_path: Path, scanned_head, side: str) -> dict:
    """The pinna's faces seen / not seen by its scan: area share, area-weighted median / p95 of the face centres'
    distance to ``scanned_head`` (mm) and the area share beyond 0.5 mm."""
    import trimesh  # noqa: PLC0415
    from scipy.spatial import cKDTree  # noqa: PLC0415

    from ppm.align import prepare_target  # noqa: PLC0415
    from reporting.coverage import SEEN_MM  # noqa: PLC0415

    pinna = trimesh.load(pinna_path, process=False, force="mesh")
    scan_points = prepare_target(scan_path, side=side, segment=False).points_mm  # the layer's evidence, as coverage
    centres, areas = pinna.triangles_center, pinna.area_faces
    seen = cKDTree(scan_points).query(centres, distance_upper_bound=SEEN_MM)[0] <= SEEN_MM
    in_head = centres @ MIRROR if side == "right" else centres  # back to the head's own frame
    distance = trimesh.proximity.closest_point(scanned_head, in_head)[1]
    rows = {}
    for name, mask in (("seen", seen), ("unseen", ~seen)):
        if not mask.any():
            continue
        d, w = distance[mask], areas[mask]
        rows[name] = {"area_share": round(float(w.sum() / areas.sum()), 3),
                      "median_mm": round(weighted_quantile(d, w, 0.5), 3),
                      "p95_mm": round(weighted_quantile(d, w, 0.95), 3),
                      "share_over_0_5mm": round(float(w[d > 0.5].sum() / w.sum()), 3)}
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subject", default="P143")
    parser.add_argument("--draw", type=int, default=0,
                        help="N >= 1: the listeners of the N-th other draw of the hard scans (packaged and points)")
    args = parser.parse_args()
    if args.draw < 0:
        parser.error(f"--draw {args.draw}: give 0 (the first draw) or a draw N >= 1 that "
                     "benchmarks/new_listener.py solved")
    import bpy  # noqa: F401, PLC0415  (before pymeshlab)
    import trimesh  # noqa: PLC0415

    scanned_head = trimesh.load(STORE / f"{args.subject}_new" / "scanned" / "head.ply", process=False, force="mesh")
    result = {}
    if args.draw:
        kinds = ((f"hard_placed_draw{args.draw}", "detail"), (f"hard_points_placed_draw{args.draw}", "detail"),
                 (f"hard_oracle_placed_draw{args.draw}", "detail"))
    else:
        kinds = (("hard_placed", "detail"), ("hard_ppm_placed", "align"), ("hard_oracle_placed", "detail"),
                 ("hard_noise_placed", "detail"), ("hard_supple_placed", "detail"), ("hard_points_placed", "detail"),
                 ("hard_blind_oracle_placed", "detail"))
    # the scans of the draw: every listener of one draw is fitted to the same ones (its first listener's copy)
    scan_folders = [ROOT / "results" / "listeners" / f"{args.subject}_{kind}" / "prepared" for kind, _ in kinds]
    hard_scans = next((folder for folder in scan_folders if folder.is_dir()), scan_folders[0])
    for kind, step in kinds:
        base = ROOT / "results" / "listeners" / f"{args.subject}_{kind}"
        if not base.is_dir() or not hard_scans.is_dir():
            print(f"{base} is missing: run benchmarks/new_listener.py --hard --placed [--no-layer | --oracle | --blind-oracle | --noise-floor | --supple-end | --layer-variant points] first",
                  flush=True)
            continue
        result[kind] = {}
        for side in ("left", "right"):
            # split by what the hard scans saw, also for the oracle, whose scans are completed where they were blind
            rows = split_errors(base / step / side / "aligned_pinna.ply", hard_scans / f"ear_scan_{side}.ply",
                                scanned_head, side)
            result[kind][side] = rows
            for name, row in rows.items():
                print(f"{args.subject}_{kind} {side:5s} {name:6s}: {100 * row['area_share']:4.1f} % of the pinna, "
                      f"to the head as scanned median {row['median_mm']:.3f} / p95 {row['p95_mm']:.3f} mm, "
                      f"{100 * row['share_over_0_5mm']:.0f} % beyond 0.5 mm", flush=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
