"""Solving a Mesh2HRTF project with the embedded solver (bempp-cl), step by step, resumable.

Reads the project exactly as NumCalc does (nodes, elements, ear ranges, grids, frequencies) and
writes NumCalc-format results (``be.out/be.<step>/pEvalGrid``), so the SOFA collection is shared.
Finished steps are skipped; each step's file appears atomically when it is complete.
"""
from __future__ import annotations

import logging
import os
import time

import numpy as np

from core.progress import Progress

from .bem import estimate_cost, solve_sources
from .project_reader import Project, read_project
from .results import missing_steps, write_eval_grid_pressure, write_solver_mark

log = logging.getLogger(__name__)


def solve_project_embedded(folder: str | os.PathLike, steps: list[int] | None = None,
                           max_vertices: int = 12000) -> dict:
    """Solve the missing steps (1-based; default all) of every source. Returns a summary with the
    estimated and measured seconds per step. Refuses meshes above ``max_vertices`` (dense memory)."""
    from .bem import current_backend  # noqa: PLC0415

    project: Project = read_project(folder)
    points = project.evaluation_points_m
    node_ids = np.concatenate([grid.node_ids for grid in project.grids])
    backend = current_backend()
    cost = estimate_cost(len(project.vertices_m), len(project.faces), len(points), backend=backend)
    # on a GPU the limit is its memory, checked before the first frequency (bem_arrays.gpu_work_budget)
    if backend != "cuda" and len(project.vertices_m) > max_vertices:
        from .errors import Mesh2HrtfIoError  # noqa: PLC0415

        raise Mesh2HrtfIoError(f"{folder}: {len(project.vertices_m)} vertices exceed the embedded solver's limit of "
                               f"{max_vertices} (it would need {cost.memory_gb_per_frequency:.1f} GB and "
                               f"~{cost.seconds_per_frequency:.0f} s per frequency); use NumCalc, a coarser mesh, or a GPU "
                               "(hrtf.embedded_device: cuda)")
    n_steps = len(project.frequencies_hz)
    wanted = list(range(1, n_steps + 1)) if steps is None else list(steps)
    todo = {source.folder: [s for s in missing_steps(source.folder, n_steps, len(points)) if s in wanted]
            for source in project.sources}
    total = sum(len(v) for v in todo.values())
    steps_todo = sorted({step for steps_of_source in todo.values() for step in steps_of_source})
    log.info("embedded solver (%s): %d vertices, %d elements, %d evaluation points; estimate %.0f s and %.2f GB per "
             "frequency (all sources of a frequency share one factorised matrix); %d source step(s) at %d frequencies to "
             "solve (%.1f min)", backend, len(project.vertices_m), len(project.faces), len(points), cost.seconds_per_frequency,
             cost.memory_gb_per_frequency, total, len(steps_todo), len(steps_todo) * cost.seconds_per_frequency / 60)
    measured, per_frequency = [], []
    progress = Progress(total, "embedded solver, source steps", log)
    for step in steps_todo:
        # every source missing this step is solved with the same factorised system matrix
        sources = [source for source in project.sources if step in todo[source.folder]]
        frequency = float(project.frequencies_hz[step - 1])
        start = time.perf_counter()
        pressures = solve_sources(project.vertices_m, project.faces,
                                  [(source.elements, source.velocity_m_s) for source in sources], points, frequency,
                                  project.speed_of_sound_m_s, project.density_kg_m3)
        for source, pressure in zip(sources, pressures):
            write_eval_grid_pressure(source.folder, step, node_ids, pressure,
                                     f"Mesh2HRTF {project.parameters.get('Mesh2HRTF_Version', '1.2.4')}")
            write_solver_mark(source.folder, step, f"embedded ({backend})")
        elapsed = time.perf_counter() - start
        measured += [elapsed / len(sources)] * len(sources)
        per_frequency.append(elapsed)
        progress.step(f"step {step}, {frequency:.0f} Hz, {' + '.join(source.folder.name for source in sources)}: "
                      f"{elapsed:.1f} s", units=len(sources))
    return {"steps_solved": progress.done, "backend": backend, "estimated_seconds_per_step": cost.seconds_per_frequency,
            "estimated_memory_gb": cost.memory_gb_per_frequency,
            "measured_seconds_per_step": float(np.mean(measured)) if measured else None,
            # every source of a frequency at once; the first includes numba's compilation when it is the process's first
            "seconds_per_frequency": [round(value, 3) for value in per_frequency]}
