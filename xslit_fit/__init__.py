"""xslit_fit: virtual slits of reflected ray bundles.

Plücker and GLC algebra, two-slit fits, GLC type classification, the XSlit frame
and local fit maps. This package never reads or writes files and never prints.
"""

from .errors import FitError
from .fit import REASONS, FailedFit, SlitFit, fit_two_slits
from .frame import PixelFrame, XSlitFrame, frame_for_pixels, interpolate_rays
from .glc import GLC, GLC_TYPES, fit_glc, glc_type
from .plucker import Line, lines_through_four, plucker, ray_line_distance, reciprocal_product
from .tiles import TileMap, fit_tiles

__all__ = [
    "FitError",
    "Line",
    "plucker",
    "reciprocal_product",
    "ray_line_distance",
    "lines_through_four",
    "SlitFit",
    "FailedFit",
    "REASONS",
    "fit_two_slits",
    "XSlitFrame",
    "PixelFrame",
    "interpolate_rays",
    "frame_for_pixels",
    "GLC",
    "GLC_TYPES",
    "fit_glc",
    "glc_type",
    "TileMap",
    "fit_tiles",
]
