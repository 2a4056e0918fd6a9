"""Local two-slit fit maps: `fit_tiles` over a per-pixel ray map, returning a `TileMap`.

One XSlit is a poor model of a whole curved mirror, so the image is cut into tiles and each
tile's reflected rays get their own two-slit fit and XSlit frame (image plane through the
tile's ray centroid). The map reports per tile z1, z2, the baseline |z2 − z1|, the ratio
z2/z1, the rms ray-to-slit distance and whether the fit succeeded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import FitError
from .fit import fit_two_slits
from .frame import XSlitFrame, _as_ray_map

__all__ = ["TileMap", "fit_tiles"]


@dataclass(frozen=True)
class TileMap:
    """Per-tile two-slit fits of a ray map; every array is (ny, nx).

    Attributes
    ----------
    z1, z2 : float64
        Slit depths (paper's z1, z2) of each tile's XSlit frame, metres; NaN if invalid.
    baseline : float64
        |z2 − z1|, metres.
    ratio : float64
        z2 / z1.
    theta2 : float64
        Angle of slit 2 to slit 1 (θ2 with θ1 = 0), radians.
    rms, max_distance : float64
        Rms and maximum ray-to-slit distance of the tile's rays (subsample), metres.
    n_rays : int64
        Rays used in the tile's fit.
    valid : bool
        The fit succeeded.
    bounds : (ny, nx, 4) int64
        Pixel bounds (x0, y0, x1, y1) of each tile, x1 and y1 exclusive.
    reasons : (ny, nx) object
        "" for valid tiles, else the `FailedFit` reason.
    frames : list of lists
        The tile's `XSlitFrame`, or None.
    """

    z1: np.ndarray
    z2: np.ndarray
    baseline: np.ndarray
    ratio: np.ndarray
    theta2: np.ndarray
    rms: np.ndarray
    max_distance: np.ndarray
    n_rays: np.ndarray
    valid: np.ndarray
    bounds: np.ndarray
    reasons: np.ndarray
    frames: list

    @property
    def shape(self) -> tuple[int, int]:
        return self.valid.shape


def fit_tiles(points, directions, valid=None, tiles=(16, 16), max_rays_per_tile: int = 1500,
              min_rays: int = 16, max_rms: float | None = None, seed: int = 0, progress=None,
              **fit_options) -> TileMap:
    """Fit two slits in every tile of a per-pixel ray map.

    Parameters
    ----------
    points, directions : (H, W, 3) float64
        Per-pixel reflected rays (mirror point, direction toward the scene).
    valid : (H, W) bool, optional
        Pixels that carry a ray (default: finite entries).
    tiles : (ny, nx)
        Number of tile rows and columns; tile edges are spread evenly over the image.
    max_rays_per_tile : int
        At most this many valid rays per tile, a seeded random subsample, enter the fit.
    min_rays : int
        Tiles with fewer valid rays are invalid ("too few rays").
    max_rms : float, optional
        Tiles whose rms ray-to-slit distance exceeds this (metres) are invalid
        ("rms above max_rms"): the XSlit model does not hold there.
    seed : int
        Seed of the subsampling.
    progress : callable(done: int, total: int), optional
        Called after each tile.
    **fit_options
        Passed to `fit_two_slits` (e.g. refine=False).
    """
    p, d, v = _as_ray_map(points, directions, valid)
    try:
        ny, nx = (int(t) for t in tiles)
    except (TypeError, ValueError) as exc:
        raise FitError(f"tiles: expected (ny, nx) integers, got {tiles!r}") from exc
    h, w = v.shape
    if not (1 <= ny <= h and 1 <= nx <= w):
        raise FitError(f"tiles: expected 1 <= ny <= {h} and 1 <= nx <= {w}, got {(ny, nx)}")
    if max_rays_per_tile < 4 or min_rays < 4:
        raise FitError("max_rays_per_tile, min_rays: expected at least 4")
    rows = np.linspace(0, h, ny + 1).round().astype(int)
    cols = np.linspace(0, w, nx + 1).round().astype(int)
    rng = np.random.default_rng(seed)
    shape = (ny, nx)
    out = {k: np.full(shape, np.nan) for k in
           ("z1", "z2", "baseline", "ratio", "theta2", "rms", "max_distance")}
    n_rays = np.zeros(shape, dtype=np.int64)
    ok = np.zeros(shape, dtype=bool)
    reasons = np.full(shape, "", dtype=object)
    bounds = np.zeros(shape + (4,), dtype=np.int64)
    frames = [[None] * nx for _ in range(ny)]
    for i in range(ny):
        for j in range(nx):
            y0, y1, x0, x1 = rows[i], rows[i + 1], cols[j], cols[j + 1]
            bounds[i, j] = (x0, y0, x1, y1)
            mask = v[y0:y1, x0:x1]
            tp, td = p[y0:y1, x0:x1][mask], d[y0:y1, x0:x1][mask]
            if len(tp) > max_rays_per_tile:
                idx = rng.choice(len(tp), size=max_rays_per_tile, replace=False)
                tp, td = tp[idx], td[idx]
            n_rays[i, j] = len(tp)
            if len(tp) < min_rays:
                reasons[i, j] = "too few rays"
            else:
                fit = fit_two_slits(tp, td, **fit_options)
                if fit and max_rms is not None and fit.rms_distance > max_rms:
                    reasons[i, j] = "rms above max_rms"
                    out["rms"][i, j] = fit.rms_distance
                elif fit:
                    frame = XSlitFrame.from_fit(fit)
                    frames[i][j] = frame
                    ok[i, j] = True
                    out["z1"][i, j], out["z2"][i, j] = frame.z1, frame.z2
                    out["baseline"][i, j] = abs(frame.z2 - frame.z1)
                    out["ratio"][i, j] = frame.z2 / frame.z1 if frame.z1 != 0 else np.inf
                    out["theta2"][i, j] = frame.theta2 - frame.theta1
                    out["rms"][i, j] = fit.rms_distance
                    out["max_distance"][i, j] = fit.max_distance
                else:
                    reasons[i, j] = fit.reason
            if progress is not None:
                progress(i * nx + j + 1, ny * nx)
    return TileMap(n_rays=n_rays, valid=ok, bounds=bounds, reasons=reasons, frames=frames,
                   **out)
