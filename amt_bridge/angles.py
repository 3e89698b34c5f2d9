"""Angle conversions with MATLAB's floating-point steps (the model's quadrant boundary is exact, so
round-off matters: ``../shared/docs/baumgartner2014_spec.md`` §0 and pitfall 1).

Spherical (SOFA): azimuth 0 = front, +90 = left; elevation +90 = up. Horizontal-polar: lateral
angle φ in [-90, 90] (positive = left), polar angle θ in [-90, 270) (0 = front, 90 = top, 180 = back).
"""
from __future__ import annotations

import math

import numpy as np

EPS = float(np.finfo(np.float64).eps)


def matlab_mod(x: np.ndarray, m: float) -> np.ndarray:
    """MATLAB's ``mod``: x - floor(x / m) * m (sign of m)."""
    x = np.asarray(x, dtype=np.float64)
    return x - np.floor(x / m) * m


def matlab_colon(start: float, step: float, stop: float) -> np.ndarray:
    """MATLAB's ``start:step:stop`` (empty when stop < start), tolerant to round-off as MATLAB is."""
    if stop < start:
        return np.zeros(0)
    count = int(np.floor((stop - start) / step + 1e-10)) + 1
    return start + step * np.arange(count)


def deg2rad(deg: np.ndarray) -> np.ndarray:
    return np.asarray(deg, dtype=np.float64) * (np.pi / 180.0)


def rad2deg(rad: np.ndarray) -> np.ndarray:
    return np.asarray(rad, dtype=np.float64) * (180.0 / np.pi)


# The C library's functions, as MATLAB/Octave call them: NumPy's vectorised cos/sin/atan2 may differ
# from them in the last bit, which moves angles such as 140° to 140.00000000000003 and back.
_cos = np.vectorize(math.cos, otypes=[np.float64])
_sin = np.vectorize(math.sin, otypes=[np.float64])
_atan2 = np.vectorize(math.atan2, otypes=[np.float64])


def spherical_to_horizontal_polar(azimuth_deg: np.ndarray, elevation_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lateral φ, polar θ) in degrees from SOFA azimuth/elevation in degrees, as the SOFA API's sph2hor."""
    azimuth, elevation = deg2rad(azimuth_deg), deg2rad(elevation_deg)
    x = _cos(elevation) * _cos(azimuth)
    y = _cos(elevation) * _sin(azimuth)
    z = _sin(elevation)
    for component in (x, y, z):
        component[np.abs(component) < EPS] = 0.0
    polar = rad2deg(_atan2(z, x))
    lateral = rad2deg(-_atan2(-y, np.sqrt(x**2 + z**2)))
    return lateral, matlab_mod(polar + 90.0, 360.0) - 90.0
