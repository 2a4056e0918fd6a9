"""Errors of the catadioptric package: `CatadioptricError` and `SetupError`.

The CLI prints any of these (and the base errors of `raytrace`, `xslit_fit`, `depth`) as one line
and exits 1.
"""


class CatadioptricError(ValueError):
    """Base error of the catadioptric package."""


class SetupError(CatadioptricError):
    """A setup file (or setup dictionary) is invalid; the message names the file and the key."""
