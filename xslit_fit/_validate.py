"""Argument coercion helpers of `xslit_fit`: `as_rays`, `as_weights`, `as_vector`.

They coerce at the public boundary to float64 and raise `FitError` naming the argument.
"""

from __future__ import annotations

import numpy as np

from .errors import FitError


def as_array(value, name: str, width: int) -> np.ndarray:
    """Return `value` as a finite (N, width) float64 array (a single row is promoted)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FitError(f"{name}: expected an (N, {width}) array of numbers") from exc
    if arr.ndim == 1 and arr.shape == (width,):
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise FitError(f"{name}: expected shape (N, {width}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise FitError(f"{name}: expected finite numbers, got NaN or infinity")
    return arr


def as_rays(points, directions) -> tuple[np.ndarray, np.ndarray]:
    """Return (points (N, 3), unit directions (N, 3)) float64; reject zero directions."""
    p = as_array(points, "points", 3)
    d = as_array(directions, "directions", 3)
    if p.shape != d.shape:
        raise FitError(f"directions: expected the shape of points {p.shape}, got {d.shape}")
    norm = np.linalg.norm(d, axis=1)
    if np.any(~(norm > 1e-300)):
        raise FitError("directions: expected non-zero direction vectors")
    return p, d / norm[:, None]


def as_weights(weights, n: int) -> np.ndarray | None:
    """Return `weights` as a finite non-negative (n,) float64 array, or None."""
    if weights is None:
        return None
    try:
        w = np.asarray(weights, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FitError("weights: expected an (N,) array of numbers") from exc
    if w.shape != (n,):
        raise FitError(f"weights: expected shape ({n},), got {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise FitError("weights: expected finite non-negative numbers")
    if not np.sum(w) > 0:
        raise FitError("weights: expected at least one positive weight")
    return w


def as_vector(value, name: str, size: int = 3) -> np.ndarray:
    """Return `value` as a finite float64 vector of length `size`."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FitError(f"{name}: expected {size} numbers, got {value!r}") from exc
    if arr.shape != (size,):
        raise FitError(f"{name}: expected {size} numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise FitError(f"{name}: expected finite numbers, got {arr.tolist()}")
    return arr


def as_unit(value, name: str) -> np.ndarray:
    """Return `value` as a unit float64 3-vector; reject zero length."""
    arr = as_vector(value, name)
    norm = np.linalg.norm(arr)
    if not norm > 1e-300:
        raise FitError(f"{name}: expected a non-zero direction, got {arr.tolist()}")
    return arr / norm
