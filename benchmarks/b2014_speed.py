"""Benchmark: time of baumgartner2014 for one listener: DTFs, 3 lateral planes (-20, 0, +20 deg),
calibration of S on the listener's own HRTFs (reference QE 8 %), then the prediction for another
listener's HRTFs heard with that template.

Run: .venv/bin/python benchmarks/b2014_speed.py [--repeats 5]
Last line: JSON with seconds (median, model only), seconds_with_io, and the QE/PE computed.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from amt_bridge import LocalisationModel, read_hrtf_set

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "hrtf"


def one_listener(template, target):
    reference = LocalisationModel(template, template)
    sensitivity = reference.calibrate(8.0)
    return sensitivity, reference.predict(sensitivity), LocalisationModel(target, template).predict(sensitivity)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    model_seconds, io_seconds = [], []
    for _ in range(args.repeats):
        start = time.perf_counter()
        template = read_hrtf_set(DATA / "measured_axd_example1.sofa")
        target = read_hrtf_set(DATA / "measured_axd_example2.sofa")
        loaded = time.perf_counter()
        sensitivity, reference, condition = one_listener(template, target)
        done = time.perf_counter()
        model_seconds.append(done - loaded)
        io_seconds.append(done - start)
    print(f"template AXD example 1 (793 directions, 256 taps, 48 kHz), target AXD example 2; planes -20/0/+20 deg")
    print(f"calibrated S = {sensitivity:.4f} dB: reference QE {reference.qe:.2f} %, PE {reference.pe:.2f} deg")
    print(f"other listener: QE {condition.qe:.2f} %, PE {condition.pe:.2f} deg")
    print(f"model time median {statistics.median(model_seconds):.3f} s, with SOFA reading "
          f"{statistics.median(io_seconds):.3f} s ({args.repeats} runs)")
    print(json.dumps({"seconds": round(statistics.median(model_seconds), 4),
                      "seconds_with_io": round(statistics.median(io_seconds), 4),
                      "sensitivity_db": round(sensitivity, 4), "reference_qe_percent": round(reference.qe, 3),
                      "reference_pe_deg": round(reference.pe, 3), "qe_percent": round(condition.qe, 3),
                      "pe_deg": round(condition.pe, 3)}))


if __name__ == "__main__":
    main()
