"""HRTFs solved at a sparse frequency set, rebuilt on a uniform grid as impulse responses.

Spectra here are in the DFT convention of the impulse response (``numpy.fft.rfft(h)``, e^{+iωt}
physics); Mesh2HRTF's e^{-iωt} pressures are conjugated first. Steps, per response:

1. **Magnitude**: dB levels interpolated by PCHIP over the ERB-number scale, anchored at 0 dB at
   0 Hz (a referenced HRTF tends to 1 at DC, as Output2HRTF sets it) unless 0 Hz is given. PCHIP is
   shape-preserving: it does not overshoot next to a deep notch as a cubic spline does (measured on
   the SONICOM sets with the 40-frequency preset: max ΔQE/ΔPE 0.33 pp / 0.12° with PCHIP, 0.49 / 0.19
   with linear dB over log f, 0.73 / 0.37 with a cubic spline; ``benchmarks/frequency_set.py``).
2. **Above the highest solved frequency** f_max: the last level held, faded by a half cosine in
   magnitude to silence (-100 dB) at Nyquist; nothing changes when f_max is Nyquist.
3. **Phase**: the minimum phase of that magnitude (folded real cepstrum), delayed by the response's
   own delay: the low-frequency group delay of the solved phases (least-squares slope of the
   unwrapped phase through 0 Hz, solved frequencies up to 1.5 kHz) minus that of the minimum-phase
   part, plus a constant ``delay_shift_s`` (e.g. Output2HRTF's 30 cm of travel time that makes
   referenced responses causal).
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator

from hrtf_dsp.erb import freq_to_erb_number
from hrtf_dsp.phase import minimum_phase_spectrum

from .errors import Mesh2HrtfIoError
from .frequency_sets import FEWEST_FOR_REBUILD, check_frequency_set

DELAY_BAND_HZ = 1500.0       # solved frequencies used for the delay (phase unwrapped from 0 Hz up)
FLOOR_DB = -100.0            # level of the roll-off at Nyquist and of silent bins
METHOD_NOTE = ("magnitude: PCHIP of dB over the ERB-number scale, 0 dB at 0 Hz, last level faded by a half "
               "cosine to Nyquist above the highest solved frequency; phase: minimum phase plus the response's "
               f"low-frequency group delay (solved frequencies up to {DELAY_BAND_HZ:g} Hz)")


def sample_spectra(irs: np.ndarray, sampling_rate_hz: float, frequencies_hz) -> np.ndarray:
    """Exact DFT of impulse responses (..., N samples) at arbitrary frequencies (Hz): (..., K) complex."""
    n = np.arange(irs.shape[-1])
    kernel = np.exp(-2j * np.pi * np.outer(n, np.asarray(frequencies_hz, dtype=np.float64)) / sampling_rate_hz)
    return np.asarray(irs, dtype=np.float64) @ kernel


def low_frequency_delay(spectra: np.ndarray, frequencies_hz: np.ndarray, band_hz: float = DELAY_BAND_HZ) -> np.ndarray:
    """Group delay (s) per response: slope of the phase unwrapped from 0 Hz over the frequencies <= band_hz.

    Needs frequencies dense enough that the phase turns by less than π between neighbours (e.g. 150 and
    300 Hz below the first ERB steps for delays up to ~1.6 ms)."""
    chosen = frequencies_hz <= band_hz
    if chosen.sum() < 1:
        raise Mesh2HrtfIoError(f"the delay needs at least one solved frequency at or below {band_hz:g} Hz "
                               f"(lowest: {frequencies_hz.min():g} Hz); add low frequencies to the set")
    unit = spectra[..., chosen] / np.maximum(np.abs(spectra[..., chosen]), 1e-300)
    phase = np.unwrap(np.angle(np.concatenate([np.ones(spectra.shape[:-1] + (1,)), unit], axis=-1)), axis=-1)
    omega = 2 * np.pi * np.concatenate([[0.0], frequencies_hz[chosen]])
    return -(phase @ omega) / (omega @ omega)


INTERPOLANTS = ("pchip", "linear", "cubic")


def _levels_on_grid(levels_db: np.ndarray, frequencies_hz: np.ndarray, grid_hz: np.ndarray,
                    interpolant: str = "pchip") -> np.ndarray:
    x = freq_to_erb_number(frequencies_hz)
    inside = grid_hz <= frequencies_hz[-1]
    out = np.empty(levels_db.shape[:-1] + (grid_hz.size,))
    x_inside = freq_to_erb_number(grid_hz[inside])
    if interpolant == "pchip":
        out[..., inside] = PchipInterpolator(x, levels_db, axis=-1)(x_inside)
    elif interpolant == "cubic":
        out[..., inside] = CubicSpline(x, levels_db, axis=-1)(x_inside)
    elif interpolant == "linear":
        flat = levels_db.reshape(-1, x.size)
        out[..., inside] = np.stack([np.interp(x_inside, x, row) for row in flat]).reshape(
            levels_db.shape[:-1] + (x_inside.size,))
    else:
        raise Mesh2HrtfIoError(f"interpolant must be one of {INTERPOLANTS}, got {interpolant!r}")
    above = ~inside
    if above.any():
        nyquist = grid_hz[-1]
        fade = np.cos(0.5 * np.pi * (grid_hz[above] - frequencies_hz[-1]) / (nyquist - frequencies_hz[-1]))
        out[..., above] = levels_db[..., -1:] + 20 * np.log10(np.maximum(fade, 10 ** (FLOOR_DB / 20)))
    return np.maximum(out, FLOOR_DB)


def rebuild_hrirs(spectra: np.ndarray, frequencies_hz, sampling_rate_hz: float = 48000.0, n_samples: int = 320,
                  delay_shift_s: float = 0.0, source: str = "HRTFs", interpolant: str = "pchip") -> np.ndarray:
    """Impulse responses (..., n_samples) at ``sampling_rate_hz`` from spectra (..., K) solved at a sparse set.

    ``frequencies_hz`` must be increasing, unique, at most Nyquist and at least 8; 0 Hz may lead (its
    value is then the DC level; otherwise 0 dB). See the module docstring for the method; ``interpolant``
    'linear' or 'cubic' (over the same ERB-number axis) are there for comparison."""
    f = np.asarray(frequencies_hz, dtype=np.float64)
    spectra = np.asarray(spectra, dtype=np.complex128)
    if spectra.shape[-1] != f.size:
        raise Mesh2HrtfIoError(f"{source}: {spectra.shape[-1]} spectral values per response for {f.size} frequencies")
    if not np.isfinite(spectra).all():
        raise Mesh2HrtfIoError(f"{source}: the spectra hold NaN or inf values")
    if n_samples < 16 or n_samples % 2:
        raise Mesh2HrtfIoError(f"{source}: n_samples must be even and at least 16, got {n_samples}")
    has_dc = f.size > 0 and f[0] == 0
    solved = check_frequency_set(f[1:] if has_dc else f, source, nyquist_hz=sampling_rate_hz / 2,
                                 fewest=FEWEST_FOR_REBUILD - int(has_dc))
    values = spectra[..., 1:] if has_dc else spectra
    dc_db = (20 * np.log10(np.maximum(np.abs(spectra[..., :1]), 1e-5)) if has_dc
             else np.zeros(spectra.shape[:-1] + (1,)))
    levels = np.concatenate([dc_db, 20 * np.log10(np.maximum(np.abs(values), 1e-5))], axis=-1)
    grid = np.arange(n_samples // 2 + 1) * sampling_rate_hz / n_samples
    levels_grid = _levels_on_grid(levels, np.concatenate([[0.0], solved]), grid, interpolant)

    log_magnitude = levels_grid * (np.log(10) / 20)
    two_sided = np.concatenate([log_magnitude, log_magnitude[..., -2:0:-1]], axis=-1)
    minimum_phase = minimum_phase_spectrum(two_sided)[..., : grid.size]
    excess = low_frequency_delay(values, solved) - low_frequency_delay(minimum_phase[..., 1:], grid[1:])
    spectrum = minimum_phase * np.exp(-2j * np.pi * grid * (excess[..., None] + delay_shift_s))
    spectrum[..., -1] = np.abs(spectrum[..., -1]) * np.sign(spectrum[..., -1].real + 1e-300)
    return np.fft.irfft(spectrum, n=n_samples, axis=-1)
