"""Minimum phase from a magnitude (folded real cepstrum): the phase of the DTF's common transfer function
(:mod:`amt_bridge.dtf`) and of HRIRs rebuilt from a sparse frequency set (:mod:`mesh2hrtf_io.sparse_hrtf`)."""
from __future__ import annotations

import numpy as np


def minimum_phase_spectrum(log_magnitude: np.ndarray) -> np.ndarray:
    """The minimum-phase spectrum exp(C + i·phase) of a full (two-sided, length N along the last axis)
    natural-log magnitude C, by folding its real cepstrum."""
    n = log_magnitude.shape[-1]
    cepstrum = np.fft.ifft(log_magnitude, axis=-1).real
    fold = np.zeros(n)
    fold[0] = 1.0
    half = n // 2
    if n % 2 == 0:
        fold[1:half] = 2.0
        fold[half] = 1.0
    else:
        fold[1:half + 1] = 2.0
    return np.exp(np.fft.fft(cepstrum * fold, axis=-1))
