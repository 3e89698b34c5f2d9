"""Scheduler requests of the workflow's rules from measured peaks: the largest resident memory and wall clock
of each rule's jobs in Snakemake benchmark files (``benchmarks/timings/<group>/<rule>/<job>.tsv``), kept in
``workflow/resources.yaml`` and turned into ``mem_mb`` and ``runtime`` (minutes) with a margin.

NumCalc steps are not in the file: their requests come from the cost model (mesh2hrtf_io.numcalc_cost)."""
from __future__ import annotations

import math
import os
from pathlib import Path

import yaml

from core.atomic import write_text_atomic

from .cost import read_benchmark

#: Requests from peaks: memory x 1.5 + 512 MB (a cluster job also holds Snakemake's own process, ~350 MB; at least
#: 768 MB), time x 3 (at least 10 min).
MEMORY_FACTOR, MEMORY_EXTRA_MB, MEMORY_FLOOR_MB = 1.5, 512, 768
TIME_FACTOR, TIME_FLOOR_MIN = 3.0, 10
DEFAULT_FILE = Path(__file__).resolve().parents[1] / "workflow" / "resources.yaml"
#: Rules whose requests come from elsewhere (the NumCalc cost model, the embedded solver's dense model).
MODELLED = ("solve_numcalc_step",)


def rule_peaks(timing_roots: list[str | os.PathLike]) -> dict[str, dict]:
    """Per rule: the largest max_rss (MB) and seconds over every benchmark file under the roots, and the count."""
    peaks: dict[str, dict] = {}
    for root in timing_roots:
        for path in sorted(Path(root).rglob("*.tsv")):
            rule = path.parent.name  # <group>/<rule>/<job>.tsv
            if rule in MODELLED:
                continue
            try:
                seconds, rss = read_benchmark(path)
            except ValueError:
                continue
            row = peaks.setdefault(rule, {"max_rss_mb": 0.0, "seconds": 0.0, "jobs": 0})
            row["max_rss_mb"] = round(max(row["max_rss_mb"], rss or 0.0), 1)
            row["seconds"] = round(max(row["seconds"], seconds), 1)
            row["jobs"] += 1
    return dict(sorted(peaks.items()))


def write_peaks(path: str | os.PathLike, peaks: dict[str, dict], sources: list[str]) -> Path:
    """The peaks file, merged over what it held (a rule's peak only grows; delete the file to start afresh after a change that lowers a peak), with where they were measured."""
    path = Path(path)
    old = yaml.safe_load(path.read_text()) if path.is_file() else {}
    rules = dict(old.get("rules", {}))
    for rule, row in peaks.items():
        before = rules.get(rule, {})
        rules[rule] = {"max_rss_mb": max(row["max_rss_mb"], before.get("max_rss_mb", 0.0)),
                       "seconds": max(row["seconds"], before.get("seconds", 0.0))}
    header = ("# Measured peaks of each rule's jobs (largest resident memory in MB, wall clock in s), from Snakemake\n"
              "# benchmark files; requests are mem_mb = 1.5 x peak + 512 (>= 768) and runtime = 3 x peak (>= 10 min)\n"
              "# (reporting/resources.py). Remeasure after a change: .venv/bin/python scripts/measure_resources.py\n"
              "# benchmarks/timings [more folders]. NumCalc steps use the cost model instead.\n")
    body = yaml.safe_dump({"sources": sorted(set(old.get("sources", [])) | set(sources)), "rules": dict(sorted(rules.items()))},
                          sort_keys=False)
    return write_text_atomic(path, header + body)


def requests(rule: str, path: str | os.PathLike = DEFAULT_FILE) -> dict[str, int]:
    """``{"mem_mb": ..., "runtime": ...}`` (runtime in minutes) for ``rule`` from its measured peak; a rule never
    measured gets 4000 MB and 60 min (said so in the file's absence of it)."""
    peaks = (yaml.safe_load(Path(path).read_text()) or {}).get("rules", {}) if Path(path).is_file() else {}
    peak = peaks.get(rule)
    if not peak:
        return {"mem_mb": 4000, "runtime": 60}
    memory = max(MEMORY_FLOOR_MB, int(math.ceil(MEMORY_FACTOR * peak["max_rss_mb"] + MEMORY_EXTRA_MB)))
    runtime = max(TIME_FLOOR_MIN, int(math.ceil(TIME_FACTOR * peak["seconds"] / 60.0)))
    return {"mem_mb": memory, "runtime": runtime}
