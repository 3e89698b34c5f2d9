"""The ERB-number scale of Glasberg and Moore (frequencies in Hz), as LTFAT's ``freqtoaud(..., 'erb')``: the axis
of the auditory filterbank (:mod:`amt_bridge.filterbank`) and of the sparse-set rebuild
(:mod:`mesh2hrtf_io.sparse_hrtf`, :mod:`mesh2hrtf_io.frequency_sets`)."""
from __future__ import annotations

import numpy as np


def freq_to_erb_number(frequency_hz: np.ndarray) -> np.ndarray:
    """ERB-number scale (Glasberg & Moore), as LTFAT's freqtoaud(..., 'erb')."""
    return 9.2645 * np.sign(frequency_hz) * np.log(1 + np.abs(frequency_hz) * 0.00437)


def erb_number_to_freq(erb_number: np.ndarray) -> np.ndarray:
    """Inverse of :func:`freq_to_erb_number` (Hz)."""
    return (1 / 0.00437) * np.sign(erb_number) * (np.exp(np.abs(erb_number) / 9.2645) - 1)
