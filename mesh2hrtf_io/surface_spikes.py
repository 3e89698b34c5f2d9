"""A physical check of a solved step: no boundary element may be much louder than the ear's source.

With the reciprocal setup (a vibrating patch in the ear canal, the rest of the head rigid) the surface pressure
is highest on and next to the source and falls off away from it: on P143's stitched heads every other element
stayed 4-6 dB under the source's loudest from 150 Hz to 24 kHz. An element far louder than the source is a
numerical spike, found on sliver triangles (an angle of ~2 degrees): on P067's stitched head nine elements 18 mm
from the source were up to 22.5 dB above it at 150 Hz, and the far field's DTFs were off by ~1 dB there. NumCalc
still reports convergence in such a case, so each solved step is checked here, from NumCalc's own
``be.out/be.<step>/pBoundary`` (pressure per boundary element, in NumCalc's element order).
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .results import source_folders, step_folder, step_status

SPIKE_MARGIN_DB = 6.0  # an element this much above the source's loudest element is a spike
BOUNDARY_FILE = "pBoundary"
_SOURCE_LINE = re.compile(r"^\s*ELEM\s+(\d+)\s+TO\s+(\d+)\s+VELO\b", re.MULTILINE)


def source_elements(nc_inp_text: str) -> np.ndarray:
    """Element ids (0-based, NumCalc's) given a velocity in NC.inp's BOUNDARY block: the ear's source."""
    ranges = [(int(a), int(b)) for a, b in _SOURCE_LINE.findall(nc_inp_text)]
    return np.unique(np.concatenate([np.arange(a, b + 1) for a, b in ranges])) if ranges else np.array([], int)


def read_boundary_pressure(source_folder: str | os.PathLike, step: int) -> np.ndarray | None:
    """Complex pressure per boundary element of one step, None when NumCalc left no pBoundary."""
    path = step_folder(source_folder, step) / BOUNDARY_FILE
    if not path.is_file():
        return None
    rows = [line.split() for line in path.read_text().splitlines()[3:]]
    values = np.array([row[:3] for row in rows if len(row) >= 3], dtype=np.float64)
    pressure = np.zeros(int(values[:, 0].max()) + 1, dtype=np.complex128)
    pressure[values[:, 0].astype(int)] = values[:, 1] + 1j * values[:, 2]
    return pressure


def surface_spikes(source_folder: str | os.PathLike, step: int, margin_db: float = SPIKE_MARGIN_DB) -> dict | None:
    """Elements of a solved step louder than the source's loudest element by more than ``margin_db``:
    {"elements": ids, "max_db_above_source": dB}, None when the step left no pBoundary or NC.inp has no source."""
    folder = Path(source_folder)
    sources = source_elements((folder / "NC.inp").read_text()) if (folder / "NC.inp").is_file() else []
    pressure = read_boundary_pressure(folder, step)
    if pressure is None or len(sources) == 0 or sources.max() >= len(pressure):
        return None
    level = 20.0 * np.log10(np.abs(pressure) + 1e-30)
    others = np.ones(len(level), dtype=bool)
    others[sources] = False
    above = level - level[sources].max()
    spikes = np.where(others & (above > margin_db))[0]
    return {"elements": spikes.tolist(), "max_db_above_source": round(float(above[others].max()), 2)}


def _finished(source_folder: Path, step: int) -> bool:
    """The runner marked the step solved and converged (``status.json``): its pBoundary is final. A step still
    running, or rerun after a non-converged attempt, has a pBoundary being written or from the failed attempt."""
    return bool((step_status(source_folder, step) or {}).get("converged", False))


def project_spikes(project: str | os.PathLike, margin_db: float = SPIKE_MARGIN_DB) -> dict:
    """Every finished step of every source of a project judged by :func:`surface_spikes` (steps restored from a
    store have no pBoundary and are left out): {"source_N": {step: result}}, plus "spiked_steps" and
    "unfinished" (per source, steps with NumCalc output but no converged status: running or being retried)."""
    found: dict = {"spiked_steps": 0, "unfinished": {}}
    for folder in source_folders(Path(project) / "NumCalc"):
        steps = sorted(int(d.name.split(".")[1]) for d in folder.glob("be.out/be.*") if d.name.split(".")[1].isdigit())
        finished = [step for step in steps if _finished(folder, step)]
        found["unfinished"][folder.name] = [step for step in steps if step not in finished]
        judged = {step: surface_spikes(folder, step, margin_db) for step in finished}
        found[folder.name] = {step: result for step, result in judged.items() if result is not None}
        found["spiked_steps"] += sum(bool(result["elements"]) for result in found[folder.name].values())
    return found
