"""Depth-dependent slope (DDS): depth of a frontal-parallel line from its image slope (Eqn. lro + getz).

A line direction d = (dx, dy) in the plane is decomposed on the slit directions,
d = a·v1 + b·v2; its ratio is r = a/b (the aspect ratio of the parallelogram whose diagonal it
is). With φ the direction's angle to the x axis this is

    r(φ) = sin(θ2 − φ) / sin(φ − θ1).

For a 3D line of slope s this is r_o; for its image of slope s' it is r_i; Eqn. getz then gives
the depth. Slopes may be ±∞ (vertical lines): everything is computed from angles, never from
dividing by dx. For a PO-XSlit (θ1 = 0, θ2 = 90°) r = 1/s, as Eqn. lro gives; for general angles
the printed Eqn. lro, (sin θ2 − s·sin θ1)/(s·cos θ1 − cos θ2), differs from the decomposition
above (e.g. θ1 = 45°, θ2 = 135°, s = 0 gives +1 instead of −1); tests check the decomposition
against projected lines.

A line parallel to a slit (b = 0 or a = 0) keeps its slope at every depth: it carries no depth
and raises DegenerateGeometryError.
"""

from __future__ import annotations

import numpy as np

from depth import ddar
from depth.errors import DegenerateGeometryError, DepthError
from depth.xslit import XSlit

__all__ = [
    "slope_angle",
    "ratio_from_angle",
    "ratio_from_slope",
    "angle_from_ratio",
    "depth_from_slope",
    "slope_angle_at_depth",
    "depth_std_from_angle",
]

_PARALLEL_TOL = 1e-9


def slope_angle(slope) -> np.ndarray:
    """Direction angle φ in (−π/2, π/2] of a slope s = dy/dx; s = ±∞ gives π/2."""
    s = np.asarray(slope, dtype=np.float64)
    if np.any(np.isnan(s)):
        raise DepthError("slope: expected a number or ±inf, got NaN")
    phi = np.arctan(s)
    return np.where(np.isclose(phi, -np.pi / 2, rtol=0, atol=1e-15), np.pi / 2, phi)


def ratio_from_angle(phi, xslit: XSlit) -> np.ndarray:
    """r = a/b for the direction (cos φ, sin φ) = a·v1 + b·v2 (r_o for a 3D line, r_i for its image)."""
    phi = np.asarray(phi, dtype=np.float64)
    num = np.sin(xslit.theta2 - phi)
    den = np.sin(phi - xslit.theta1)
    if np.any(np.abs(den) < _PARALLEL_TOL) or np.any(np.abs(num) < _PARALLEL_TOL):
        raise DegenerateGeometryError(
            "line direction parallel to a slit: its slope does not change with depth")
    return num / den


def ratio_from_slope(slope, xslit: XSlit) -> np.ndarray:
    """r for a line of slope s = dy/dx (±∞ allowed): the corrected Eqn. lro."""
    return ratio_from_angle(slope_angle(slope), xslit)


def angle_from_ratio(r, xslit: XSlit) -> np.ndarray:
    """Inverse of `ratio_from_angle`: the direction angle φ in (−π/2, π/2] with ratio r."""
    r = np.asarray(r, dtype=np.float64)
    d = r[..., None] * np.array([np.cos(xslit.theta1), np.sin(xslit.theta1)]) + \
        np.array([np.cos(xslit.theta2), np.sin(xslit.theta2)])
    phi = np.arctan2(d[..., 1], d[..., 0])
    phi = np.where(phi <= -np.pi / 2, phi + np.pi, phi)
    return np.where(phi > np.pi / 2, phi - np.pi, phi)


def depth_from_slope(image_slope, object_slope, xslit: XSlit, strict: bool = True) -> np.ndarray:
    """Depth z of a frontal-parallel 3D line of slope `object_slope` whose image has slope `image_slope`.

    Slopes are dy/dx in the XSlit frame; ±∞ is a vertical line.
    """
    r_i = ratio_from_slope(image_slope, xslit)
    r_o = ratio_from_slope(object_slope, xslit)
    return ddar.depth_from_aspect_ratio(r_i, xslit.z1, xslit.z2, r_o, strict=strict)


def slope_angle_at_depth(z, object_slope, xslit: XSlit) -> np.ndarray:
    """Direction angle φ' of the image of a frontal 3D line of slope `object_slope` at depth z."""
    r_o = ratio_from_slope(object_slope, xslit)
    r_i = ddar.aspect_ratio(z, xslit.z1, xslit.z2, r_o)
    return angle_from_ratio(r_i, xslit)


def depth_std_from_angle(image_angle, object_slope, sigma_angle, xslit: XSlit) -> np.ndarray:
    """First-order σ of z from the noise σ_φ (radians) of the image line's angle φ'.

    dz/dφ' = ∂z/∂r_i · dr/dφ' with dr/dφ = −sin(θ2 − θ1)/sin²(φ − θ1).
    """
    phi = np.asarray(image_angle, dtype=np.float64)
    r_i = ratio_from_angle(phi, xslit)
    r_o = ratio_from_slope(object_slope, xslit)
    dr_dphi = -np.sin(xslit.theta2 - xslit.theta1) / np.sin(phi - xslit.theta1) ** 2
    return np.abs(ddar.depth_derivative(r_i, xslit.z1, xslit.z2, r_o) * dr_dphi) * sigma_angle
