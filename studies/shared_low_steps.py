"""How much QE/PE move if a pinna-swapped head borrowed the unchanged head's lowest frequency steps.

    .venv/bin/python studies/shared_low_steps.py [--evaluation evaluation/sonicom] [--steps 3 4 6]

Below about 1 kHz the wavelength (0.4-2.3 m) is far larger than a pinna, and these steps are NumCalc's slowest
on a graded head (9-20 min each here, 22-30 % of a head's NumCalc time in the committed step statuses). For every subject whose committed evaluation
holds the unchanged head (``original``), each other solved condition's left-ear HRTFs get their lowest N steps
replaced by the original's (referenced HRTFs, direction by direction), and QE/PE (baumgartner2014, S calibrated on
the reference rebuilt at the same frequencies, right ear from the reference) are computed with and without the
swap. Reads committed files only (seconds). Last line (JSON): per subject, condition and N the frequencies swapped
(Hz) and ``delta_qe_pp`` / ``delta_pe_deg`` (swapped minus as solved), and the largest of each over all.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SONICOM = ROOT.parent / "shared" / "data" / "sonicom"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--evaluation", type=Path, default=ROOT / "evaluation" / "sonicom")
    parser.add_argument("--steps", type=int, nargs="+", default=[3, 4, 6])
    args = parser.parse_args()

    import sofar
    import yaml

    from amt_bridge.evaluation import compare_conditions
    from reporting.evaluation_files import left_hrtf_files

    settings = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["localisation"]
    figures: dict = {"conditions": {}}
    largest_qe = largest_pe = 0.0
    for original in sorted((args.evaluation / "sofa").glob("*_original_left_HRTF.sofa")):
        subject = original.name.split("_")[0]
        unchanged = sofar.read_sofa(str(original), verify=False)
        frequencies = np.asarray(unchanged.N, dtype=np.float64)
        others = {name: p for name, p in left_hrtf_files(args.evaluation / "sofa", subject).items() if p != original}
        for condition, path in others.items():
            solved = sofar.read_sofa(str(path), verify=False)
            with tempfile.TemporaryDirectory() as tmp:
                variants = {"as_solved": path}
                for count in args.steps:
                    swapped = sofar.read_sofa(str(path), verify=False)
                    real, imag = np.array(solved.Data_Real), np.array(solved.Data_Imag)
                    real[..., :count], imag[..., :count] = unchanged.Data_Real[..., :count], unchanged.Data_Imag[..., :count]
                    swapped.Data_Real, swapped.Data_Imag = real, imag
                    variants[f"lowest_{count}"] = Path(tmp) / f"lowest_{count}.sofa"
                    sofar.write_sofa(str(variants[f"lowest_{count}"]), swapped, compression=0)
                _, predictions = compare_conditions(SONICOM / subject / settings["reference_sofa"], variants,
                                                    settings["calibration_qe_percent"], settings["lateral_angles_deg"],
                                                    frequencies, "left")
            base = predictions["as_solved"]
            rows = {}
            print(f"{subject} {condition}: as solved QE {base.qe:.3f} %, PE {base.pe:.3f} deg")
            for count in args.steps:
                moved = predictions[f"lowest_{count}"]
                delta_qe, delta_pe = float(moved.qe - base.qe), float(moved.pe - base.pe)
                largest_qe, largest_pe = max(largest_qe, abs(delta_qe)), max(largest_pe, abs(delta_pe))
                rows[str(count)] = {"frequencies_hz": [round(float(f), 2) for f in frequencies[:count]],
                                    "delta_qe_pp": round(delta_qe, 4), "delta_pe_deg": round(delta_pe, 4)}
                print(f"  lowest {count} steps ({frequencies[count - 1]:.0f} Hz and below) from the unchanged head: "
                      f"ΔQE {delta_qe:+.4f} pp, ΔPE {delta_pe:+.4f} deg")
            figures["conditions"][f"{subject}_{condition}"] = rows
    figures["max_abs_delta_qe_pp"] = round(largest_qe, 4)
    figures["max_abs_delta_pe_deg"] = round(largest_pe, 4)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
