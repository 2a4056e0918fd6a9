"""Two-slit fits of ray bundles: `fit_two_slits` returning a `SlitFit` or a falsy `FailedFit`.

A bundle of reflected rays is modelled by an XSlit camera: every ray meets two lines, the
virtual slits. The linear step works on Plücker coordinates of rays centred on their
centroid and scaled (the moments depend on the origin): each ray r gives one equation
⟨r, S⟩ = d_r·m_S + m_r·d_S = 0 on a slit S; the two-dimensional null space of the stacked
equations meets the Klein quadric d·m = 0 in the two slits. A non-linear refinement
(scipy `least_squares`) then minimises the (weighted) squared ray-to-slit distances.
Degenerate bundles (parallel rays, a single centre of projection, a slit at infinity,
complex slits) are reported by reason instead of with invented slits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ._validate import as_rays, as_weights
from .plucker import Line, _distance_to_line, cross, klein_roots, line_from_plucker

__all__ = ["SlitFit", "FailedFit", "fit_two_slits", "REASONS"]

#: Reasons a `FailedFit` can carry (its `reason` is one of these strings).
REASONS = (
    "too few rays",
    "parallel rays",
    "pencil (single centre of projection)",
    "coplanar rays",
    "ill-conditioned",
    "complex roots",
    "double root (one slit)",
    "double root at infinity (twisted orthographic)",
    "slit at infinity (pushbroom)",
    "slits intersect",
    "degenerate rays",
    "refinement failed",
)


@dataclass(frozen=True)
class SlitFit:
    """A successful two-slit fit (truthy).

    Attributes
    ----------
    slits : tuple of two `Line`
        World-coordinate slits; slit 1 is the one nearer the reference plane (the plane
        through `centroid` parallel to both slits), i.e. |z1| < |z2| (docs/CONVENTIONS.md).
    rms_distance, max_distance : float
        Root-mean-square (weighted if weights were given) and maximum ray-to-slit distance
        over all rays and both slits, in world units (metres).
    condition : float
        σ1/σ4 of the normalised linear system: how well its two-dimensional null space is
        separated from the rest (large = close to a pinhole / ill-conditioned).
    n_rays : int
        Number of rays with positive weight.
    centroid : (3,) float64
        Weighted centroid of the ray points (the default image-plane point).
    mean_direction : (3,) float64
        Unit mean ray direction (the scene side, +e_z of the XSlit frame).
    singular_values : (6,) float64
        Singular values of the normalised linear system, descending, relative to the largest.
    refined : bool
        Whether the non-linear refinement ran.
    """

    slits: tuple
    rms_distance: float
    max_distance: float
    condition: float
    n_rays: int
    centroid: np.ndarray
    mean_direction: np.ndarray
    singular_values: np.ndarray = field(repr=False)
    refined: bool = True

    def __bool__(self) -> bool:
        return True

    @property
    def plane_normal(self) -> np.ndarray:
        """Unit normal e_z of the planes parallel to both slits, on the scene side : (3,)."""
        n = np.cross(self.slits[0].direction, self.slits[1].direction)
        n /= np.linalg.norm(n)
        return n if n @ self.mean_direction >= 0 else -n

    def slit_offsets(self, plane_point=None) -> np.ndarray:
        """Signed distances (z1, z2) of the slits from the plane through `plane_point`
        (default `centroid`) parallel to both slits, along `plane_normal` : (2,)."""
        c = self.centroid if plane_point is None else np.asarray(plane_point, dtype=np.float64)
        n = self.plane_normal
        return np.array([(s.point - c) @ n for s in self.slits])

    def distances(self, points, directions) -> np.ndarray:
        """Distances of rays (N, 3), (N, 3) to slit 1 and slit 2 : (N, 2) float64."""
        p, d = as_rays(points, directions)
        return np.stack([
            _distance_to_line(p - s.point, d, s.direction) for s in self.slits], axis=1)


@dataclass(frozen=True)
class FailedFit:
    """A fit that could not be made (falsy). `reason` is one of `REASONS`; `detail` explains."""

    reason: str
    n_rays: int = 0
    condition: float = float("nan")
    detail: str = ""

    def __bool__(self) -> bool:
        return False


def fit_two_slits(points, directions, weights=None, refine: bool = True, *,
                  max_condition: float = 1e9, degenerate_tol: float = 1e-11,
                  parallel_tol: float = 1e-12, pinhole_tol: float = 1e-6,
                  pinhole_ratio: float = 1.5,
                  max_refine_rays: int = 10000, seed: int = 0):
    """Fit two slits (an XSlit camera) to a bundle of rays.

    Parameters
    ----------
    points : (N, 3) float64
        A point on each ray (e.g. the mirror point of a reflected ray), metres.
    directions : (N, 3) float64
        Ray directions toward the scene (normalised here).
    weights : (N,) float64, optional
        Non-negative weights of the rays in both steps; rays of weight 0 are ignored.
    refine : bool
        Run the non-linear refinement of the squared ray-to-slit distances.
    max_condition : float
        Fail with "ill-conditioned" when σ1/σ4 of the linear system exceeds this.
    degenerate_tol : float
        σ4/σ1 below this means the null space is at least three-dimensional (a pinhole or
        coplanar rays).
    parallel_tol : float
        Rays whose directions differ by less than this (radians) are "parallel rays".
    pinhole_tol : float
        Fail as a pencil when every ray passes within this fraction of the bundle's size
        (rms distance of the rays from their centroid) of one point.
    pinhole_ratio : float
        Fail as a pencil when one point explains the rays with an rms distance within this
        factor of the two slits' rms distance and below 1 % of the bundle's size (a noisy
        pinhole must not yield slits).
    max_refine_rays : int
        The refinement uses a seeded random subset of at most this many rays; the reported
        distances are always computed over all rays.
    seed : int
        Seed of that subset.

    Returns
    -------
    SlitFit (truthy) or FailedFit (falsy, with `reason`).
    """
    p, d = as_rays(points, directions)
    w = as_weights(weights, len(p))
    if w is not None:
        keep = w > 0
        p, d, w = p[keep], d[keep], w[keep]
    n = len(p)
    if n < 4:
        return FailedFit("too few rays", n, detail=f"{n} rays; at least 4 are needed")
    wn = np.full(n, 1.0 / n) if w is None else w / w.sum()

    # Parallel rays (an orthographic bundle): no finite slit.
    spread = np.abs(cross(d, d[0])).max()
    if spread <= parallel_tol:
        return FailedFit("parallel rays", n, detail="all ray directions are equal")
    mean_dir = wn @ d
    mean_dir = mean_dir / np.linalg.norm(mean_dir) if np.linalg.norm(mean_dir) > 0 else d[0]

    lin = _linear_step(p, d, wn)
    c, scale, rel, sv, vt = lin["centroid"], lin["scale"], lin["rel"], lin["sv"], lin["vt"]
    condition = float(sv[0] / sv[3]) if sv[3] > 0 else float("inf")
    rel_sv = sv / sv[0]

    centre, centre_rms = _nearest_point(rel, d, wn)
    if centre_rms <= pinhole_tol:
        return FailedFit("pencil (single centre of projection)", n, condition,
                         detail=f"all rays pass within {scale * centre_rms:.3g} of "
                                f"{(c + scale * centre).tolist()}")
    if rel_sv[3] <= degenerate_tol:
        if _coplanar(rel, d) <= 1e3 * degenerate_tol:
            return FailedFit("coplanar rays", n, condition,
                             detail="all rays lie in one plane (an EPI bundle)")
        return FailedFit("degenerate rays", n, condition,
                         detail="more than a pencil of lines meets every ray")
    if condition > max_condition:
        return FailedFit("ill-conditioned", n, condition,
                         detail=f"σ1/σ4 = {condition:.3g} > {max_condition:.3g}")

    kind, roots = klein_roots(vt[4], vt[5])
    if kind == "complex":
        return FailedFit("complex roots", n, condition,
                         detail="no real line meets all rays (bilinear or twisted orthographic)")
    if kind == "all":
        return FailedFit("slits intersect", n, condition,
                         detail="the null space is a planar pencil of lines")
    if kind == "double":
        if np.linalg.norm(roots[0][:3]) <= 1e-9:
            return FailedFit("double root at infinity (twisted orthographic)", n, condition,
                             detail="rays parallel to one plane with no finite slit")
        return FailedFit("double root (one slit)", n, condition,
                         detail="the two slits coincide (GLC pencil camera)")
    if min(np.linalg.norm(x[:3]) for x in roots) <= 1e-9:
        return FailedFit("slit at infinity (pushbroom)", n, condition,
                         detail="one slit is the line at infinity of the rays' direction plane")
    lines = [line_from_plucker(x) for x in roots]           # (point, direction), normalised
    if abs(_reciprocal(lines[0], lines[1])) <= 1e-10:
        return FailedFit("slits intersect", n, condition,
                         detail="the two transversals meet: a pinhole with a plane of rays")

    refined = False
    if refine:
        out = _refine(lines, rel, d, wn, max_refine_rays, seed)
        if out is None:
            return FailedFit("refinement failed", n, condition,
                             detail="least_squares did not return finite slits")
        lines, refined = out, True

    slits = [Line(c + scale * q, _canonical_sign(u)) for q, u in lines]
    dist = np.stack([_distance_to_line(p - s.point, d, s.direction) for s in slits], axis=1)
    rms = float(np.sqrt(np.sum(wn[:, None] * dist**2) / 2.0))
    if not np.isfinite(rms):
        return FailedFit("refinement failed", n, condition, detail="non-finite distances")
    if centre_rms <= 0.01 and scale * centre_rms <= pinhole_ratio * rms:
        return FailedFit("pencil (single centre of projection)", n, condition,
                         detail=f"one point explains the rays as well as two slits "
                                f"(rms {scale * centre_rms:.3g} vs {rms:.3g})")
    normal = np.cross(slits[0].direction, slits[1].direction)
    offsets = [abs((s.point - c) @ normal) for s in slits]
    if offsets[1] < offsets[0]:
        slits = slits[::-1]
    return SlitFit(slits=tuple(slits), rms_distance=rms, max_distance=float(dist.max()),
                   condition=condition, n_rays=n, centroid=c, mean_direction=mean_dir,
                   singular_values=rel_sv, refined=refined)


def _linear_step(p: np.ndarray, d: np.ndarray, wn: np.ndarray) -> dict:
    """Normalise rays and return the SVD of their reciprocal-product equations.

    The rays are centred on their weighted centroid c and scaled by the rms distance of
    their lines from c, so moments and directions have comparable size.
    """
    c = wn @ p
    rel = p - c
    m = cross(rel, d)
    scale = float(np.sqrt(wn @ np.einsum("ij,ij->i", m, m)))
    if not scale > 0:
        scale = float(np.sqrt(wn @ np.einsum("ij,ij->i", rel, rel))) or 1.0
    rel = rel / scale
    m = m / scale
    sw = np.sqrt(wn)[:, None]
    # Unknown slit X = (X_d, X_m): the equation of ray (d, m) is m·X_d + d·X_m = 0.
    a = np.concatenate([m * sw, d * sw], axis=1)
    r = np.linalg.qr(a, mode="r") if len(a) >= 6 else a
    _, s, vt = np.linalg.svd(r, full_matrices=True)
    sv = np.zeros(6)
    sv[: len(s)] = s
    return {"centroid": c, "scale": scale, "rel": rel, "sv": sv, "vt": vt}


def _nearest_point(rel: np.ndarray, d: np.ndarray, wn: np.ndarray) -> tuple[np.ndarray, float]:
    """The point nearest all rays (normalised coordinates) and its weighted rms distance."""
    wd = wn[:, None] * d
    a = np.eye(3) - wd.T @ d                       # Σ w (I − d dᵀ)
    b = wn @ rel - wd.T @ np.einsum("ij,ij->i", d, rel)
    x = np.linalg.lstsq(a, b, rcond=None)[0]
    dist2 = np.einsum("ij,ij->i", rel, rel) - 2 * rel @ x + x @ x \
        - (np.einsum("ij,ij->i", d, rel) - d @ x) ** 2
    return x, float(np.sqrt(max(wn @ dist2, 0.0)))


def _coplanar(rel: np.ndarray, d: np.ndarray) -> float:
    """Smallest relative singular value of the stacked points and directions (0 if coplanar)."""
    s = np.linalg.svd(np.concatenate([rel, d]), compute_uv=False)
    return float(s[-1] / s[0])


def _reciprocal(a, b) -> float:
    (pa, da), (pb, db) = a, b
    return float(da @ np.cross(pb, db) + db @ np.cross(pa, da))


def _canonical_sign(u: np.ndarray) -> np.ndarray:
    """Flip a direction so its largest-magnitude component is positive."""
    return u if u[np.argmax(np.abs(u))] > 0 else -u


def _perp_basis(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.eye(3)[np.argmin(np.abs(u))]
    e1 = np.cross(u, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def _signed_distance(rel: np.ndarray, d: np.ndarray, v: np.ndarray):
    """Signed distance of lines (rel + t·d) to the line through 0 along v, with ĝ, |g|.

    g = d × v; a ray parallel to the slit gets |g| clamped to 1e-300 (no exact zero)."""
    g = cross(d, v)
    g_norm = np.maximum(np.sqrt(np.einsum("ij,ij->i", g, g)), 1e-300)
    g_hat = g / g_norm[:, None]
    return np.einsum("ij,ij->i", rel, g_hat), g_hat, g_norm


def _refine(lines, rel, d, wn, max_rays: int, seed: int):
    """Least-squares refinement of two slits (normalised coordinates); None on failure."""
    if len(rel) > max_rays:
        idx = np.random.default_rng(seed).choice(len(rel), size=max_rays, replace=False)
        rel, d, wn = rel[idx], d[idx], wn[idx] / wn[idx].sum()
    sw = np.sqrt(wn)
    bases = [(q, u, *_perp_basis(u)) for q, u in lines]

    def unpack(x):
        out = []
        for k, (q, u, e1, e2) in enumerate(bases):
            a, b, s, t = x[4 * k: 4 * k + 4]
            out.append((q + s * e1 + t * e2, u + a * e1 + b * e2))   # direction unnormalised
        return out

    def residuals(x):
        return np.concatenate([
            sw * _signed_distance(rel - q, d, v)[0] for q, v in unpack(x)])

    def jacobian(x):
        jac = np.zeros((2 * len(rel), 8))
        for k, ((q, v), (_, _, e1, e2)) in enumerate(zip(unpack(x), bases)):
            r, g_hat, g_norm = _signed_distance(rel - q, d, v)
            # r = k·ĝ with k = P − q, g = D × v:  ∂r/∂v = ((k − r ĝ) × D) / |g|,  ∂r/∂q = −ĝ
            dr_dv = cross((rel - q) - r[:, None] * g_hat, d) / g_norm[:, None]
            rows = slice(k * len(rel), (k + 1) * len(rel))
            jac[rows, 4 * k + 0] = dr_dv @ e1
            jac[rows, 4 * k + 1] = dr_dv @ e2
            jac[rows, 4 * k + 2] = -g_hat @ e1
            jac[rows, 4 * k + 3] = -g_hat @ e2
        return jac * np.concatenate([sw, sw])[:, None]

    try:
        res = least_squares(residuals, np.zeros(8), jac=jacobian, method="lm", x_scale="jac",
                            xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=200)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(res.x)):
        return None
    lines = [(q, v / np.linalg.norm(v)) for q, v in unpack(res.x)]
    # Re-express each point as the point of its line nearest the centroid (the origin here).
    return [(q - (q @ u) * u, u) for q, u in lines]
