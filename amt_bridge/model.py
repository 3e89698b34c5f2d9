"""baumgartner2014: sagittal-plane localisation predicted from a listener's DTFs (template: the
listener's own ears) and the DTFs of the sounds heard (target), as AMT 0.9.10 computes it.

One sagittal plane per lateral angle; several planes (lateral segments, default -20°, 0°, +20°)
are combined with equal weights. The spectral analysis does not depend on the sensitivity S, so it is
done once per plane and reused when S is calibrated.
"""
from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
from scipy.optimize import brentq

from .dtf import hrtf_to_dtf
from .errors import AmtBridgeError
from .filterbank import band_levels_db, centre_frequencies
from .hrtf_set import HrirSet
from .performance import Performance, performance
from .sagittal import SagittalPlane, extract_sagittal_plane
from .settings import ModelSettings, default_settings, load_defaults
from .stages import (combine_ears, gradient_offset, positive_gradients, probability_mass_vectors,
                     sensorimotor_mapping, similarity, spectral_distance)

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class PlanePrediction:
    """The model's output for one sagittal plane: p (responses × targets), response and target polar
    angles (deg), and the performance derived from p."""

    lateral_deg: float
    p: np.ndarray
    response_polar_deg: np.ndarray
    target_polar_deg: np.ndarray
    performance: Performance

    @property
    def rang(self) -> np.ndarray:
        return self.response_polar_deg

    @property
    def tang(self) -> np.ndarray:
        return self.target_polar_deg


@dataclasses.dataclass(frozen=True)
class Prediction:
    """Predictions for several sagittal planes and their equal-weight average: quadrant errors (%),
    local polar RMS error (deg), elevation bias (deg), at sensitivity ``sensitivity_db``."""

    planes: tuple[PlanePrediction, ...]
    sensitivity_db: float

    @property
    def qe(self) -> float:
        return float(np.mean([plane.performance.qe_percent for plane in self.planes]))

    @property
    def pe(self) -> float:
        return float(np.mean([plane.performance.pe_deg for plane in self.planes]))

    @property
    def eb(self) -> float:
        return float(np.nanmean([plane.performance.eb_deg for plane in self.planes]))

    def as_dict(self) -> dict:
        return {"qe_percent": round(self.qe, 6), "pe_deg": round(self.pe, 6), "eb_deg": round(self.eb, 6),
                "sensitivity_db": self.sensitivity_db,
                "planes": [{"lateral_deg": plane.lateral_deg, "qe_percent": plane.performance.qe_percent,
                            "pe_deg": plane.performance.pe_deg, "eb_deg": plane.performance.eb_deg,
                            "n_targets": int(plane.target_polar_deg.size)} for plane in self.planes]}


@dataclasses.dataclass(frozen=True)
class _PlaneDistances:
    """What S does not change: the spectral distances σ (templates × targets × ears) of one plane."""

    lateral_deg: float
    distances_db: np.ndarray
    template_polar_deg: np.ndarray
    target_polar_deg: np.ndarray


def spectral_profiles(plane: SagittalPlane, settings: ModelSettings) -> np.ndarray:
    """Positive gradient profiles (bands - Δ, directions, ears) in dB, or raw band levels when
    ``positive_gradients`` is off."""
    if plane.sampling_rate_hz / 2 <= settings.highest_frequency_hz:
        raise AmtBridgeError(f"sampling rate {plane.sampling_rate_hz:g} Hz is too low for bands up to "
                             f"{settings.highest_frequency_hz:g} Hz (its Nyquist frequency must lie above the highest band); use "
                             f"more than {2 * settings.highest_frequency_hz:g} Hz or lower highest_frequency_hz")
    centres = centre_frequencies(settings.lowest_frequency_hz, settings.highest_frequency_hz, settings.band_spacing_erb)
    n, directions, ears = plane.irs.shape
    levels = band_levels_db(plane.irs.reshape(n, directions * ears), plane.sampling_rate_hz, centres,
                            settings.gammatone_order).reshape(len(centres), directions, ears)
    if not settings.positive_gradients:
        return levels
    return positive_gradients(levels, gradient_offset(centres))  # AMT keeps the spacing factor at 1


def _plane_distances(target: HrirSet, template: HrirSet, lateral_deg: float, settings: ModelSettings,
                     plane_options: dict) -> _PlaneDistances:
    target_plane = extract_sagittal_plane(target, lateral_deg, **plane_options)
    template_plane = extract_sagittal_plane(template, lateral_deg, **plane_options)
    distances = spectral_distance(spectral_profiles(target_plane, settings), spectral_profiles(template_plane, settings))
    return _PlaneDistances(float(lateral_deg), distances, template_plane.polar_deg, target_plane.polar_deg)


