"""Time and memory of one NumCalc step, predicted from the mesh and NumCalc's own memory estimate.

A step's time goes to (i) the near-field matrix, dense between elements of neighbouring finest clusters,
assembled once by numerical integration, and (ii) the FMM matrices (translations, expansions, grid
points), which grow with frequency as the expansions get more terms, and are applied in every CGS
iteration. We count (i) from the mesh: element pairs whose centres lie within twice the finest cluster
size of NumCalc's tree (:mod:`mesh2hrtf_io.clusters`); this count matched NumCalc's own near-field
nonzeros within 7 % on a stitched head with 2 and 3 levels. (ii) follows from ``NumCalc -estimate_ram``
(GB per step, which counts all nonzeros; its estimate matched the measured peak within 2 %).

    seconds = a · near_pairs[millions] + b · memory_gb

with a and b fitted to steps measured on this 2-core machine (``benchmarks/numcalc_graded.py``: P039's
head with the PPM stitched in, with NumCalc's default tree and with ours, and P039's own graded head, at
1, 8 and 16 kHz; every step within 18 % of its prediction). The same step measured at different times
here varies by up to 25 % (e.g. 128 and 167 s), which bounds what any model can promise.
"""
from __future__ import annotations

import dataclasses
import functools
import os
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .clusters import ClusterTree, cluster_tree, mean_element_length_m

NEAR_FIELD_REACH = 2.0          # near-field pairs: centres within this many finest cluster sizes
SECONDS_PER_MILLION_NEAR_PAIRS = 1.363  # fitted (least relative error) to 9 steps, see module docstring
SECONDS_PER_GB = 41.47                  # fitted with it


@dataclasses.dataclass(frozen=True)
class StepCost:
    """Predicted cost of one NumCalc step of one ear."""

    frequency_hz: float
    seconds: float
    memory_gb: float
    near_pairs_million: float
    levels: int


def near_field_pairs(vertices_m: np.ndarray, faces: np.ndarray, finest_m: float) -> int:
    """Element pairs (ordered, self included) whose centres lie within NEAR_FIELD_REACH finest cluster sizes."""
    centres = vertices_m[faces].mean(axis=1)
    return int(cKDTree(centres).query_ball_point(centres, r=NEAR_FIELD_REACH * finest_m, return_length=True).sum())


def step_seconds(near_pairs: float, memory_gb: float) -> float:
    """Predicted wall time (s) of one step from near-field pairs and NumCalc's memory estimate (GB)."""
    return SECONDS_PER_MILLION_NEAR_PAIRS * near_pairs / 1e6 + SECONDS_PER_GB * memory_gb


def tree_of_project(vertices_m: np.ndarray, faces: np.ndarray, nc_inp: str | os.PathLike) -> ClusterTree:
    """The cluster tree NumCalc builds for a project: the level-0 size is read back from its NC.inp."""
    lines = Path(nc_inp).read_text().split("\n")
    written = float(lines[lines.index("## 2. Main Parameters II") + 1].split()[3])
    return cluster_tree(len(faces), mean_element_length_m(vertices_m, faces), written)


def predict_steps(vertices_m: np.ndarray, faces: np.ndarray, tree: ClusterTree, frequencies_hz,
                  memory_gb) -> list[StepCost]:
    """Per-step cost for the given frequencies and NumCalc's memory estimates (GB, one per frequency)."""
    pairs = near_field_pairs(vertices_m, faces, tree.finest_m)
    return [StepCost(float(f), round(step_seconds(pairs, m), 1), float(m), round(pairs / 1e6, 2), tree.levels)
            for f, m in zip(frequencies_hz, memory_gb)]


@functools.lru_cache(maxsize=64)
def _project_step_costs(project_dir: str, numcalc: str, parameters_mtime_ns: int) -> tuple[StepCost, ...]:
    from .numcalc import estimate_memory  # noqa: PLC0415
    from .project_reader import read_project  # noqa: PLC0415

    project = read_project(project_dir)
    source = project.sources[0].folder
    memory = [e.memory_gb for e in estimate_memory(Path(numcalc), source)]
    tree = tree_of_project(project.vertices_m, project.faces, source / "NC.inp")
    return tuple(predict_steps(project.vertices_m, project.faces, tree, project.frequencies_hz, memory))


def project_step_costs(project_dir: str | os.PathLike, numcalc: str | os.PathLike) -> tuple[StepCost, ...]:
    """Predicted cost of every step of one ear of an exported project (cached per project and export),
    for the scheduler's runtime and mem_mb."""
    project_dir = Path(project_dir)
    return _project_step_costs(str(project_dir.resolve()), str(numcalc),
                               (project_dir / "parameters.json").stat().st_mtime_ns)
