"""Error type of the `mesh2hrtf_io` package."""


class Mesh2HrtfIoError(ValueError):
    """Any invalid input or failed step inside `mesh2hrtf_io` (meshes, grids, projects, solver runs)."""
