"""Cost of solving a project: elements, frequencies, predicted CPU-hours and peak memory.

Embedded solver: the dense Burton–Miller model of :func:`mesh2hrtf_io.bem.estimate_cost`.
NumCalc: with a NumCalc binary, memory per step from ``NumCalc -estimate_ram`` and time from the model of
:mod:`mesh2hrtf_io.numcalc_cost` (near-field pairs of the cluster tree NumCalc will build, plus that
memory; benchmarks/numcalc_graded.py measures it against real steps). Without a binary, a rough rule of
thumb t = a · NE · (1 + (f / f_ref)^2) per step and ear, measured on Mesh2HRTF's uniform example head
(graded heads cost several times more per element; the result says which was used).
"""
from __future__ import annotations

import dataclasses
import os


from .bem import estimate_cost
from .project_reader import read_project

# NumCalc 1.2.4 on this 2-core VM, Mesh2HRTF's example head (17,432 elements, 216 grid points, one ear):
# 34.1 s at 1 kHz, 39.0 s at 4 kHz, 39.8 s at 8 kHz per step (benchmarks/solve_cost.py)
NUMCALC_SECONDS_PER_ELEMENT = 0.9e-3   # at low frequency, per step and ear
NUMCALC_REFERENCE_FREQUENCY_HZ = 20000.0  # iterations and near-field work grow with (f / f_ref)^2


@dataclasses.dataclass(frozen=True)
class ProjectCost:
    """Predicted cost of a whole project (all sources and steps)."""

    n_elements: int
    n_vertices: int
    n_evaluation_points: int
    n_sources: int
    n_frequencies: int
    solver: str
    cpu_hours: float
    peak_memory_gb: float
    memory_source: str
    time_source: str = ""

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def numcalc_seconds(n_elements: int, frequency_hz: float) -> float:
    """Predicted NumCalc time (s) of one step of one ear."""
    return NUMCALC_SECONDS_PER_ELEMENT * n_elements * (1 + (frequency_hz / NUMCALC_REFERENCE_FREQUENCY_HZ) ** 2)


def project_cost(folder: str | os.PathLike, solver: str = "embedded", numcalc: str | os.PathLike | None = None,
                 device: str = "auto") -> ProjectCost:
    """Predict CPU-hours and peak RAM of solving the project at ``folder`` with ``solver`` (the embedded solver on
    ``device``: 'cuda' gives GPU hours and GPU memory; anything else the 2-core CPU model)."""
    project = read_project(folder)
    n_points = len(project.evaluation_points_m)
    n_elements, n_vertices = len(project.faces), len(project.vertices_m)
    n_sources, frequencies = len(project.sources), project.frequencies_hz
    if solver == "embedded":
        gpu = device == "cuda"
        cost = estimate_cost(n_vertices, n_elements, n_points, backend="cuda" if gpu else "numba")
        # on the GPU every source of a frequency shares one assembly and LU; the CPU model counts per source
        seconds = cost.seconds_per_frequency * len(frequencies) * (1 if gpu else n_sources)
        return ProjectCost(n_elements, n_vertices, n_points, n_sources, len(frequencies),
                           "embedded (cuda)" if gpu else solver, round(seconds / 3600, 3),
                           cost.memory_gb_per_frequency,
                           "GPU memory model (bem_arrays, H200)" if gpu else "dense operator model",
                           "GPU hours, model measured on an H200 (benchmarks/gpu_solve.py)" if gpu else "")
    if solver != "numcalc":
        raise ValueError(f"solver must be 'embedded' or 'numcalc', got {solver!r}")
    from .numcalc import NumCalcError, find_numcalc  # noqa: PLC0415

    try:
        binary = find_numcalc(numcalc)
    except NumCalcError:
        if numcalc:
            raise
        binary = None
    if binary is None:
        seconds = sum(numcalc_seconds(n_elements, f) for f in frequencies) * n_sources
        return ProjectCost(n_elements, n_vertices, n_points, n_sources, len(frequencies), solver,
                           round(seconds / 3600, 3), float("nan"), "unknown (no NumCalc binary to run -estimate_ram)",
                           "element-count rule of thumb (no NumCalc binary; graded heads cost several times more)")
    from .numcalc_cost import project_step_costs  # noqa: PLC0415

    steps = project_step_costs(folder, binary)
    seconds = sum(step.seconds for step in steps) * n_sources
    return ProjectCost(n_elements, n_vertices, n_points, n_sources, len(frequencies), solver, round(seconds / 3600, 3),
                       round(max(step.memory_gb for step in steps), 3), "NumCalc -estimate_ram",
                       f"near-field pairs ({steps[0].near_pairs_million} M, {steps[0].levels} levels) and memory "
                       "(mesh2hrtf_io.numcalc_cost)")
