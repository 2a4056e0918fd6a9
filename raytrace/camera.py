"""Cameras: `PinholeCamera`, the ideal two-slit `XSlitCamera` and `PushbroomCamera`.

Every camera maps pixels (u, v) = (column, row) to world rays with `rays` and world points
back to pixels with `project`; `sample_offsets` gives a reproducible stratified sub-pixel pattern
and `pixel_sample_offsets` that pattern rotated differently in every pixel.
Conventions are those of docs/CONVENTIONS.md (OpenCV pinhole, pixel (0, 0) is the centre of
the top-left pixel). A pinhole camera may carry a lens's distortion, OpenCV's model (`raytrace.lens`):
its rays and projections then bend by it, so everything built on them does. Its `response` says how the
8-bit values it stores relate to linear light (`raytrace.response`; None: sRGB).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._validate import (
    as_finite,
    as_intrinsics,
    as_points,
    as_positive,
    as_resolution,
    as_rotation,
    as_vector,
)
from .errors import RaytraceError
from .chroma import CHANNELS, ChannelLens, as_channel_lens
from .lens import as_distortion, distort, distortion_jacobian, undistort
from .response import CameraResponse, as_response

__all__ = ["PinholeCamera", "distortion_fold", "XSlitCamera", "PushbroomCamera", "sample_offsets",
           "pixel_sample_offsets", "pixel_grid"]


def pixel_grid(resolution: tuple[int, int]) -> np.ndarray:
    """Pixel centres of a W×H image in row-major order.

    Returns
    -------
    pixels : (H*W, 2) float64
        (u, v) = (column, row); row ``k`` is pixel ``(k % W, k // W)``.
    """
    w, h = as_resolution(resolution)
    v, u = np.divmod(np.arange(w * h, dtype=np.int64), w)
    return np.stack([u, v], axis=1).astype(np.float64)


def sample_offsets(spp: int, seed: int = 0) -> np.ndarray:
    """Stratified jittered sub-pixel offsets, reproducible byte for byte for a given seed.

    A perfect square ``spp = n²`` gives one jittered sample per cell of an n×n grid;
    other counts give a Latin-hypercube (N-rooks) pattern, stratified along both axes.
    The first offset is always the pixel centre when ``spp == 1``.

    Returns
    -------
    offsets : (spp, 2) float64
        (du, dv) in [-0.5, 0.5), added to pixel centres.
    """
    if isinstance(spp, bool) or not isinstance(spp, (int, np.integer)) or spp < 1:
        raise RaytraceError(f"spp: expected a positive integer, got {spp!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise RaytraceError(f"seed: expected a non-negative integer, got {seed!r}")
    spp = int(spp)
    if spp == 1:
        return np.zeros((1, 2))
    rng = np.random.default_rng(int(seed))
    n = int(round(np.sqrt(spp)))
    if n * n == spp:
        j, i = np.divmod(np.arange(spp), n)
        cells = np.stack([i, j], axis=1).astype(np.float64)
        offsets = (cells + rng.random((spp, 2))) / n
    else:
        perm_u = rng.permutation(spp)
        perm_v = rng.permutation(spp)
        jitter = rng.random((spp, 2))
        offsets = np.stack([(perm_u + jitter[:, 0]) / spp, (perm_v + jitter[:, 1]) / spp], axis=1)
    return offsets - 0.5


def _splitmix64(x: np.ndarray) -> np.ndarray:
    """The splitmix64 finaliser on uint64 arrays (wrapping arithmetic): a counter-based hash."""
    x = (x + np.uint64(0x9E3779B97F4A7C15)) & np.uint64(0xFFFFFFFFFFFFFFFF)
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def pixel_sample_offsets(pixels, spp: int, seed: int = 0) -> np.ndarray:
    """Sub-pixel sample offsets for the given flat pixel indices: `sample_offsets(spp, seed)`
    toroidally shifted (Cranley–Patterson rotation) by a per-pixel amount hashed from (seed, pixel).

    Every pixel keeps a stratified pattern, each sample is uniform over its pixel (so a pixel's
    mean is an unbiased estimate of its area average) and neighbouring pixels' errors are
    independent. One pattern shared by all pixels would instead give a straight edge the same
    coverage error in every pixel along it: an aliased, systematically shifted edge. The result
    depends only on (pixel, spp, seed), not on how the pixels are split among workers.

    Returns
    -------
    offsets : (N, spp, 2) float64 in [-0.5, 0.5)
    """
    base = sample_offsets(spp, seed) + 0.5
    if spp == 1:
        return np.zeros((len(np.atleast_1d(pixels)), 1, 2))
    idx = np.asarray(pixels, dtype=np.int64).astype(np.uint64).reshape(-1)
    h = _splitmix64(idx * np.uint64(2) + _splitmix64(np.full(1, seed, dtype=np.uint64)))
    h2 = _splitmix64(h)
    shift = np.stack([h >> np.uint64(11), h2 >> np.uint64(11)], axis=1).astype(np.float64) * 2.0**-53
    return np.mod(base[None, :, :] + shift[:, None, :], 1.0) - 0.5


def distortion_fold(resolution, K, distortion) -> tuple[float, float] | None:
    """Where a pinhole camera's `distortion` (`raytrace.lens.as_distortion`'s, or None) fails to map a region
    onto its image one-to-one: a pixel (u, v) of a grid over the image of `resolution` (W, H) and its border
    (1 px beyond it) that does not undistort through the intrinsics `K` (3, 3), or where the distortion's
    Jacobian is not positive; None where there is none (or no distortion)."""
    if distortion is None:
        return None
    w, h = resolution
    gu, gv = np.meshgrid(np.linspace(-1.0, w, 65), np.linspace(-1.0, h, 49))
    edge = np.linspace(0.0, 1.0, 257)
    px = np.concatenate([np.column_stack([gu.ravel(), gv.ravel()]),
                         np.column_stack([-1.0 + (w + 1.0) * edge, np.full_like(edge, -1.0)]),
                         np.column_stack([-1.0 + (w + 1.0) * edge, np.full_like(edge, float(h))]),
                         np.column_stack([np.full_like(edge, -1.0), -1.0 + (h + 1.0) * edge]),
                         np.column_stack([np.full_like(edge, float(w)), -1.0 + (h + 1.0) * edge])])
    xy, err = undistort(_normalized(K, px), distortion)
    J = distortion_jacobian(xy, distortion)
    det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
    bad = ~((err <= 1e-10) & (det > 0))
    return tuple(float(v) for v in px[np.argmax(bad)]) if bad.any() else None


def _normalized(K, px: np.ndarray) -> np.ndarray:
    """K⁻¹ (u, v, 1)'s first two coordinates, (N, 2): the (distorted) normalised points of pixels (N, 2)."""
    Kinv = np.linalg.inv(np.asarray(K, dtype=np.float64))
    return px @ Kinv[:2, :2].T + Kinv[:2, 2]


