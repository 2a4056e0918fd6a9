"""Aspect-ratio measurement of imaged circles and rectangles: `EllipseFit`, `fit_ellipse`, `rectangle_extents`.

A circle (base ratio r_o = 1) at depth z images in an XSlit to an ellipse whose half-extents along
the slit directions are in the ratio r_i = κ_u/κ_v of Eqn. ardef. `fit_ellipse` is a direct
least-squares conic fit (Halir & Flusser's stable form of Fitzgibbon's method) in float64 on
sub-pixel iso-contour points (`closed_contours`, marching squares of scikit-image);
`EllipseFit.half_extent` gives the extent along any direction, so the measured r_i is independent of
the ellipse's orientation. `rectangle_extents` measures an anti-aliased rectangle's extents along v1
and v2 from its second moments (area sampling adds a known 1/12 px² of variance).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from depth.errors import DepthError
from depth.lines import XSlitSampling
from depth.xslit import as_points

__all__ = ["EllipseFit", "fit_ellipse", "closed_contours", "ellipse_ratio", "rectangle_extents"]


@dataclass(frozen=True)
class EllipseFit:
    """An ellipse {p : (p − center)ᵀ·M·(p − center) = 1}, or a falsy failed fit with its `reason`.

    center : (2,) float64; matrix : (2, 2) float64 symmetric positive definite M;
    rms : rms algebraic distance of the points, in units of the mean semi-axis; n_points : int.
    """

    center: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    matrix: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))
    rms: float = np.nan
    n_points: int = 0
    reason: str = ""

    def __bool__(self) -> bool:
        return not self.reason

    @property
    def semi_axes(self) -> np.ndarray:
        """(2,) semi-axes, major first."""
        w = np.linalg.eigvalsh(self.matrix)
        return np.sort(1.0 / np.sqrt(w))[::-1]

    def half_extent(self, direction) -> float:
        """Half the ellipse's extent along a direction (2,): sqrt(nᵀ·M⁻¹·n) for the unit n."""
        n = np.asarray(direction, dtype=np.float64)
        n = n / np.linalg.norm(n)
        return float(np.sqrt(n @ np.linalg.solve(self.matrix, n)))


def fit_ellipse(points, min_points: int = 6) -> EllipseFit:
    """Direct least-squares ellipse through points (N, 2) float64; falsy when it is not an ellipse."""
    p = as_points(points, "points", 2)
    if len(p) < max(6, int(min_points)):
        return EllipseFit(reason=f"{len(p)} points: need at least {max(6, int(min_points))}")
    mean = p.mean(axis=0)
    scale = np.sqrt(np.mean(np.sum((p - mean) ** 2, axis=1)))
    if not scale > 0:
        return EllipseFit(reason="all points coincide")
    x, y = ((p - mean) / scale).T
    d1 = np.column_stack([x * x, x * y, y * y])
    d2 = np.column_stack([x, y, np.ones_like(x)])
    s1, s2, s3 = d1.T @ d1, d1.T @ d2, d2.T @ d2
    try:
        t = -np.linalg.solve(s3, s2.T)
    except np.linalg.LinAlgError:
        return EllipseFit(reason="points are collinear")
    m = s1 + s2 @ t
    m = np.array([m[2] / 2.0, -m[1], m[0] / 2.0])
    vals, vecs = np.linalg.eig(m)
    vecs = np.real(vecs)
    cond = 4.0 * vecs[0] * vecs[2] - vecs[1] ** 2
    ok = np.flatnonzero(cond > 0)
    if ok.size == 0:
        return EllipseFit(reason="the best conic through the points is not an ellipse")
    a1 = vecs[:, ok[np.argmin(np.abs(np.real(vals[ok])))]]
    a, b, c = a1
    d, e, f = t @ a1
    q = np.array([[a, b / 2.0], [b / 2.0, c]])
    try:
        c0 = np.linalg.solve(2.0 * q, -np.array([d, e]))
    except np.linalg.LinAlgError:
        return EllipseFit(reason="degenerate conic")
    k = -(f + 0.5 * (d * c0[0] + e * c0[1]))
    mat = q / k
    if not np.all(np.linalg.eigvalsh(mat) > 0):
        return EllipseFit(reason="the best conic through the points is not an ellipse")
    rel = np.einsum("ni,ij,nj->n", np.column_stack([x, y]) - c0, mat, np.column_stack([x, y]) - c0) - 1.0
    return EllipseFit(center=mean + scale * c0, matrix=mat / scale ** 2,
                      rms=float(np.sqrt(np.mean(rel ** 2)) / 2.0), n_points=len(p))


def closed_contours(image, level: float = 0.5, min_points: int = 20) -> list[np.ndarray]:
    """Sub-pixel closed iso-contours of an (H, W) float image: list of (N, 2) float64 (u, v) pixels."""
    from skimage.measure import find_contours

    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2:
        raise DepthError(f"image: expected an (H, W) array, got shape {img.shape}")
    out = []
    for c in find_contours(img, float(level)):
        if len(c) >= min_points and np.allclose(c[0], c[-1]):
            out.append(np.ascontiguousarray(c[:-1, ::-1]))
    return out


def ellipse_ratio(contour_px, sampling: XSlitSampling) -> tuple[float, EllipseFit]:
    """Image aspect ratio r_i of an ellipse from its contour pixels (N, 2).

    The ellipse is fitted in plane κ coordinates (v1, v2 basis), and r_i is its half-extent along
    κ_u over its half-extent along κ_v. Returns (r_i, fit); r_i is NaN when the fit failed.
    """
    fit = fit_ellipse(sampling.kappa(contour_px))
    if not fit:
        return float("nan"), fit
    return fit.half_extent((1.0, 0.0)) / fit.half_extent((0.0, 1.0)), fit


def rectangle_extents(weight, sampling: XSlitSampling) -> np.ndarray:
    """Full extents (κ_u, κ_v) along v1, v2 of one anti-aliased rectangle whose sides are along the slits.

    weight : (H, W) float64 coverage in [0, 1] of the rectangle (0 elsewhere) → (2,) plane lengths.
    A uniform rectangle of extent w has variance w²/12 along it; area sampling by square pixels adds
    the pixel's own covariance (I/12 px²), removed here.
    """
    w = np.asarray(weight, dtype=np.float64)
    if w.ndim != 2 or not np.all(np.isfinite(w)):
        raise DepthError(f"weight: expected a finite (H, W) coverage image, got shape {w.shape}")
    total = w.sum()
    if not total > 0:
        raise DepthError("weight: the rectangle covers no pixel")
    rows, cols = np.nonzero(w)
    px = np.column_stack([cols, rows]).astype(np.float64)
    wt = w[rows, cols]
    binv = np.linalg.inv(sampling.xslit.basis)
    k = px @ binv.T  # κ in pixel units
    mu = (wt[:, None] * k).sum(axis=0) / total
    var = (wt * ((k - mu) ** 2).T).sum(axis=1) / total
    pix_var = np.diag(binv @ binv.T) / 12.0
    ext_px = np.sqrt(np.maximum(12.0 * (var - pix_var), 0.0))
    return ext_px * np.asarray(sampling.pitch)
