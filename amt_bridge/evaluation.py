"""The paper's localisation comparison: S calibrated so that the reference listener's own HRTFs
(target = template) give a chosen quadrant error rate (8 %), then each condition (e.g. the HRTFs of
the PPM head) heard with the reference as template at that S."""
from __future__ import annotations

import os
from pathlib import Path

from .hrtf_set import read_hrtf_set, read_one_ear_completed, resampled_at
from .model import LocalisationModel, Prediction


def compare_conditions(reference: str | os.PathLike, conditions: dict[str, str | os.PathLike],
                       qe_percent: float = 8.0, lateral_angles_deg=None,
                       reference_frequencies_hz=None, solved_ear: str | None = None
                       ) -> tuple[float, dict[str, Prediction]]:
    """(S in dB, predictions by name; 'reference' first) for SOFA files of HRIRs or HRTFs. A reference
    that cannot reach ``qe_percent`` is calibrated to the closest S of the bracket (a warning; the
    summary then shows the QE it reached). With ``reference_frequencies_hz`` (the sparse set the
    conditions were solved at) the reference is sampled there and rebuilt the same way first. With
    ``solved_ear`` ("left" or "right") the conditions hold that ear only and take the other from the
    (rebuilt) reference, direction by direction, as in the paper: only the solved pinna differs."""
    reference_set = read_hrtf_set(reference)
    if reference_frequencies_hz is not None:
        reference_set = resampled_at(reference_set, reference_frequencies_hz)
    self_model = LocalisationModel(reference_set, reference_set, lateral_angles_deg)
    sensitivity = self_model.calibrate(qe_percent, closest=True)
    predictions = {"reference": self_model.predict(sensitivity)}
    for name, path in conditions.items():
        condition = (read_one_ear_completed(path, solved_ear, reference_set) if solved_ear else read_hrtf_set(path))
        predictions[name] = LocalisationModel(condition, reference_set, lateral_angles_deg).predict(sensitivity)
    return sensitivity, predictions


def comparison_summary(reference: str | os.PathLike, qe_percent: float, sensitivity: float,
                       predictions: dict[str, Prediction]) -> dict:
    """JSON-ready summary of :func:`compare_conditions`."""
    reached = float(predictions["reference"].qe)
    summary = {"reference": str(Path(reference)), "calibration_qe_percent": qe_percent, "sensitivity_db": sensitivity,
               "calibration_reached": bool(abs(reached - qe_percent) < 0.01),
               "conditions": {name: prediction.as_dict() for name, prediction in predictions.items()}}
    if not summary["calibration_reached"]:
        summary["calibration_note"] = (f"the reference cannot reach {qe_percent:g} % quadrant errors in the "
                                       f"sensitivity bracket; S = {sensitivity:g} dB gives {reached:.2f} %")
    return summary
