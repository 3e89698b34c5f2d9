"""The HRTF stage of the workflow as plain functions (one per rule): export, solve, collect.

Each writes its declared output atomically and only after the work is complete, so a killed job
leaves no output that Snakemake could take as finished.
"""
from __future__ import annotations

import json
import logging
import os
import tempfile
import shutil
from pathlib import Path

import numpy as np

from core.atomic import write_text_atomic
from core.progress import Progress

from .constants import SPEED_OF_SOUND_M_S
from .frequency_sets import describe_set, frequencies_from_spec
from .errors import Mesh2HrtfIoError
from .grids import full_grid, grid_from_sofa, sagittal_grid, with_directions_of
from .project import write_project
from .project_reader import read_project

log = logging.getLogger(__name__)
SOURCE_TYPES = {"both": "Both ears", "left": "Left ear", "right": "Right ear"}


def export_head_project(head_path: str | os.PathLike, project: str | os.PathLike, settings: dict,
                        grid_sofa: str | os.PathLike | None = None, title: str | None = None,
                        head_store: str | os.PathLike | None = None,
                        sources_json: str | os.PathLike | None = None) -> None:
    """Export ``head_path`` (mm) with ear-canal sources (config hrtf.ears) and the configured frequencies, on
    the sagittal-plane grid or, with ``grid_sofa``, on that SOFA file's source positions (grid "Directions",
    e.g. the reference HRIRs' 793, so that solved and reference sets combine direction by direction); with settings
    grid "full" (a new listener) on the full grid, plus ``grid_sofa``'s directions where given
    (:func:`mesh2hrtf_io.grids.with_directions_of`). With
    ``head_store`` (the variant's step store folder, for heads the pipeline built), the head is kept there too
    (:func:`mesh2hrtf_io.step_store.save_head`), so that a fresh clone solves, and restores, the very same mesh.
    With ``sources_json`` (a band mesh's, :func:`stitching.frequency_bands.write_band_head`), the sources are the
    faces it names (those of the full head, kept) instead of being found again."""
    import trimesh  # noqa: PLC0415

    from .ear_canal import ear_canal_elements  # noqa: PLC0415

    head_path = Path(head_path)
    if not head_path.is_file() or head_path.stat().st_size == 0:
        raise Mesh2HrtfIoError(f"{head_path}: missing or empty head mesh")
    head = trimesh.load(head_path, process=False, force="mesh")
    sides = ("left", "right") if settings["ears"] == "both" else (settings["ears"],)
    if sources_json:
        given = json.loads(Path(sources_json).read_text())["sources"]
        missing = [side for side in sides if side not in given]
        if missing:
            raise Mesh2HrtfIoError(f"{sources_json}: no source faces for the {', '.join(missing)} ear; make the band "
                                   "mesh again with the ears of config hrtf.ears")
        ears = {side: np.asarray(given[side], dtype=np.int64) for side in sides}
    else:
        ears = {side: ear_canal_elements(head, side, source=str(head_path)) for side in sides}
    frequencies = frequencies_from_spec(settings["frequencies_hz"])
    if settings.get("grid") == "full":  # a new listener: all round the head, with a dataset's directions where given
        grid = full_grid(settings["polar_step_deg"])
        if grid_sofa:
            grid = with_directions_of(grid, grid_from_sofa(grid_sofa, name="Dataset"))
    elif grid_sofa:
        grid = grid_from_sofa(grid_sofa, name="Directions")
    else:
        grid = sagittal_grid(polar_step_deg=settings["polar_step_deg"])
    layout = write_project(project, head.vertices, head.faces, ears, [grid],
                           frequencies, source_type=SOURCE_TYPES[settings["ears"]], title=title or head_path.parent.name,
                           compute_hrirs=True, numcalc_cluster_size=settings.get("numcalc_cluster_size", "auto"),
                           speed_of_sound_m_s=float(settings.get("speed_of_sound_m_s", SPEED_OF_SOUND_M_S)))
    log.info("exported %s: %d elements, ears %s, %s", project, layout.n_object_elements, layout.ear_ranges,
             describe_set(frequencies))
    if head_store:
        from .step_store import save_head  # noqa: PLC0415

        log.info("head kept as %s", save_head(head_path, head_store))


