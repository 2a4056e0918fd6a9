"""The XSlit frame of a two-slit fit: `XSlitFrame`, `interpolate_rays` and `frame_for_pixels`.

`XSlitFrame` is the frame of docs/CONVENTIONS.md in which the paper's equations hold: the
virtual image plane z = 0 is parallel to both slits, e_z points toward the scene, the origin
is where the slits' orthogonal projections onto the plane cross, and slit i is the line
{t·(cos θi, sin θi, 0) + (0, 0, z_i)} with |z1| < |z2|. It maps rays to plane points (u, v)
and those to the slit basis coordinates (κ_u, κ_v): (u, v) = κ_u·v1 + κ_v·v2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_array, as_rays, as_unit, as_vector
from .errors import FitError
from .fit import FailedFit, SlitFit, fit_two_slits
from .plucker import Line

__all__ = ["XSlitFrame", "PixelFrame", "interpolate_rays", "frame_for_pixels"]


@dataclass(frozen=True)
class XSlitFrame:
    """An XSlit frame (docs/CONVENTIONS.md) in world coordinates.

    Attributes
    ----------
    origin : (3,) float64
        World position of the frame origin (on the image plane z = 0).
    e_x, e_y, e_z : (3,) float64
        Orthonormal right-handed axes; e_z is the plane normal toward the scene.
    z1, z2 : float
        Signed depths of slit 1 and slit 2 along e_z (paper's z1, z2), |z1| < |z2|.
        Negative for the virtual slits of a convex mirror.
    theta1, theta2 : float
        Slit angles to e_x in radians (paper's θ1, θ2): θ1 ∈ (−π/2, π/2] (0 by default)
        and θ2 ∈ (θ1, θ1 + π), so that (v1, v2) is a right-handed basis.
    slits : tuple of two `Line`
        The slits in world coordinates, slit 1 first.
    """

    origin: np.ndarray
    e_x: np.ndarray
    e_y: np.ndarray
    e_z: np.ndarray
    z1: float
    z2: float
    theta1: float
    theta2: float
    slits: tuple

    @classmethod
    def from_fit(cls, fit: SlitFit, plane_point=None, e_x=None) -> "XSlitFrame":
        """Build the frame of a `SlitFit`.

        Parameters
        ----------
        fit : SlitFit
            A successful fit (a `FailedFit` raises `FitError`).
        plane_point : (3,) float64, optional
            A world point on the virtual image plane; default the rays' centroid.
        e_x : (3,) float64, optional
            In-plane x axis (projected onto the plane); default slit 1's direction (θ1 = 0).
        """
        if not isinstance(fit, SlitFit):
            raise FitError(f"fit: expected a successful SlitFit, got {fit!r}")
        c = fit.centroid if plane_point is None else as_vector(plane_point, "plane_point")
        n = fit.plane_normal
        slits = list(fit.slits)
        offsets = [float((s.point - c) @ n) for s in slits]
        if abs(offsets[1]) < abs(offsets[0]):
            slits, offsets = slits[::-1], offsets[::-1]
        d1, d2 = slits[0].direction, slits[1].direction
        p1 = slits[0].point - offsets[0] * n
        p2 = slits[1].point - offsets[1] * n
        ts = np.linalg.lstsq(np.stack([d1, -d2], axis=1), p2 - p1, rcond=None)[0]
        origin = p1 + ts[0] * d1
        if e_x is None:
            ex = d1
        else:
            ex = as_unit(e_x, "e_x")
            ex = ex - (ex @ n) * n
            if not np.linalg.norm(ex) > 1e-9:
                raise FitError("e_x: expected a direction not normal to the image plane")
            ex = ex / np.linalg.norm(ex)
        ey = np.cross(n, ex)
        th1 = 0.0 if e_x is None else float(np.arctan2(d1 @ ey, d1 @ ex))
        if th1 <= -np.pi / 2:
            th1 += np.pi
        elif th1 > np.pi / 2:
            th1 -= np.pi
        th2 = float(np.arctan2(d2 @ ey, d2 @ ex))
        th2 = th1 + float(np.mod(th2 - th1, np.pi))
        v1 = np.cos(th1) * ex + np.sin(th1) * ey
        v2 = np.cos(th2) * ex + np.sin(th2) * ey
        world_slits = (Line(origin + offsets[0] * n, v1), Line(origin + offsets[1] * n, v2))
        return cls(origin=origin, e_x=ex, e_y=ey, e_z=n, z1=offsets[0], z2=offsets[1],
                   theta1=th1, theta2=th2, slits=world_slits)

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) float64 with rows e_x, e_y, e_z: frame = rotation · (world − origin)."""
        return np.stack([self.e_x, self.e_y, self.e_z])

    @property
    def v1(self) -> np.ndarray:
        """(2,) in-plane direction of slit 1: (cos θ1, sin θ1)."""
        return np.array([np.cos(self.theta1), np.sin(self.theta1)])

    @property
    def v2(self) -> np.ndarray:
        """(2,) in-plane direction of slit 2: (cos θ2, sin θ2)."""
        return np.array([np.cos(self.theta2), np.sin(self.theta2)])

    def to_frame(self, points_world) -> np.ndarray:
        """World points (N, 3) → frame coordinates (x, y, z) (N, 3); z is the paper's depth z."""
        return (as_array(points_world, "points_world", 3) - self.origin) @ self.rotation.T

    def to_world(self, points_frame) -> np.ndarray:
        """Frame coordinates (N, 3) → world points (N, 3)."""
        return as_array(points_frame, "points_frame", 3) @ self.rotation + self.origin

    def directions_to_frame(self, directions_world) -> np.ndarray:
        """World directions (N, 3) → frame directions (N, 3) (rotation only)."""
        return as_array(directions_world, "directions_world", 3) @ self.rotation.T

    def rays_to_plane(self, points, directions) -> np.ndarray:
        """Where world rays meet the virtual image plane z = 0.

        Parameters
        ----------
        points, directions : (N, 3) float64
            World rays (any point on each ray).

        Returns
        -------
        (N, 2) float64
            Plane coordinates (u, v); NaN for rays parallel to the plane.
        """
        p, d = as_rays(points, directions)
        pf = (p - self.origin) @ self.rotation.T
        df = d @ self.rotation.T
        ok = np.abs(df[:, 2]) > 1e-12
        t = np.where(ok, -pf[:, 2] / np.where(ok, df[:, 2], 1.0), np.nan)
        return pf[:, :2] + t[:, None] * df[:, :2]

    def kappa(self, uv) -> np.ndarray:
        """Plane points (u, v) (N, 2) → slit-basis coordinates (κ_u, κ_v) (N, 2),
        with (u, v) = κ_u·v1 + κ_v·v2."""
        basis = np.stack([self.v1, self.v2], axis=1)
        return np.linalg.solve(basis, as_array(uv, "uv", 2).T).T

    def from_kappa(self, kappa) -> np.ndarray:
        """(κ_u, κ_v) (N, 2) → plane points (u, v) = κ_u·v1 + κ_v·v2 (N, 2).

        The same map takes a scene point's (κ_x, κ_y) to its frame (x, y)."""
        return as_array(kappa, "kappa", 2) @ np.stack([self.v1, self.v2])

    def to_dict(self) -> dict:
        """Plain-float dictionary (world coordinates, metres, radians)."""
        return {
            "origin": self.origin.tolist(), "e_x": self.e_x.tolist(),
            "e_y": self.e_y.tolist(), "e_z": self.e_z.tolist(),
            "z1": self.z1, "z2": self.z2, "theta1": self.theta1, "theta2": self.theta2,
            "slits": [s.to_dict() for s in self.slits],
        }


def _as_ray_map(ray_points, ray_dirs, valid):
    p = np.asarray(ray_points, dtype=np.float64)
    d = np.asarray(ray_dirs, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3:
        raise FitError(f"ray_points: expected shape (H, W, 3), got {p.shape}")
    if d.shape != p.shape:
        raise FitError(f"ray_dirs: expected the shape of ray_points {p.shape}, got {d.shape}")
    if valid is None:
        v = np.all(np.isfinite(p), axis=2) & np.all(np.isfinite(d), axis=2)
    else:
        v = np.asarray(valid, dtype=bool)
        if v.shape != p.shape[:2]:
            raise FitError(f"valid: expected shape {p.shape[:2]}, got {v.shape}")
    return p, d, v


def interpolate_rays(ray_points, ray_dirs, pixels, valid=None):
    """Rays at sub-pixel positions, by bilinear interpolation of a per-pixel ray map.

    Bilinear interpolation of mirror points and directions is exact to second order in the
    pixel step; for exact sub-pixel rays, trace the camera ray of the sub-pixel position and
    reflect it on the analytic mirror (raytrace), then call `XSlitFrame.rays_to_plane`.

    Parameters
    ----------
    ray_points, ray_dirs : (H, W, 3) float64
        Per-pixel reflected rays (mirror point, direction toward the scene).
    pixels : (N, 2) float64
        Sub-pixel positions (u, v) = (column, row); pixel (0, 0) is the top-left pixel centre.
    valid : (H, W) bool, optional
        Pixels that carry a ray; default: finite entries.

    Returns
    -------
    points (N, 3), directions (N, 3) float64 and ok (N,) bool. Rows with ok False (outside
    the image or next to an invalid pixel) are NaN.
    """
    p, d, v = _as_ray_map(ray_points, ray_dirs, valid)
    px = as_array(pixels, "pixels", 2)
    h, w = v.shape
    if h < 2 or w < 2:
        raise FitError(f"ray_points: expected at least 2 x 2 pixels, got {h} x {w}")
    u, r = px[:, 0], px[:, 1]
    inside = (u >= 0) & (u <= w - 1) & (r >= 0) & (r <= h - 1)
    j0 = np.clip(np.floor(np.where(inside, u, 0)).astype(int), 0, w - 2)
    i0 = np.clip(np.floor(np.where(inside, r, 0)).astype(int), 0, h - 2)
    fu = np.where(inside, u - j0, 0.0)[:, None]
    fv = np.where(inside, r - i0, 0.0)[:, None]
    corners = [(i0, j0, (1 - fu) * (1 - fv)), (i0, j0 + 1, fu * (1 - fv)),
               (i0 + 1, j0, (1 - fu) * fv), (i0 + 1, j0 + 1, fu * fv)]
    ok = inside.copy()
    pts = np.zeros((len(px), 3))
    dirs = np.zeros((len(px), 3))
    for i, j, wgt in corners:
        ok &= v[i, j]
        pts += wgt * np.nan_to_num(p[i, j])
        dirs += wgt * np.nan_to_num(d[i, j])
    norm = np.linalg.norm(dirs, axis=1)
    ok &= norm > 0
    dirs = dirs / np.where(norm > 0, norm, 1.0)[:, None]
    pts[~ok] = np.nan
    dirs[~ok] = np.nan
    return pts, dirs, ok


@dataclass(frozen=True)
class PixelFrame:
    """Result of `frame_for_pixels` (truthy).

    Attributes
    ----------
    frame : XSlitFrame
    fit : SlitFit
        The two-slit fit over the pixels' neighbourhood.
    points, directions : (N, 3) float64
        The interpolated rays of the requested pixels.
    uv : (N, 2) float64
        Where those rays meet the frame's image plane.
    kappa : (N, 2) float64
        (κ_u, κ_v) of `uv` on the slit basis v1, v2.
    """

    frame: XSlitFrame
    fit: SlitFit
    points: np.ndarray
    directions: np.ndarray
    uv: np.ndarray
    kappa: np.ndarray

    def __bool__(self) -> bool:
        return True


def frame_for_pixels(ray_points, ray_dirs, pixels, valid=None, margin: int = 2,
                     plane_point=None, e_x=None, **fit_options):
    """Fit the local XSlit around some pixels and map those pixels into its frame.

    The slits are fitted to every valid ray of the pixels' bounding box grown by `margin`
    pixels; the pixels' rays (bilinear sub-pixel interpolation, see `interpolate_rays`) are
    then mapped to (u, v) and (κ_u, κ_v) on the frame's image plane.

    Parameters
    ----------
    ray_points, ray_dirs : (H, W, 3) float64
        Per-pixel reflected rays.
    pixels : (N, 2) float64
        Sub-pixel positions (u, v) = (column, row), e.g. the corners of a cube face.
    valid : (H, W) bool, optional
    margin : int
        Pixels added around the bounding box of `pixels` for the fit.
    plane_point, e_x : optional
        Passed to `XSlitFrame.from_fit`.
    **fit_options
        Passed to `fit_two_slits`.

    Returns
    -------
    PixelFrame, or the falsy `FailedFit` of the fit (reason "too few rays" when a pixel
    has no interpolable ray).
    """
    p, d, v = _as_ray_map(ray_points, ray_dirs, valid)
    px = as_array(pixels, "pixels", 2)
    pts, dirs, ok = interpolate_rays(p, d, px, v)
    if not np.all(ok):
        return FailedFit("too few rays", 0,
                         detail=f"pixels {px[~ok].tolist()} have no interpolable ray")
    h, w = v.shape
    j0 = max(int(np.floor(px[:, 0].min())) - margin, 0)
    j1 = min(int(np.ceil(px[:, 0].max())) + margin + 1, w)
    i0 = max(int(np.floor(px[:, 1].min())) - margin, 0)
    i1 = min(int(np.ceil(px[:, 1].max())) + margin + 1, h)
    box = v[i0:i1, j0:j1]
    fit = fit_two_slits(p[i0:i1, j0:j1][box], d[i0:i1, j0:j1][box], **fit_options)
    if not fit:
        return fit
    frame = XSlitFrame.from_fit(fit, plane_point=plane_point, e_x=e_x)
    uv = frame.rays_to_plane(pts, dirs)
    return PixelFrame(frame=frame, fit=fit, points=pts, directions=dirs, uv=uv,
                      kappa=frame.kappa(uv))
