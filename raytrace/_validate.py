"""Argument coercion helpers: `as_vector`, `as_points`, `as_matrix` and friends.

They coerce at the public boundary to float64 and raise `RaytraceError` naming the argument.
"""

from __future__ import annotations

import numpy as np

from .errors import RaytraceError


def as_vector(value, name: str, size: int = 3) -> np.ndarray:
    """Return `value` as a finite float64 vector of length `size`."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise RaytraceError(f"{name}: expected {size} numbers, got {value!r}") from exc
    if arr.shape != (size,):
        raise RaytraceError(f"{name}: expected {size} numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise RaytraceError(f"{name}: expected finite numbers, got {arr.tolist()}")
    return arr


def as_unit(value, name: str) -> np.ndarray:
    """Return `value` as a unit float64 3-vector; reject zero length."""
    arr = as_vector(value, name)
    norm = np.linalg.norm(arr)
    if not norm > 1e-12:
        raise RaytraceError(f"{name}: expected a non-zero direction, got {arr.tolist()}")
    return arr / norm


def as_positive(value, name: str) -> float:
    """Return `value` as a finite float > 0."""
    try:
        out = float(value)
    except (TypeError, ValueError) as exc:
        raise RaytraceError(f"{name}: expected a positive number, got {value!r}") from exc
    if not (np.isfinite(out) and out > 0):
        raise RaytraceError(f"{name}: expected a positive finite number, got {value!r}")
    return out


def as_finite(value, name: str) -> float:
    """Return `value` as a finite float."""
    try:
        out = float(value)
    except (TypeError, ValueError) as exc:
        raise RaytraceError(f"{name}: expected a number, got {value!r}") from exc
    if not np.isfinite(out):
        raise RaytraceError(f"{name}: expected a finite number, got {value!r}")
    return out


def as_points(value, name: str, width: int = 3) -> np.ndarray:
    """Return `value` as a finite (N, width) float64 array (a single row is promoted)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise RaytraceError(f"{name}: expected an (N, {width}) array of numbers") from exc
    if arr.ndim == 1 and arr.shape == (width,):
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise RaytraceError(f"{name}: expected shape (N, {width}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise RaytraceError(f"{name}: expected finite numbers")
    return arr


def as_rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    """Coerce a ray bundle: origins (N, 3), directions (N, 3) (not necessarily unit)."""
    o = as_points(origins, "origins")
    d = as_points(directions, "directions")
    if o.shape != d.shape:
        raise RaytraceError(f"origins and directions: expected equal shapes, got {o.shape} and {d.shape}")
    return o, d


def as_rotation(value, name: str) -> np.ndarray:
    """Return `value` as a (3, 3) proper rotation matrix (orthonormal, det +1)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise RaytraceError(f"{name}: expected a 3x3 rotation matrix") from exc
    if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
        raise RaytraceError(f"{name}: expected a finite 3x3 rotation matrix, got shape {arr.shape}")
    if not np.allclose(arr @ arr.T, np.eye(3), atol=1e-9) or np.linalg.det(arr) < 0:
        raise RaytraceError(f"{name}: expected an orthonormal matrix with determinant +1")
    return arr


def as_resolution(value, name: str = "resolution") -> tuple[int, int]:
    """Return `value` as (W, H), two positive integers."""
    try:
        w, h = value
        wi, hi = int(w), int(h)
    except (TypeError, ValueError) as exc:
        raise RaytraceError(f"{name}: expected [width, height] in pixels, got {value!r}") from exc
    if wi != w or hi != h or wi <= 0 or hi <= 0:
        raise RaytraceError(f"{name}: expected two positive integers, got {value!r}")
    return wi, hi


def as_intrinsics(value, name: str = "K") -> np.ndarray:
    """A pinhole's 3×3 intrinsic matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] as float64, fx and fy positive."""
    K = np.asarray(value, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise RaytraceError(f"{name}: expected a finite 3x3 matrix, got shape {K.shape}")
    if not (K[0, 0] > 0 and K[1, 1] > 0):
        raise RaytraceError(f"{name}: expected positive focal lengths fx, fy, got {K[0, 0]}, {K[1, 1]}")
    if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0:
        raise RaytraceError(f"{name}: expected an upper-triangular matrix with last row [0, 0, 1]")
    return K


def check_same_rgb8(images: list) -> None:
    """Raise unless every one of `images` (arrays) is an (H, W, 3) uint8 RGB image of the first one's size."""
    for k, im in enumerate(images):
        if im.dtype != np.uint8 or im.ndim != 3 or im.shape[2] != 3:
            raise RaytraceError(f"images[{k}]: expected an (H, W, 3) uint8 RGB image, got {im.dtype} {im.shape}")
        if im.shape != images[0].shape:
            raise RaytraceError(f"images[{k}]: expected the size of images[0], {images[0].shape[1]}×"
                                f"{images[0].shape[0]}, got {im.shape[1]}×{im.shape[0]}")
