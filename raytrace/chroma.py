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

from ._validate import as_intrinsics, check_same_rgb8
from .errors import RaytraceError
from .lens import as_distortion, distort, undistort

__all__ = ["CHANNELS", "ChannelLens", "ChannelCalibration", "as_channel_lens", "channel_pixels", "calibrate_channels",
           "BAYER_PATTERNS", "bayer_channels", "bayer_mosaic", "demosaiced", "demosaiced_mosaic"]

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


@dataclass(frozen=True)
class ChannelCalibration:
    """`calibrate_channels`' result: green's intrinsics (the camera's `K` and `distortion`), red's and blue's
    (`ChannelLens`), each channel's rms reprojection error over the corners (px), the views used (of those given),
    how far red and blue image the image's farthest corner from green (px), and the share of the image the boards'
    corners spanned."""

    K: np.ndarray
    distortion: np.ndarray
    red: ChannelLens
    blue: ChannelLens
    rms_px: dict
    views: tuple
    corner_shift_px: dict
    coverage: float


def _board_corners(images, board):
    """Each view's inner chessboard corners (cols × rows) found on its green channel, refined to sub-pixel on each
    channel: {view index: (3, N, 2)}."""
    import cv2
    found = {}
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    for k, im in enumerate(images):
        ok, corners = cv2.findChessboardCorners(np.ascontiguousarray(im[..., 1]), board,
                                                cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not ok:
            continue
        per = [cv2.cornerSubPix(np.ascontiguousarray(im[..., c]), corners.astype(np.float32).copy(), (5, 5), (-1, -1),
                                criteria).reshape(-1, 2) for c in range(3)]
        found[k] = np.stack(per).astype(np.float64)
    return found


def _channel_fit(object_points, corners, rvecs, tvecs, K, dist):
    """A channel's K and distortion as green's changed where a lens's colours differ: its magnification (fx and fy
    scaled alike), its principal point and its k1 (k2 as well extrapolated worse toward the corners the board did not
    reach); each view's pose held at green's. Least squares on the channel's
    corners' reprojection, from green's own. Returns (K, dist, rms px)."""
    import cv2
    from scipy.optimize import least_squares

    def lens(x):
        Kc = np.array([[K[0, 0] * x[0], 0.0, K[0, 2] + x[1]], [0.0, K[1, 1] * x[0], K[1, 2] + x[2]], [0.0, 0.0, 1.0]])
        dc = np.array(dist, dtype=np.float64)
        dc[0] += x[3]
        return Kc, dc

    def residuals(x):
        Kc, dc = lens(x)
        out = [cv2.projectPoints(obj.astype(np.float64), rv, tv, Kc, dc)[0].reshape(-1, 2) - seen  # (float32 points
               for obj, seen, rv, tv in zip(object_points, corners, rvecs, tvecs)]  # project to float32: no Jacobian)
        return np.concatenate(out).ravel()

    fit = least_squares(residuals, np.array([1.0, 0.0, 0.0, 0.0]), x_scale=[1e-3, 0.1, 0.1, 1e-3], method="lm")
    Kc, dc = lens(fit.x)
    return Kc, dc, float(np.sqrt(np.mean(fit.fun.reshape(-1, 2) ** 2) * 2))


def calibrate_channels(images, board: tuple[int, int], square: float) -> ChannelCalibration:
    """Each colour channel's intrinsics from views of a chessboard (lateral chromatic aberration).

    images : sequence of (H, W, 3) uint8 RGB images of a flat chessboard in different poses
    board : (columns, rows) of its inner corners; square : its squares' side (any unit: it cancels)

    The corners are found on green and refined on each channel (`cv2.cornerSubPix`). Green is calibrated by
    `cv2.calibrateCamera` (K and k1, k2, p1, p2; k3 held at 0, which few views overfit); red and blue each by least
    squares on their own corners with every view's pose held at green's, since a lens's channels share the camera's
    pose and differ only in where each images a ray: green's K and distortion with a magnification, a principal
    point and a k1 of their own (`_channel_fit`). Views where the board is not found are left out (`views` lists
    those used); fewer than 3 is an error. `coverage` is the share of the image the boards' corners spanned (the
    union of each view's hull): beyond it the channels' maps are extrapolated. Raises `RaytraceError` naming the
    argument on bad input.
    """
    import cv2
    imgs = [np.asarray(im) for im in images]
    if len(imgs) < 3:
        raise RaytraceError(f"images: expected at least 3 views of the chessboard, got {len(imgs)}")
    check_same_rgb8(imgs)
    cols, rows = (int(v) for v in board)
    if cols < 3 or rows < 3 or (cols, rows) != tuple(board):
        raise RaytraceError(f"board: expected the inner corners' columns and rows, whole numbers >= 3, got {board}")
    if not (np.isfinite(square) and square > 0):
        raise RaytraceError(f"square: expected the squares' side, > 0, got {square}")
    found = _board_corners(imgs, (cols, rows))
    if len(found) < 3:
        raise RaytraceError(f"images: the chessboard ({cols}×{rows} inner corners) was found in {len(found)} of "
                            f"{len(imgs)} views; expected at least 3")
    grid = np.zeros((cols * rows, 3), np.float32)
    grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    views = sorted(found)
    objects = [grid] * len(views)
    h, w = imgs[0].shape[:2]
    green = [found[k][1].astype(np.float32) for k in views]
    rms_g, K, dist, rvecs, tvecs = cv2.calibrateCamera(objects, green, (w, h), None, None,
                                                       flags=cv2.CALIB_FIX_K3)
    dist = np.ravel(dist)[:5]
    lenses, rms = {}, {"green": float(rms_g)}
    for c, name in ((0, "red"), (2, "blue")):
        Kc, dc, rms[name] = _channel_fit(objects, [found[k][c] for k in views], rvecs, tvecs, K, dist)
        lenses[name] = ChannelLens(Kc, dc)
    spanned = np.zeros((h, w), np.uint8)
    for k in views:
        cv2.fillConvexPoly(spanned, cv2.convexHull(found[k][1].astype(np.int32)), 1)
    calibration = ChannelCalibration(K=np.asarray(K, dtype=np.float64), distortion=dist, red=lenses["red"],
                                     blue=lenses["blue"], rms_px=rms, views=tuple(views), corner_shift_px={},
                                     coverage=float(spanned.mean()))
    far = max(((0.0, 0.0), (w - 1.0, 0.0), (0.0, h - 1.0), (w - 1.0, h - 1.0)),
              key=lambda p: np.hypot(p[0] - calibration.K[0, 2], p[1] - calibration.K[1, 2]))
    green = ChannelLens(calibration.K, dist)  # (`_node_moves` reads a camera's K and distortion alone)
    for name in CHANNELS:
        move = _node_moves(green, lenses[name], np.array([far[0]]), np.array([far[1]]))
        calibration.corner_shift_px[name] = float(np.hypot(*move[0, 0]))
    return calibration


BAYER_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
"""A Bayer colour filter mosaic's 2 × 2 tile, read row by row from the sensor's first pixel: "RGGB" has red at even
rows and even columns, blue at odd rows and odd columns, green between."""


def bayer_channels(pattern: str, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) intp: the channel (0 red, 1 green, 2 blue) each pixel of a `pattern` mosaic of `shape` records."""
    if pattern not in BAYER_PATTERNS:
        raise RaytraceError(f"pattern: expected one of {', '.join(BAYER_PATTERNS)}, got {pattern!r}")
    tile = np.array(["RGB".index(c) for c in pattern], dtype=np.intp).reshape(2, 2)
    h, w = shape
    return np.tile(tile, ((h + 1) // 2, (w + 1) // 2))[:h, :w]


def bayer_mosaic(image, pattern: str = "RGGB") -> np.ndarray:
    """(H, W), of the image's dtype: what a Bayer sensor with the colour filter tile `pattern` (`BAYER_PATTERNS`)
    records of an (H, W, 3) RGB image (uint8, uint16 or float), each pixel its own filter's channel."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3:
        raise RaytraceError(f"image: expected an (H, W, 3) RGB image (uint8, uint16 or float), got {img.dtype} "
                            f"{img.shape}")
    channel = bayer_channels(pattern, img.shape[:2])
    return np.take_along_axis(img, channel[..., None], axis=2)[..., 0]


def demosaiced(image, pattern: str = "RGGB") -> np.ndarray:
    """The (H, W, 3) uint8 RGB image a Bayer camera (filter tile `pattern`) makes of the uint8 RGB `image`: its mosaic
    (`bayer_mosaic`) demosaiced by OpenCV's variable number of gradients (`cv2.COLOR_Bayer...2RGB_VNG`). Each channel
    keeps its own samples; red and blue are interpolated over three pixels of four, green over one of two."""
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise RaytraceError(f"image: expected an (H, W, 3) uint8 RGB image, got {img.dtype} {img.shape}")
    return demosaiced_mosaic(bayer_mosaic(img, pattern), pattern)


def demosaiced_mosaic(mosaic, pattern: str = "RGGB") -> np.ndarray:
    """(H, W, 3) uint8 RGB: an (H, W) uint8 `pattern` mosaic of sRGB codes demosaiced by OpenCV's VNG (8-bit only)."""
    import cv2
    raw = np.asarray(mosaic)
    if raw.dtype != np.uint8 or raw.ndim != 2:
        raise RaytraceError(f"mosaic: expected an (H, W) uint8 mosaic, got {raw.dtype} {raw.shape}")
    bayer_channels(pattern, (2, 2))  # (the pattern checked)
    return cv2.cvtColor(np.ascontiguousarray(raw), getattr(cv2, f"COLOR_Bayer{pattern}2RGB_VNG"))
