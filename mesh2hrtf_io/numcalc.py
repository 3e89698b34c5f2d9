"""Running Mesh2HRTF's NumCalc: one process per frequency step, resumable, with convergence checks.

NumCalc is found from a configured path or on PATH. ``NumCalc -estimate_ram`` predicts the memory of
every step (``Memory.txt``), which the workflow passes to the scheduler as ``mem_mb``. A step runs as
``NumCalc -istart k -iend k`` in ``NumCalc/source_N``; its log ``NCk-k.out`` is checked for
non-convergence ("Maximum number of iterations is reached!") and input problems ("Too many integral
points"). A non-converged step is rerun once with more iterations, then reported. Its boundary pressures are
checked for spikes (``surface_spikes``: elements far louder than the ear's source), recorded in the status. Each finished step
gets ``be.out/be.k/status.json``; steps with a complete, converged result are never recomputed.
"""
from __future__ import annotations

import dataclasses
import json
import logging
import os
import re
import shutil
import resource
import subprocess
import sys
import time
from pathlib import Path

from core.atomic import write_text_atomic

from .errors import Mesh2HrtfIoError
from .project import MAIN_PARAMETERS_II, main_parameters_ii
from .results import step_folder, step_is_complete, step_status
from .surface_spikes import surface_spikes

log = logging.getLogger(__name__)

NOT_CONVERGED = "Maximum number of iterations is reached"
BAD_ELEMENTS = "Too many integral points"
DEFAULT_MAX_ITERATIONS = 250
NUMCALC_TOLERANCE = 1e-9  # NumCalc 1.2.4's CGS stops at this relative residual (ErroIterSols)
ACCEPTED_RESIDUAL = 1e-6
"""A step stopped by the iteration limit with a relative residual at or below this is kept, not rerun: its far
field differs from the fully converged one by far less than 0.01 dB (``studies/numcalc_residual.py``)."""
_CGS_START = "CGS: err_ori"
_CGS_LINE = re.compile(r"^\s*(\d+) ([-+0-9.eE]+)\s*$", re.MULTILINE)


class NumCalcError(Mesh2HrtfIoError):
    """NumCalc is missing, crashed, or a step did not converge."""


@dataclasses.dataclass(frozen=True)
class StepEstimate:
    step: int
    frequency_hz: float
    memory_gb: float


INSTALL_HINT = ("build it from a Mesh2HRTF 1.2.x checkout with `bash scripts/install_numcalc.sh MESH2HRTF_DIR` "
                "(installs .venv/bin/NumCalc) or set hrtf.numcalc to its path, or use the embedded solver "
                "(hrtf.solver: embedded)")


def venv_numcalc() -> Path:
    """Where scripts/install_numcalc.sh puts NumCalc: beside this environment's Python."""
    return Path(sys.executable).parent / "NumCalc"


def find_numcalc(configured: str | os.PathLike | None = None) -> Path:
    """The NumCalc binary: the configured path, else ``NumCalc`` on PATH, else the one installed into this
    environment by scripts/install_numcalc.sh."""
    if configured:
        path = Path(configured).expanduser()
        if path.is_file() and os.access(path, os.X_OK):
            return path.resolve()
        found = shutil.which(str(configured))
        if found:
            return Path(found)
        raise NumCalcError(f"NumCalc binary {configured!r} (config hrtf.numcalc) not found or not executable: fix "
                           f"the path, or {INSTALL_HINT}")
    found = shutil.which("NumCalc")
    if found:
        return Path(found)
    if venv_numcalc().is_file() and os.access(venv_numcalc(), os.X_OK):
        return venv_numcalc()
    raise NumCalcError(f"NumCalc is not on PATH nor in {venv_numcalc().parent}: {INSTALL_HINT}")


def _killed_hint(returncode: int) -> str:
    """What a negative exit status (killed by a signal) most likely means, for the error message; '' otherwise."""
    if returncode >= 0:
        return ""
    import signal  # noqa: PLC0415

    try:
        name = signal.Signals(-returncode).name
    except ValueError:
        name = f"signal {-returncode}"
    if -returncode == signal.SIGKILL:
        return (f": killed by {name}, most often the out-of-memory killer. Each step needs the memory NumCalc "
                "-estimate_ram gives (the job's mem_mb); run fewer at once (--cores, or --resources mem_mb=<the "
                "machine's MB>), and never two Snakemake runs side by side on one machine, which do not see each "
                "other's jobs")
    return f": killed by {name}"


def estimate_memory(numcalc: Path, source_folder: str | os.PathLike) -> list[StepEstimate]:
    """Run ``NumCalc -estimate_ram`` and read ``Memory.txt``: one estimate per frequency step."""
    source_folder = Path(source_folder)
    result = subprocess.run([str(numcalc), "-estimate_ram"], cwd=source_folder, capture_output=True, text=True,
                            timeout=600)
    memory_file = source_folder / "Memory.txt"
    if result.returncode != 0 or not memory_file.is_file():
        raise NumCalcError(f"{source_folder}: NumCalc -estimate_ram failed (exit {result.returncode}): "
                           f"{(result.stdout + result.stderr)[-800:]}")
    estimates = []
    for line in memory_file.read_text().split("\n"):
        parts = line.split()
        if len(parts) >= 3:
            try:
                estimates.append(StepEstimate(int(parts[0]), float(parts[1]), float(parts[2])))
            except ValueError:
                continue  # header lines
    return estimates


