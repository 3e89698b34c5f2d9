"""Analytic HRTF of a rigid sphere with a point "ear" on its surface (Duda & Martens 1998).

Convention: time factor e^{+iωt} (a delay is e^{-iωτ}), pressures referenced to the free field of
the same source at the sphere's centre, which is what a Mesh2HRTF/our solver's referenced HRTF is.
By reciprocity the result equals the pressure at an ear point for a point source at the field point.
SI units (metres, Hz).
"""
from __future__ import annotations

import numpy as np
from scipy.special import eval_legendre, spherical_jn, spherical_yn


def _h2(n: int, x: np.ndarray) -> np.ndarray:
    """Spherical Hankel function of the second kind (outgoing for e^{+iωt})."""
    return spherical_jn(n, x) - 1j * spherical_yn(n, x)


def _h2_derivative(n: int, x: np.ndarray) -> np.ndarray:
    return spherical_jn(n, x, derivative=True) - 1j * spherical_yn(n, x, derivative=True)


def rigid_sphere_hrtf(frequency_hz: float, radius_m: float, points_m: np.ndarray, ear_direction: np.ndarray,
                      speed_of_sound_m_s: float = 343.0, terms: int | None = None) -> np.ndarray:
    """Complex HRTF (ratio to the free field at the centre) at `points_m` (n, 3), metres from the
    sphere's centre, for an ear on the surface in the unit direction `ear_direction`."""
    points_m = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
    ear = np.asarray(ear_direction, dtype=np.float64)
    ear = ear / np.linalg.norm(ear)
    r = np.linalg.norm(points_m, axis=1)
    cos_angle = np.clip(points_m @ ear / r, -1.0, 1.0)
    k = 2.0 * np.pi * frequency_hz / speed_of_sound_m_s
    mu, rho = k * radius_m, r / radius_m
    # orders far above ka add nothing (h'_m(ka) explodes); they would only overflow
    terms = terms or int(mu + 40)
    series = np.zeros(len(points_m), dtype=complex)
    for m in range(terms):
        with np.errstate(over="ignore", invalid="ignore"):
            term = (2 * m + 1) * eval_legendre(m, cos_angle) * _h2(m, mu * rho) / _h2_derivative(m, mu)
        if not np.isfinite(term).all():
            break
        series += term
    # free field of a point source at the centre, heard at distance r: e^{-ikr}/r (same source strength)
    return -(rho / mu) * np.exp(1j * mu * rho) * series
