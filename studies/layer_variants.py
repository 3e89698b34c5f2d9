"""Issues 54 and 56: the placed hard listener's layer variants, measured on the benchmark's nine defective scans.

``benchmarks/new_listener.py --hard --layer-variant NAME`` solves a layer variant on P143's two placed hard ear scans;
this study lays the same variants (``LAYER_VARIANTS`` of that benchmark) on the fits of
``benchmarks/align_defects.py``'s nine scans (three subjects x light / medium / hard, kept by
studies/surface_measures.py) and measures them as that benchmark does (studies/noise_stiffness.py's measure: truth ->
surface, surface -> truth, the parts the scan saw and never saw; median / p95, mm), with the trimmed screened Poisson
reconstruction of the same scan beside them. So a variant judged by its acoustics on one listener is also judged by
its geometry on scans and subjects it was not chosen on.

    .venv/bin/python studies/layer_variants.py [--seed 19] [--variants supple points] [--subjects P039 P067 P143]

Fits are kept in results/studies/surface_measures[_seed<N>] (about 12 min to fit nine scans where missing); the
layers take about a minute each. Last line (JSON): per variant ``beats_poisson``, the mean change of every figure
against the packaged layer (mm) and how many subject-levels it worsens by more than 0.005 mm, and the rows.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "studies"))
sys.path.insert(0, str(ROOT / "benchmarks"))


def main() -> None:
    from new_listener import LAYER_VARIANTS  # noqa: PLC0415

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", nargs="*", default=["P039", "P067", "P143"])
    parser.add_argument("--seed", type=int, default=19, help="the benchmark's draws (19) or others")
    parser.add_argument("--variants", nargs="*", default=["supple", "points"], choices=sorted(LAYER_VARIANTS))
    args = parser.parse_args()
    from noise_stiffness import measure, summarise  # noqa: PLC0415
    from surface_measures import fit_scans  # noqa: PLC0415

    folder = "surface_measures" if args.seed == 19 else f"surface_measures_seed{args.seed}"
    cache = ROOT / "results" / "studies" / folder
    fit_scans(args.subjects, cache, args.seed)
    variants = {name: LAYER_VARIANTS[name] for name in args.variants}
    rows = measure(args.subjects, cache, [], variants)
    summary = summarise(rows, ["packaged", *variants])
    for name, figures in summary.items():
        print(f"{name}: at or below the reconstruction at {figures['beats_poisson']:.0%} of subject-levels; mean "
              "change against the packaged layer (mm): " + ", ".join(f"{k} {v:+.4f}" for k, v in
                                                                     figures["mean_change_mm"].items()))
    print(json.dumps({"seed": args.seed, "subjects": args.subjects, "variants": variants, "summary": summary,
                      "rows": rows}))


if __name__ == "__main__":
    main()
