"""Benchmark: the default run (`snakemake --cores 2`, no data configured: the synthetic demo) end to end
in a fresh copy of the workflow, with the default demo config (2 subjects, 8 frequencies).

Prints per subject the alignment, the recovery of the true parameters, the solve cost and the
localisation predictions, then the wall-clock time of the whole run.

Run: .venv/bin/python benchmarks/demo_run.py [--subjects N]
Last line: JSON with seconds, subjects, align_median_mm (worst subject), recovery medians per group
(location_mm, rotation_deg, scale, shape_key), solve_seconds_per_frequency, qe/pe of reference and PPM.
"""
from __future__ import annotations

import argparse
import csv
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ppm.parameters import PinnaParameters  # noqa: E402
from reporting.cost import solve_costs, subject_timings  # noqa: E402
from reporting.subject import parameter_recovery  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) / "project"
        for folder in ("workflow", "rules", "config"):
            shutil.copytree(ROOT / folder, work / folder)
        config = yaml.safe_load((work / "config" / "config.yaml").read_text())
        config["demo"]["subjects"] = args.subjects
        (work / "config" / "benchmark.yaml").write_text(yaml.safe_dump(config))
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", "--configfile",
                               str(work / "config" / "benchmark.yaml")], cwd=work,
                              capture_output=True, text=True, timeout=7200)
        seconds = time.perf_counter() - start
        if done.returncode != 0:
            raise SystemExit((done.stdout + done.stderr)[-4000:])
        results = work / "results"
        rows = list(csv.DictReader((results / "dataset_summary.csv").open()))
        recovery: dict[str, list[float]] = {}
        per_frequency = []
        jobs = [json.loads(path.read_text()) for path in sorted(results.glob("*/hrtf/embedded.json"))]
        backends = sorted({job.get("backend", {}).get("backend", job.get("device", "?")) for job in jobs})
        probe_seconds = sum(job.get("backend", {}).get("probe_seconds", 0.0) for job in jobs)
        for row in rows:
            subject = row["subject"]
            truth = PinnaParameters.read(results / "demo_data" / subject / "truth_parameters.json")
            fitted = PinnaParameters.read(results / subject / "align" / "parameters.json", out_of_range="clip")
            groups = parameter_recovery(fitted, truth)
            for group in groups:
                recovery.setdefault(group["group"].split()[0], []).append(group["median"])
            costs = solve_costs(results / subject, subject_timings(work / "benchmarks" / "timings", subject))
            per_frequency += [c["seconds_per_frequency"] for c in costs]
            print(f"{subject}: scan -> PPM median {float(row['align_median_mm']):.3f} mm, p95 "
                  f"{float(row['align_p95_mm']):.3f} mm; parameter error medians "
                  + ", ".join(f"{g['group']} {g['median']:.3f}" for g in groups))
            print(f"  {row['triangles']} triangles; solve {row['solve_seconds_reference']} s (reference), "
                  f"{row['solve_seconds_ppm']} s (PPM); QE {float(row['qe_reference_percent']):.2f} -> "
                  f"{float(row['qe_ppm_percent']):.2f} %, PE {float(row['pe_reference_deg']):.2f} -> "
                  f"{float(row['pe_ppm_deg']):.2f} deg")
        print(f"whole demo run: {seconds:.0f} s ({seconds / 60:.1f} min) for {len(rows)} subjects; embedded solver "
              f"backend {', '.join(backends)} ({jobs[0].get('backend', {}).get('reason', '') if jobs else ''}), "
              f"probes {probe_seconds:.1f} s")
        figures = {
            "seconds": round(seconds, 1), "subjects": len(rows),
            "align_median_mm": max(float(r["align_median_mm"]) for r in rows),
            "recovery_median_location_mm": round(max(recovery["location"]), 3),
            "recovery_median_rotation_deg": round(max(recovery["rotation"]), 3),
            "recovery_median_scale": round(max(recovery["scale"]), 4),
            "recovery_median_shape_key": round(max(recovery["shape"]), 3),
            "solve_seconds_per_frequency": round(max(per_frequency), 2),
            "embedded_backend": ", ".join(backends), "backend_probe_seconds": round(probe_seconds, 2),
            "qe_reference_percent": [float(r["qe_reference_percent"]) for r in rows],
            "qe_ppm_percent": [float(r["qe_ppm_percent"]) for r in rows],
            "pe_reference_deg": [float(r["pe_reference_deg"]) for r in rows],
            "pe_ppm_deg": [float(r["pe_ppm_deg"]) for r in rows],
        }
        print(json.dumps(figures))


if __name__ == "__main__":
    main()
