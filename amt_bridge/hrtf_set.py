"""Binaural head-related impulse responses on a grid of directions, read from SOFA files.

Frame: SOFA spherical source positions (azimuth 0 = front, +90 = left; elevation +90 = up; degrees).
Receiver 0 is the LEFT ear, receiver 1 the right ear, as in SOFA's SimpleFreeFieldHRIR.
"""
from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path

import numpy as np

# HRTF -> HRIR: responses are delayed by the lead the pipeline writes its HRIRs with, so that an HRTF file read
# here gives the HRIRs written beside it.
from mesh2hrtf_io.constants import HRIR_LEAD_S

from .errors import AmtBridgeError


@dataclasses.dataclass(frozen=True)
class HrirSet:
    """Impulse responses ``irs`` (M directions, 2 ears [left, right], N samples) at ``sampling_rate_hz``,
    with the SOFA azimuth/elevation (degrees) of every direction."""

    irs: np.ndarray
    sampling_rate_hz: float
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray
    source: str = "<memory>"

    def __post_init__(self):
        irs = np.asarray(self.irs, dtype=np.float64)
        if irs.ndim != 3:
            raise AmtBridgeError(f"{self.source}: impulse responses must be (directions, ears, samples), "
                                 f"got shape {irs.shape}")
        if irs.shape[1] != 2:
            raise AmtBridgeError(f"{self.source}: the model needs 2 ears (left, right), the data hold "
                                 f"{irs.shape[1]} receiver(s); a mono set cannot be weighted binaurally")
        if irs.shape[0] < 4 or irs.shape[2] < 16:
            raise AmtBridgeError(f"{self.source}: too few directions ({irs.shape[0]}) or samples ({irs.shape[2]})")
        if not np.isfinite(irs).all():
            raise AmtBridgeError(f"{self.source}: the impulse responses hold NaN or inf values")
        if not np.any(irs):
            raise AmtBridgeError(f"{self.source}: all impulse responses are zero")
        if not (np.isfinite(self.sampling_rate_hz) and self.sampling_rate_hz > 0):
            raise AmtBridgeError(f"{self.source}: invalid sampling rate {self.sampling_rate_hz}")
        azimuth = np.asarray(self.azimuth_deg, dtype=np.float64).ravel()
        elevation = np.asarray(self.elevation_deg, dtype=np.float64).ravel()
        if azimuth.shape != (irs.shape[0],) or elevation.shape != (irs.shape[0],):
            raise AmtBridgeError(f"{self.source}: {irs.shape[0]} responses but {azimuth.size} positions")
        if not (np.isfinite(azimuth).all() and np.isfinite(elevation).all()):
            raise AmtBridgeError(f"{self.source}: source positions hold NaN or inf values")
        object.__setattr__(self, "irs", irs)
        object.__setattr__(self, "azimuth_deg", azimuth)
        object.__setattr__(self, "elevation_deg", elevation)
        object.__setattr__(self, "sampling_rate_hz", float(self.sampling_rate_hz))


def _cartesian_to_spherical_deg(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    azimuth = np.degrees(np.arctan2(points[:, 1], points[:, 0]))
    elevation = np.degrees(np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1])))
    return azimuth, elevation


def hrtf_to_hrir(spectra: np.ndarray, frequencies_hz: np.ndarray, source: str) -> tuple[np.ndarray, float]:
    """Impulse responses from one-sided spectra (..., K) on the grid f_k = k Δf (k = 1..K or 0..K),
    as Mesh2HRTF writes them (without a 0 Hz bin, it is set to the magnitude of the lowest bin, phase 0).
    The highest frequency is taken as Nyquist, so the sampling rate is 2 f_K. Responses are shifted by
    ``HRIR_LEAD_S`` so that the head's lead (up to ~0.7 ms) does not wrap around. Spectra at any other
    (sparse) set are rebuilt at 48 kHz by :func:`mesh2hrtf_io.sparse_hrtf.rebuild_hrirs`."""
    frequencies = np.asarray(frequencies_hz, dtype=np.float64).ravel()
    if frequencies.size < 8:
        raise AmtBridgeError(f"{source}: {frequencies.size} frequencies are too few for impulse responses")
    dc = None
    if frequencies[0] == 0:
        dc, spectra, frequencies = spectra[..., :1].real, spectra[..., 1:], frequencies[1:]
    step = frequencies[0]
    if not np.allclose(frequencies, step * np.arange(1, frequencies.size + 1), rtol=0, atol=1e-6 * step):
        return _rebuilt_from_sparse_set(spectra, frequencies, dc, source)
    if dc is None:
        dc = np.abs(spectra[..., :1])
    full = np.concatenate([dc, spectra], axis=-1)
    n_samples = 2 * (full.shape[-1] - 1)
    sampling_rate = 2.0 * frequencies[-1]
    irs = np.fft.irfft(full, n=n_samples, axis=-1)
    return np.roll(irs, int(round(HRIR_LEAD_S * sampling_rate)), axis=-1), sampling_rate


