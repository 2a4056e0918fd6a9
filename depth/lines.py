"""Line cues of XSlit images: `XSlitSampling` (pixels ↔ image plane), LSD segments, grouping by AR range, DDS depth.

An XSlit image is sampled on the virtual image plane (z = 0 of the XSlit frame, docs/CONVENTIONS.md)
with a pitch p1 along slit 1's direction v1 and p2 along v2. Equal pitches are the ideal
`raytrace.camera.XSlitCamera`; unequal ones are an anisotropic sensor or a resampled panorama, which
keeps objects of strongly anisotropic XSlits (z2/z1 ≫ 1) many pixels wide in both directions.
All geometry (ratios r_i, slopes, depths) is computed on the plane, never in pixel units.

A line segment's plane direction d = a·v1 + b·v2 has the ratio r_i = a/b (the corrected Eqn. lro,
`depth.dds.ratio_from_angle`). A frontal 3D line of base ratio r_o images with r_i inside the range of
Eqn. ratiorange (`depth.ddar.aspect_ratio_limits`); `group_by_ratio` assigns each segment to the
candidate 3D direction whose range contains its r_i, and `segment_depths` inverts Eqn. getz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from depth import ddar
from depth.errors import DepthError
from depth.xslit import XSlit, as_points

__all__ = ["XSlitSampling", "detect_segments", "segment_ratios", "group_by_ratio", "segment_depths",
           "LineCues", "line_cues"]


@dataclass(frozen=True)
class XSlitSampling:
    """An XSlit (z1, z2, θ1, θ2) sampled by pixels: plane point = B·diag(p1, p2)·B⁻¹·(pixel − c).

    Attributes
    ----------
    xslit : depth.xslit.XSlit
    pitch : (p1, p2) plane length per pixel along v1 and v2 (same unit as z1, z2)
    principal_px : (cx, cy) pixel of the plane origin
    """

    xslit: XSlit
    pitch: tuple[float, float]
    principal_px: tuple[float, float]

    def __post_init__(self):
        if not isinstance(self.xslit, XSlit):
            raise DepthError(f"xslit: expected a depth.xslit.XSlit, got {type(self.xslit).__name__}")
        p = np.broadcast_to(np.asarray(self.pitch, dtype=np.float64), (2,))
        if not np.all(np.isfinite(p)) or np.any(p <= 0):
            raise DepthError(f"pitch: expected one or two positive lengths per pixel, got {self.pitch!r}")
        c = np.asarray(self.principal_px, dtype=np.float64)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise DepthError(f"principal_px: expected two finite pixel coordinates, got {self.principal_px!r}")
        object.__setattr__(self, "pitch", (float(p[0]), float(p[1])))
        object.__setattr__(self, "principal_px", (float(c[0]), float(c[1])))

    @property
    def linear(self) -> np.ndarray:
        """(2, 2) float64 matrix M with plane = M·(pixel − c)."""
        b = self.xslit.basis
        return b @ np.diag(self.pitch) @ np.linalg.inv(b)

    def to_plane(self, pixels) -> np.ndarray:
        """Plane points (N, 2) of pixels (N, 2)."""
        px = as_points(pixels, "pixels", 2)
        return (px - np.asarray(self.principal_px)) @ self.linear.T

    def to_pixels(self, plane) -> np.ndarray:
        """Pixels (N, 2) of plane points (N, 2)."""
        q = as_points(plane, "plane", 2)
        return q @ np.linalg.inv(self.linear).T + np.asarray(self.principal_px)

    def kappa(self, pixels) -> np.ndarray:
        """(κ_u, κ_v) plane coordinates (N, 2) of pixels (N, 2) on the slit basis v1, v2."""
        return self.xslit.to_kappa(self.to_plane(pixels))

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """Rays of pixels (N, 2) in the XSlit frame: origins (N, 3) on z = 0, unit directions (N, 3)."""
        return self.xslit.ray(self.to_plane(pixels))


def detect_segments(gray, min_length: float = 10.0) -> np.ndarray:
    """LSD line segments (`cv2.createLineSegmentDetector`) of a gray image.

    gray : (H, W) float in [0, 1] or uint8 → (N, 4) float64 rows (u0, v0, u1, v1), pixels,
    only segments at least `min_length` pixels long.
    """
    import cv2

    g = np.asarray(gray)
    if g.ndim != 2 or min(g.shape) < 3:
        raise DepthError(f"gray: expected an (H, W) image, got shape {g.shape}")
    if g.dtype != np.uint8:
        g = np.clip(np.rint(np.asarray(g, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)
    lsd = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD)
    lines = lsd.detect(g)[0]
    if lines is None:
        return np.zeros((0, 4))
    seg = lines.reshape(-1, 4).astype(np.float64)
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    return seg[length >= float(min_length)]


def segment_ratios(segments, sampling: XSlitSampling) -> np.ndarray:
    """r_i = a/b of each segment's plane direction a·v1 + b·v2 (corrected Eqn. lro).

    segments : (N, 4) pixels (u0, v0, u1, v1) → (N,) float64 (±inf when b = 0, along slit 1).
    """
    seg = as_points(segments, "segments", 4)
    d = sampling.to_plane(seg[:, 2:]) - sampling.to_plane(seg[:, :2])
    ab = sampling.xslit.to_kappa(d)
    with np.errstate(divide="ignore", invalid="ignore"):
        return ab[:, 0] / ab[:, 1]


def group_by_ratio(r_i, xslit: XSlit, base_ratios) -> np.ndarray:
    """Assign each ratio r_i to the candidate base ratio r_o whose reachable range contains it.

    The range of r_o is Eqn. ratiorange, (r_i at z_near, r_i at ∞) = `ddar.aspect_ratio_limits`.
    r_i : (N,), base_ratios : (K,) → (N,) int64 index into base_ratios, −1 for none (or for more than one).
    """
    r = np.asarray(r_i, dtype=np.float64).ravel()
    ro = np.asarray(base_ratios, dtype=np.float64).ravel()
    if ro.size == 0:
        raise DepthError("base_ratios: expected at least one candidate r_o")
    inside = np.zeros((r.size, ro.size), dtype=bool)
    for k, value in enumerate(ro):
        lo, hi = ddar.aspect_ratio_limits(xslit.z1, xslit.z2, value)
        inside[:, k] = np.isfinite(r) & (r > lo) & (r < hi)
    label = np.argmax(inside, axis=1).astype(np.int64)
    label[inside.sum(axis=1) != 1] = -1
    return label


def segment_depths(r_i, r_o, xslit: XSlit) -> np.ndarray:
    """DDS depth z of segments from r_i and their group's r_o (Eqn. getz); NaN outside the range."""
    return ddar.depth_from_aspect_ratio(np.asarray(r_i, float), xslit.z1, xslit.z2,
                                        np.asarray(r_o, float), strict=False)


