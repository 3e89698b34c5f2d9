"""Benchmark: the CI-sized demo (one subject) through a real SLURM controller with --profile profiles/slurm.

Starts the single-node SLURM of scripts/local_slurm.sh (Debian's slurm-wlm, slurmdbd, munge, MariaDB), runs the
workflow in a fresh copy, cancels the running solve job once (scancel) and resumes, then reads every job from
sacct: state, requested memory and time against MaxRSS and Elapsed, per rule. Stops the daemons it started.

Run: .venv/bin/python benchmarks/slurm_demo.py [--keep-running]
Last line: JSON with jobs_submitted, jobs_failed, jobs_cancelled, max_rss_over_request (largest MaxRSS / ReqMem),
max_elapsed_over_limit, seconds.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from reporting.slurm_accounting import run_demo_on_slurm  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep-running", action="store_true", help="leave the SLURM daemons running")
    parser.add_argument("--work", type=Path, default=None, help="folder for the workflow copy (default: a temp folder)")
    args = parser.parse_args()
    start = time.perf_counter()
    result = run_demo_on_slurm(ROOT, args.work, stop_after=not args.keep_running, log=print)
    for rule, row in sorted(result["per_rule"].items()):
        print(f"{rule:22s} jobs {row['jobs']:3d}  states {','.join(sorted(set(row['states'])))}  "
              f"MaxRSS/ReqMem {row['max_rss_over_request']:.2f}  Elapsed/Timelimit {row['max_elapsed_over_limit']:.3f}")
    figures = {key: result[key] for key in ("jobs_submitted", "jobs_failed", "jobs_cancelled", "max_rss_over_request",
                                            "max_elapsed_over_limit", "resumed_after_scancel")}
    figures["steps_solved_after_resume"] = result.get("steps_solved_after_resume")
    figures["seconds"] = round(time.perf_counter() - start, 1)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
