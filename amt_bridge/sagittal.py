"""Sagittal-plane extraction: the directions of an HRTF set that lie in one sagittal plane (one lateral
angle), sorted by polar angle, as AMT's ``extractsp`` (spec §1), but with a bounded search.

AMT widens the lateral tolerance from ±0.505° to ±2.505° until the plane covers polar angles from
-30° to 210° without gaps over 30°; it loops forever when no direction lies in the plane. Here an
empty or too sparse plane is a clear error naming the file and the lateral angle.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .angles import matlab_mod, spherical_to_horizontal_polar
from .errors import AmtBridgeError
from .hrtf_set import HrirSet


@dataclasses.dataclass(frozen=True)
class SagittalPlane:
    """Impulse responses (N samples, D directions, 2 ears) of one sagittal plane sorted by polar angle (deg)."""

    irs: np.ndarray
    polar_deg: np.ndarray
    lateral_deg: float
    sampling_rate_hz: float
    lateral_actual_deg: np.ndarray


def extract_sagittal_plane(hrirs: HrirSet, lateral_deg: float, *, first_half_width_deg: float = 1.0,
                           largest_half_width_deg: float = 5.0, tolerance_deg: float = 0.01,
                           lowest_polar_deg: float = -30.0, highest_polar_deg: float = 210.0,
                           largest_gap_deg: float = 30.0, fewest_directions: int = 4) -> SagittalPlane:
    """The sagittal plane at ``lateral_deg`` (positive = left). AMT's loop: tolerance ``dlat`` starts at
    ``first_half_width_deg`` (a full width; half-width (dlat + dx)/2) and grows by 1° up to
    ``largest_half_width_deg`` while the plane misses -30°, 210° or has a gap over 30°."""
    if not -90.0 <= lateral_deg <= 90.0:
        raise AmtBridgeError(f"lateral angle must lie in [-90, 90] deg, got {lateral_deg}")
    lateral, polar = spherical_to_horizontal_polar(hrirs.azimuth_deg, hrirs.elevation_deg)
    dlat, dx = first_half_width_deg, tolerance_deg
    selected, pol = np.zeros(0, dtype=np.int64), np.zeros(0)
    while True:
        inside = np.flatnonzero((lateral >= -(dlat + dx) / 2 + lateral_deg) & (lateral <= (dlat + dx) / 2 + lateral_deg))
        pol, first = np.unique(polar[inside], return_index=True)
        selected = inside[first]
        dlat += 1.0
        covered = pol.size > 0 and not (pol.min() > lowest_polar_deg + dx or pol.max() < highest_polar_deg - dx
                                        or (pol.size > 1 and np.diff(pol).max() > largest_gap_deg))
        if covered or dlat > largest_half_width_deg:
            break
    if pol.size < fewest_directions:
        raise AmtBridgeError(
            f"{hrirs.source}: only {pol.size} direction(s) lie within ±{(dlat - 1 + dx) / 2:.2f} deg of the sagittal "
            f"plane at lateral angle {lateral_deg:g} deg; the model needs at least {fewest_directions} "
            "(use a denser grid or other lateral angles)")
    if (pol >= 270).any() or (pol < -90).any():
        pol = matlab_mod(pol + 90.0, 360.0) - 90.0
        order = np.argsort(pol, kind="stable")
        pol, selected = pol[order], selected[order]
    irs = np.transpose(hrirs.irs[selected], (2, 0, 1))
    return SagittalPlane(irs, pol, float(lateral_deg), hrirs.sampling_rate_hz, lateral[selected])
