"""Errors of the depth package: `DepthError` and its degenerate-geometry subclass."""


class DepthError(ValueError):
    """Base error of the depth package."""


class DegenerateGeometryError(DepthError):
    """The geometry carries no depth: a pinhole (z1 == z2), a line parallel to a slit, ..."""
