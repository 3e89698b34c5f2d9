"""Errors of the stitching stage (head + pinna -> one closed BEM surface)."""
from core.errors import PipelineError


class StitchError(PipelineError):
    """A head or pinna that cannot be stitched; the message names the file and the fix."""
