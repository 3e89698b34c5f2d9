"""Model settings of baumgartner2014, loaded from ``amt_bridge/data/baumgartner2014.yaml``."""
from __future__ import annotations

import dataclasses
from importlib import resources

import yaml

from .errors import AmtBridgeError


@dataclasses.dataclass(frozen=True)
class ModelSettings:
    """Parameters of the model (degrees, Hz, dB). Field names follow the physics; AMT's keys in brackets."""

    sensitivity_db: float = 0.7            # S
    slope_per_db: float = 6.0              # gamma
    binaural_coefficient_deg: float = 13.0  # bwcoef
    motor_scatter_deg: float = 17.0        # mrsmsp
    response_step_deg: float = 5.0         # rangsamp
    band_spacing_erb: float = 1.0          # space
    lowest_frequency_hz: float = 700.0     # flow
    highest_frequency_hz: float = 18000.0  # fhigh
    positive_gradients: bool = True        # do == 1
    gammatone_order: int = 4

    def __post_init__(self):
        for name in ("slope_per_db", "response_step_deg", "band_spacing_erb", "lowest_frequency_hz"):
            if not getattr(self, name) > 0:
                raise AmtBridgeError(f"model setting {name} must be positive, got {getattr(self, name)}")
        if self.motor_scatter_deg < 0:
            raise AmtBridgeError(f"motor_scatter_deg must be >= 0, got {self.motor_scatter_deg}")
        if not self.highest_frequency_hz > self.lowest_frequency_hz:
            raise AmtBridgeError("highest_frequency_hz must exceed lowest_frequency_hz")

    def replace(self, **changes) -> "ModelSettings":
        """A copy with some fields changed (e.g. ``sensitivity_db``)."""
        return dataclasses.replace(self, **changes)


def load_defaults() -> dict:
    """The whole defaults file as a dict (sections model, dtf, sagittal_plane, evaluation)."""
    text = resources.files("amt_bridge").joinpath("data/baumgartner2014.yaml").read_text(encoding="utf-8")
    return yaml.safe_load(text)


def default_settings() -> ModelSettings:
    """AMT 0.9.10's defaults."""
    return ModelSettings(**load_defaults()["model"])