def _children_cpu_seconds() -> float:
    """CPU seconds (user + system) of this process's finished children: NumCalc's own time, unlike the wall clock
    unaffected by other work on the machine."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def step_done(source_folder: str | os.PathLike, step: int, expected_nodes: int) -> bool:
    """A complete result that is not marked as non-converged."""
    status = step_status(source_folder, step)
    return step_is_complete(source_folder, step, expected_nodes) and (status is None or status.get("converged", True))


def last_residual(stdout: str) -> tuple[int, float] | None:
    """(iteration, relative residual) where NumCalc's CGS solver stopped, from its standard output (it prints
    "<iteration> <relative residual>" every 10 iterations and at the last); None when it printed none."""
    start = stdout.rfind(_CGS_START)
    found = _CGS_LINE.findall(stdout[start:]) if start >= 0 else []
    return (int(found[-1][0]), float(found[-1][1])) if found else None


def _log_problems(log_text: str) -> list[str]:
    problems = []
    if NOT_CONVERGED in log_text:
        problems.append("not converged (maximum number of iterations reached)")
    if BAD_ELEMENTS in log_text:
        problems.append("too many integral points: elements too large or badly shaped for this frequency")
    return problems


def _take_results(scratch: Path, source_folder: Path, step: int, results: bool = True) -> None:
    """Move a step solved in a scratch sibling (another cluster tree) into the source folder: its be.out/be.<step>
    replaces the old one (only with ``results``: NumCalc exited cleanly; else the recorded attempts stay), its log
    becomes NC<step>-<step>.out; the scratch folder is removed."""
    solved = step_folder(scratch, step)
    if results and solved.is_dir():
        target = step_folder(source_folder, step)
        shutil.rmtree(target, ignore_errors=True)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(solved), str(target))
    log_file = scratch / f"NC{step}-{step}.out"
    if log_file.is_file():
        shutil.move(str(log_file), str(source_folder / f"NC{step}-{step}.out"))
    shutil.rmtree(scratch, ignore_errors=True)


def _close_enough(attempt: dict) -> bool:
    """An attempt whose only problem is the iteration limit, stopped at or below :data:`ACCEPTED_RESIDUAL`."""
    only_limit = len(attempt["problems"]) == 1 and attempt["problems"][0].startswith("not converged")
    return only_limit and attempt.get("relative_residual", float("inf")) <= ACCEPTED_RESIDUAL


DEFAULT_TREE = "numcalc_default"
"""The cluster tree of a retry: NumCalc's own (level-0 size 0 in NC.inp). The project's tuned tree
(``mesh2hrtf_io.clusters``) halves a step's time and agrees with NumCalc's to 0.1 dB, but once let CGS diverge
(P143's default-PPM head at 24 kHz: 250 and then 500 iterations ended with boundary elements 85 dB above the
source); a second attempt with the same tree would repeat the same iteration."""


def _attempt_plan(max_iterations: int) -> list[tuple[int, str]]:
    """(iteration limit, cluster tree) of each attempt: the project's tree, then NumCalc's with twice the limit."""
    return [(max_iterations, "project"), (2 * max_iterations, DEFAULT_TREE)]


def _already_tried(previous: list[dict], iterations: int, tree: str) -> bool:
    """An earlier run of this step (its status.json) made this attempt or a longer one with the same tree."""
    return any(a.get("cluster_tree", "project") == tree and a["max_iterations"] >= iterations for a in previous)


def _default_tree_folder(source_folder: Path) -> Path:
    """A sibling of the source folder (so NC.inp's ../../ paths still hold) whose NC.inp asks NumCalc for its own
    cluster tree; its results are moved into the source folder's be.out."""
    scratch = source_folder.with_name(f"{DEFAULT_TREE}_{source_folder.name}")
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir()
    lines = (source_folder / "NC.inp").read_text().split("\n")
    if MAIN_PARAMETERS_II not in lines[:-1]:
        raise NumCalcError(f"{source_folder / 'NC.inp'}: no {MAIN_PARAMETERS_II!r} line to reset the cluster tree "
                           "under; export the project again (m2h export)")
    lines[lines.index(MAIN_PARAMETERS_II) + 1] = main_parameters_ii(0.0)
    (scratch / "NC.inp").write_text("\n".join(lines))
    return scratch


def _status(step: int, attempts: list[dict]) -> dict:
    """A step's status from its attempts so far: converged when the last one had no problem."""
    return {"step": step, "solver": "NumCalc", "converged": not attempts[-1]["problems"],
            "problems": attempts[-1]["problems"], "attempts": attempts}


def _write_status(source_folder: Path, step: int, status: dict) -> None:
    write_text_atomic(step_folder(source_folder, step) / "status.json", json.dumps(status, indent=2) + "\n")


def run_step(numcalc: Path, source_folder: str | os.PathLike, step: int, expected_nodes: int,
             max_iterations: int = DEFAULT_MAX_ITERATIONS, timeout_s: float | None = None) -> dict:
    """Solve one frequency step (1-based) unless it is already done; returns its status. Attempts an earlier
    run recorded as not converged are not repeated (see :func:`_attempt_plan`)."""
    source_folder = Path(source_folder)
    if step_done(source_folder, step, expected_nodes):
        return step_status(source_folder, step) or {"step": step, "converged": True, "resumed": True}
    previous = (step_status(source_folder, step) or {}).get("attempts", [])
    attempts = list(previous)
    for iterations, tree in _attempt_plan(max_iterations):
        if _already_tried(previous, iterations, tree):
            continue
        folder = source_folder if tree == "project" else _default_tree_folder(source_folder)
        start, cpu_start = time.perf_counter(), _children_cpu_seconds()
        try:
            result = subprocess.run([str(numcalc), "-istart", str(step), "-iend", str(step), "-nitermax",
                                     str(iterations)], cwd=folder, capture_output=True, text=True,
                                    timeout=timeout_s)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise NumCalcError(f"{folder}: NumCalc step {step} could not run ({exc})") from exc
        seconds, cpu_seconds = time.perf_counter() - start, _children_cpu_seconds() - cpu_start
        if folder != source_folder:
            _take_results(folder, source_folder, step, results=result.returncode == 0)
        log_file = source_folder / f"NC{step}-{step}.out"
        log_text = log_file.read_text(errors="replace") if log_file.is_file() else ""
        problems = _log_problems(log_text)
        complete = step_is_complete(source_folder, step, expected_nodes)
        if result.returncode != 0 or not complete:
            raise NumCalcError(f"{source_folder}: NumCalc step {step} failed (exit {result.returncode}, result "
                               f"{'complete' if complete else 'missing or incomplete'}){_killed_hint(result.returncode)}"
                               f"; log {log_file}:\n{(log_text or result.stdout + result.stderr)[-1500:]}")
        stopped = last_residual(result.stdout)
        attempt = {"max_iterations": iterations, "cluster_tree": tree, "seconds": round(seconds, 2),
                   "cpu_seconds": round(cpu_seconds, 2), "problems": problems}
        if stopped is not None:
            attempt["iterations"], attempt["relative_residual"] = stopped[0], stopped[1]
        attempts.append(attempt)
        if not problems or _close_enough(attempt):
            break
        # recorded before the next attempt: if that one is killed (memory, wall-clock), a rerun starts from it
        _write_status(source_folder, step, _status(step, attempts))
        log.warning("%s step %d: %s (relative residual %s, %s cluster tree); trying again", source_folder.name,
                    step, "; ".join(problems), attempt.get("relative_residual", "not printed"), tree)
    status = _status(step, attempts)
    if _close_enough(attempts[-1]):
        status.update(converged=True, accepted=f"stopped at relative residual {attempts[-1]['relative_residual']:.2e} "
                      f"(NumCalc's target {NUMCALC_TOLERANCE:g}; kept at or below {ACCEPTED_RESIDUAL:g})")
        log.warning("%s step %d: %s", source_folder.name, step, status["accepted"])
    spikes = surface_spikes(source_folder, step)
    if spikes is not None:
        status["surface_spikes"] = spikes
        if spikes["elements"]:
            log.warning("%s step %d: %d boundary elements are up to %.1f dB louder than the ear's source (elements %s): "
                        "numerical spikes, e.g. on sliver triangles; remesh the head (its far field may be off)",
                        source_folder, step, len(spikes["elements"]), spikes["max_db_above_source"],
                        spikes["elements"][:10])
    _write_status(source_folder, step, status)
    if not status["converged"]:
        raise NumCalcError(f"{source_folder}: step {step} {'; '.join(status['problems'])} after "
                           f"{len(attempts)} attempts; refine the mesh or check it (see NC{step}-{step}.out)")
    return status


def solve_project_numcalc(folder: str | os.PathLike, numcalc: str | os.PathLike | None = None,
                          steps: list[int] | None = None, max_iterations: int = DEFAULT_MAX_ITERATIONS) -> dict:
    """Run the missing steps (1-based; default all) of every source one after another (for clusters,
    the workflow runs one job per step instead). Returns measured seconds per step."""
    from .project_reader import read_project  # noqa: PLC0415

    binary = find_numcalc(numcalc)
    project = read_project(folder)
    n_points = len(project.evaluation_points_m)
    wanted = list(range(1, len(project.frequencies_hz) + 1)) if steps is None else list(steps)
    seconds = []
    for source in project.sources:
        for step in wanted:
            if step_done(source.folder, step, n_points):
                continue
            start = time.perf_counter()
            run_step(binary, source.folder, step, n_points, max_iterations)
            seconds.append(time.perf_counter() - start)
            log.info("%s step %d (%.0f Hz): %.1f s", source.folder.name, step, project.frequencies_hz[step - 1],
                     seconds[-1])
    return {"steps_solved": len(seconds), "measured_seconds_per_step": float(sum(seconds) / len(seconds))
            if seconds else None}
