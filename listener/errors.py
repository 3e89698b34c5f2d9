"""Errors of a new listener's inputs (head scan, ear scans, listener table)."""
from ppm.errors import PpmError


class ListenerError(PpmError):
    """A listener's input that cannot be used; the message names the file and the fix."""
