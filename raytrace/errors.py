"""Raytrace errors: the single base error `RaytraceError` of the `raytrace` package.

Every invalid argument at the public boundary of `raytrace` raises `RaytraceError`, whose
message names the argument and what was expected, so the CLI can print it on one line.
"""


class RaytraceError(ValueError):
    """Invalid input to a `raytrace` function or class."""
