"""Update workflow/resources.yaml (measured peak memory and wall clock per rule) from Snakemake benchmark files.

Run: .venv/bin/python scripts/measure_resources.py benchmarks/timings [other/benchmarks/timings ...] [--note "what ran"]
     [--sacct SINCE]    # also SLURM's MaxRSS and Elapsed of the jobs since SINCE (e.g. 2026-12-01T08:00):
                        # what a scheduler enforces, the job's whole process tree with Snakemake's own process
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from reporting.resources import DEFAULT_FILE, MODELLED, requests, rule_peaks, write_peaks  # noqa: E402


def main(argv: list[str]) -> int:
    note, since = None, None
    if "--note" in argv:
        at = argv.index("--note")
        note, argv = argv[at + 1], argv[:at] + argv[at + 2:]
    if "--sacct" in argv:
        at = argv.index("--sacct")
        since, argv = argv[at + 1], argv[:at] + argv[at + 2:]
    if not argv:
        print(__doc__)
        return 2
    missing = [folder for folder in argv if not Path(folder).is_dir()]
    if missing:
        print(f"no such folder: {', '.join(missing)}; give folders of Snakemake benchmark files", file=sys.stderr)
        return 2
    peaks = rule_peaks(argv)
    if since:
        from reporting.slurm_accounting import sacct_jobs  # noqa: PLC0415

        for job in sacct_jobs(since):
            if job["rule"] == "unknown" or job["rule"] in MODELLED or job["state"] != "COMPLETED":
                continue
            row = peaks.setdefault(job["rule"], {"max_rss_mb": 0.0, "seconds": 0.0, "jobs": 0})
            row["max_rss_mb"] = round(max(row["max_rss_mb"], job["max_rss_mb"]), 1)
            row["seconds"] = round(max(row["seconds"], job["elapsed_s"] or 0.0), 1)
            row["jobs"] += 1
    write_peaks(DEFAULT_FILE, peaks, [note] if note else [str(Path(folder)) for folder in argv])
    for rule, row in peaks.items():
        request = requests(rule)
        print(f"{rule:22s} {row['jobs']:4d} jobs  peak {row['max_rss_mb']:8.1f} MB {row['seconds']:8.1f} s  ->  "
              f"mem_mb {request['mem_mb']}, runtime {request['runtime']} min")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
