"""Benchmark: time to build the workflow's DAG (snakemake --dry-run) for 10, 100 and 1000 subjects.

Subjects are empty placeholder folders (a dry run only checks that the input files exist), in a temp
dataset; the default config (HRTFs off) plans templates, alignment, stitching and remeshing per
subject; ``--hrtf`` also plans the NumCalc step jobs (2 ears x frequencies x 2 variants per subject).

Run: .venv/bin/python benchmarks/workflow_scale.py [--hrtf]
Last line: JSON with dag_seconds_10, dag_seconds_100, dag_seconds_1000 (and job counts).
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def dry_run(work: Path, data: Path, hrtf: bool) -> tuple[float, int]:
    args = [sys.executable, "-m", "snakemake", "-n", "--quiet", "rules", "--cores", "2"]
    if hrtf:
        import yaml  # noqa: PLC0415

        config = yaml.safe_load((work / "config" / "config.yaml").read_text())
        config["hrtf"].update(enabled=True, frequencies_hz={"min": 500.0, "max": 2000.0, "step": 500.0})
        (work / "config" / "scale.yaml").write_text(yaml.safe_dump(config))
        args += ["--configfile", str(work / "config" / "scale.yaml")]
    args += ["--config", f"data_root={data}"]
    start = time.perf_counter()
    done = subprocess.run(args, cwd=work, capture_output=True, text=True, timeout=3600)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit((done.stdout + done.stderr)[-3000:])
    total = re.search(r"^total\s+(\d+)", done.stdout + done.stderr, re.MULTILINE)
    return seconds, int(total.group(1)) if total else -1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--hrtf", action="store_true", help="also plan the HRTF jobs (4 frequencies)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    args = parser.parse_args()
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) / "project"
        for folder in ("workflow", "rules", "config"):
            shutil.copytree(ROOT / folder, work / folder)
        for size in args.sizes:
            data = Path(tmp) / f"data_{size}"
            for index in range(size):
                subject = data / f"S{index:04d}"
                subject.mkdir(parents=True)
                for name in ("pinna_left_crop.ply", "head_graded_left.ply"):
                    (subject / name).touch()
            seconds, jobs = dry_run(work, data, args.hrtf)
            result[f"dag_seconds_{size}"] = round(seconds, 2)
            result[f"jobs_{size}"] = jobs
            print(f"{size:5d} subjects: {jobs} jobs planned in {seconds:.1f} s")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