def _rebuilt_from_sparse_set(spectra: np.ndarray, frequencies: np.ndarray, dc, source: str) -> tuple[np.ndarray, float]:
    """HRIRs at 48 kHz (320 taps, or more for a set above 24 kHz) rebuilt from a sparse frequency set
    (mesh2hrtf_io.sparse_hrtf), shifted by ``HRIR_LEAD_S``."""
    from mesh2hrtf_io.errors import Mesh2HrtfIoError  # noqa: PLC0415
    from mesh2hrtf_io.sparse_hrtf import rebuild_hrirs  # noqa: PLC0415

    rate = max(48000.0, 2 * float(np.ceil(frequencies[-1] / 1000) * 1000))
    if dc is not None:
        spectra, frequencies = np.concatenate([dc, spectra], axis=-1), np.concatenate([[0.0], frequencies])
    try:
        irs = rebuild_hrirs(spectra, frequencies, rate, int(2 * round(rate / 300)), HRIR_LEAD_S, source)
    except Mesh2HrtfIoError as exc:
        raise AmtBridgeError(str(exc)) from exc
    return irs, rate


def resampled_at(hrirs: HrirSet, frequencies_hz, interpolant: str = "pchip") -> HrirSet:
    """The same set sampled at ``frequencies_hz`` (exact DFT) and rebuilt at its own rate and length, as HRTFs
    solved at that set are: compares a full reference like with like against solved conditions."""
    from mesh2hrtf_io.errors import Mesh2HrtfIoError  # noqa: PLC0415
    from mesh2hrtf_io.sparse_hrtf import rebuild_hrirs, sample_spectra  # noqa: PLC0415

    frequencies = np.asarray(frequencies_hz, dtype=np.float64)
    try:
        irs = rebuild_hrirs(sample_spectra(hrirs.irs, hrirs.sampling_rate_hz, frequencies), frequencies,
                            hrirs.sampling_rate_hz, hrirs.irs.shape[-1], 0.0, hrirs.source, interpolant)
    except Mesh2HrtfIoError as exc:
        raise AmtBridgeError(str(exc)) from exc
    return dataclasses.replace(hrirs, irs=irs, source=f"{hrirs.source} at {frequencies.size} frequencies")


def _unit_vectors(hrirs: HrirSet) -> np.ndarray:
    azimuth, elevation = np.radians(hrirs.azimuth_deg), np.radians(hrirs.elevation_deg)
    return np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], 1)


