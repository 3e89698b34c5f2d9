"""Errors of the localisation model: bad HRTF files, grids without a usable sagittal plane."""
from core.errors import PipelineError


class AmtBridgeError(PipelineError):
    """Input that the localisation model cannot use; the message names the file or value and the fix."""
