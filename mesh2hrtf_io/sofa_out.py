"""Collecting a solved project into SOFA files, as Mesh2HRTF's Output2HRTF does.

Per evaluation grid: ``HRTF_<grid>.sofa`` (SimpleFreeFieldHRTF with 2 ears, GeneralTF with one),
pressures divided by the free-field pressure of a point source at the origin with the ear's volume
velocity (at the smallest grid radius), in NumCalc's e^{-iωt} convention as Mesh2HRTF stores them;
and ``HRIR_<grid>.sofa`` (SimpleFreeFieldHRIR / GeneralFIR): when the frequencies are Δf, 2Δf, ...,
f_max, exactly at 2·f_max with a 0 Hz bin of 1, conjugated to the usual e^{+iωt} DFT convention and
delayed by ``constants.HRIR_LEAD_S`` (30 cm of travel) to be causal; for any other (sparse) set, rebuilt at a chosen
rate and length by :func:`mesh2hrtf_io.sparse_hrtf.rebuild_hrirs` with the same delay. Each file says in
its GLOBAL_Comment how it was made. Files are verified by sofar and written atomically.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from core.atomic import atomic_path

from .constants import HRIR_LEAD_S
from .errors import Mesh2HrtfIoError
from .frequency_sets import describe_set, is_linear_grid
from .project_reader import Project, read_project
from .results import missing_steps, read_eval_grid_pressure
from .sparse_hrtf import METHOD_NOTE, rebuild_hrirs

APPLICATION = "ppm-hrtf mesh2hrtf_io"
HRIR_RATE_HZ, HRIR_SAMPLES = 48000.0, 320  # HRIRs rebuilt from a sparse set: the SONICOM references' own


def _spherical(points_m: np.ndarray) -> np.ndarray:
    radius = np.linalg.norm(points_m, axis=1)
    elevation = 90 - np.degrees(np.arccos(np.clip(points_m[:, 2] / np.where(radius > 0, radius, 1), -1, 1)))
    azimuth = np.mod(np.degrees(np.arctan2(points_m[:, 1], points_m[:, 0])), 360)
    return np.c_[azimuth, elevation, radius]


def referenced_pressure(project: Project) -> np.ndarray:
    """(points, sources, frequencies) complex HRTFs (e^{-iωt}) of all grids, referenced to the free field."""
    points = project.evaluation_points_m
    n_steps = len(project.frequencies_hz)
    for source in project.sources:
        missing = missing_steps(source.folder, n_steps, len(points))
        if missing:
            raise Mesh2HrtfIoError(f"{source.folder}: steps {missing} are not solved (or incomplete); solve them "
                                   "before collecting, partial results are not mixed into SOFA files")
    pressure = np.stack([np.stack([read_eval_grid_pressure(source.folder, step, len(points))
                                   for step in range(1, n_steps + 1)], axis=-1) for source in project.sources], axis=1)
    if not project.parameters.get("reference", True):
        return pressure
    radius = float(np.min(np.linalg.norm(points, axis=1)))
    f = project.frequencies_hz
    k = 2 * np.pi * f / project.speed_of_sound_m_s
    areas = np.atleast_1d(project.parameters["sourceArea"]).astype(np.float64)
    if areas.size != len(project.sources):
        raise Mesh2HrtfIoError(f"{project.folder}/parameters.json: sourceArea has {areas.size} value(s) for "
                               f"{len(project.sources)} source(s)")
    for index, (source, area) in enumerate(zip(project.sources, areas)):
        volume_flow = source.velocity_m_s * area
        free_field = (-1j * project.density_kg_m3 * 2 * np.pi * f * volume_flow / (4 * np.pi)
                      * np.exp(1j * k * radius) / radius)
        pressure[:, index, :] /= free_field
    return pressure


def hrirs_from_hrtfs(hrtf: np.ndarray, frequencies_hz: np.ndarray) -> tuple[np.ndarray, float]:
    """Impulse responses (..., 2K samples) and sampling rate 2·f_K from referenced HRTFs (e^{-iωt}) on Δf, ..., KΔf."""
    f = np.asarray(frequencies_hz, dtype=np.float64)
    if f.size < 2 or f[0] <= 0 or not np.allclose(f, f[0] * np.arange(1, f.size + 1), atol=1e-6 * f[0]):
        raise Mesh2HrtfIoError("HRIRs need frequencies Δf, 2Δf, ..., f_max (equidistant, starting one step above 0 Hz)")
    spectrum = np.concatenate([np.ones(hrtf.shape[:-1] + (1,)), hrtf], axis=-1)
    spectrum[..., -1] = np.abs(spectrum[..., -1])
    sampling_rate = 2.0 * float(f[-1])
    hrir = np.fft.irfft(np.conj(spectrum), axis=-1)
    shift = int(round(HRIR_LEAD_S * sampling_rate))
    return np.roll(hrir, shift, axis=-1), sampling_rate


def rebuilt_hrirs(hrtf: np.ndarray, frequencies_hz: np.ndarray, sampling_rate_hz: float, n_samples: int,
                  source: str) -> np.ndarray:
    """Impulse responses (..., n_samples) rebuilt from referenced HRTFs (e^{-iωt}) at a sparse set, shifted
    by ``HRIR_LEAD_S`` like the exact ones."""
    return rebuild_hrirs(np.conj(hrtf), frequencies_hz, sampling_rate_hz, n_samples,
                         delay_shift_s=HRIR_LEAD_S, source=source)


def _receivers(project: Project) -> np.ndarray:
    centres = np.atleast_2d(np.asarray(project.parameters.get("sourceCenter", [[0, 0, 0]] * len(project.sources)),
                                       dtype=np.float64))
    return centres.reshape(len(project.sources), 3)


def _sofa(convention: str, project: Project, points_m: np.ndarray, title: str):
    import sofar  # noqa: PLC0415

    sofa = sofar.Sofa(convention)
    sofa.GLOBAL_ApplicationName = APPLICATION
    sofa.GLOBAL_ApplicationVersion = f"Mesh2HRTF {project.parameters.get('Mesh2HRTF_Version', '1.2.4')} project"
    sofa.GLOBAL_History = "numerically simulated data (boundary element method)"
    sofa.GLOBAL_Title = title
    sofa.GLOBAL_Comment = ("pressure referenced to a point source at the origin; phase in NumCalc's e^{-iwt} "
                           "convention for HRTF files, e^{+iwt} DFT convention for HRIR files")
    sofa.SourcePosition = _spherical(points_m)
    sofa.SourcePosition_Type, sofa.SourcePosition_Units = "spherical", "degree, degree, metre"
    sofa.ReceiverPosition = _receivers(project)
    sofa.ReceiverPosition_Type, sofa.ReceiverPosition_Units = "cartesian", "metre"
    if hasattr(sofa, "GLOBAL_ListenerShortName"):
        sofa.GLOBAL_ListenerShortName = str(project.parameters.get("projectTitle", ""))
    return sofa


def _write(sofa, path: Path) -> Path:
    import sofar  # noqa: PLC0415

    with atomic_path(path) as tmp:
        sofar.write_sofa(str(tmp), sofa, compression=4)
    return path


def project_solver(project: Project) -> str:
    """Which solver(s) made a project's steps: 'NumCalc', 'embedded (cuda)', ... (several joined by ' + ')."""
    from .results import step_solver  # noqa: PLC0415

    solvers = sorted({step_solver(source.folder, step) for source in project.sources
                      for step in range(1, len(project.frequencies_hz) + 1)})
    return " + ".join(solvers)


