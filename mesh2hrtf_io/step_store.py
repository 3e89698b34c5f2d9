"""Solved frequency steps kept outside a project, so that they can be committed and restored.

Hours of NumCalc must survive the end of a session and a fresh clone. A store folder holds, per source
and step, ``source_N/step_KKK.npz``: the complex pressures at the evaluation nodes (Pa, e^{-iωt}, as
NumCalc writes them), the node IDs, the step's frequency, the project's fingerprint and when it was saved
(UTC). The fingerprint is the SHA-256 of everything the result depends on: the object and grid meshes and
the source's NC.inp (frequencies, ear elements, cluster size). A stored step is restored into ``be.out/be.K`` only when
the fingerprint matches, so a changed mesh or setting is solved again instead of reusing a stale
result. Files are small (~13 kB per step for 793 points) and written atomically.
"""
from __future__ import annotations

import hashlib
import json
import io
import os
import time
from pathlib import Path

import numpy as np

from ppm.atomic import atomic_path

from .project_reader import read_project
from .results import read_eval_grid_pressure, step_is_complete, write_eval_grid_pressure


def project_fingerprint(project_dir: str | os.PathLike, source: int) -> str:
    """SHA-256 of the meshes, grids and ``NumCalc/source_<source>/NC.inp`` of a project."""
    project_dir = Path(project_dir)
    digest = hashlib.sha256()
    files = [project_dir / "ObjectMeshes" / "Reference" / name for name in ("Nodes.txt", "Elements.txt")]
    files += sorted((project_dir / "EvaluationGrids").glob("*/*.txt"))
    files.append(project_dir / "NumCalc" / f"source_{source}" / "NC.inp")
    for path in files:
        digest.update(path.relative_to(project_dir).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _stored(store: Path, source: int, step: int) -> Path:
    return Path(store) / f"source_{source}" / f"step_{step:03d}.npz"


def save_step(project_dir: str | os.PathLike, source: int, step: int, store: str | os.PathLike,
              fingerprint: str | None = None, status: dict | None = None) -> Path:
    """Copy a solved step (complete result) from the project into the store (kept as it is when the store
    already holds it for this fingerprint: committed files do not churn). ``status`` (the solver's, e.g.
    NumCalc's attempts with their seconds) is kept with it, so the CPU time of a result survives restoring."""
    fingerprint = fingerprint or project_fingerprint(project_dir, source)
    target = _stored(Path(store), source, step)
    if target.is_file():
        with np.load(target) as stored:
            if str(stored["fingerprint"]) == fingerprint:
                return target
    project = read_project(project_dir)
    folder = project.folder / "NumCalc" / f"source_{source}"
    nodes = np.concatenate([grid.node_ids for grid in project.grids])
    pressure = read_eval_grid_pressure(folder, step, len(nodes))
    buffer = io.BytesIO()
    np.savez_compressed(buffer, pressure=pressure.astype(np.complex128), node_ids=nodes.astype(np.int64),
                        frequency_hz=float(project.frequencies_hz[step - 1]),
                        fingerprint=fingerprint, status_json=json.dumps(status or {}),
                        saved_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(target) as tmp:
        Path(tmp).write_bytes(buffer.getvalue())
    return target


def restore_step(project_dir: str | os.PathLike, source: int, step: int, store: str | os.PathLike,
                 fingerprint: str | None = None) -> bool:
    """Write a stored step back into the project when its fingerprint matches; True if restored (or the
    project already holds a complete result)."""
    path = _stored(Path(store), source, step)
    folder = Path(project_dir) / "NumCalc" / f"source_{source}"
    if not path.is_file():
        return False
    with np.load(path) as stored:
        if str(stored["fingerprint"]) != (fingerprint or project_fingerprint(project_dir, source)):
            return False
        nodes, pressure = stored["node_ids"], stored["pressure"]
    if step_is_complete(folder, step, len(nodes)):
        return True
    write_eval_grid_pressure(folder, step, nodes, pressure)
    return True


def stored_status(store: str | os.PathLike, source: int, step: int) -> dict | None:
    """The solver status kept with a stored step ({} when saved without one), None when not stored."""
    path = _stored(Path(store), source, step)
    if not path.is_file():
        return None
    with np.load(path) as stored:
        return json.loads(str(stored["status_json"])) if "status_json" in stored.files else {}


def solve_seconds(status: dict | None) -> float:
    """Wall-clock seconds a step's solver status records (NumCalc attempts, or the embedded solver's)."""
    if not status:
        return 0.0
    if "attempts" in status:
        return float(sum(attempt.get("seconds", 0.0) for attempt in status["attempts"]))
    return float(status.get("seconds", 0.0))
