"""XSlit panoramas from a translating pinhole camera: `LinearPanorama` (stitched rays, their two slits).

A pinhole camera (intrinsics K, world→camera rotation R, OpenCV conventions) moves along a straight
line: frame k has its centre at c_k = c_0 + k·s·m (m the unit motion direction, s the step per frame).
Panorama column k is source column u_k = u_0 + α·k of frame k (α the column rate), every row kept
(Zomet et al.'s linearly varying column schedule). Panorama pixel (k, v) is the pinhole ray of
source pixel (u_k, v) of frame k; a fractional k is the continuous motion between frames.

Slits (derivation, camera coordinates of frame 0, K without skew, m ⟂ optical axis):
with a = (u_0 − cx)/fx and b = α/fx, ray (k, y) has origin k·s·m and direction (a + b·k, y, 1).

- Slit A is the trajectory {c_0 + t·m}: every ray starts on it.
- The column plane of frame k contains c_k and the directions (0, 1, 0) and (a + b·k, 0, 1); its
  trace in the x-z plane, x = k·s·m_x + (z − 0)·(a + b·k), passes for every k through
  z = Z_B = −s·m_x/b = −s·m_x·fx/α, x = a·Z_B. Slit B is the camera-y line through
  (a·Z_B, 0, Z_B): it lies in every column plane, so it meets every ray of every column.

Both slits are parallel to the camera's image plane, so the XSlit frame's plane normal e_z is the
optical axis; with the virtual image plane at camera depth Z_p (`plane_depth`) the slit depths are
−Z_p (trajectory) and Z_B − Z_p (paper's z1, z2 after ordering |z1| < |z2|). A motion with a
component along the optical axis makes the rays a general linear complex (no two slits) and is
refused; α = 0 (one fixed column) is a pushbroom (slit B at infinity) and is refused too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_array, as_unit, as_vector
from .errors import FitError
from .frame import XSlitFrame
from .plucker import Line

__all__ = ["LinearPanorama"]

_PERP_TOL = 1e-9


@dataclass(frozen=True)
class LinearPanorama:
    """Columns u_0 + α·k of frames k = 0 … n_frames − 1 of a pinhole camera translating along a line.

    Attributes
    ----------
    K : (3, 3) float64, intrinsics [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)
    R : (3, 3) float64, world→camera rotation (rows: camera x, y, z in the world)
    position : (3,) float64, camera centre c_0 of frame 0
    motion : (3,) float64, unit motion direction m (normalised here)
    step : float > 0, distance s travelled per frame (world units)
    column0 : float, source column u_0 of frame 0
    column_rate : float != 0, source columns α added per frame
    n_frames : int >= 2, panorama width W
    height : int >= 2, rows kept, the panorama height H (source rows 0 … H − 1)
    """

    K: np.ndarray
    R: np.ndarray
    position: np.ndarray
    motion: np.ndarray
    step: float
    column0: float
    column_rate: float
    n_frames: int
    height: int

    def __post_init__(self):
        K = as_array(self.K, "K", 3)
        if K.shape != (3, 3) or not (K[0, 0] > 0 and K[1, 1] > 0):
            raise FitError(f"K: expected 3x3 intrinsics with positive fx, fy, got {np.asarray(self.K).tolist()}")
        if K[0, 1] != 0 or K[1, 0] != 0 or not np.allclose(K[2], [0.0, 0.0, 1.0]):
            raise FitError("K: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)")
        R = as_array(self.R, "R", 3)
        if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise FitError("R: expected a 3x3 rotation matrix")
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "position", as_vector(self.position, "position"))
        object.__setattr__(self, "motion", as_unit(self.motion, "motion"))
        for name in ("step", "column0", "column_rate"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not np.isfinite(v):
                raise FitError(f"{name}: expected a finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not self.step > 0:
            raise FitError(f"step: expected a positive distance per frame, got {self.step}")
        if self.column_rate == 0:
            raise FitError("column_rate: expected a non-zero rate; one fixed column is a pushbroom (slit at infinity)")
        for name in ("n_frames", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 2:
                raise FitError(f"{name}: expected an integer >= 2, got {v!r}")
            object.__setattr__(self, name, int(v))

    @classmethod
    def from_camera(cls, camera, motion, step, column0, column_rate, n_frames) -> "LinearPanorama":
        """The panorama of a pinhole `camera` (anything with K, R, position, resolution) at frame 0."""
        for attr in ("K", "R", "position", "resolution"):
            if not hasattr(camera, attr):
                raise FitError(f"camera: expected a pinhole camera with `{attr}`, got {type(camera).__name__}")
        return cls(camera.K, camera.R, camera.position, motion, step, column0, column_rate, n_frames,
                   int(camera.resolution[1]))

    # -- the stitched image -------------------------------------------------------------------------
    @property
    def resolution(self) -> tuple[int, int]:
        """(W, H) = (n_frames, height)."""
        return (self.n_frames, self.height)

    def frame_position(self, k) -> np.ndarray:
        """Camera centres c_k = c_0 + k·s·m of frames k : (N,) → (N, 3) float64."""
        k = np.asarray(k, dtype=np.float64).reshape(-1)
        return self.position + (k * self.step)[:, None] * self.motion

    def source_column(self, k) -> np.ndarray:
        """Source column u_k = u_0 + α·k of frames k : (N,) → (N,) float64."""
        return self.column0 + self.column_rate * np.asarray(k, dtype=np.float64)

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """Rays of panorama pixels (N, 2) = (k, v): origins c_k (N, 3), unit directions (N, 3) of source
        pixel (u_k, v) of frame k (the pinhole camera's own ray)."""
        px = as_array(pixels, "pixels", 2)
        k, v = px[:, 0], px[:, 1]
        src = np.column_stack([self.source_column(k), v, np.ones(len(px))])
        d_cam = src @ np.linalg.inv(self.K).T
        d = d_cam @ self.R
        return self.frame_position(k), d / np.linalg.norm(d, axis=1, keepdims=True)

    # -- its two slits --------------------------------------------------------------------------------
    def slit_depth(self) -> float:
        """Z_B = −s·m_x·fx/α: camera depth (frame 0) of the non-trajectory slit (slit B)."""
        m_cam = self.R @ self.motion
        self._check_motion(m_cam)
        return float(-self.step * m_cam[0] * self.K[0, 0] / self.column_rate)

    def _check_motion(self, m_cam: np.ndarray) -> None:
        if abs(m_cam[2]) > _PERP_TOL:
            raise FitError(f"motion: expected a direction perpendicular to the optical axis, got a component "
                           f"{m_cam[2]:.3g} along it; the stitched rays then have no two slits")
        if abs(m_cam[0]) < 1e-6:
            raise FitError("motion: expected a component along the camera's x axis (the columns' normal); "
                           "motion along the columns gives a slit at infinity")

    def slits(self, plane_depth: float = 1.0) -> XSlitFrame:
        """The XSlit frame (docs/CONVENTIONS.md) of the stitched rays, derived from the trajectory and
        the column schedule (see the module docstring).

        plane_depth : Z_p, camera depth (frame 0) of the virtual image plane, != 0 and != Z_B.
        The frame's e_x is slit 1's direction (θ1 = 0); z1, z2 are −Z_p and Z_B − Z_p, ordered.
        """
        zp = float(plane_depth)
        if not np.isfinite(zp) or zp == 0.0:
            raise FitError(f"plane_depth: expected a non-zero camera depth of the image plane, got {plane_depth!r}")
        zb = self.slit_depth()
        if abs(zb - zp) <= 1e-12 * max(1.0, abs(zb)):
            raise FitError(f"plane_depth: {zp:g} puts the image plane on slit B (camera depth {zb:g})")
        fx, cx = self.K[0, 0], self.K[0, 2]
        a = (self.column0 - cx) / fx
        ex_c, ey_c, ez = self.R            # camera axes in the world
        c0 = self.position
        line_a = Line(c0, self.motion)
        line_b = Line(c0 + a * zb * ex_c + zb * ez, ey_c)
        offsets = [-zp, zb - zp]
        lines = [line_a, line_b]
        if abs(offsets[1]) < abs(offsets[0]):
            lines, offsets = lines[::-1], offsets[::-1]
        # origin: where the slits' orthogonal projections onto the plane cross
        p1 = lines[0].point + (zp - (lines[0].point - c0) @ ez) * ez
        p2 = lines[1].point + (zp - (lines[1].point - c0) @ ez) * ez
        d1, d2 = lines[0].direction, lines[1].direction
        ts = np.linalg.lstsq(np.stack([d1, -d2], axis=1), p2 - p1, rcond=None)[0]
        origin = p1 + ts[0] * d1
        ex = d1
        ey = np.cross(ez, ex)
        th2 = float(np.mod(np.arctan2(d2 @ ey, d2 @ ex), np.pi))
        v2 = np.cos(th2) * ex + np.sin(th2) * ey
        world = (Line(origin + offsets[0] * ez, ex), Line(origin + offsets[1] * ez, v2))
        return XSlitFrame(origin=origin, e_x=ex, e_y=ey, e_z=ez.copy(), z1=float(offsets[0]),
                          z2=float(offsets[1]), theta1=0.0, theta2=th2, slits=world)

    def plane_map(self, plane_depth: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Affine map of panorama pixels onto the frame's image plane: (u, v) = A·(k, v_px) + t.

        Returns A : (2, 2) float64 and t : (2,) float64 (frame plane coordinates of pixel (0, 0)).
        Exact: a ray's plane point is affine in (k, v) because the plane is parallel to the motion.
        """
        frame = self.slits(plane_depth)
        px = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        o, d = self.rays(px)
        q = frame.rays_to_plane(o, d)
        return np.column_stack([q[1] - q[0], q[2] - q[0]]), q[0]

    def pitch_and_principal(self, plane_depth: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Pitches (p1, p2) along v1, v2 and the principal pixel (cx, cy) of the plane origin, when the
        pixel→plane map is B·diag(p1, p2)·B⁻¹ (B = [v1 v2]), as for motion along the camera's x axis
        (then `depth.lines.XSlitSampling(xslit, pitch, principal)` samples the panorama exactly).

        Returns pitch : (2,) float64 (may be negative for a mirrored axis) and principal : (2,) float64.
        """
        frame = self.slits(plane_depth)
        A, t = self.plane_map(plane_depth)
        B = np.stack([frame.v1, frame.v2], axis=1)
        M = np.linalg.solve(B, A @ B)
        if abs(M[0, 1]) > 1e-9 * np.abs(M).max() or abs(M[1, 0]) > 1e-9 * np.abs(M).max():
            raise FitError("motion: the panorama's pixel axes are not along the slits (motion has a "
                           "component along the camera's y axis); use plane_map instead")
        return np.array([M[0, 0], M[1, 1]]), np.linalg.solve(A, -t)
