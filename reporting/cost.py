"""What each stage of a subject cost: wall-clock seconds and peak memory from the Snakemake benchmark
files (``benchmarks/timings/<group>/<rule>/<subject>[_<variant>...].tsv``), and the HRTF solve per
head variant (solver, elements, frequencies, seconds per frequency)."""
from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class StageTiming:
    """One job's benchmark: ``rule`` (e.g. solve_embedded), ``job`` (file stem, e.g. demo01_ppm),
    ``seconds`` wall clock, ``max_rss_mb`` peak resident memory (None where not measured)."""

    rule: str
    job: str
    seconds: float
    max_rss_mb: float | None


def _number(text: str | None) -> float | None:
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def read_benchmark(path: str | os.PathLike) -> tuple[float, float | None]:
    """(seconds, max_rss_mb) of a Snakemake benchmark TSV (the mean over repeats if it has several)."""
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle, delimiter="\t"))
    if not rows:
        raise ValueError(f"{path}: empty benchmark file (rerun the rule that wrote it)")
    seconds = [s for s in (_number(r.get("s")) for r in rows) if s is not None]
    rss = [m for m in (_number(r.get("max_rss")) for r in rows) if m is not None]
    return sum(seconds) / max(len(seconds), 1), (max(rss) if rss else None)


#: Rules in pipeline order (the order of the cost table); others follow alphabetically.
STAGE_ORDER = ("make_demo_subject", "build_template", "prepare_target", "align_ppm", "stitch", "remesh",
               "export_project", "solve_numcalc_step", "solve_embedded", "collect_sofa", "localisation",
               "report_subject")


def _of_job(stem: str, name: str) -> bool:
    """Whether a benchmark file stem belongs to job ``name`` (a subject, or subject_variant)."""
    return stem == name or stem.startswith(f"{name}_")


def subjects_timings(timings_root: str | os.PathLike, subjects: list[str]) -> dict[str, list[StageTiming]]:
    """Every benchmark of each subject's jobs under ``timings_root`` (the tree is listed once), in
    pipeline order."""
    paths = sorted(Path(timings_root).rglob("*.tsv"))
    rank = {rule: i for i, rule in enumerate(STAGE_ORDER)}
    found = {}
    for subject in subjects:
        timings = [StageTiming(path.parent.name, path.stem, *read_benchmark(path))
                   for path in paths if _of_job(path.stem, subject)]
        found[subject] = sorted(timings, key=lambda t: (rank.get(t.rule, len(rank)), t.rule, t.job))
    return found


def subject_timings(timings_root: str | os.PathLike, subject: str) -> list[StageTiming]:
    """Every benchmark of ``subject``'s jobs under ``timings_root``, in pipeline order."""
    return subjects_timings(timings_root, [subject])[subject]


def project_elements(project: str | os.PathLike) -> int | None:
    """Number of head-mesh elements of an exported Mesh2HRTF project (first line of Elements.txt)."""
    path = Path(project) / "ObjectMeshes" / "Reference" / "Elements.txt"
    if not path.is_file():
        return None
    with open(path) as handle:
        return int(handle.readline().split()[0])


def solve_costs(results: str | os.PathLike, timings: list[StageTiming]) -> list[dict]:
    """Per head variant with an exported project under ``results`` (a subject's folder, named after it):
    solver, elements, frequencies, solve seconds, seconds per frequency (both ears), peak memory. Embedded
    solves (one job per subject for all its heads) are read from their status (``hrtf/embedded.json``), which
    keeps each head's seconds per frequency; the first frequency of the job, which includes numba's
    compilation, is left out of the per-frequency figure. NumCalc solves from the step jobs' benchmarks."""
    subject = Path(results).name
    embedded_path = Path(results) / "hrtf" / "embedded.json"
    embedded = json.loads(embedded_path.read_text()).get("projects", {}) if embedded_path.is_file() else {}
    embedded_rss = [t.max_rss_mb for t in timings if t.rule == "solve_embedded" and t.max_rss_mb is not None]
    rows = []
    for variant in ("reference", "original", "ppm", "own_pinna", "default_ppm", "ppm_detail", "ppm_hard", "ppm_detail_hard",
                    "nricp_hard", "scan_hard"):
        project = Path(results) / "hrtf" / variant / "project"
        if not project.is_dir():
            continue
        parameters = json.loads((project / "parameters.json").read_text()) if (project / "parameters.json").is_file() else {}
        frequencies = parameters.get("frequencies") or []
        if variant in embedded:
            times = embedded[variant].get("seconds_per_frequency", [])
            first_of_job = variant == next(iter(embedded))
            steady = times[1:] if first_of_job and len(times) > 1 else times
            rows.append({"variant": variant, "solver": "embedded", "elements": project_elements(project),
                         "frequencies": len(frequencies), "solve_seconds": round(sum(times), 1),
                         "seconds_per_frequency": round(sum(steady) / len(steady), 2) if steady else None,
                         "max_rss_mb": max(embedded_rss) if embedded_rss else None})
            continue
        jobs = [t for t in timings if t.rule.startswith("solve_") and _of_job(t.job, f"{subject}_{variant}")]
        solver = "NumCalc" if jobs else "given"
        seconds = sum(t.seconds for t in jobs)
        rss = [t.max_rss_mb for t in jobs if t.max_rss_mb is not None]
        rows.append({"variant": variant, "solver": solver, "elements": project_elements(project),
                     "frequencies": len(frequencies), "solve_seconds": round(seconds, 1),
                     "seconds_per_frequency": round(seconds / len(frequencies), 2) if frequencies and jobs else None,
                     "max_rss_mb": max(rss) if rss else None})
    return rows
