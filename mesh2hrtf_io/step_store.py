"""Solved frequency steps kept outside a project, so that they can be committed and restored.

Hours of NumCalc must survive the end of a session and a fresh clone. A store folder holds, per source
and step, ``source_N/step_KKK.npz``: the complex pressures at the evaluation nodes (Pa, e^{-iωt}, as
NumCalc writes them), the node IDs, the step's frequency, the project's fingerprint and when it was saved
(UTC). The fingerprint is the SHA-256 of everything the result depends on: the object and grid meshes and
the source's NC.inp (frequencies, ear elements, cluster size). A stored step is restored into ``be.out/be.K`` only when
the fingerprint matches, so a changed mesh or setting is solved again instead of reusing a stale
result. Files are small (~13 kB per step for 793 points) and written atomically.

A head the pipeline built (PPM head, controls) is kept beside its steps as ``head.ply``, byte for byte, with
``head.json`` (SHA-256, triangles, when saved): align, stitch and remesh give bit-identical meshes when rerun on
one machine but not on another CPU (P143's PPM head came out with 27,598 triangles on one machine and 27,594 on
the next), and a step's fingerprint depends on every byte of the mesh. A fresh clone exports the stored head
instead of its own rebuild, so its steps are restored; delete ``head.ply`` to solve a rebuilt head instead.
"""
from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import shutil
import time
from pathlib import Path

import numpy as np

from core.atomic import atomic_path, write_text_atomic

from .project_reader import read_project
from .results import read_eval_grid_pressure, step_is_complete, write_eval_grid_pressure, write_solver_mark

log = logging.getLogger(__name__)
HEAD_FILE = "head.ply"


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
                        saved_utc=utc_now())
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
        status = _status_of(stored)
    if step_is_complete(folder, step, len(nodes)):
        return True
    write_eval_grid_pressure(folder, step, nodes, pressure)
    if str(status.get("solver", "")).startswith("embedded"):
        write_solver_mark(folder, step, status["solver"])
    return True


def stored_status(store: str | os.PathLike, source: int, step: int) -> dict | None:
    """The solver status kept with a stored step ({} when saved without one), None when not stored."""
    path = _stored(Path(store), source, step)
    if not path.is_file():
        return None
    with np.load(path) as stored:
        return _status_of(stored)


def _status_of(stored) -> dict:
    """The solver status kept in an open stored step ({} when saved without one)."""
    return json.loads(str(stored["status_json"])) if "status_json" in stored.files else {}


def solve_seconds(status: dict | None) -> float:
    """Wall-clock seconds a step's solver status records (NumCalc attempts, or the embedded solver's)."""
    if not status:
        return 0.0
    if "attempts" in status:
        return float(sum(attempt.get("seconds", 0.0) for attempt in status["attempts"]))
    return float(status.get("seconds", 0.0))


def solve_cpu_seconds(status: dict | None) -> float:
    """CPU seconds of a step's NumCalc attempts where every attempt recorded them (since 2026-12-04), else its
    wall-clock seconds (:func:`solve_seconds`): NumCalc is single-threaded, so the two agree on an idle core."""
    attempts = (status or {}).get("attempts")
    if attempts and all("cpu_seconds" in attempt for attempt in attempts):
        return float(sum(attempt["cpu_seconds"] for attempt in attempts))
    return solve_seconds(status)


def stored_head(store: str | os.PathLike | None) -> Path | None:
    """The head mesh kept in a variant's store folder (``head.ply``, mm), None when there is none."""
    if not store:
        return None
    path = Path(store) / HEAD_FILE
    return path if path.is_file() else None


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes, e.g. a head mesh's."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def utc_now() -> str:
    """The time now, ISO 8601 in UTC (when a step or head was saved)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def save_head(head_path: str | os.PathLike, store: str | os.PathLike) -> Path:
    """Keep ``head_path`` (the head a variant's steps are solved for, mm) as the store's ``head.ply``, byte for
    byte and with its modification time (so Snakemake does not take it for a newer input than the project
    exported from it), and write ``head.json``. A stored head that differs is replaced (its steps no longer
    match any project and are solved again), with a warning."""
    import trimesh  # noqa: PLC0415

    head_path, target = Path(head_path), Path(store) / HEAD_FILE
    digest = file_sha256(head_path)
    if target.is_file():
        kept = file_sha256(target)
        if kept == digest:
            return target
        log.warning("%s: replacing the stored head (SHA-256 %s) by %s (%s); the steps stored for the old head "
                    "are solved again", target, kept[:16], head_path, digest[:16])
    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(target) as tmp:
        shutil.copy2(head_path, tmp)
    faces = len(trimesh.load(target, process=False, force="mesh").faces)
    write_text_atomic(target.with_suffix(".json"), json.dumps(
        {"sha256": digest, "triangles": faces, "copied_from": str(head_path),
         "saved_utc": utc_now()}, indent=2) + "\n")
    return target


def save_band_sources(sources_json: str | os.PathLike, store: str | os.PathLike) -> Path:
    """Keep a band mesh's source faces (``sources.json`` of :func:`stitching.frequency_bands.write_band_head`)
    beside its kept head, so that a fresh clone exports the kept band mesh with the same sources."""
    target = Path(store) / "sources.json"
    text = Path(sources_json).read_text()
    if not target.is_file() or target.read_text() != text:
        write_text_atomic(target, text)
    return target
