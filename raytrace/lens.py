"""Lens distortion: OpenCV's radial-tangential model, `distort` and its inverse `undistort`.

A real lens bends the pinhole's rays. OpenCV's model maps the ideal normalised image point
(x, y) = (X_c/Z_c, Y_c/Z_c) to the distorted one

    r² = x² + y²,  g = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)
    x_d = x g + 2 p1 x y + p2 (r² + 2 x²)
    y_d = y g + p1 (r² + 2 y²) + 2 p2 x y

with the coefficients in OpenCV's order (k1, k2, p1, p2[, k3[, k4, k5, k6]]), as
`cv2.calibrateCamera` gives them; the pixel is then K (x_d, y_d, 1). `undistort` inverts the
map by Newton's method on its exact Jacobian, vectorised over the points. `distorted_image` makes the image a
distorted camera takes from a finer image of the ideal camera's view (any renderer's), each pixel integrating its
area.
"""

from __future__ import annotations

import numpy as np

from .errors import RaytraceError

__all__ = ["as_distortion", "distort", "distortion_jacobian", "undistort", "distorted_image"]

UNDISTORT_TOL = 1e-13
"""Newton's stop: the re-distorted point within this of its target (normalised units; 1e-13 is
about 1e-9 px at a focal length of 10,000 px)."""

UNDISTORT_ITERATIONS = 40


def as_distortion(value, name: str = "distortion") -> np.ndarray | None:
    """`value` as OpenCV's 8 coefficients (k1, k2, p1, p2, k3, k4, k5, k6), float64, or None where it is
    None or all zero (no distortion). Accepts 4, 5 or 8 numbers, as OpenCV does."""
    if value is None:
        return None
    try:
        d = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise RaytraceError(f"{name}: expected 4, 5 or 8 numbers (k1, k2, p1, p2[, k3[, k4, k5, k6]]), "
                            f"got {value!r}") from exc
    if d.size not in (4, 5, 8):
        raise RaytraceError(f"{name}: expected 4, 5 or 8 numbers (k1, k2, p1, p2[, k3[, k4, k5, k6]]), "
                            f"got {d.size}")
    if not np.all(np.isfinite(d)):
        raise RaytraceError(f"{name}: expected finite numbers, got {d.tolist()}")
    if not np.any(d):
        return None
    return np.concatenate([d, np.zeros(8 - d.size)])


def _terms(xy: np.ndarray, c: np.ndarray):
    x, y = xy[:, 0], xy[:, 1]
    k1, k2, p1, p2, k3, k4, k5, k6 = c
    r2 = x * x + y * y
    a = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    b = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
    return x, y, r2, a, b


def distort(xy, coeffs) -> np.ndarray:
    """The distorted normalised points of ideal ones.

    Parameters
    ----------
    xy : (N, 2) float64, ideal normalised image points (X_c/Z_c, Y_c/Z_c)
    coeffs : (8,) float64, `as_distortion`'s

    Returns
    -------
    (N, 2) float64, (x_d, y_d)
    """
    xy = np.asarray(xy, dtype=np.float64)
    x, y, r2, a, b = _terms(xy, coeffs)
    p1, p2 = coeffs[2], coeffs[3]
    g = a / b
    return np.column_stack([x * g + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                            y * g + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y])


def distortion_jacobian(xy, coeffs) -> np.ndarray:
    """∂(x_d, y_d)/∂(x, y) at ideal normalised points, (N, 2, 2) float64."""
    xy = np.asarray(xy, dtype=np.float64)
    x, y, r2, a, b = _terms(xy, coeffs)
    k1, k2, p1, p2, k3, k4, k5, k6 = coeffs
    da = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
    db = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2)
    g = a / b
    dg = (da * b - a * db) / (b * b)  # ∂g/∂r²
    xy2 = 2.0 * x * y * dg
    J = np.empty((len(xy), 2, 2))
    J[:, 0, 0] = g + 2.0 * x * x * dg + 2.0 * p1 * y + 6.0 * p2 * x
    J[:, 0, 1] = xy2 + 2.0 * p1 * x + 2.0 * p2 * y
    J[:, 1, 0] = xy2 + 2.0 * p1 * x + 2.0 * p2 * y
    J[:, 1, 1] = g + 2.0 * y * y * dg + 6.0 * p1 * y + 2.0 * p2 * x
    return J


def undistort(xy_d, coeffs) -> tuple[np.ndarray, np.ndarray]:
    """The ideal normalised points whose distortion is `xy_d`: `_PLAIN_STEPS` Newton steps from x_d / g(r_d²),
    then, for the points still short of the tolerance, one step at a time, each taken only where it brings the
    point nearer its target (a point with no ideal point, beyond a fold of the lens's map, reports a residual
    over the tolerance).

    Parameters
    ----------
    xy_d : (N, 2) float64, distorted normalised image points
    coeffs : (8,) float64, `as_distortion`'s

    Returns
    -------
    xy : (N, 2) float64, ideal normalised points
    residual : (N,) float64, |distort(xy) − xy_d|, ≤ `UNDISTORT_TOL` where Newton converged
    """
    target = np.asarray(xy_d, dtype=np.float64)
    xy = np.empty_like(target)
    for lo in range(0, len(target), _CHUNK):  # chunks that stay in the cache
        xy[lo:lo + _CHUNK] = _newton(target[lo:lo + _CHUNK], coeffs, _PLAIN_STEPS)
    res = distort(xy, coeffs) - target
    err = np.hypot(res[:, 0], res[:, 1])
    for _ in range(UNDISTORT_ITERATIONS):  # the points plain steps left short, a step at a time
        todo = np.flatnonzero(~(err <= UNDISTORT_TOL))
        if todo.size == 0:
            break
        q = _newton(target[todo], coeffs, 1, start=xy[todo])
        rq = distort(q, coeffs) - target[todo]
        eq = np.hypot(rq[:, 0], rq[:, 1])
        better = eq < err[todo]
        if not better.any():
            break
        sel = todo[better]
        xy[sel], err[sel] = q[better], eq[better]
    return xy, err