def _normalize_rows(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@dataclass(frozen=True)
class PinholeCamera:
    """A pinhole camera with OpenCV conventions.

    Attributes
    ----------
    resolution : (W, H) ints
    K : (3, 3) float64
        Intrinsics [[fx, s, cx], [0, fy, cy], [0, 0, 1]].
    R : (3, 3) float64
        World→camera rotation; rows are the camera axes x (right), y (down), z (forward).
    position : (3,) float64
        Camera centre in the world.
    distortion : (8,) float64 or None
        The lens's distortion, OpenCV's (k1, k2, p1, p2, k3, k4, k5, k6) (`raytrace.lens`; 4, 5 or 8
        numbers are accepted); None (or all zero): an ideal pinhole. It must be one-to-one over the image.
    response : raytrace.response.CameraResponse or None
        How the 8-bit values of its images relate to linear light (`as_response`'s values are accepted);
        None (or "srgb"): sRGB.
    red, blue : raytrace.chroma.ChannelLens or None
        That colour channel's own K and distortion (lateral chromatic aberration, `raytrace.chroma`), where
        `K` and `distortion` are green's; None: the camera's own.
    """

    resolution: tuple[int, int]
    K: np.ndarray
    R: np.ndarray
    position: np.ndarray
    distortion: np.ndarray | None = None
    response: CameraResponse | None = None
    red: ChannelLens | None = None
    blue: ChannelLens | None = None
    is_central: bool = field(default=True, init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "resolution", as_resolution(self.resolution))
        object.__setattr__(self, "K", as_intrinsics(self.K))
        object.__setattr__(self, "R", as_rotation(self.R, "R"))
        object.__setattr__(self, "position", as_vector(self.position, "position"))
        object.__setattr__(self, "distortion", as_distortion(self.distortion))
        object.__setattr__(self, "response", as_response(self.response))
        if self.distortion is not None:
            self._check_one_to_one(self.K, self.distortion, "distortion")
        for channel in CHANNELS:
            lens = as_channel_lens(getattr(self, channel), channel)
            if lens is not None and lens.distortion is not None:
                self._check_one_to_one(lens.K, lens.distortion, f"{channel}.distortion")

    def _check_one_to_one(self, K, distortion, name) -> None:
        """Raise unless the distortion is one-to-one over the image (`distortion_fold`)."""
        fold = distortion_fold(self.resolution, K, distortion)
        if fold is not None:
            raise RaytraceError(f"{name}: expected coefficients whose distortion is one-to-one over the image; "
                                f"it folds near pixel ({fold[0]:.0f}, {fold[1]:.0f}) "
                                f"(coefficients {distortion.tolist()})")

    @property
    def has_channel_lenses(self) -> bool:
        """Whether a colour channel images the scene through a lens of its own (`red`, `blue`)."""
        return self.red is not None or self.blue is not None

    def channel_camera(self, channel: str) -> "PinholeCamera":
        """The camera `channel` ("red", "green" or "blue") sees the scene through: this one's pose, response and
        resolution with that channel's K and distortion (its own where it has none), and no channel lenses."""
        if channel not in ("green",) + CHANNELS:
            raise RaytraceError(f"channel: expected red, green or blue, got {channel!r}")
        lens = None if channel == "green" else getattr(self, channel)
        if lens is None:
            return PinholeCamera(self.resolution, self.K, self.R, self.position, self.distortion, self.response)
        return PinholeCamera(self.resolution, lens.K, self.R, self.position, lens.distortion, self.response)

    def undistorted_pixels(self, pixels) -> np.ndarray:
        """Where this camera without its distortion images what it images at `pixels` (N, 2): (N, 2) pixels."""
        px = as_points(pixels, "pixels", width=2)
        if self.distortion is None:
            return px
        xy, _ = undistort(_normalized(self.K, px), self.distortion)
        return xy @ self.K[:2, :2].T + self.K[:2, 2]

    @classmethod
    def from_look_at(cls, resolution, focal_px, principal_px=None, position=None, look_at=None, up=(0.0, 1.0, 0.0),
                     distortion=None, response=None, red=None, blue=None):
        """Build a camera from the setup contract's keys.

        Parameters
        ----------
        resolution : (W, H)
        focal_px : float or (fx, fy), pixels, > 0
        position, look_at, up : (3,) world
        principal_px : (cx, cy) or None for ((W-1)/2, (H-1)/2)
        distortion : OpenCV's (k1, k2, p1, p2[, k3[, k4, k5, k6]]) or None for an ideal pinhole
        response : how its 8-bit values relate to linear light (`raytrace.response.as_response`); None: sRGB
        red, blue : that colour channel's own `raytrace.chroma.ChannelLens`, or None
        """
        w, h = as_resolution(resolution)
        f = np.atleast_1d(np.asarray(focal_px, dtype=np.float64)) if focal_px is not None else None
        if f is None or f.shape not in ((1,), (2,)):
            raise RaytraceError(f"focal_px: expected one or two numbers [fx, fy], got {focal_px!r}")
        if not np.all(np.isfinite(f)) or not np.all(f > 0):
            raise RaytraceError(f"focal_px: expected positive finite focal lengths, got {f.tolist()}")
        fx, fy = (f[0], f[0]) if f.shape == (1,) else (f[0], f[1])
        if principal_px is None:
            cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
        else:
            cx, cy = as_vector(principal_px, "principal_px", size=2)
        if position is None or look_at is None:
            raise RaytraceError("position, look_at: expected two world points, got None")
        position = as_vector(position, "position")
        look_at = as_vector(look_at, "look_at")
        up = as_vector(up, "up")
        if not np.linalg.norm(up) > 1e-12:
            raise RaytraceError(f"up: expected a non-zero direction, got {up.tolist()}")
        view = look_at - position
        if not np.linalg.norm(view) > 1e-12:
            raise RaytraceError("look_at: expected a point different from position")
        z = view / np.linalg.norm(view)
        x = np.cross(z, up / np.linalg.norm(up))
        if not np.linalg.norm(x) > 1e-9:
            raise RaytraceError("up: expected a direction not parallel to the view direction (look_at - position)")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        return cls(resolution=(w, h), K=K, R=np.stack([x, y, z]), position=position, distortion=distortion,
                   response=response, red=red, blue=blue)

    @property
    def width(self) -> int:
        return self.resolution[0]

    @property
    def height(self) -> int:
        return self.resolution[1]

    def pixel_grid(self) -> np.ndarray:
        """Pixel centres, (H*W, 2) float64, row-major (see `pixel_grid`)."""
        return pixel_grid(self.resolution)

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """Rays through pixel positions.

        Parameters
        ----------
        pixels : (N, 2) float64, (u, v)

        Returns
        -------
        origins : (N, 3) float64, all equal to `position`
        directions : (N, 3) float64, unit
        """
        px = as_points(pixels, "pixels", width=2)
        if self.distortion is None:
            Kinv = np.linalg.inv(self.K)
            d_cam = px @ Kinv[:, :2].T + Kinv[:, 2]
        else:
            xy, _ = undistort(_normalized(self.K, px), self.distortion)
            d_cam = np.column_stack([xy, np.ones(len(xy))])
        d = _normalize_rows(d_cam @ self.R)
        return np.broadcast_to(self.position, d.shape).copy(), d

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Project world points.

        Parameters
        ----------
        points : (N, 3) float64

        Returns
        -------
        pixels : (N, 2) float64, (u, v); meaningless where ``z_cam <= 0``
        z_cam : (N,) float64, depth along the optical axis
        """
        p = as_points(points, "points")
        xc = (p - self.position) @ self.R.T
        if self.distortion is None:
            uvw = xc @ self.K.T
            with np.errstate(divide="ignore", invalid="ignore"):
                pix = uvw[:, :2] / uvw[:, 2:3]
            return pix, xc[:, 2].copy()
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = distort(xc[:, :2] / xc[:, 2:3], self.distortion)
        return xy @ self.K[:2, :2].T + self.K[:2, 2], xc[:, 2].copy()


@dataclass(frozen=True)
class XSlitCamera:
    """An ideal two-slit (XSlit) camera whose image plane is parallel to both slits.

    In the camera's XSlit frame (docs/CONVENTIONS.md) the image plane is z = 0, scene points
    have z > 0, and slit i is the line { t·(cos θi, sin θi, 0) + (0, 0, z_i) }. A pixel (u, v)
    sits at the plane point ((u - cx)·pitch, (v - cy)·pitch, 0); its ray passes through both
    slits and travels toward +z.

    Attributes
    ----------
    resolution : (W, H)
    z1, z2 : float
        Slit depths (paper z1, z2), non-zero and different; negative for a convex mirror.
    theta1, theta2 : float
        Slit angles θ1, θ2 in radians, not parallel.
    pitch : float
        Pixel pitch on the image plane, metres per pixel.
    origin : (3,) float64
        World position of the frame origin (on the image plane).
    frame : (3, 3) float64
        Rows e_x, e_y, e_z of the XSlit frame in world coordinates.
    principal_px : (cx, cy) or None for the image centre.
    """

    resolution: tuple[int, int]
    z1: float
    z2: float
    theta1: float = 0.0
    theta2: float = np.pi / 2
    pitch: float = 1e-4
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    frame: np.ndarray = field(default_factory=lambda: np.eye(3))
    principal_px: tuple[float, float] | None = None
    is_central: bool = field(default=False, init=False, repr=False)

    def __post_init__(self):
        w, h = as_resolution(self.resolution)
        object.__setattr__(self, "resolution", (w, h))
        z1, z2 = as_finite(self.z1, "z1"), as_finite(self.z2, "z2")
        if z1 == 0 or z2 == 0:
            raise RaytraceError(f"z1, z2: expected non-zero slit depths, got {z1}, {z2}")
        if z1 == z2:
            raise RaytraceError(f"z1, z2: expected two different slit depths, got {z1} twice")
        t1, t2 = as_finite(self.theta1, "theta1"), as_finite(self.theta2, "theta2")
        if abs(np.sin(t2 - t1)) < 1e-9:
            raise RaytraceError("theta1, theta2: expected non-parallel slits")
        object.__setattr__(self, "z1", z1)
        object.__setattr__(self, "z2", z2)
        object.__setattr__(self, "theta1", t1)
        object.__setattr__(self, "theta2", t2)
        object.__setattr__(self, "pitch", as_positive(self.pitch, "pitch"))
        object.__setattr__(self, "origin", as_vector(self.origin, "origin"))
        object.__setattr__(self, "frame", as_rotation(self.frame, "frame"))
        if self.principal_px is None:
            object.__setattr__(self, "principal_px", ((w - 1) / 2.0, (h - 1) / 2.0))
        else:
            object.__setattr__(self, "principal_px", tuple(as_vector(self.principal_px, "principal_px", 2)))

    @property
    def v1(self) -> np.ndarray:
        """Slit-1 direction in the image plane, (cos θ1, sin θ1)."""
        return np.array([np.cos(self.theta1), np.sin(self.theta1)])

    @property
    def v2(self) -> np.ndarray:
        """Slit-2 direction in the image plane, (cos θ2, sin θ2)."""
        return np.array([np.cos(self.theta2), np.sin(self.theta2)])

    def pixel_grid(self) -> np.ndarray:
        """Pixel centres, (H*W, 2) float64, row-major."""
        return pixel_grid(self.resolution)

    def _plane_points(self, px: np.ndarray) -> np.ndarray:
        cx, cy = self.principal_px
        return np.stack([(px[:, 0] - cx) * self.pitch, (px[:, 1] - cy) * self.pitch], axis=1)

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """Rays through pixel positions and both slits.

        Parameters
        ----------
        pixels : (N, 2) float64

        Returns
        -------
        origins : (N, 3) float64, on the image plane (world)
        directions : (N, 3) float64, unit, toward +e_z
        """
        px = as_points(pixels, "pixels", width=2)
        p = self._plane_points(px)
        # slit i meets the ray p + λ(d, 1) at λ = z_i: n_i·(p + z_i d) = 0 with n_i ⟂ v_i.
        n1 = np.array([-np.sin(self.theta1), np.cos(self.theta1)])
        n2 = np.array([-np.sin(self.theta2), np.cos(self.theta2)])
        A = np.stack([n1, n2])
        b = np.stack([-(p @ n1) / self.z1, -(p @ n2) / self.z2], axis=1)
        dxy = b @ np.linalg.inv(A).T
        d_local = _normalize_rows(np.concatenate([dxy, np.ones((len(p), 1))], axis=1))
        o_local = np.concatenate([p, np.zeros((len(p), 1))], axis=1)
        return o_local @ self.frame + self.origin, d_local @ self.frame

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Project world points with the paper's Eqn. pinproj.

        κ_u = −z2/(z − z2)·κ_x, κ_v = −z1/(z − z1)·κ_y in the basis v1, v2.

        Returns
        -------
        pixels : (N, 2) float64
        z : (N,) float64, distance from the image plane along e_z
        """
        p = as_points(points, "points")
        local = (p - self.origin) @ self.frame.T
        B = np.stack([self.v1, self.v2], axis=1)  # columns v1, v2
        kappa = local[:, :2] @ np.linalg.inv(B).T  # (κ_x, κ_y)
        z = local[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            ku = -self.z2 / (z - self.z2) * kappa[:, 0]
            kv = -self.z1 / (z - self.z1) * kappa[:, 1]
        plane = np.stack([ku, kv], axis=1) @ B.T
        cx, cy = self.principal_px
        pix = np.stack([plane[:, 0] / self.pitch + cx, plane[:, 1] / self.pitch + cy], axis=1)
        return pix, z.copy()


@dataclass(frozen=True)
class PushbroomCamera:
    """A linear pushbroom camera: perspective across the sensor line, orthographic along the motion.

    In its local frame (rows of `frame`: e_x motion, e_y sensor line, e_z view) pixel (u, v)
    has origin ((u - cx)·step, 0, 0) and direction ∝ (0, (v - cy)/f, 1). It is the XSlit
    camera whose slit 2 is the motion line at infinity and slit 1 the sensor's line of pinholes.

    Attributes
    ----------
    resolution : (W, H)
    focal_px : float, > 0, perspective focal length across the sensor line
    step : float, > 0, metres travelled per column
    origin : (3,), frame : (3, 3) rows e_x, e_y, e_z
    principal_px : (cx, cy) or None for the image centre
    """

    resolution: tuple[int, int]
    focal_px: float
    step: float
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    frame: np.ndarray = field(default_factory=lambda: np.eye(3))
    principal_px: tuple[float, float] | None = None
    is_central: bool = field(default=False, init=False, repr=False)

    def __post_init__(self):
        w, h = as_resolution(self.resolution)
        object.__setattr__(self, "resolution", (w, h))
        object.__setattr__(self, "focal_px", as_positive(self.focal_px, "focal_px"))
        object.__setattr__(self, "step", as_positive(self.step, "step"))
        object.__setattr__(self, "origin", as_vector(self.origin, "origin"))
        object.__setattr__(self, "frame", as_rotation(self.frame, "frame"))
        if self.principal_px is None:
            object.__setattr__(self, "principal_px", ((w - 1) / 2.0, (h - 1) / 2.0))
        else:
            object.__setattr__(self, "principal_px", tuple(as_vector(self.principal_px, "principal_px", 2)))

    def pixel_grid(self) -> np.ndarray:
        """Pixel centres, (H*W, 2) float64, row-major."""
        return pixel_grid(self.resolution)

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """origins (N, 3), unit directions (N, 3) of pixels (N, 2)."""
        px = as_points(pixels, "pixels", width=2)
        cx, cy = self.principal_px
        n = len(px)
        o_local = np.zeros((n, 3))
        o_local[:, 0] = (px[:, 0] - cx) * self.step
        d_local = np.stack([np.zeros(n), (px[:, 1] - cy) / self.focal_px, np.ones(n)], axis=1)
        return o_local @ self.frame + self.origin, _normalize_rows(d_local) @ self.frame

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """pixels (N, 2) and depth z (N,) of world points (N, 3)."""
        p = as_points(points, "points")
        local = (p - self.origin) @ self.frame.T
        cx, cy = self.principal_px
        with np.errstate(divide="ignore", invalid="ignore"):
            v = self.focal_px * local[:, 1] / local[:, 2] + cy
        u = local[:, 0] / self.step + cx
        return np.stack([u, v], axis=1), local[:, 2].copy()
