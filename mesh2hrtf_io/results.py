"""NumCalc's result files (``be.out/be.<step>/pEvalGrid``) and the state of each frequency step.

A step is *complete* when its ``pEvalGrid`` holds all evaluation nodes; anything else (missing,
truncated, NaN) counts as not done, so interrupted runs resume exactly where they stopped and
partial results are never mixed with complete ones. The embedded solver writes the same files, so
one collector serves both.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from core.atomic import write_text_atomic

from .errors import Mesh2HrtfIoError

RESULT_FILE = "pEvalGrid"


def step_folder(source_folder: str | os.PathLike, step: int) -> Path:
    """``be.out/be.<step>`` (1-based steps, as NumCalc numbers them)."""
    return Path(source_folder) / "be.out" / f"be.{step}"


def source_folders(numcalc_folder: str | os.PathLike) -> list[Path]:
    """A project's ``NumCalc/source_<n>`` folders in source order; scratch folders beside them are not sources."""
    found = [d for d in Path(numcalc_folder).glob("source_*") if d.name.split("_", 1)[1].isdigit()]
    return sorted(found, key=lambda d: int(d.name.split("_", 1)[1]))


def step_status(source_folder: str | os.PathLike, step: int) -> dict | None:
    """The solver's ``status.json`` of a step (attempts, convergence), None when there is none or it is corrupt."""
    path = step_folder(source_folder, step) / "status.json"
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError:
        return None


SOLVER_FILE = "solver.txt"
#: What made a step without a solver mark: NumCalc writes none.
DEFAULT_SOLVER = "NumCalc"


def write_solver_mark(source_folder: str | os.PathLike, step: int, solver: str) -> Path:
    """Record which solver made a step (``be.out/be.<step>/solver.txt``, e.g. 'embedded (cuda)')."""
    return write_text_atomic(step_folder(source_folder, step) / SOLVER_FILE, solver.strip() + "\n")


def step_solver(source_folder: str | os.PathLike, step: int) -> str:
    """Which solver made a step: its mark, or NumCalc where there is none."""
    path = step_folder(source_folder, step) / SOLVER_FILE
    return path.read_text().strip() if path.is_file() else DEFAULT_SOLVER


def write_eval_grid_pressure(source_folder: str | os.PathLike, step: int, node_ids: np.ndarray,
                             pressure: np.ndarray, version: str = "Mesh2HRTF 1.2.4") -> Path:
    """Write complex pressures (Pa, e^{-iωt}) at the grid nodes in NumCalc's format, atomically."""
    lines = [version, "0", f"{step} {len(node_ids)}"]
    lines += [f"{int(i)} {p.real:.8e} {p.imag:.8e}" for i, p in zip(node_ids, pressure)]
    return write_text_atomic(step_folder(source_folder, step) / RESULT_FILE, "\n".join(lines) + "\n")


def read_eval_grid_pressure(source_folder: str | os.PathLike, step: int, expected_nodes: int | None = None) -> np.ndarray:
    """Complex pressures of one step; raises if the file is missing, truncated or holds NaN."""
    path = step_folder(source_folder, step) / RESULT_FILE
    if not path.is_file():
        raise Mesh2HrtfIoError(f"{path}: missing (step {step} not solved)")
    lines = path.read_text().split("\n")
    try:
        declared = int(lines[2].split()[-1])
        rows = np.array([line.split()[:3] for line in lines[3:] if line.strip()], dtype=np.float64)
    except (IndexError, ValueError) as exc:
        raise Mesh2HrtfIoError(f"{path}: not a NumCalc result file ({exc})") from exc
    if rows.shape[0] != declared or (expected_nodes is not None and declared != expected_nodes):
        raise Mesh2HrtfIoError(f"{path}: {rows.shape[0]} of {expected_nodes or declared} nodes; the step is "
                               "incomplete (rerun it)")
    pressure = rows[:, 1] + 1j * rows[:, 2]
    if not np.isfinite(pressure).all():
        raise Mesh2HrtfIoError(f"{path}: holds NaN or inf; the step did not converge (rerun it)")
    return pressure


def step_is_complete(source_folder: str | os.PathLike, step: int, expected_nodes: int) -> bool:
    try:
        read_eval_grid_pressure(source_folder, step, expected_nodes)
    except Mesh2HrtfIoError:
        return False
    return True


def missing_steps(source_folder: str | os.PathLike, n_steps: int, expected_nodes: int) -> list[int]:
    """1-based steps whose results are not complete yet."""
    return [step for step in range(1, n_steps + 1) if not step_is_complete(source_folder, step, expected_nodes)]
