"""General Linear Cameras (Yu & McMillan 2004): `GLC`, `fit_glc` and `glc_type`.

A GLC is the affine family of rays r = α·r1 + β·r2 + (1 − α − β)·r3 spanned by three
generator rays in a two-plane parameterisation: a ray meets the plane z = 0 at (u, v) and
the plane z = 1 at (s, t) (lengths in units of the frame's `scale`). Its characteristic
equation A·λ² + B·λ + C = 0, with

    A = det[σ τ 1],  B = det[σ v 1] + det[u τ 1],  C = det[u v 1],  σ = s − u, τ = t − v,

gives the depths λ where the generators' points are collinear: the slits. The numbers of
roots (and whether the points at a double root coincide, or all rays are parallel) give
the seven types XSlit, pinhole, pushbroom, pencil, orthographic, twisted orthographic and
bilinear (and "epi" when all rays are coplanar).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_rays, as_unit, as_vector, as_weights
from .errors import FitError
from .fit import _linear_step
from .plucker import Line, cross

__all__ = ["GLC", "GLC_TYPES", "fit_glc", "glc_type"]

#: Types returned by `GLC.type` / `glc_type`.
GLC_TYPES = ("xslit", "pinhole", "pushbroom", "pencil", "orthographic",
             "twisted_orthographic", "bilinear", "epi")


@dataclass(frozen=True)
class GLC:
    """A General Linear Camera given by three generator rays in a two-plane parameterisation.

    Attributes
    ----------
    uv, st : (3, 2) float64
        The generators' intersections with the planes z = 0 and z = 1 of the 2PP frame,
        in units of `scale`.
    origin : (3,) float64
        World origin of the 2PP frame (on the uv plane).
    rotation : (3, 3) float64
        Rows e_x, e_y, e_z of the 2PP frame; e_z is the planes' normal.
    scale : float
        World length of one 2PP unit (the st plane lies at z = scale in world units).
    residual : float
        For `fit_glc`: rms misfit of the bundle's (s, t) to the affine model, in 2PP units
        (0 for an exact GLC); 0 for `from_rays`.
    """

    uv: np.ndarray
    st: np.ndarray
    origin: np.ndarray
    rotation: np.ndarray
    scale: float
    residual: float = 0.0

    @classmethod
    def from_rays(cls, points, directions, plane_point=None, plane_normal=None,
                  scale: float | None = None) -> "GLC":
        """The GLC of three generator rays.

        Parameters
        ----------
        points, directions : (3, 3) float64
            The three generator rays.
        plane_point : (3,) float64, optional
            A point of the uv plane; default the generators' centroid.
        plane_normal : (3,) float64, optional
            The 2PP planes' normal; default the generators' mean direction.
        scale : float, optional
            World length of one 2PP unit; default the rms distance of the uv points from
            their centroid.
        """
        p, d = as_rays(points, directions)
        if len(p) != 3:
            raise FitError(f"points: expected 3 generator rays, got {len(p)}")
        origin = p.mean(axis=0) if plane_point is None else as_vector(plane_point, "plane_point")
        normal = d.mean(axis=0) if plane_normal is None else plane_normal
        rot = _frame(as_unit(normal, "plane_normal"))
        uv, st = _two_plane(p, d, origin, rot, 1.0)
        if scale is None:
            scale = float(np.sqrt(np.mean(np.sum((uv - uv.mean(axis=0)) ** 2, axis=1)))) or 1.0
        uv, st = _two_plane(p, d, origin, rot, scale)
        return cls(uv=uv, st=st, origin=origin, rotation=rot, scale=float(scale))

    @property
    def coefficients(self) -> tuple[float, float, float]:
        """(A, B, C) of the characteristic equation A·λ² + B·λ + C = 0 (λ in 2PP units)."""
        u, v = self.uv[:, 0], self.uv[:, 1]
        sig, tau = self.st[:, 0] - u, self.st[:, 1] - v
        one = np.ones(3)

        def det(a, b):
            return float(np.linalg.det(np.stack([a, b, one], axis=1)))

        return det(sig, tau), det(sig, v) + det(u, tau), det(u, v)

    def depths(self) -> np.ndarray:
        """Real roots λ of the characteristic equation as signed world distances from the
        uv plane along e_z : (k,) float64, k ∈ {0, 1, 2} (a double root is listed once)."""
        a, b, c = self.coefficients
        if a == 0.0:
            return np.array([] if b == 0.0 else [-c / b * self.scale])
        disc = b * b - 4 * a * c
        if disc < 0:
            return np.array([])
        q = -0.5 * (b + np.copysign(np.sqrt(disc), b))
        roots = {q / a, c / q} if q != 0 else {0.0}
        return np.sort(np.array(sorted(roots))) * self.scale

    def points_at(self, depth: float) -> np.ndarray:
        """World points (3, 3) where the generators cross the plane at `depth` (world units)."""
        lam = depth / self.scale
        local = self.uv + lam * (self.st - self.uv)
        pts = np.concatenate([local, np.full((3, 1), lam)], axis=1) * self.scale
        return pts @ self.rotation + self.origin

    def slits(self) -> list[Line]:
        """The real slits: at each root depth, the line through the collinear generator
        points (parallel to the 2PP planes). A pinhole's double root gives no line."""
        out = []
        for depth in self.depths():
            pts = self.points_at(depth)
            gaps = pts[:, None, :] - pts[None, :, :]
            i, j = np.unravel_index(np.argmax(np.sum(gaps**2, axis=2)), (3, 3))
            if np.linalg.norm(pts[i] - pts[j]) > 1e-12 * self.scale:
                out.append(Line(pts[i], pts[j] - pts[i]))
        return out

    def type(self, tol: float = 1e-6) -> str:
        """The GLC type (one of `GLC_TYPES`) from the characteristic equation.

        `tol` is relative: a root counts as infinite when the slit would lie 1/tol times
        farther than the other (or than the 2PP unit), two roots coincide when they differ
        by tol relative, and points or directions coincide to tol in 2PP units.
        """
        big_a, big_b, big_c = self.coefficients
        if abs(big_c) <= 1e-12:
            if abs(big_a) <= tol and abs(big_b) <= tol:
                return "epi"
            raise FitError("GLC: generators meet the uv plane on a line; choose other generators")
        a, b = big_a / big_c, big_b / big_c            # det(M − I), tr(M − I)
        nu = max(abs(b), np.sqrt(abs(a)))               # size of the roots' inverse depths
        if nu <= tol:
            sig = self.st - self.uv
            parallel = np.max(np.abs(sig - sig[0])) <= tol
            return "orthographic" if parallel else "twisted_orthographic"
        if abs(a) <= tol * nu**2:
            return "pushbroom"
        disc = b * b - 4 * a
        if abs(disc) <= tol * nu**2:
            lam = -2.0 / b
            pts = self.uv + lam * (self.st - self.uv)
            spread = np.max(np.linalg.norm(pts - pts.mean(axis=0), axis=1))
            return "pinhole" if spread <= np.sqrt(tol) else "pencil"
        return "xslit" if disc > 0 else "bilinear"


