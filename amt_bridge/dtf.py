"""Directional transfer functions (DTFs): HRTFs divided by their common transfer function (CTF), as
the SOFA API's ``SOFAhrtf2dtf`` in its default 'log' mode (spec §1).

The CTF magnitude is the mean log magnitude over all directions (per ear), its phase the minimum
phase of that magnitude; dividing by it removes what every direction shares (ear canal, microphone).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from hrtf_dsp.phase import minimum_phase_spectrum

from .angles import EPS
from .errors import AmtBridgeError
from .hrtf_set import HrirSet

ATTENUATION_DB = 20.0  # SOFAhrtf2dtf scales DTFs down by 20 dB; a constant gain that the gradients cancel


def directional_levels_db(spectra: np.ndarray) -> np.ndarray:
    """Levels (dB) of complex spectra (directions, ...) minus their mean over the directions (axis 0): the DTF's
    magnitude per frequency, for comparing two sets direction by direction (a per-frequency gain drops out)."""
    level = 20.0 * np.log10(np.abs(spectra) + EPS)
    return level - level.mean(axis=0, keepdims=True)


def common_transfer_function(hrirs: HrirSet, mode: str = "log") -> np.ndarray:
    """The CTF spectrum (2 ears, N bins, complex, two-sided)."""
    spectra = np.fft.fft(hrirs.irs, axis=-1)
    if mode == "log":
        magnitude_log = np.mean(np.log(np.abs(spectra) + EPS), axis=0)
    elif mode == "rms":
        magnitude_log = np.log(np.sqrt(np.mean(np.abs(spectra) ** 2, axis=0)) + EPS)
    else:
        raise AmtBridgeError(f"DTF mode must be 'log' or 'rms', got {mode!r}")
    return minimum_phase_spectrum(magnitude_log)


def hrtf_to_dtf(hrirs: HrirSet, mode: str = "log", lowest_frequency_hz: float = 50.0,
                highest_frequency_hz: float = 18000.0) -> HrirSet:
    """DTF impulse responses: H / CTF in the bins from ``lowest`` to ``highest`` frequency (and their
    mirrors), the HRTF elsewhere, scaled by -20 dB. Same directions and sampling rate."""
    spectra = np.fft.fft(hrirs.irs, axis=-1)
    ctf = common_transfer_function(hrirs, mode)
    n = spectra.shape[-1]
    frequencies = np.arange(n) * hrirs.sampling_rate_hz / n
    band = (frequencies >= lowest_frequency_hz) & (frequencies <= highest_frequency_hz)
    band = band | np.roll(band[::-1], 1)  # bin k and its mirror N - k
    dtf = spectra.copy()
    dtf[:, :, band] = spectra[:, :, band] / ctf[None, :, band]
    irs = np.fft.ifft(dtf, axis=-1).real * 10 ** (-ATTENUATION_DB / 20)
    return dataclasses.replace(hrirs, irs=irs, source=f"DTF of {hrirs.source}")
