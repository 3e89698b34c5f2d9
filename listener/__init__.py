"""A new listener: a head scan in any pose and unit, brought into the project frame, with both ears."""
from .errors import ListenerError
from .head_frame import HeadFrame, find_head_frame

__all__ = ["HeadFrame", "ListenerError", "find_head_frame"]
