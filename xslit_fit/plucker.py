"""Plücker line algebra: `Line`, `plucker`, `reciprocal_product`, `ray_line_distance`, `lines_through_four`.

A line is stored as Plücker coordinates (d, m): direction d (3,) and moment m = p × d (3,) for
any point p on the line. Two lines meet (or are parallel) iff their reciprocal product
d_a·m_b + d_b·m_a vanishes; a 6-vector is a line iff d·m = 0 (the Klein quadric).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_array, as_rays, as_unit, as_vector
from .errors import FitError

__all__ = [
    "Line",
    "plucker",
    "reciprocal_product",
    "ray_line_distance",
    "lines_through_four",
]


@dataclass(frozen=True)
class Line:
    """A straight line (a virtual slit) in world coordinates.

    Attributes
    ----------
    point : (3,) float64
        A point on the line (for fitted slits: the point nearest the rays' centroid).
    direction : (3,) float64
        Unit direction (its sign carries no meaning).
    """

    point: np.ndarray
    direction: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "point", as_vector(self.point, "point"))
        object.__setattr__(self, "direction", as_unit(self.direction, "direction"))

    def plucker(self) -> np.ndarray:
        """Plücker coordinates (d, m) : (6,) float64 with |d| = 1."""
        return np.concatenate([self.direction, np.cross(self.point, self.direction)])

    def distance_to(self, points: np.ndarray) -> np.ndarray:
        """Distance from points (N, 3) to this line : (N,) float64."""
        p = as_array(points, "points", 3) - self.point
        return np.linalg.norm(np.cross(p, self.direction), axis=1)

    def to_dict(self) -> dict:
        """{"point": [x, y, z], "direction": [x, y, z]} as plain floats."""
        return {"point": self.point.tolist(), "direction": self.direction.tolist()}


def plucker(points, directions) -> np.ndarray:
    """Plücker coordinates of rays.

    Parameters
    ----------
    points : (N, 3) float64
        A point on each ray (e.g. its origin).
    directions : (N, 3) float64
        Ray directions (normalised here).

    Returns
    -------
    (N, 6) float64
        Rows (d, m): unit direction d and moment m = p × d.
    """
    p, d = as_rays(points, directions)
    return np.concatenate([d, np.cross(p, d)], axis=1)


def reciprocal_product(a, b) -> np.ndarray:
    """Reciprocal (permuted inner) product d_a·m_b + d_b·m_a of Plücker lines.

    a, b : (..., 6) float64, broadcast against each other. Returns (...) float64; zero iff
    the lines meet or are parallel. For unit directions it equals −dist·sin(angle) up to sign.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape[-1] != 6 or b.shape[-1] != 6:
        raise FitError(f"a, b: expected Plücker arrays of shape (..., 6), got {a.shape}, {b.shape}")
    return np.sum(a[..., :3] * b[..., 3:], axis=-1) + np.sum(a[..., 3:] * b[..., :3], axis=-1)


def ray_line_distance(points, directions, line_point, line_direction,
                      parallel_tol: float = 1e-12) -> np.ndarray:
    """Distance between each ray's supporting line and one line.

    Parameters
    ----------
    points, directions : (N, 3) float64
        The rays (directions need not be unit).
    line_point, line_direction : (3,) float64
        The line (e.g. a slit).
    parallel_tol : float
        Below this |sin(angle)| the lines are treated as parallel and the point-to-line
        distance is used.

    Returns
    -------
    (N,) float64, metres (the unit of the input).
    """
    p, d = as_rays(points, directions)
    q = as_vector(line_point, "line_point")
    ell = as_unit(line_direction, "line_direction")
    return _distance_to_line(p - q, d, ell, parallel_tol)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (N, 3) arrays (b may be (3,)); faster than np.cross."""
    b = np.broadcast_to(b, a.shape) if b.ndim == 1 else b
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _distance_to_line(rel: np.ndarray, d: np.ndarray, ell: np.ndarray,
                      parallel_tol: float = 1e-12, signed: bool = False) -> np.ndarray:
    """Distance of lines (rel + t·d) (rel = point − line point, d unit) to the line through 0 along ell."""
    n = cross(d, ell)
    s = np.sqrt(np.einsum("ij,ij->i", n, n))
    skew = s > parallel_tol
    if np.all(skew):
        out = np.einsum("ij,ij->i", rel, n) / s
        return out if signed else np.abs(out)
    out = np.empty(len(d))
    out[skew] = np.einsum("ij,ij->i", rel[skew], n[skew]) / s[skew]
    if not signed:
        out[skew] = np.abs(out[skew])
    out[~skew] = np.linalg.norm(cross(rel[~skew], ell), axis=1)
    return out


def line_from_plucker(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(point nearest the origin (3,), unit direction (3,)) of a finite Plücker line x (6,)."""
    d, m = x[:3], x[3:]
    n2 = float(d @ d)
    return np.cross(d, m) / n2, d / np.sqrt(n2)


def klein_roots(u: np.ndarray, v: np.ndarray, double_tol: float = 1e-12):
    """Intersect the pencil α·u + β·v of 6-vectors with the Klein quadric d·m = 0.

    Returns (kind, roots): kind "real" with two (6,) unit vectors, "double" with one,
    "complex" with one complex (6,) vector (the other is its conjugate), or "all" when every
    member of the pencil is a line (the pencil is a planar pencil of lines).
    """
    quad = np.array([
        [u[:3] @ u[3:], 0.5 * (u[:3] @ v[3:] + v[:3] @ u[3:])],
        [0.0, v[:3] @ v[3:]],
    ])
    quad[1, 0] = quad[0, 1]
    q, e = np.linalg.eigh(quad)
    scale = np.max(np.abs(q))
    if scale == 0.0:
        return "all", []
    basis = np.stack([u, v], axis=1)  # (6, 2)
    if abs(q[0]) <= double_tol * scale or abs(q[1]) <= double_tol * scale:
        k = int(np.argmin(np.abs(q)))
        x = basis @ e[:, k]
        return "double", [x / np.linalg.norm(x)]
    if q[0] < 0.0 < q[1]:
        roots = []
        for sign in (1.0, -1.0):
            y = np.array([np.sqrt(q[1]), sign * np.sqrt(-q[0])])
            x = basis @ (e @ y)
            roots.append(x / np.linalg.norm(x))
        return "real", roots
    y = np.array([np.sqrt(abs(q[1])), 1j * np.sqrt(abs(q[0]))])
    x = basis @ (e @ y)
    return "complex", [x / np.linalg.norm(x)]


def lines_through_four(lines) -> list[np.ndarray]:
    """The real lines meeting four given lines.

    Parameters
    ----------
    lines : (4, 6) float64
        Plücker coordinates (d, m) of four lines in general position.

    Returns
    -------
    list of (6,) float64
        0, 1 (a double root) or 2 transversals as Plücker vectors scaled to |d| = 1 (or to
        |(d, m)| = 1 for a line at infinity, d = 0).

    Raises
    ------
    FitError
        If `lines` is not (4, 6), a row is not a line, or the four lines are linearly
        dependent (then infinitely many transversals exist).
    """
    L = np.asarray(lines, dtype=np.float64)
    if L.shape != (4, 6) or not np.all(np.isfinite(L)):
        raise FitError(f"lines: expected a finite (4, 6) Plücker array, got shape {L.shape}")
    norms = np.linalg.norm(L, axis=1, keepdims=True)
    if np.any(norms == 0):
        raise FitError("lines: expected non-zero Plücker rows")
    L = L / norms
    if np.any(np.abs(np.sum(L[:, :3] * L[:, 3:], axis=1)) > 1e-9):
        raise FitError("lines: a row is not on the Klein quadric (d·m != 0), so it is not a line")
    rows = np.concatenate([L[:, 3:], L[:, :3]], axis=1)
    _, s, vt = np.linalg.svd(rows)
    if s[3] <= 1e-12 * s[0]:
        raise FitError("lines: the four lines are linearly dependent; infinitely many lines meet them")
    kind, roots = klein_roots(vt[4], vt[5])
    if kind not in ("real", "double"):
        return []
    out = []
    for x in roots:
        nd = np.linalg.norm(x[:3])
        out.append(x / nd if nd > 1e-12 else x / np.linalg.norm(x))
    return out
