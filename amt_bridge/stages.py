"""The processing stages of baumgartner2014 after the spectral analysis (spec §4-§9): positive
spectral gradients, comparison, similarity, binaural weighting, sensorimotor mapping, probability
mass vectors. Arrays: bands × directions × ears; similarities are templates × targets.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.special import i0

from .angles import EPS, deg2rad, matlab_colon
from .errors import AmtBridgeError
from .filterbank import equivalent_rectangular_bandwidth

FULL_CIRCLE_LOW_DEG, FULL_CIRCLE_HIGH_DEG = -90.0, 265.0  # response grid after zero-padding (5° steps)


def gradient_offset(centres_hz: np.ndarray, spacing_erb: float = 1.0) -> int:
    """Δ: how many bands apart the gradient is taken (1 for 1-ERB spacing)."""
    return int(np.round(np.mean(equivalent_rectangular_bandwidth(centres_hz[1:]) / np.diff(centres_hz)) * spacing_erb))


def positive_gradients(levels_db: np.ndarray, offset: int) -> np.ndarray:
    """max(x[b + Δ] - x[b], 0) along the band axis (first axis): the DCN-like positive spectral gradient."""
    return np.maximum(levels_db[offset:] - levels_db[:-offset], 0.0)


def spectral_distance(target: np.ndarray, template: np.ndarray) -> np.ndarray:
    """σ (dB): mean absolute difference over bands, array (templates, targets, ears), from
    target (B, targets, ears) and template (B, templates, ears)."""
    return np.mean(np.abs(target[:, None, :, :] - template[:, :, None, :]), axis=0)


def similarity(distance_db: np.ndarray, sensitivity_db: float, slope_per_db: float) -> np.ndarray:
    """s = 1 + eps - 1 / (1 + exp(-Γ (σ - S))): near 1 for small distances, near 0 for large ones."""
    return 1 + EPS - 1 / (1 + np.exp(-slope_per_db * (distance_db - sensitivity_db)))


def binaural_weights(lateral_deg: float, coefficient_deg: float = 13.0) -> tuple[float, float]:
    """(w_left, w_right): the ipsilateral ear dominates; positive lateral angles (left) favour the left ear."""
    left = 1 / (1 + np.exp(-lateral_deg / coefficient_deg))
    return float(left), float(1 - left)


def combine_ears(similarities: np.ndarray, lateral_deg: float, coefficient_deg: float = 13.0) -> np.ndarray:
    """Weighted sum over the ear axis (last; 0 = left, 1 = right)."""
    if similarities.shape[-1] != 2:
        raise AmtBridgeError(f"binaural weighting needs 2 ears, got {similarities.shape[-1]}")
    left, right = binaural_weights(lateral_deg, coefficient_deg)
    return left * similarities[..., 0] + right * similarities[..., 1]


def regular_response_grid(template_polar_deg: np.ndarray, step_deg: float = 5.0) -> np.ndarray:
    """ceil(min θ / Δθ)·Δθ : Δθ : max θ (MATLAB colon, so a template ending at 209.9999 drops 210)."""
    first = np.ceil(np.min(template_polar_deg) / step_deg) * step_deg
    return matlab_colon(first, step_deg, float(np.max(template_polar_deg)))


def sensorimotor_mapping(similarities: np.ndarray, template_polar_deg: np.ndarray, lateral_deg: float,
                         step_deg: float = 5.0, scatter_deg: float = 17.0) -> tuple[np.ndarray, np.ndarray]:
    """Interpolate the similarity (templates × targets) to a regular response grid (not-a-knot cubic
    spline, negatives clipped), zero-pad it to -90…265°, and blur it by the motor response scatter:
    a von Mises kernel of spread ``scatter_deg / cos(lateral)`` convolved circularly along the
    response axis. Returns (responses × targets, response angles in deg)."""
    polar = np.asarray(template_polar_deg, dtype=np.float64)
    responses = regular_response_grid(polar, step_deg)
    spline = CubicSpline(polar, similarities, axis=0, bc_type="not-a-knot")
    mapped = np.maximum(spline(responses), 0.0)
    if scatter_deg <= 0:
        return mapped, responses
    below = matlab_colon(FULL_CIRCLE_LOW_DEG, step_deg, responses.min() - step_deg)
    above = matlab_colon(responses.max() + step_deg, step_deg, FULL_CIRCLE_HIGH_DEG)
    angles = np.concatenate([below, responses, above])
    padded = np.concatenate([np.zeros((below.size, mapped.shape[1])), mapped, np.zeros((above.size, mapped.shape[1]))])
    spread = scatter_deg / np.cos(deg2rad(lateral_deg))
    kappa = 1 / deg2rad(spread) ** 2
    x = 2 * np.pi * np.arange(angles.size) / angles.size
    kernel = np.exp(kappa * np.cos(x)) / (2 * np.pi * i0(kappa))
    blurred = np.fft.ifft(np.fft.fft(padded, axis=0) * np.fft.fft(kernel)[:, None], axis=0).real
    return blurred, angles


def probability_mass_vectors(responses: np.ndarray) -> np.ndarray:
    """Normalise every target column to a probability mass vector: r / (Σ r + eps)."""
    return responses / (responses.sum(axis=0, keepdims=True) + EPS)