_CHUNK = 1 << 15
_PLAIN_STEPS = 3


def _newton(target: np.ndarray, c: np.ndarray, steps: int, start: np.ndarray | None = None) -> np.ndarray:
    """`steps` plain Newton steps towards the ideal points of `target` (N, 2), from `start` (N, 2) or else from
    target / g(|target|²)."""
    k1, k2, p1, p2, k3, k4, k5, k6 = c
    xd, yd = target[:, 0], target[:, 1]
    if start is None:
        r2 = xd * xd + yd * yd
        g = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        with np.errstate(divide="ignore", invalid="ignore"):
            x, y = xd / g, yd / g
        bad = ~(np.isfinite(x) & np.isfinite(y))
        x[bad], y[bad] = xd[bad], yd[bad]
    else:
        x, y = start[:, 0].copy(), start[:, 1].copy()
    for _ in range(steps):
        xx, yy, xy2 = x * x, y * y, x * y
        r2 = xx + yy
        a = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        b = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        g = a / b
        dg = ((k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)) * b - a * (k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2))) / (b * b)
        rx = x * g + 2.0 * p1 * xy2 + p2 * (r2 + 2.0 * xx) - xd
        ry = y * g + p1 * (r2 + 2.0 * yy) + 2.0 * p2 * xy2 - yd
        cross = 2.0 * xy2 * dg + 2.0 * p1 * x + 2.0 * p2 * y
        j00 = g + 2.0 * xx * dg + 2.0 * p1 * y + 6.0 * p2 * x
        j11 = g + 2.0 * yy * dg + 6.0 * p1 * y + 2.0 * p2 * x
        det = j00 * j11 - cross * cross
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            dx = (j11 * rx - cross * ry) / det
            dy = (j00 * ry - cross * rx) / det
        ok = np.isfinite(dx) & np.isfinite(dy)
        x = np.where(ok, x - dx, x)
        y = np.where(ok, y - dy, y)
    return np.column_stack([x, y])


def distorted_image(ideal, camera, pad: int, factor: int, ideal_pixels=None) -> np.ndarray:
    """The image a distorted camera takes of what an ideal camera's finer image shows.

    Parameters
    ----------
    ideal : (factor·(H + 2 pad), factor·(W + 2 pad), C) uint8 sRGB, the view of `camera` without its distortion
        on a canvas `pad` px wider each way, `factor` times finer: its pixel I lies at the canvas coordinate
        (I + 0.5) / factor − 0.5 (the image's pixel u at u + pad)
    camera : PinholeCamera with `distortion`, resolution (W, H)
    ideal_pixels : callable (N, 2) distorted pixels → (N, 2) ideal pixels of the same K, or None for this module's
        `undistort` (a test passes OpenCV's `cv2.undistortPoints` to check ours against it)

    Returns
    -------
    (H, W, C) uint8 sRGB: each pixel the mean, in linear light, of factor² points spread evenly over it, each taken
    to its ideal point and sampled there bilinearly.
    """
    import cv2

    from .render import linear_to_srgb8
    if ideal_pixels is None:
        def ideal_pixels(px):
            Kinv = np.linalg.inv(camera.K)
            xy, _ = undistort(px @ Kinv[:2, :2].T + Kinv[:2, 2], camera.distortion)
            return xy @ camera.K[:2, :2].T + camera.K[:2, 2]
    w, h = camera.resolution
    expected = (factor * (h + 2 * pad), factor * (w + 2 * pad))
    if ideal.shape[:2] != expected:
        raise RaytraceError(f"ideal: expected an image of {expected[1]}×{expected[0]} px (factor {factor}, pad {pad} "
                            f"over {w}×{h}), got {ideal.shape[1]}×{ideal.shape[0]}")
    levels = np.arange(256) / 255.0
    linear = np.where(levels <= 0.04045, levels / 12.92, ((levels + 0.055) / 1.055) ** 2.4).astype(np.float32)[ideal]
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    acc = np.zeros((h, w, ideal.shape[2]))
    for i in range(factor):
        for j in range(factor):
            px = np.column_stack([(uu - 0.5 + (i + 0.5) / factor).ravel(), (vv - 0.5 + (j + 0.5) / factor).ravel()])
            m = (factor * (np.asarray(ideal_pixels(px)).reshape(h, w, 2) + pad + 0.5) - 0.5).astype(np.float32)
            acc += cv2.remap(linear, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return linear_to_srgb8(acc / factor ** 2)