def _frame(normal: np.ndarray) -> np.ndarray:
    """Rows e_x, e_y, e_z of a right-handed frame with e_z = normal."""
    a = np.eye(3)[np.argmin(np.abs(normal))]
    ex = np.cross(a, normal)
    ex /= np.linalg.norm(ex)
    return np.stack([ex, np.cross(normal, ex), normal])


def _two_plane(p, d, origin, rot, scale):
    """(u, v) and (s, t) (N, 2) of rays on the planes z = 0 and z = 1 (units of `scale`)."""
    pl = (p - origin) @ rot.T / scale
    dl = d @ rot.T
    if np.any(np.abs(dl[:, 2]) <= 1e-12):
        raise FitError("directions: a ray is parallel to the two-plane parameterisation's planes")
    uv = pl[:, :2] - (pl[:, 2] / dl[:, 2])[:, None] * dl[:, :2]
    return uv, uv + dl[:, :2] / dl[:, 2:3]


def _plane_normal(p, d, wn) -> np.ndarray:
    """2PP normal for a bundle: one that makes the bundle affine in (u, v, s, t).

    Each basis vector X = (X_d, X_m) of the Plücker null space is a linear complex
    d·X_m + m·X_d = 0; in a 2PP frame it is affine in (u, v, s, t) iff X_d is parallel to
    the planes. So the normal is u_d × v_d for a null-space basis u, v (for an XSlit: the
    cross product of the slit directions); if that vanishes, the mean direction made
    orthogonal to the non-zero X_d; for a pinhole or parallel rays, the mean direction.
    """
    mean = wn @ d
    mean = mean / np.linalg.norm(mean) if np.linalg.norm(mean) > 0 else d[0]
    if np.abs(cross(d, d[0])).max() <= 1e-12:
        return mean
    lin = _linear_step(p, d, wn)
    sv, vt = lin["sv"], lin["vt"]
    if sv[3] <= 1e-11 * sv[0]:
        return mean
    ud, vd = vt[4, :3], vt[5, :3]
    nu, nv = np.linalg.norm(ud), np.linalg.norm(vd)
    normal = np.cross(ud, vd)
    if not np.linalg.norm(normal) > 1e-9 * nu * nv:
        x = ud if nu >= nv else vd
        if not np.linalg.norm(x) > 1e-12:
            return mean
        normal = mean - (mean @ x) / (x @ x) * x
        if not np.linalg.norm(normal) > 1e-12:
            return mean
    normal = normal / np.linalg.norm(normal)
    return normal if normal @ mean >= 0 else -normal


