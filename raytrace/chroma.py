"""Lateral chromatic aberration: a colour channel's own focal lengths, principal point and distortion.

A lens bends each wavelength its own way, so the red and the blue image of a scene are magnified (and distorted)
a little differently from the green one: a white edge 1000 px from the image centre comes out with a red fringe
on one side and a blue one on the other, the channels' edges tenths of a pixel to pixels apart. Calibrating each
channel on its own (`cv2.calibrateCamera` on the red, green and blue channels of the same chessboard views; Mallon
& Whelan, "Calibration and removal of lateral chromatic aberration in images", Pattern Recognition Letters 28,
2007) measures it: each channel's intrinsics.

Here the camera's own `K` and `distortion` are green's, and `ChannelLens` holds red's or blue's where they differ.
`channel_pixels` gives, per pixel of the camera, where a channel images that pixel's (green's) ray: sampling the
channel there aligns it with green (`depth.reconstruct` does so before it reads an image).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_intrinsics
from .errors import RaytraceError
from .lens import as_distortion, distort, undistort

__all__ = ["CHANNELS", "ChannelLens", "as_channel_lens", "channel_pixels"]

CHANNELS = ("red", "blue")
"""The channels that may have a lens of their own, against green (the camera's)."""

GRID_STEP = 8
"""px between the nodes at which `channel_pixels` takes each pixel through the lenses exactly."""
GRID_ERROR_PX = 2e-3
"""`channel_pixels`' bound on its bilinear interpolation between nodes: 1.3e-3 px at most against OpenCV's exact map
for a wide-angle lens (k1 = −0.3, 68° across, red's coefficients and centre its own;
`tests/raytrace/test_chroma.py`), where a face read 0.1 px off moves its depth by about 3 %."""


@dataclass(frozen=True)
class ChannelLens:
    """One colour channel's intrinsics: `K` (3×3, as the camera's) and `distortion` (OpenCV's 8 coefficients, or
    None for none), where the camera's own are green's."""

    K: np.ndarray
    distortion: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "K", as_intrinsics(self.K))
        object.__setattr__(self, "distortion", as_distortion(self.distortion))

    def __eq__(self, other) -> bool:
        if not isinstance(other, ChannelLens):
            return NotImplemented
        same_distortion = (self.distortion is None and other.distortion is None) or (
            self.distortion is not None and other.distortion is not None
            and np.array_equal(self.distortion, other.distortion))
        return bool(np.array_equal(self.K, other.K)) and same_distortion

    def __hash__(self) -> int:
        return hash((self.K.tobytes(), None if self.distortion is None else self.distortion.tobytes()))


def as_channel_lens(value, name: str) -> ChannelLens | None:
    """A `ChannelLens`, or None; anything else is refused with a one-line error naming `name`."""
    if value is None or isinstance(value, ChannelLens):
        return value
    raise RaytraceError(f"{name}: expected a raytrace.chroma.ChannelLens or None, got {type(value).__name__}")


def _node_moves(camera, lens, nu: np.ndarray, nv: np.ndarray) -> np.ndarray:
    """(len(nv), len(nu), 2): how far the channel of `lens` images each node pixel (nu × nv) from where green does."""
    px = np.column_stack([np.tile(nu, len(nv)), np.repeat(nv, len(nu))])
    Kinv = np.linalg.inv(camera.K)
    xy = px @ Kinv[:2, :2].T + Kinv[:2, 2]
    if camera.distortion is not None:
        xy, _ = undistort(xy, camera.distortion)
    if lens.distortion is not None:
        xy = distort(xy, lens.distortion)
    return (xy @ lens.K[:2, :2].T + lens.K[:2, 2] - px).reshape(len(nv), len(nu), 2)


def channel_pixels(camera, channel: str) -> np.ndarray:
    """(H, W, 2) float64: where `channel` ("red" or "blue") of `camera` (a `PinholeCamera`) images the ray of each
    of the camera's own pixels (green's), (u, v) per pixel; the pixel itself where that channel has no lens of its
    own.

    The channels share the camera's pose, so this is done in normalised image coordinates: a pixel taken through K⁻¹
    and the camera's undistortion, then through the channel's distortion and K. That is done exactly at nodes
    GRID_STEP px apart, from a node before the first pixel to one beyond the last (each at a GRID_STEP-block's
    centre); between them the move from the pixel is interpolated bilinearly (`cv2.resize`, whose samples of a
    field GRID_STEP times finer fall on those nodes), which is exact where neither has a distortion (the map is then
    affine) and within GRID_ERROR_PX of the exact map for a wide-angle lens's (a test measures it)."""
    import cv2

    if channel not in CHANNELS:
        raise RaytraceError(f"channel: expected one of {', '.join(CHANNELS)}, got {channel!r}")
    w, h = camera.resolution
    lens = getattr(camera, channel)
    out = np.empty((h, w, 2))
    out[..., 0] = np.arange(w, dtype=np.float64)[None, :]
    out[..., 1] = np.arange(h, dtype=np.float64)[:, None]
    if lens is None:
        return out
    g = GRID_STEP
    nu = g * np.arange(-1, -(-w // g) + 1) + (g - 1) / 2.0  # block centres, one block beyond each border
    nv = g * np.arange(-1, -(-h // g) + 1) + (g - 1) / 2.0
    move = _node_moves(camera, lens, nu, nv)
    fine = cv2.resize(move, (g * len(nu), g * len(nv)), interpolation=cv2.INTER_LINEAR)  # float64 kept
    out += fine[g:g + h, g:g + w]
    return out
