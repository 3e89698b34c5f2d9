"""What a SLURM cluster recorded of a workflow run (sacct), and the CI-sized demo run through a real controller.

The executor plugin names every job after the run's UUID and puts ``rule_<name>[_wildcards_<...>]`` into its
comment (stored with ``AccountingStoreFlags=job_comment``), so each job maps to its rule. Memory in MB, times
in seconds.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

SACCT_FIELDS = ("JobIDRaw", "JobName", "Comment", "State", "ReqMem", "MaxRSS", "Elapsed", "Timelimit", "WorkDir")
_UNITS = {"K": 1 / 1024, "M": 1.0, "G": 1024.0, "T": 1024.0 * 1024.0}


def memory_mb(text: str) -> float | None:
    """SLURM memory ('66192K', '3000M', '2G', '3000Mn', '4Gc') in MB; None when empty."""
    match = re.fullmatch(r"([0-9.]+)([KMGT]?)[nc]?", text.strip())
    if not match:
        return None
    return float(match.group(1)) * _UNITS.get(match.group(2) or "M", 1.0)


def duration_s(text: str) -> float | None:
    """SLURM duration ('[D-]HH:MM:SS', 'MM:SS', 'UNLIMITED') in seconds; None when empty or unlimited."""
    text = text.strip()
    if not text or text in ("UNLIMITED", "Partition_Limit", "INVALID"):
        return None
    days, _, clock = text.rpartition("-")
    parts = [float(p) for p in clock.split(":")]
    while len(parts) < 3:
        parts.insert(0, 0.0)
    return (float(days) if days else 0.0) * 86400 + parts[0] * 3600 + parts[1] * 60 + parts[2]


def rule_of(comment: str) -> str:
    """The rule name in the plugin's job comment (``rule_<name>_wildcards_<...>``)."""
    name = comment[len("rule_"):] if comment.startswith("rule_") else comment
    return name.split("_wildcards_")[0] or "unknown"


def sacct_jobs(since: str = "now-1days", env: dict | None = None, work_dir: Path | None = None) -> list[dict]:
    """Every job since ``since`` with its rule, state, requested memory and time, and the largest MaxRSS and
    Elapsed of its steps (the batch step holds the job's processes). ``env``: the environment sacct runs in
    (e.g. with SLURM_CONF); default this process's. ``work_dir``: only the jobs submitted from that folder (a
    run's own jobs, not a job of an earlier run that the cluster still counts as running or ended late)."""
    done = subprocess.run(["sacct", "--parsable2", "--noheader", "--starttime", since, "--format", ",".join(SACCT_FIELDS)],
                          capture_output=True, text=True, check=True, env=env)
    return parse_sacct(done.stdout, work_dir)


def parse_sacct(text: str, work_dir: Path | None = None) -> list[dict]:
    """The jobs in sacct's ``--parsable2 --noheader`` output of ``SACCT_FIELDS`` (see ``sacct_jobs``)."""
    jobs: dict[str, dict] = {}
    wanted = str(Path(work_dir).resolve()) if work_dir is not None else None
    for line in text.splitlines():
        values = dict(zip(SACCT_FIELDS, line.split("|")))
        job_id, _, step = values["JobIDRaw"].partition(".")
        if not step:
            if wanted is not None and str(Path(values.get("WorkDir") or "/").resolve()) != wanted:
                continue  # its steps are skipped with it
            jobs[job_id] = {"job_id": job_id, "run": values["JobName"], "rule": rule_of(values["Comment"]),
                            "state": values["State"].split()[0], "req_mem_mb": memory_mb(values["ReqMem"]),
                            "time_limit_s": duration_s(values["Timelimit"]), "elapsed_s": duration_s(values["Elapsed"]),
                            "max_rss_mb": memory_mb(values["MaxRSS"]) or 0.0}
        elif job_id in jobs:
            rss = memory_mb(values["MaxRSS"]) or 0.0
            jobs[job_id]["max_rss_mb"] = max(jobs[job_id]["max_rss_mb"], rss)
    return list(jobs.values())


def summarise(jobs: list[dict]) -> dict:
    """Counts and the worst use of the requests, overall and per rule."""
    per_rule: dict[str, dict] = {}
    for job in jobs:
        row = per_rule.setdefault(job["rule"], {"jobs": 0, "states": [], "max_rss_over_request": 0.0,
                                                 "max_elapsed_over_limit": 0.0, "req_mem_mb": job["req_mem_mb"],
                                                 "time_limit_s": job["time_limit_s"]})
        row["jobs"] += 1
        row["states"].append(job["state"])
        if job["req_mem_mb"]:
            row["max_rss_over_request"] = max(row["max_rss_over_request"], job["max_rss_mb"] / job["req_mem_mb"])
        if job["time_limit_s"] and job["elapsed_s"] is not None:
            row["max_elapsed_over_limit"] = max(row["max_elapsed_over_limit"], job["elapsed_s"] / job["time_limit_s"])
    return {"jobs_submitted": len(jobs),
            "jobs_failed": sum(j["state"] in ("FAILED", "OUT_OF_MEMORY", "TIMEOUT", "NODE_FAIL") for j in jobs),
            "jobs_cancelled": sum(j["state"] == "CANCELLED" for j in jobs),
            "max_rss_over_request": round(max((r["max_rss_over_request"] for r in per_rule.values()), default=0.0), 3),
            "max_elapsed_over_limit": round(max((r["max_elapsed_over_limit"] for r in per_rule.values()), default=0.0), 3),
            "per_rule": per_rule}


