"""Automatic alignment of the parametric pinna model to a listener's pinna scan."""
from .fit import AlignmentResult, AlignSettings, align
from .target import Target, prepare_target

__all__ = ["AlignSettings", "AlignmentResult", "Target", "align", "prepare_target"]