def fit_glc(points, directions, weights=None, plane_normal=None) -> GLC:
    """The GLC that best fits a ray bundle (robust variant of three generator rays).

    The 2PP planes are chosen parallel to the bundle's slits (from the Plücker null space,
    real or complex; otherwise the mean direction, made orthogonal to a single slit), the
    rays' (s, t) are fitted as an affine function of (u, v) by weighted least squares, and
    three generators are taken from that model at well-spread (u, v) (an equilateral
    triangle on the uv points' principal axes).

    Parameters
    ----------
    points, directions : (N, 3) float64, N >= 3
    weights : (N,) float64, optional
    plane_normal : (3,) float64, optional
        Override the 2PP normal.
    """
    p, d = as_rays(points, directions)
    w = as_weights(weights, len(p))
    if w is not None:
        p, d, w = p[w > 0], d[w > 0], w[w > 0]
    if len(p) < 3:
        raise FitError(f"points: expected at least 3 rays, got {len(p)}")
    wn = np.full(len(p), 1.0 / len(p)) if w is None else w / w.sum()
    normal = _plane_normal(p, d, wn) if plane_normal is None else as_unit(plane_normal, "plane_normal")
    rot = _frame(normal)
    uv, _ = _two_plane(p, d, wn @ p, rot, 1.0)
    centre = wn @ uv
    origin = wn @ p + centre @ rot[:2]            # the uv plane through the rays' centroid
    cov = (wn[:, None] * (uv - centre)).T @ (uv - centre)
    scale = float(np.sqrt(np.trace(cov))) or 1.0
    uv, st = _two_plane(p, d, origin, rot, scale)
    sw = np.sqrt(wn)[:, None]
    design = np.concatenate([uv, np.ones((len(uv), 1))], axis=1)
    coef, *_ = np.linalg.lstsq(design * sw, st * sw, rcond=None)      # st ≈ design @ coef
    residual = float(np.sqrt(np.sum(wn[:, None] * (design @ coef - st) ** 2)))
    evals, evecs = np.linalg.eigh(cov / scale**2)
    if evals[0] <= 1e-24:
        return GLC(uv=np.zeros((3, 2)), st=np.zeros((3, 2)), origin=origin, rotation=rot,
                   scale=scale, residual=residual)            # collinear (u, v): an EPI
    radii = np.sqrt(np.maximum(evals, 0))
    angles = 2 * np.pi * np.arange(3) / 3
    gen_uv = (np.stack([np.cos(angles), np.sin(angles)], axis=1) * radii) @ evecs.T
    gen_st = np.concatenate([gen_uv, np.ones((3, 1))], axis=1) @ coef
    return GLC(uv=gen_uv, st=gen_st, origin=origin, rotation=rot, scale=scale,
               residual=residual)


def glc_type(points, directions, weights=None, tol: float = 1e-6) -> str:
    """GLC type of a ray bundle: one of `GLC_TYPES` ("xslit", "pinhole", "pushbroom",
    "pencil", "orthographic", "twisted_orthographic", "bilinear", or "epi" for coplanar rays).

    Parameters
    ----------
    points, directions : (N, 3) float64
    weights : (N,) float64, optional
    tol : float
        Relative tolerance of `GLC.type`.
    """
    p, d = as_rays(points, directions)
    glc = fit_glc(p, d, weights)
    if not np.any(glc.uv):
        return "epi"
    if np.abs(cross(d, d[0])).max() <= 1e-12:
        return "orthographic"
    return glc.type(tol)