def on_common_directions(first: HrirSet, second: HrirSet, tolerance_deg: float = 2.0) -> tuple[HrirSet, HrirSet]:
    """Both sets on the same directions: each direction of ``second`` that ``first`` has within ``tolerance_deg``
    (great circle), ``first``'s nearest response taking ``second``'s direction. baumgartner2014's quadrant error
    depends on how densely a sagittal plane is sampled, so two sets on different grids (a listener's full grid,
    2.5 deg polar steps; SONICOM's 793 directions) are compared only on the directions they share."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    distance, nearest = cKDTree(_unit_vectors(first)).query(_unit_vectors(second))
    shared = np.flatnonzero(distance <= 2.0 * np.sin(np.radians(tolerance_deg) / 2.0))
    if shared.size < 4:
        raise AmtBridgeError(f"{first.source} and {second.source} share only {shared.size} directions within "
                             f"{tolerance_deg} deg; the model needs both sets on common sagittal planes")
    return (dataclasses.replace(first, irs=first.irs[nearest[shared]], azimuth_deg=second.azimuth_deg[shared],
                                elevation_deg=second.elevation_deg[shared],
                                source=f"{first.source} at {shared.size} directions of {second.source}"),
            dataclasses.replace(second, irs=second.irs[shared], azimuth_deg=second.azimuth_deg[shared],
                                elevation_deg=second.elevation_deg[shared]))


def _read_sofa_responses(path: str | os.PathLike) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """(impulse responses (M, R, N), rate in Hz, azimuth, elevation in degrees) of a SimpleFreeFieldHRIR or
    SimpleFreeFieldHRTF file, any number of receivers R."""
    import sofar  # noqa: PLC0415

    path = Path(path)
    if not path.is_file():
        raise AmtBridgeError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise AmtBridgeError(f"{path}: the file is empty")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sofa = sofar.read_sofa(str(path), verify=False, verbose=False)
    except Exception as exc:  # sofar/netCDF raise many types for broken files
        raise AmtBridgeError(f"{path}: not a readable SOFA file ({type(exc).__name__}: {exc}); "
                             "give a SimpleFreeFieldHRIR or SimpleFreeFieldHRTF file") from exc
    convention = str(getattr(sofa, "GLOBAL_SOFAConventions", ""))
    positions = np.atleast_2d(np.asarray(sofa.SourcePosition, dtype=np.float64))
    if str(getattr(sofa, "SourcePosition_Type", "spherical")).lower().startswith("cart"):
        azimuth, elevation = _cartesian_to_spherical_deg(positions)
    else:
        azimuth, elevation = positions[:, 0], positions[:, 1]
    if convention == "SimpleFreeFieldHRIR" or hasattr(sofa, "Data_IR"):
        irs = np.asarray(sofa.Data_IR, dtype=np.float64)
        rate = float(np.ravel(sofa.Data_SamplingRate)[0])
    elif convention == "SimpleFreeFieldHRTF" or hasattr(sofa, "Data_Real"):
        spectra = np.asarray(sofa.Data_Real, dtype=np.float64) + 1j * np.asarray(sofa.Data_Imag, dtype=np.float64)
        application = str(getattr(sofa, "GLOBAL_ApplicationName", ""))
        if "Mesh2HRTF" in application or "mesh2hrtf_io" in application:
            spectra = np.conj(spectra)  # NumCalc's e^{-iωt} phase convention -> the DFT's
        irs, rate = hrtf_to_hrir(spectra, np.asarray(sofa.N, dtype=np.float64), str(path))
    else:
        raise AmtBridgeError(f"{path}: convention {convention!r} holds no HRIRs or HRTFs; "
                             "give a SimpleFreeFieldHRIR or SimpleFreeFieldHRTF file")
    if irs.ndim == 2:
        irs = irs[:, None, :]
    if len(azimuth) == 1 and irs.shape[0] > 1:
        azimuth, elevation = np.repeat(azimuth, irs.shape[0]), np.repeat(elevation, irs.shape[0])
    return irs, rate, azimuth, elevation


def read_hrtf_set(path: str | os.PathLike) -> HrirSet:
    """Read a SimpleFreeFieldHRIR or SimpleFreeFieldHRTF SOFA file (2 receivers: left, right)."""
    irs, rate, azimuth, elevation = _read_sofa_responses(path)
    return HrirSet(irs, rate, azimuth, elevation, source=str(path))


def read_one_ear_completed(path: str | os.PathLike, solved_ear: str, other: HrirSet,
                           tolerance_deg: float = 0.1) -> HrirSet:
    """A SOFA file holding one ear only (``solved_ear``: "left" or "right", e.g. a head solved for its left ear)
    completed with the opposite ear of ``other`` (e.g. the reference HRIRs, rebuilt at the same frequencies),
    direction by direction: the only difference from ``other`` is then the solved ear. Directions must
    match within ``tolerance_deg``; rate and length must be equal."""
    if solved_ear not in ("left", "right"):
        raise AmtBridgeError(f"solved_ear must be 'left' or 'right', got {solved_ear!r}")
    irs, rate, azimuth, elevation = _read_sofa_responses(path)
    if irs.shape[1] != 1:
        raise AmtBridgeError(f"{path}: {irs.shape[1]} receivers; completing an ear needs a one-ear file")
    if abs(rate - other.sampling_rate_hz) > 1e-6 or irs.shape[2] != other.irs.shape[2]:
        raise AmtBridgeError(f"{path}: {rate:g} Hz x {irs.shape[2]} samples, but {other.source} has "
                             f"{other.sampling_rate_hz:g} Hz x {other.irs.shape[2]}; rebuild both alike (config hrtf.hrir)")
    from mesh2hrtf_io.grids import spherical_to_cartesian_m  # noqa: PLC0415

    mine = spherical_to_cartesian_m(azimuth, elevation, np.ones(len(azimuth)))
    theirs = spherical_to_cartesian_m(other.azimuth_deg, other.elevation_deg, np.ones(len(other.azimuth_deg)))
    cosines = mine @ theirs.T
    nearest = np.argmax(cosines, axis=1)
    off_deg = np.degrees(np.arccos(np.clip(cosines[np.arange(len(mine)), nearest], -1.0, 1.0)))
    if off_deg.max() > tolerance_deg or len(np.unique(nearest)) != len(nearest):
        raise AmtBridgeError(f"{path}: its {len(mine)} directions do not match {other.source}'s (up to "
                             f"{off_deg.max():.2f} deg apart); solve on the reference's directions "
                             "(config hrtf.grid: reference_sofa)")
    solved, kept = (0, 1) if solved_ear == "left" else (1, 0)
    combined = np.empty((len(mine), 2, irs.shape[2]))
    combined[:, solved] = irs[:, 0]
    combined[:, kept] = other.irs[nearest, kept]
    return HrirSet(combined, rate, azimuth, elevation,
                   source=f"{path} ({solved_ear} ear) + {other.source} ({'right' if kept else 'left'} ear)")