def collect_sofa(folder: str | os.PathLike, output_folder: str | os.PathLike | None = None,
                 hrirs: bool | None = None, hrir_sampling_rate_hz: float = HRIR_RATE_HZ,
                 hrir_samples: int = HRIR_SAMPLES) -> list[Path]:
    """Write HRTF (and HRIR) SOFA files for every grid of a solved project; returns their paths.

    HRIRs of a linear grid Δf..f_max are exact (rate 2·f_max); those of any other set are rebuilt at
    ``hrir_sampling_rate_hz`` with ``hrir_samples`` taps."""
    project = read_project(folder)
    output = Path(output_folder) if output_folder else project.folder / "Output2HRTF"
    pressure = referenced_pressure(project)
    two_ears = len(project.sources) == 2
    if hrirs is None:
        hrirs = bool(project.parameters.get("computeHRIRs", False))
    solver = project_solver(project)
    written, offset = [], 0
    for grid in project.grids:
        block = pressure[offset:offset + len(grid.points_m)]
        offset += len(grid.points_m)
        title = f"{project.parameters.get('projectTitle', 'head')}: {grid.name}"
        sofa = _sofa("SimpleFreeFieldHRTF" if two_ears else "GeneralTF", project, grid.points_m, title)
        sofa.Data_Real, sofa.Data_Imag = block.real, block.imag
        sofa.N = project.frequencies_hz
        sofa.GLOBAL_Comment += f"; solved at {describe_set(project.frequencies_hz)} by {solver}"
        sofa.add_attribute("GLOBAL_NumericalSolver", solver)
        written.append(_write(sofa, output / f"HRTF_{grid.name}.sofa"))
        if hrirs:
            if not project.parameters.get("reference", True):
                raise Mesh2HrtfIoError("HRIRs need referenced HRTFs (parameters.json: reference true)")
            if is_linear_grid(project.frequencies_hz):
                impulse, rate = hrirs_from_hrtfs(block, project.frequencies_hz)
                how = f"inverse DFT of {describe_set(project.frequencies_hz)}, 0 Hz = 1"
            else:
                rate = float(hrir_sampling_rate_hz)
                impulse = rebuilt_hrirs(block, project.frequencies_hz, rate, hrir_samples,
                                        f"{project.folder} grid {grid.name}")
                how = f"rebuilt from {describe_set(project.frequencies_hz)}: {METHOD_NOTE}"
            sofa = _sofa("SimpleFreeFieldHRIR" if two_ears else "GeneralFIR", project, grid.points_m, title)
            sofa.GLOBAL_Comment += f"; HRIRs: {how}; delayed by {HRIR_LEAD_S * 1000:.4f} ms; solved by {solver}"
            sofa.add_attribute("GLOBAL_NumericalSolver", solver)
            sofa.Data_IR, sofa.Data_SamplingRate = impulse, rate
            sofa.Data_Delay = np.zeros((1, len(project.sources)))
            written.append(_write(sofa, output / f"HRIR_{grid.name}.sofa"))
    return written
