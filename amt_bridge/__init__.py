"""baumgartner2014 in Python: sagittal-plane localisation (quadrant errors, polar errors) predicted
from HRTFs, as AMT 0.9.10 computes it, on SOFA files directly."""
from .errors import AmtBridgeError
from .hrtf_set import HrirSet, read_hrtf_set
from .model import LocalisationModel, PlanePrediction, Prediction, calibrate_sensitivity, predict
from .settings import ModelSettings, default_settings

__all__ = ["AmtBridgeError", "HrirSet", "LocalisationModel", "ModelSettings", "PlanePrediction", "Prediction",
           "calibrate_sensitivity", "default_settings", "predict", "read_hrtf_set"]
