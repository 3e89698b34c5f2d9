"""Error type of the `mesh2hrtf_io` package."""
from core.errors import PipelineError


class Mesh2HrtfIoError(PipelineError):
    """Any invalid input or failed step inside `mesh2hrtf_io` (meshes, grids, projects, solver runs)."""