def solve_numcalc_steps(project: str | os.PathLike, source: int, steps, status_path: str | os.PathLike,
                        numcalc: str | None, max_iterations: int, store: str | os.PathLike | None = None) -> None:
    """Run NumCalc for ``steps`` (1-based; complete ones are skipped) and write their status JSON. With a
    ``store`` folder (:mod:`mesh2hrtf_io.step_store`), steps stored there for this very project are restored
    instead of solved, and every newly solved step is copied there."""
    from .numcalc import find_numcalc, run_step  # noqa: PLC0415
    from .step_store import project_fingerprint, restore_step, save_step  # noqa: PLC0415

    folder = Path(project) / "NumCalc" / f"source_{source}"
    points = len(read_project(project).evaluation_points_m)
    fingerprint = project_fingerprint(project, source) if store else None
    statuses, binary = [], None
    progress = Progress(len(steps), f"NumCalc source_{source}", log)
    for step in steps:
        if store and restore_step(project, source, step, store, fingerprint):
            statuses.append({"step": step, "solver": "NumCalc", "converged": True, "restored_from": str(store)})
        else:
            binary = binary or find_numcalc(numcalc)
            statuses.append(run_step(binary, folder, step, points, max_iterations))
            if store:
                save_step(project, source, step, store, fingerprint, statuses[-1])
        progress.step(f"step {step}")
    write_text_atomic(status_path, json.dumps({"steps": statuses}, indent=2) + "\n")


def solve_embedded(projects: dict[str, str | os.PathLike], status_path: str | os.PathLike,
                   stores: dict[str, str | os.PathLike | None] | None = None, threads: int | None = None,
                   device: str = "auto") -> None:
    """Solve every missing step of several projects (e.g. a subject's reference and PPM heads, by name) with
    the embedded solver in this one process, so that bempp-cl builds (OpenCL) or compiles (numba) its kernels
    once for all of them; write a summary JSON per project (steps solved and restored, seconds per step and per
    frequency, the first including the kernel builds) and the job's total seconds and backend. With ``stores``
    (name -> folder), stored steps are restored first and solved ones copied there. ``threads``: threads of the assembly (default: all cores); ``device``: bempp-cl's
    backend, 'auto' (cuda where a GPU passes its probe, else numba), 'numba', 'opencl' or 'cuda'
    (:mod:`mesh2hrtf_io.backends`)."""
    import time  # noqa: PLC0415

    from .bem import backend_choice_summary, use_device  # noqa: PLC0415
    from .embedded import solve_project_embedded  # noqa: PLC0415
    from .step_store import project_fingerprint, restore_step, save_step  # noqa: PLC0415

    device = use_device(device, threads)
    stores = stores or {}
    start = time.perf_counter()
    summaries = {}
    for name, project in projects.items():
        store = stores.get(name)
        solved = read_project(project)
        steps = range(1, len(solved.frequencies_hz) + 1)
        fingerprints = ({source: project_fingerprint(project, source) for source in range(1, len(solved.sources) + 1)}
                        if store else {})
        restored = sum(restore_step(project, source, step, store, fingerprint)
                       for source, fingerprint in fingerprints.items() for step in steps)
        summary = solve_project_embedded(project)
        summary["steps_restored"] = restored
        for source, fingerprint in fingerprints.items():
            for step in steps:
                save_step(project, source, step, store, fingerprint,
                          {"solver": f"embedded ({device})", "seconds": summary["measured_seconds_per_step"] or 0.0})
        summaries[name] = {"project": str(project), **summary}
    write_text_atomic(status_path, json.dumps({"projects": summaries,
                                               "seconds": round(time.perf_counter() - start, 2),
                                               "threads": threads, "device": device,
                                               "backend": backend_choice_summary()}, indent=2) + "\n")