def local_slurm(root: Path, action: str) -> subprocess.CompletedProcess:
    """Run ``scripts/local_slurm.sh <action>``."""
    return subprocess.run(["bash", str(root / "scripts" / "local_slurm.sh"), action], capture_output=True, text=True)


def _copy_workflow(root: Path, work: Path) -> None:
    for folder in ("workflow", "rules", "config", "profiles"):
        shutil.copytree(root / folder, work / folder, dirs_exist_ok=True)
    (work / "config" / "one_subject.yaml").write_text("demo:\n  subjects: 1\n")


def run_demo_on_slurm(root: Path, work: Path | None = None, stop_after: bool = True,
                      log: Callable[[str], None] = lambda _: None, cancel_rule: str = "solve_embedded",
                      cancel_when: str = "results/demo01/hrtf/reference/project/NumCalc/source_1/be.out/be.1/pEvalGrid"
                      ) -> dict:
    """Start the local SLURM, run the one-subject demo with ``--profile profiles/slurm`` in a copy of the
    workflow, cancel the job of ``cancel_rule`` (scancel) once ``cancel_when`` exists (its first solved step)
    and let the run resume it (the profile's retry, else the same command again), then summarise sacct for this
    run's jobs and how many solved steps the resumed job redid. Raises RuntimeError with the tool's words when
    SLURM cannot be started or the run fails."""
    started = local_slurm(root, "start")
    if started.returncode != 0:
        raise RuntimeError(f"scripts/local_slurm.sh start failed: {started.stderr.strip()[-1500:]}")
    env = dict(os.environ, SLURM_CONF=started.stdout.strip().split("=", 1)[-1])
    scratch = None
    if work is None:
        scratch = tempfile.TemporaryDirectory()
        work = Path(scratch.name) / "project"
    try:
        _copy_workflow(root, work)
        # the plugin's first status check of a job comes 40 s after submission, and the wait grows by 10 s per
        # check that finds nothing finished: on a one-node test cluster running a chain of short jobs, that is most
        # of the run; 5 s here (a shared cluster keeps the polite default of the profile)
        command = [sys.executable, "-m", "snakemake", "--profile", "profiles/slurm", "--configfile",
                   "config/one_subject.yaml", "--latency-wait", "5", "--slurm-init-seconds-before-status-checks", "5"]
        since = time.strftime("%Y-%m-%dT%H:%M:%S")
        log(f"running the demo through SLURM in {work}")
        first = subprocess.Popen(command, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                 start_new_session=True)
        cancelled = _cancel_once(cancel_rule, work / cancel_when, env, first, log)
        first_out = first.communicate(timeout=3600)[0]
        if first.returncode != 0:
            if not cancelled:
                raise RuntimeError(f"the run through SLURM failed:\n{first_out[-3000:]}")
            log("resuming after scancel with the same command")
            again = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True, timeout=3600)
            if again.returncode != 0:
                raise RuntimeError(f"the resumed run failed:\n{(again.stdout + again.stderr)[-3000:]}")
        jobs = sacct_jobs(since, env, work_dir=work)
        summary = summarise(jobs)
        summary["resumed_after_scancel"] = cancelled
        status = work / "results" / "demo01" / "hrtf" / "embedded.json"
        if status.is_file():
            import json  # noqa: PLC0415

            projects = json.loads(status.read_text())["projects"]
            summary["steps_solved_after_resume"] = sum(p["steps_solved"] for p in projects.values())
        summary["outputs"] = sorted(str(p.relative_to(work)) for p in (work / "results").rglob("*") if p.is_file())
        return summary
    finally:
        if scratch is not None:
            scratch.cleanup()
        if stop_after:
            local_slurm(root, "stop")


def _cancel_once(rule: str, ready: Path, env: dict, run: subprocess.Popen, log: Callable[[str], None]) -> bool:
    """scancel the running job of ``rule`` once the file ``ready`` exists; False if the run ended first."""
    deadline = time.time() + 3000
    while time.time() < deadline and run.poll() is None:
        if not ready.is_file():
            time.sleep(1)
            continue
        listed = subprocess.run(["squeue", "--noheader", "--format=%i|%k|%T|%M"], capture_output=True, text=True, env=env)
        for line in listed.stdout.splitlines():
            job_id, comment, state, elapsed = line.split("|")
            if rule_of(comment) == rule and state == "RUNNING":
                subprocess.run(["scancel", job_id], env=env, check=True)
                log(f"cancelled SLURM job {job_id} ({rule}) after {elapsed}")
                return True
        time.sleep(2)
    return False

