"""Errors of the stitching stage (head + pinna -> one closed BEM surface)."""
from ppm.errors import PpmError


class StitchError(PpmError):
    """A head or pinna that cannot be stitched; the message names the file and the fix."""
