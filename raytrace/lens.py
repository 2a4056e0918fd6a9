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


def _radial(r2: np.ndarray, c) -> tuple:
    """The radial factor's numerator and denominator at r²: g = a / b."""
    k1, k2, _, _, k3, k4, k5, k6 = c
    return 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)), 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))


def _model(xy: np.ndarray, c, jacobian: bool = False) -> tuple:
    """The distorted point's coordinates (x_d, y_d), (N,) each, of ideal points (N, 2); with `jacobian`, also the
    Jacobian's entries ∂x_d/∂x, ∂x_d/∂y (= ∂y_d/∂x) and ∂y_d/∂y."""
    x, y = xy[:, 0], xy[:, 1]
    k1, k2, p1, p2, k3, k4, k5, k6 = c
    r2 = x * x + y * y
    a, b = _radial(r2, c)
    g = a / b
    xd = x * g + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * g + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    if not jacobian:
        return xd, yd
    dg = ((k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)) * b - a * (k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2))) / (b * b)  # ∂g/∂r²
    return (xd, yd, g + 2.0 * x * x * dg + 2.0 * p1 * y + 6.0 * p2 * x,
            2.0 * x * y * dg + 2.0 * p1 * x + 2.0 * p2 * y,
            g + 2.0 * y * y * dg + 6.0 * p1 * y + 2.0 * p2 * x)


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
    return np.column_stack(_model(np.asarray(xy, dtype=np.float64), coeffs))


def distortion_jacobian(xy, coeffs) -> np.ndarray:
    """∂(x_d, y_d)/∂(x, y) at ideal normalised points, (N, 2, 2) float64."""
    _, _, j00, j01, j11 = _model(np.asarray(xy, dtype=np.float64), coeffs, jacobian=True)
    return np.stack([np.column_stack([j00, j01]), np.column_stack([j01, j11])], axis=1)


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
    """`steps` plain Newton steps (`_model`) towards the ideal points of `target` (N, 2), from `start` (N, 2) or
    else from target / g(|target|²); a point whose step is not finite stays where it is."""
    xd, yd = target[:, 0], target[:, 1]
    if start is None:
        a, b = _radial(xd * xd + yd * yd, c)
        with np.errstate(divide="ignore", invalid="ignore"):
            x, y = xd * b / a, yd * b / a
        bad = ~(np.isfinite(x) & np.isfinite(y))
        x[bad], y[bad] = xd[bad], yd[bad]
        xy = np.column_stack([x, y])
    else:
        xy = start.copy()
    for _ in range(steps):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            fx, fy, j00, j01, j11 = _model(xy, c, jacobian=True)
            rx, ry = fx - xd, fy - yd
            det = j00 * j11 - j01 * j01
            dx = (j11 * rx - j01 * ry) / det
            dy = (j00 * ry - j01 * rx) / det
        ok = np.isfinite(dx) & np.isfinite(dy)
        xy[:, 0] -= np.where(ok, dx, 0.0)
        xy[:, 1] -= np.where(ok, dy, 0.0)
    return xy


def distorted_image(ideal, camera, pad: int, factor: int, ideal_pixels=None) -> np.ndarray:
    """The image a distorted camera takes of what an ideal camera's finer image shows.

    Parameters
    ----------
    ideal : (factor·(H + 2 pad), factor·(W + 2 pad), C) uint8 sRGB, the view of `camera` without its distortion
        on a canvas `pad` px wider each way, `factor` times finer: its pixel I lies at the canvas coordinate
        (I + 0.5) / factor − 0.5 (the image's pixel u at u + pad)
    camera : PinholeCamera with `distortion`, resolution (W, H)
    ideal_pixels : callable (N, 2) distorted pixels → (N, 2) ideal pixels of the same K, or None for the camera's
        own (`PinholeCamera.undistorted_pixels`; a test passes OpenCV's `cv2.undistortPoints` to check ours)

    Returns
    -------
    (H, W, C) uint8 sRGB: each pixel the mean, in linear light, of factor² points spread evenly over it, each taken
    to its ideal point and sampled there bilinearly.
    """
    import cv2

    from .render import linear_to_srgb8
    if ideal_pixels is None:
        ideal_pixels = camera.undistorted_pixels
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
