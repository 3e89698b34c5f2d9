"""Evaluation frequency set: baumgartner2014's QE/PE from full HRIRs vs the same HRIRs sampled at a sparse
set (exact DFT) and rebuilt (mesh2hrtf_io.sparse_hrtf), on every target/template pair of the SONICOM sets.

S is calibrated to 8 % QE on each template, for the full and the rebuilt sets separately (AMT's protocol).
Prints the chosen set (config preset, default 'evaluation') with each interpolant, then other sets for
comparison, and ends with one JSON line for the chosen set and interpolant:
n_frequencies, max_dqe_pp, max_dpe_deg, pairs, seconds (plus the rows of the table).

    .venv/bin/python benchmarks/frequency_set.py [--data ../shared/data/sonicom] [--preset evaluation]
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from amt_bridge import read_hrtf_set  # noqa: E402
from amt_bridge.hrtf_set import resampled_at  # noqa: E402
from amt_bridge.model import LocalisationModel  # noqa: E402
from mesh2hrtf_io.frequency_sets import frequencies_from_spec  # noqa: E402

QE_GOAL = 8.0


def predictions(sets: dict) -> dict:
    """(target, template) -> (QE %, PE deg), S calibrated on each template's self-prediction."""
    out = {}
    for template_name, template in sets.items():
        own = LocalisationModel(template, template)
        sensitivity = own.calibrate(QE_GOAL, closest=True)
        for target_name, target in sets.items():
            model = own if target_name == template_name else LocalisationModel(target, template)
            prediction = model.predict(sensitivity)
            out[(target_name, template_name)] = (prediction.qe, prediction.pe)
    return out


def compare(full: dict, reference: dict, frequencies: np.ndarray, interpolant: str) -> dict:
    rebuilt = predictions({name: resampled_at(hrirs, frequencies, interpolant) for name, hrirs in full.items()})
    dqe = [abs(rebuilt[pair][0] - reference[pair][0]) for pair in reference]
    dpe = [abs(rebuilt[pair][1] - reference[pair][1]) for pair in reference]
    return {"n_frequencies": int(frequencies.size), "interpolant": interpolant, "max_dqe_pp": round(max(dqe), 3),
            "max_dpe_deg": round(max(dpe), 3), "mean_dqe_pp": round(float(np.mean(dqe)), 3),
            "mean_dpe_deg": round(float(np.mean(dpe)), 3)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "sonicom")
    parser.add_argument("--preset", default="evaluation")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    start = time.perf_counter()
    files = sorted(args.data.glob("*/hrir_mesh2hrtf_48k.sofa"))
    if len(files) < 2:
        print(f"no SONICOM sets under {args.data} (need <subject>/hrir_mesh2hrtf_48k.sofa)", file=sys.stderr)
        return 2
    full = {path.parent.name: read_hrtf_set(path) for path in files}
    reference = predictions(full)
    print(f"{len(full)} sets ({', '.join(full)}), {len(reference)} target/template pairs, S -> {QE_GOAL:g} % QE")
    for (target, template), (qe, pe) in sorted(reference.items()):
        print(f"  full HRIRs: {target} heard with {template}'s template: QE {qe:.2f} %, PE {pe:.2f} deg")

    chosen = frequencies_from_spec({"preset": args.preset})
    rows = [dict(set=f"preset {args.preset}", **compare(full, reference, chosen, interpolant))
            for interpolant in ("pchip", "linear", "cubic")]
    others = {
        "all 160 bins (150 Hz grid)": frequencies_from_spec({"preset": "sonicom_linear"}),
        "preset erb_half (0.5 ERB)": frequencies_from_spec({"preset": "erb_half"}),
        "0.85 ERB 600-18000 + 150/300/450, 19.5/21/24 kHz": frequencies_from_spec(
            {"scale": "erb", "min": 600.0, "max": 18000.0, "step_erb": 0.85,
             "extra": [150.0, 300.0, 450.0, 19500.0, 21000.0, 24000.0]}),
    }
    rows += [dict(set=name, **compare(full, reference, frequencies, "pchip")) for name, frequencies in others.items()]
    print(f"\n{'set':<52} {'n':>4} {'interpolant':<8} {'max dQE pp':>10} {'max dPE deg':>11} {'mean dQE':>9} {'mean dPE':>9}")
    for row in rows:
        print(f"{row['set']:<52} {row['n_frequencies']:>4} {row['interpolant']:<8} {row['max_dqe_pp']:>10.3f} "
              f"{row['max_dpe_deg']:>11.3f} {row['mean_dqe_pp']:>9.3f} {row['mean_dpe_deg']:>9.3f}")
    measured = sorted((args.data.parent / "hrtf").glob("measured_axd_example*.sofa"))
    if len(measured) >= 2:  # a check outside the use case: measured HRIRs (torso, room) have finer structure
        measured_sets = {path.stem: read_hrtf_set(path) for path in measured}
        measured_reference = predictions(measured_sets)
        print("\nmeasured AXD listeners (torso and rig reflections; not what the set is solved for):")
        for name, frequencies in (("preset " + args.preset, chosen), ("preset erb_half (0.5 ERB)",
                                                                      others["preset erb_half (0.5 ERB)"])):
            row = compare(measured_sets, measured_reference, frequencies, "pchip")
            print(f"  {name:<50} {row['n_frequencies']:>4} max dQE {row['max_dqe_pp']:.3f} pp, max dPE "
                  f"{row['max_dpe_deg']:.3f} deg ({len(measured_reference)} pairs)")
            rows.append(dict(set=f"measured AXD, {name}", **row))
    best = rows[0]
    goal = best["n_frequencies"] <= 40 and best["max_dqe_pp"] <= 0.5 and best["max_dpe_deg"] <= 0.5
    print(f"\ngoal (<= 40 frequencies, max dQE <= 0.5 pp, max dPE <= 0.5 deg): {'met' if goal else 'NOT met'}")
    summary = {"n_frequencies": best["n_frequencies"], "max_dqe_pp": best["max_dqe_pp"],
               "max_dpe_deg": best["max_dpe_deg"], "pairs": len(reference),
               "seconds": round(time.perf_counter() - start, 1), "preset": args.preset,
               "rows": rows}
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
