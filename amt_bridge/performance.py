"""Psychoacoustic performance parameters from probability mass vectors (spec §10, AMT's
``baumgartner2014_pmv2ppp``): quadrant error rate, local polar RMS error, elevation bias."""
from __future__ import annotations

import dataclasses

import numpy as np

from .angles import matlab_colon, matlab_mod

ARI_POLAR_DEG = np.concatenate([np.arange(-30.0, 75.0, 5.0), [80.0, 100.0], np.arange(110.0, 215.0, 5.0)])


@dataclasses.dataclass(frozen=True)
class Performance:
    """Quadrant errors (%), local polar RMS error (deg), elevation bias (deg), and their values per target."""

    qe_percent: float
    pe_deg: float
    eb_deg: float
    qe_per_target: np.ndarray
    pe_per_target: np.ndarray
    eb_per_target: np.ndarray


def performance(p: np.ndarray, target_polar_deg: np.ndarray, response_polar_deg: np.ndarray,
                experimental_polar_deg: np.ndarray | None = None) -> Performance:
    """QE, PE, EB from p (responses × targets). With ``experimental_polar_deg`` the per-target values are
    linearly interpolated to those angles (each counts once), -90 and 270 added as AMT does.

    A quadrant error is a response 90° or more from the target (inclusive); PE is the mean over targets
    of the RMS error of the responses within 90°; EB excludes targets between 80° and 180° (up-rear)
    and flips its sign in the rear."""
    p = np.asarray(p, dtype=np.float64)
    targets = np.asarray(target_polar_deg, dtype=np.float64).ravel()
    responses = np.asarray(response_polar_deg, dtype=np.float64).ravel()
    if p.shape[0] == 49:  # AMT's baumgartner2013 legacy: a 49-row PMV means responses -30:5:210
        responses = matlab_colon(-30.0, 5.0, 210.0)
    if p.shape != (responses.size, targets.size):
        raise ValueError(f"p has shape {p.shape}; expected (responses {responses.size}, targets {targets.size})")
    p = p / p.sum(axis=0, keepdims=True)
    qe, pe, eb = np.zeros(targets.size), np.zeros(targets.size), np.zeros(targets.size)
    not_up_rear = np.zeros(targets.size, dtype=bool)
    for i, target in enumerate(targets):
        d = target - responses
        wrap = (d < -180) | (d > 180)
        d[wrap] = matlab_mod(d[wrap] + 180.0, 360.0) - 180.0
        d = np.abs(d)
        local = d < 90
        qe[i] = p[~local, i].sum()
        conditional = p[local, i] / p[local, i].sum()
        pe[i] = np.sqrt(np.sum(conditional * d[local] ** 2))
        if target < 80:
            eb[i] = np.sum(conditional * responses[local]) - target
            not_up_rear[i] = True
        elif target > 180:
            eb[i] = -(np.sum(conditional * responses[local]) - target)
    eb_valid = eb[not_up_rear]
    if experimental_polar_deg is not None and len(experimental_polar_deg):
        experimental = np.asarray(experimental_polar_deg, dtype=np.float64).ravel()
        qe, pe, eb_valid = _interpolate_to_experiment(targets, qe, pe, eb_valid, not_up_rear, experimental)
    return Performance(float(np.mean(qe) * 100), float(np.mean(pe)), float(np.mean(eb_valid)) if eb_valid.size else
                       float("nan"), qe, pe, eb_valid)


def _interpolate_to_experiment(targets, qe, pe, eb, not_up_rear, experimental):
    qe_end, pe_end = (qe[0] + qe[-1]) / 2, (pe[0] + pe[-1]) / 2
    eb_end = (eb[0] + eb[-1]) / 2 if eb.size else np.nan
    angles, included = targets.copy(), not_up_rear.copy()
    if angles.min() > -90:
        angles, qe, pe, eb = np.r_[-90.0, angles], np.r_[qe_end, qe], np.r_[pe_end, pe], np.r_[eb_end, eb]
        included = np.r_[True, included]
    if angles.max() < 270:
        angles, qe, pe, eb = np.r_[angles, 270.0], np.r_[qe, qe_end], np.r_[pe, pe_end], np.r_[eb, eb_end]
        included = np.r_[included, True]
    front_or_back = (experimental < 80) | (experimental > 180)
    return (np.interp(experimental, angles, qe), np.interp(experimental, angles, pe),
            np.interp(experimental[front_or_back], angles[included], eb))


def chance_performance(target_polar_deg: np.ndarray = ARI_POLAR_DEG,
                       response_polar_deg: np.ndarray | None = None) -> Performance:
    """Performance of uniform guessing over the response grid (default -90:5:265)."""
    responses = matlab_colon(-90.0, 5.0, 265.0) if response_polar_deg is None else np.asarray(response_polar_deg)
    return performance(np.ones((responses.size, len(target_polar_deg))), target_polar_deg, responses)
