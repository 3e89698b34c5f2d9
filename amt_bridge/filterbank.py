"""Auditory spectral analysis (spec §3): ERB-spaced complex all-pole gammatone filters (Lyon 1997),
as AMT's ``auditoryfilterbank``/``gammatone(..., 'complex')`` with LTFAT's ERB scale."""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from hrtf_dsp.erb import erb_number_to_freq, freq_to_erb_number

__all__ = ["erb_number_to_freq", "freq_to_erb_number"]  # the scale lives in hrtf_dsp.erb; named here too


def equivalent_rectangular_bandwidth(frequency_hz: np.ndarray) -> np.ndarray:
    """ERB in Hz at a centre frequency, LTFAT's audfiltbw: 24.7 + f / 9.265."""
    return 24.7 + np.asarray(frequency_hz, dtype=np.float64) / 9.265


def centre_frequencies(lowest_hz: float = 700.0, highest_hz: float = 18000.0, spacing_erb: float = 1.0) -> np.ndarray:
    """Band centres (Hz) spaced ``spacing_erb`` apart and centred in [lowest, highest] on the ERB scale
    (LTFAT audspacebw): 28 bands from 729.5 Hz to 17439.3 Hz for the defaults."""
    low, high = freq_to_erb_number(lowest_hz), freq_to_erb_number(highest_hz)
    span = high - low
    count = int(np.floor(span / spacing_erb))
    remainder = span - count * spacing_erb
    return erb_number_to_freq(low + np.arange(count + 1) * spacing_erb + remainder / 2)


def gammatone_bandwidth_factor(order: int = 4) -> float:
    """β = factor · ERB so that the order-n gammatone has the ERB as its equivalent bandwidth (1.0186 for n = 4)."""
    return math.factorial(order - 1) ** 2 / (math.pi * math.factorial(2 * order - 2) * 2.0 ** (-(2 * order - 2)))


def gammatone_coefficients(centre_hz: float, sampling_rate_hz: float, order: int = 4) -> tuple[float, np.ndarray]:
    """(b0, a) of the complex all-pole gammatone: pole exp(-2πβ/fs - i2πfc/fs) repeated ``order`` times,
    b0 = (1 - exp(-2πβ/fs))^order, unit gain at the centre frequency."""
    beta = gammatone_bandwidth_factor(order) * equivalent_rectangular_bandwidth(centre_hz)
    pole = np.exp(-2 * np.pi * beta / sampling_rate_hz - 1j * 2 * np.pi * centre_hz / sampling_rate_hz)
    return (1 - np.exp(-2 * np.pi * beta / sampling_rate_hz)) ** order, np.poly(np.full(order, pole))


def band_levels_db(signals: np.ndarray, sampling_rate_hz: float, centres_hz: np.ndarray, order: int = 4) -> np.ndarray:
    """RMS level (dB) of every band for signals (N samples, ...): array (bands, ...). Causal filtering
    from rest, output truncated to N samples (no tail), RMS over N, no mean removal (spec §3)."""
    signals = np.asarray(signals, dtype=np.float64)
    complex_input = signals.astype(np.complex128)
    levels = np.empty((len(centres_hz),) + signals.shape[1:])
    for band, centre in enumerate(centres_hz):
        b0, a = gammatone_coefficients(float(centre), sampling_rate_hz, order)
        output = 2 * lfilter(np.array([b0], dtype=np.complex128), a, complex_input, axis=0).real
        levels[band] = 20 * np.log10(np.sqrt(np.mean(output**2, axis=0)))
    return levels