@dataclass(frozen=True)
class LineCues:
    """Sparse depth cues from line segments.

    segments : (N, 4) pixels; r_i : (N,); group : (N,) index into base_ratios or −1;
    depth : (N,) z per segment (NaN when ungrouped or unreachable); base_ratios : (K,)
    """

    segments: np.ndarray
    r_i: np.ndarray
    group: np.ndarray
    depth: np.ndarray
    base_ratios: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """(N,) bool, segments that carry a depth."""
        return np.isfinite(self.depth)


def line_cues(gray, sampling: XSlitSampling, base_ratios, min_length: float = 10.0) -> LineCues:
    """LSD segments of `gray`, grouped by AR range against `base_ratios`, each with its DDS depth."""
    seg = detect_segments(gray, min_length)
    ro = np.asarray(base_ratios, dtype=np.float64).ravel()
    if len(seg) == 0:
        e = np.zeros(0)
        return LineCues(seg, e, e.astype(np.int64), e, ro)
    r = segment_ratios(seg, sampling)
    g = group_by_ratio(r, sampling.xslit, ro)
    z = np.full(len(seg), np.nan)
    ok = g >= 0
    z[ok] = segment_depths(r[ok], ro[g[ok]], sampling.xslit)
    return LineCues(seg, r, g, z, ro)
