"""XSlit projection: the paper's two-slit camera model (Eqn. pinproj) as `XSlit`.

`XSlit` holds the slit depths z1, z2 and angles θ1, θ2 of a crossed-slit camera in the frame of
docs/CONVENTIONS.md: the virtual image plane is z = 0, slit i is the line
{t·(cos θi, sin θi, 0) + (0, 0, z_i)}, and scene points lie on the side the rays travel to.
A point's in-plane coordinates are decomposed on the slit directions v1, v2 (its κ coordinates),
and each component is projected like a pinhole whose centre is the *other* slit:

    κ_u = −z2 / (z − z2) · κ_x,      κ_v = −z1 / (z − z1) · κ_y          (Eqn. pinproj)

Angles are in radians; lengths in any unit, used consistently.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from depth.errors import DegenerateGeometryError, DepthError

__all__ = ["XSlit", "as_points"]


def as_points(points, name: str, dim: int) -> np.ndarray:
    """Coerce `points` to a finite (N, dim) float64 array, or raise DepthError naming `name`."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 1 and arr.shape[0] == dim:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise DepthError(f"{name}: expected an (N, {dim}) array, got shape {np.shape(points)}")
    if not np.all(np.isfinite(arr)):
        raise DepthError(f"{name}: expected finite numbers, got NaN or infinity")
    return arr


@dataclass(frozen=True)
class XSlit:
    """A crossed-slit camera: slits at depths z1, z2 with angles θ1, θ2 to the frame's x axis.

    Parameters
    ----------
    z1, z2 : float
        Depths of slit 1 and slit 2 along the plane normal (paper's z1, z2). z1 != z2
        (z1 == z2 is a pinhole, which carries no depth), and neither lies on the image plane.
    theta1, theta2 : float
        Slit directions in radians (paper's θ1, θ2); θ1 - θ2 must not be a multiple of π.
    """

    z1: float
    z2: float
    theta1: float = 0.0
    theta2: float = np.pi / 2

    def __post_init__(self):
        for name in ("z1", "z2", "theta1", "theta2"):
            value = getattr(self, name)
            if not isinstance(value, (int, float, np.floating, np.integer)) or not np.isfinite(value):
                raise DepthError(f"{name}: expected a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.z1 == 0.0 or self.z2 == 0.0:
            raise DegenerateGeometryError(
                f"z1={self.z1}, z2={self.z2}: a slit on the image plane (z = 0) images everything to a line")
        if np.isclose(self.z1, self.z2, rtol=1e-12, atol=0.0):
            raise DegenerateGeometryError(
                f"z1 == z2 == {self.z1}: the slits meet, this is a pinhole and aspect ratios carry no depth")
        if abs(np.sin(self.theta2 - self.theta1)) < 1e-9:
            raise DegenerateGeometryError(
                f"theta1={self.theta1}, theta2={self.theta2}: parallel slits do not span the image plane")

    @classmethod
    def from_degrees(cls, z1: float, z2: float, theta1_deg: float = 0.0, theta2_deg: float = 90.0) -> "XSlit":
        """An XSlit with slit angles given in degrees."""
        return cls(z1, z2, np.deg2rad(theta1_deg), np.deg2rad(theta2_deg))

    # -- the slit basis -------------------------------------------------------------------------
    @property
    def basis(self) -> np.ndarray:
        """(2, 2) float64 matrix whose columns are v1 = (cos θ1, sin θ1) and v2 = (cos θ2, sin θ2)."""
        return np.array([[np.cos(self.theta1), np.cos(self.theta2)],
                         [np.sin(self.theta1), np.sin(self.theta2)]])

    def to_kappa(self, xy) -> np.ndarray:
        """κ coordinates of in-plane vectors: xy = κ_1·v1 + κ_2·v2.

        xy : (N, 2) float64 → (N, 2) float64 (κ on v1, κ on v2).
        """
        xy = as_points(xy, "xy", 2)
        return np.linalg.solve(self.basis, xy.T).T

    def from_kappa(self, kappa) -> np.ndarray:
        """In-plane vectors from κ coordinates: (N, 2) → (N, 2)."""
        kappa = as_points(kappa, "kappa", 2)
        return kappa @ self.basis.T

    # -- projection -----------------------------------------------------------------------------
    def _check_depths(self, z: np.ndarray) -> None:
        on_slit = np.isclose(z, self.z1, rtol=0, atol=1e-12 * max(1.0, abs(self.z1))) | \
            np.isclose(z, self.z2, rtol=0, atol=1e-12 * max(1.0, abs(self.z2)))
        if np.any(on_slit):
            raise DepthError("points: a point at a slit's depth has no XSlit image")

    def kappa_scales(self, z) -> tuple[np.ndarray, np.ndarray]:
        """Scale factors (s_u, s_v) with κ_u = s_u·κ_x and κ_v = s_v·κ_y at depth z (Eqn. pinproj)."""
        z = np.asarray(z, dtype=np.float64)
        return -self.z2 / (z - self.z2), -self.z1 / (z - self.z1)

    def project_kappa(self, points) -> np.ndarray:
        """(κ_u, κ_v) of 3D frame points: points (N, 3) → (N, 2)."""
        points = as_points(points, "points", 3)
        self._check_depths(points[:, 2])
        kx_ky = self.to_kappa(points[:, :2])
        s_u, s_v = self.kappa_scales(points[:, 2])
        return np.stack([s_u * kx_ky[:, 0], s_v * kx_ky[:, 1]], axis=1)

    def project(self, points) -> np.ndarray:
        """Image-plane (u, v) of 3D frame points: points (N, 3) → (N, 2)."""
        return self.from_kappa(self.project_kappa(points))

    def back_project(self, uv, z) -> np.ndarray:
        """3D frame points at depth z whose image is (u, v): uv (N, 2), z (N,) or scalar → (N, 3)."""
        uv = as_points(uv, "uv", 2)
        z = np.broadcast_to(np.asarray(z, dtype=np.float64), (uv.shape[0],)).copy()
        self._check_depths(z)
        k_uv = self.to_kappa(uv)
        s_u, s_v = self.kappa_scales(z)
        xy = self.from_kappa(np.stack([k_uv[:, 0] / s_u, k_uv[:, 1] / s_v], axis=1))
        return np.column_stack([xy, z])

    def ray(self, uv) -> tuple[np.ndarray, np.ndarray]:
        """The ray of image point (u, v): the line through (u, v, 0) meeting both slits.

        uv : (N, 2) → origins (N, 3) on the plane z = 0, directions (N, 3) unit, pointing to +z.
        """
        uv = as_points(uv, "uv", 2)
        origins = np.column_stack([uv, np.zeros(len(uv))])
        far = self.back_project(uv, np.full(len(uv), 1.0 + 2.0 * max(abs(self.z1), abs(self.z2))))
        d = far - origins
        return origins, d / np.linalg.norm(d, axis=1, keepdims=True)
