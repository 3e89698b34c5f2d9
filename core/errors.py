"""The error every domain error of the project derives from (PpmError, StitchError, Mesh2HrtfIoError, ...)."""


class PipelineError(ValueError):
    """Invalid input or a failed step anywhere in the pipeline; the message names the file and the fix. Catch this to
    report any stage's error as a message instead of a traceback."""