def merge_band_steps(project: str | os.PathLike, band_projects: dict[str | os.PathLike, list[int]]) -> int:
    """Copy the results of the steps solved on band meshes (``band_projects``: band project -> its steps, 1-based
    numbers of the full frequency set) into the full project's ``be.out``, so that it is collected as one solve;
    a step the full project already holds complete is left alone. Returns the number of steps copied.

    Raises
    ------
    Mesh2HrtfIoError
        If a band project's frequencies differ from the full one's, or a step it should hold is not complete.
    """
    from .numcalc import step_done  # noqa: PLC0415

    full = read_project(project)
    n_points = len(full.evaluation_points_m)
    copied = 0
    for band_project, steps in band_projects.items():
        band = read_project(band_project)
        if not np.array_equal(band.frequencies_hz, full.frequencies_hz) or len(band.sources) != len(full.sources):
            raise Mesh2HrtfIoError(f"{band_project}: its frequencies or ears differ from {project}'s; export both "
                                   "with the same settings")
        for band_source, full_source in zip(band.sources, full.sources):
            for step in steps:
                if step_done(full_source.folder, step, n_points):
                    continue
                if not step_done(band_source.folder, step, n_points):
                    raise Mesh2HrtfIoError(f"{band_project}: step {step} of {band_source.folder.name} is not solved")
                target = full_source.folder / "be.out" / f"be.{step}"
                partial = target.with_name(target.name + ".partial")
                shutil.rmtree(partial, ignore_errors=True)
                shutil.copytree(band_source.folder / "be.out" / f"be.{step}", partial)
                shutil.rmtree(target, ignore_errors=True)
                partial.rename(target)
                copied += 1
    return copied


def collect(project: str | os.PathLike, hrtf_path: str | os.PathLike, hrir_path: str | os.PathLike,
            hrir: dict | None = None) -> None:
    """SOFA files of the project's (first) grid, moved to the declared outputs; ``hrir`` (config hrtf.hrir:
    sampling_rate_hz, n_samples) sets the HRIRs rebuilt from a sparse frequency set."""
    from .sofa_out import HRIR_RATE_HZ, HRIR_SAMPLES, collect_sofa  # noqa: PLC0415

    hrir = hrir or {"sampling_rate_hz": HRIR_RATE_HZ, "n_samples": HRIR_SAMPLES}

    with tempfile.TemporaryDirectory(dir=Path(hrtf_path).parent) as tmp:
        written = {p.name: p for p in collect_sofa(project, tmp, hrirs=True,
                                                   hrir_sampling_rate_hz=hrir["sampling_rate_hz"],
                                                   hrir_samples=hrir["n_samples"])}
        name = read_project(project).grids[0].name
        for kind, target in (("HRTF", hrtf_path), ("HRIR", hrir_path)):
            os.replace(written[f"{kind}_{name}.sofa"], target)
    log.info("collected %s and %s", hrtf_path, hrir_path)


def collect_pressures(project: str | os.PathLike, pressures, folder: str | os.PathLike,
                      hrir: dict | None = None) -> Path:
    """SOFA files of given left-ear ``pressures`` (per step, at the project's evaluation grid; e.g. steps kept in a
    step store or solved elsewhere) as the workflow collects them: written into a copy of ``project`` in ``folder``
    and collected there. Returns the HRTF file (``folder/HRTF.sofa``; ``HRIR.sofa`` beside it)."""
    from .results import write_eval_grid_pressure  # noqa: PLC0415

    folder = Path(folder)
    copy = folder / "project"
    shutil.copytree(project, copy)
    solved = read_project(copy)
    node_ids = np.concatenate([grid.node_ids for grid in solved.grids])
    for step, pressure in enumerate(pressures, start=1):
        write_eval_grid_pressure(solved.sources[0].folder, step, node_ids, pressure)
    hrtf = folder / "HRTF.sofa"
    collect(copy, hrtf, folder / "HRIR.sofa", hrir or {"sampling_rate_hz": 48000.0, "n_samples": 320})
    return hrtf