def _predict_plane(plane: _PlaneDistances, settings: ModelSettings, sensitivity_db: float,
                   experimental_polar_deg: np.ndarray | None = None) -> PlanePrediction:
    s = combine_ears(similarity(plane.distances_db, sensitivity_db, settings.slope_per_db), plane.lateral_deg,
                     settings.binaural_coefficient_deg)
    mapped, responses = sensorimotor_mapping(s, plane.template_polar_deg, plane.lateral_deg,
                                             settings.response_step_deg, settings.motor_scatter_deg)
    p = probability_mass_vectors(mapped)
    return PlanePrediction(plane.lateral_deg, p, responses, plane.target_polar_deg,
                           performance(p, plane.target_polar_deg, responses, experimental_polar_deg))


def _plane_options() -> dict:
    return load_defaults()["sagittal_plane"]


def _as_dtfs(hrirs: HrirSet, already_dtf: bool) -> HrirSet:
    if already_dtf:
        return hrirs
    options = load_defaults()["dtf"]
    return hrtf_to_dtf(hrirs, options["mode"], options["lowest_frequency_hz"], options["highest_frequency_hz"])


class LocalisationModel:
    """baumgartner2014 for one pair (target, template): DTFs and spectral distances are computed once per
    lateral angle; :meth:`predict` and :meth:`calibrate` then cost milliseconds."""

    def __init__(self, target: HrirSet, template: HrirSet, lateral_angles_deg=None,
                 settings: ModelSettings | None = None, already_dtf: bool = False):
        self.settings = settings or default_settings()
        if lateral_angles_deg is None:
            lateral_angles_deg = load_defaults()["evaluation"]["lateral_angles_deg"]
        lateral_angles_deg = [float(angle) for angle in np.atleast_1d(lateral_angles_deg)]
        if not lateral_angles_deg:
            raise AmtBridgeError("give at least one lateral angle")
        start = time.perf_counter()
        target_dtf = _as_dtfs(target, already_dtf)
        template_dtf = target_dtf if template is target else _as_dtfs(template, already_dtf)
        options = _plane_options()
        self.planes = tuple(_plane_distances(target_dtf, template_dtf, angle, self.settings, options)
                            for angle in lateral_angles_deg)
        log.debug("spectral analysis of %d planes in %.2f s", len(self.planes), time.perf_counter() - start)

    def predict(self, sensitivity_db: float | None = None, experimental_polar_deg=None) -> Prediction:
        """Predictions for every plane at sensitivity S (default: the settings' S, 0.7 dB)."""
        sensitivity = self.settings.sensitivity_db if sensitivity_db is None else float(sensitivity_db)
        return Prediction(tuple(_predict_plane(plane, self.settings, sensitivity, experimental_polar_deg)
                                for plane in self.planes), sensitivity)

    def calibrate(self, qe_percent: float | None = None, bracket_db: tuple[float, float] | None = None,
                  closest: bool = False) -> float:
        """The sensitivity S (dB) at which the mean quadrant error over the planes equals ``qe_percent``
        (default 8 %): QE grows monotonically with S, so a bracketed root search finds it.

        A goal outside the QE range of the bracket is an error, or with ``closest`` the bracket end
        nearest to it (HRTFs with poor spectral cues, e.g. coarse demo heads, keep more quadrant errors
        than the goal even at the smallest S)."""
        defaults = load_defaults()["evaluation"]
        goal = defaults["calibration_qe_percent"] if qe_percent is None else float(qe_percent)
        low, high = bracket_db or defaults["calibration_bracket_db"]
        qe_low, qe_high = self.predict(low).qe, self.predict(high).qe
        if not qe_low <= goal <= qe_high:
            if closest:
                nearest = float(low if goal < qe_low else high)
                log.warning("no sensitivity in [%g, %g] dB gives %g%% quadrant errors (QE runs from %.2f%% to "
                            "%.2f%%); using the closest, S = %g dB", low, high, goal, qe_low, qe_high, nearest)
                return nearest
            raise AmtBridgeError(f"no sensitivity in [{low}, {high}] dB gives {goal}% quadrant errors "
                                 f"(QE runs from {qe_low:.2f}% to {qe_high:.2f}%); choose another goal or bracket")
        return float(brentq(lambda s: self.predict(s).qe - goal, low, high, xtol=1e-6))


def predict(target: HrirSet, template: HrirSet, lateral_angles_deg=None, sensitivity_db: float | None = None,
            settings: ModelSettings | None = None, already_dtf: bool = False) -> Prediction:
    """Predict the localisation of ``target`` HRTFs by a listener whose own HRTFs are ``template``.

    Both are HRIR sets (read with :func:`amt_bridge.read_hrtf_set`); DTFs are computed from them
    unless ``already_dtf``. Returns per-plane p, rang, tang and QE/PE/EB, and their mean."""
    return LocalisationModel(target, template, lateral_angles_deg, settings, already_dtf).predict(sensitivity_db)


def calibrate_sensitivity(reference: HrirSet, qe_percent: float | None = None, lateral_angles_deg=None,
                          settings: ModelSettings | None = None, already_dtf: bool = False) -> float:
    """S such that the reference heard through itself (target = template) gives ``qe_percent`` (8 %)."""
    return LocalisationModel(reference, reference, lateral_angles_deg, settings, already_dtf).calibrate(qe_percent)
