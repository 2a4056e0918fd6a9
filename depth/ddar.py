"""Depth-dependent aspect ratio (DDAR): the paper's Eqns. ardef, getz, sensit, ratiorange, depthrange.

Functions of the slit depths z1, z2 (paper's symbols), the base aspect ratio r_o of an object
(r_o = κ_x/κ_y: its extent along slit 1's direction over its extent along slit 2's) and its
image aspect ratio r_i = κ_u/κ_v. All are vectorised over numpy arrays and use float64.

Two deliberate departures from the printed paper, both checked against finite differences and
direct inversion in tests/depth/test_ddar.py:

- Eqn. depthrange is printed as z_max = (z2/z1)·[1 + (z2 − z1)·r_o/ε], which is not
  dimensionally consistent. Solving |r_i(z) − r_i(∞)| = ε exactly gives
  z_max = z2 + |z2·(z2 − z1)·r_o / (z1·ε)|; the two differ by the constant z2 − z2/z1.
- The paper assumes r_i decreases with z (slits on the scene side, z2 > z1 > 0). With virtual slits
  behind the image plane (z1, z2 < 0, a convex mirror) r_i *increases* with z. Nothing here relies
  on the sign of ∂r_i/∂z.

The scene is taken to lie beyond the image plane and beyond both slits: z > z_near with
z_near = max(0, z1, z2). The reachable aspect ratios are r_i(z) for z in (z_near, ∞).
"""

from __future__ import annotations

import numpy as np

from depth.errors import DegenerateGeometryError, DepthError

__all__ = [
    "aspect_ratio",
    "depth_from_aspect_ratio",
    "depth_derivative",
    "sensitivity",
    "near_depth",
    "aspect_ratio_limits",
    "max_discernible_depth",
    "depth_std_from_aspect_ratio",
]


def _check_slits(z1, z2) -> tuple[float, float]:
    z1, z2 = float(z1), float(z2)
    if not (np.isfinite(z1) and np.isfinite(z2)):
        raise DepthError(f"z1={z1}, z2={z2}: expected finite slit depths")
    if z1 == 0.0 or z2 == 0.0:
        raise DegenerateGeometryError(f"z1={z1}, z2={z2}: a slit on the image plane carries no depth")
    if abs(z1 - z2) <= 1e-12 * abs(z2):
        raise DegenerateGeometryError(
            f"z1 == z2 == {z1}: a pinhole; its aspect ratios do not depend on depth")
    return z1, z2


def _check_ro(r_o) -> np.ndarray:
    r_o = np.asarray(r_o, dtype=np.float64)
    if not np.all(np.isfinite(r_o)) or np.any(r_o == 0.0):
        raise DepthError(f"r_o: expected a finite non-zero base aspect ratio, got {r_o}")
    return r_o


def near_depth(z1: float, z2: float) -> float:
    """z_near = max(0, z1, z2): the scene lies at z > z_near (beyond the plane and both slits)."""
    z1, z2 = _check_slits(z1, z2)
    return max(0.0, z1, z2)


def aspect_ratio(z, z1: float, z2: float, r_o=1.0) -> np.ndarray:
    """Image aspect ratio r_i of an object at depth z (Eqn. ardef).

    r_i = z2·(z − z1) / (z1·(z − z2)) · r_o.
    z : scalar or (N,) float64 → same shape.
    """
    z1, z2 = _check_slits(z1, z2)
    r_o = _check_ro(r_o)
    z = np.asarray(z, dtype=np.float64)
    return z2 * (z - z1) / (z1 * (z - z2)) * r_o


def depth_from_aspect_ratio(r_i, z1: float, z2: float, r_o=1.0, strict: bool = True) -> np.ndarray:
    """Depth z from the image aspect ratio r_i (Eqn. getz).

    z = z1·z2·(r_i − r_o) / (z1·r_i − z2·r_o).

    r_i : scalar or (N,) float64. With `strict`, an r_i outside the reachable range
    (`aspect_ratio_limits`) raises DepthError; otherwise such entries are NaN.
    """
    z1, z2 = _check_slits(z1, z2)
    r_o = _check_ro(r_o)
    r_i = np.asarray(r_i, dtype=np.float64)
    den = z1 * r_i - z2 * r_o
    with np.errstate(divide="ignore", invalid="ignore"):
        z = z1 * z2 * (r_i - r_o) / den
    ok = np.isfinite(z) & (z > near_depth(z1, z2)) & np.isfinite(r_i)
    if not np.all(ok):
        if strict:
            lo, hi = aspect_ratio_limits(z1, z2, np.min(r_o) if r_o.ndim else r_o)
            bad = np.atleast_1d(r_i)[~np.atleast_1d(ok)][0] if r_i.ndim else float(r_i)
            raise DepthError(
                f"r_i={bad:.6g}: outside the reachable aspect-ratio range ({lo:.6g}, {hi:.6g}) "
                f"of this XSlit (z1={z1:g}, z2={z2:g})")
        z = np.where(ok, z, np.nan)
    return z


