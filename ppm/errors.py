"""Error type of the `ppm` package."""


class PpmError(ValueError):
    """Any invalid input or failed step inside `ppm` (template, rig, parameters, mesh I/O)."""
