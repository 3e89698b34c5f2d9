"""Error type of the `ppm` package."""
from core.errors import PipelineError


class PpmError(PipelineError):
    """Any invalid input or failed step inside `ppm` (template, rig, parameters, mesh I/O)."""