def depth_derivative(r_i, z1: float, z2: float, r_o=1.0) -> np.ndarray:
    """∂z/∂r_i = z1·z2·(z1 − z2)·r_o / (z1·r_i − z2·r_o)²  (the paper's monotonicity equation)."""
    z1, z2 = _check_slits(z1, z2)
    r_o = _check_ro(r_o)
    r_i = np.asarray(r_i, dtype=np.float64)
    return z1 * z2 * (z1 - z2) * r_o / (z1 * r_i - z2 * r_o) ** 2


def sensitivity(z, z1: float, z2: float, r_o=1.0) -> np.ndarray:
    """∂r_i/∂z = z2·(z1 − z2)·r_o / (z1·(z − z2)²)  (Eqn. sensit). Its magnitude is the sensitivity."""
    z1, z2 = _check_slits(z1, z2)
    r_o = _check_ro(r_o)
    z = np.asarray(z, dtype=np.float64)
    return z2 * (z1 - z2) * r_o / (z1 * (z - z2) ** 2)


def aspect_ratio_limits(z1: float, z2: float, r_o=1.0) -> tuple[float, float]:
    """(low, high) of the reachable r_i (Eqn. ratiorange): r_i at z_near and at z → ∞ (= z2/z1·r_o).

    With z_near a slit depth the limit there is ±∞.
    """
    z1, z2 = _check_slits(z1, z2)
    r_o = float(_check_ro(r_o))
    r_inf = z2 / z1 * r_o
    zn = near_depth(z1, z2)
    if zn == z2:
        # sign of r_i just beyond z2: r_i - r_inf = (z2/z1)·r_o·(z2 - z1)/(z - z2), z - z2 -> 0+
        r_near = np.inf if (z2 / z1) * r_o * (z2 - z1) > 0 else -np.inf
    elif zn == z1:
        r_near = 0.0
    else:
        r_near = float(aspect_ratio(zn, z1, z2, r_o))
    return (min(r_near, r_inf), max(r_near, r_inf))


def max_discernible_depth(z1: float, z2: float, r_o=1.0, eps: float | None = None,
                          image_size: int | None = None) -> float:
    """Largest depth whose aspect ratio differs from r_i(∞) by at least ε (Eqn. depthrange, corrected).

    z_max = z2 + |z2·(z2 − z1)·r_o / (z1·ε)|.  ε defaults to 1/L for an image of L pixels
    (`image_size`); pass a smaller ε for sub-pixel measurement.
    """
    z1, z2 = _check_slits(z1, z2)
    r_o = float(_check_ro(r_o))
    if eps is None:
        if image_size is None or int(image_size) <= 0:
            raise DepthError("eps: give eps > 0 or image_size L > 0 (then eps = 1/L)")
        eps = 1.0 / int(image_size)
    eps = float(eps)
    if not (np.isfinite(eps) and eps > 0):
        raise DepthError(f"eps: expected a positive aspect-ratio resolution, got {eps}")
    return z2 + abs(z2 * (z2 - z1) * r_o / (z1 * eps))


def depth_std_from_aspect_ratio(r_i, sigma_r, z1: float, z2: float, r_o=1.0, sigma_ro=0.0) -> np.ndarray:
    """First-order standard deviation of z from the noise σ_r of r_i (and optionally σ of r_o)."""
    z1, z2 = _check_slits(z1, z2)
    r_o = _check_ro(r_o)
    r_i = np.asarray(r_i, dtype=np.float64)
    den = (z1 * r_i - z2 * r_o) ** 2
    dz_dri = z1 * z2 * (z1 - z2) * r_o / den
    dz_dro = z1 * z2 * (z2 - z1) * r_i / den
    return np.sqrt((dz_dri * sigma_r) ** 2 + (dz_dro * sigma_ro) ** 2)
