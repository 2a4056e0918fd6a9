"""Mirrors: the analytic open `CylinderMirror`, any triangle mesh as a `MeshMirror`, and `reflect`.

Each mirror answers `intersect` (first hit in float64 with surface normals), gives a
`mesh()` for Embree, and `refine_hits` turns an Embree hit on that mesh into an exact float64
hit (`CylinderMirror.first_hits` is the renderer's analytic fast path). `MIRRORS` maps a setup file's `type` key to its class.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass, field

import numpy as np

if TYPE_CHECKING:  # trimesh is imported where meshes are made: it costs 0.7 s of start-up
    import trimesh

from ._embree import build_scene, first_hits
from ._validate import as_positive, as_rays, as_unit, as_vector
from .errors import RaytraceError

__all__ = ["CylinderMirror", "MeshMirror", "MIRRORS", "reflect", "EPS_T"]

EPS_T = 1e-9
"""Smallest accepted ray parameter t (metres along a unit ray): hits closer are ignored."""


def reflect(directions, normals) -> np.ndarray:
    """Mirror reflection r = d − 2 (d·n) n; independent of the sign of n.

    Parameters
    ----------
    directions : (N, 3) float64, incoming ray directions (unit)
    normals : (N, 3) float64, unit surface normals

    Returns
    -------
    reflected : (N, 3) float64, unit
    """
    d = np.asarray(directions, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    if d.shape != n.shape or d.shape[-1:] != (3,):
        r = d - 2.0 * np.sum(d * n, axis=-1, keepdims=True) * n
        with np.errstate(invalid="ignore", divide="ignore"):
            return r / np.linalg.norm(r, axis=-1, keepdims=True)
    # the same sums in the same order as np.sum / np.linalg.norm over the last axis, per component (faster)
    dn = d[..., 0] * n[..., 0] + d[..., 1] * n[..., 1] + d[..., 2] * n[..., 2]
    r = d - (2.0 * dn)[..., None] * n
    with np.errstate(invalid="ignore", divide="ignore"):
        r /= np.sqrt(r[..., 0] * r[..., 0] + r[..., 1] * r[..., 1] + r[..., 2] * r[..., 2])[..., None]
    return r


def _nan_rows(n: int) -> np.ndarray:
    return np.full((n, 3), np.nan)


@dataclass(frozen=True)
class CylinderMirror:
    """The open lateral surface of a circular cylinder (no caps), reflecting perfectly.

    Attributes
    ----------
    radius : float, metres (> 0)
    height : float, metres (> 0), along `axis`, centred on `center`
    center : (3,) float64
    axis : (3,) float64, unit (normalised on construction)
    """

    radius: float
    height: float
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))

    def __post_init__(self):
        object.__setattr__(self, "radius", as_positive(self.radius, "radius"))
        object.__setattr__(self, "height", as_positive(self.height, "height"))
        object.__setattr__(self, "center", as_vector(self.center, "center"))
        object.__setattr__(self, "axis", as_unit(self.axis, "axis"))

    # -- geometry helpers -------------------------------------------------------------
    def axial(self, points) -> np.ndarray:
        """Signed axial coordinate of points (N, 3) relative to `center`, (N,)."""
        return (np.asarray(points, dtype=np.float64) - self.center) @ self.axis

    def radial_vectors(self, points) -> np.ndarray:
        """Component of (points − center) perpendicular to the axis, (N, 3)."""
        rel = np.asarray(points, dtype=np.float64) - self.center
        return rel - np.outer(rel @ self.axis, self.axis)

    def distance_to_axis(self, points) -> np.ndarray:
        """Distance of points (N, 3) from the mirror axis, (N,)."""
        return np.linalg.norm(self.radial_vectors(np.atleast_2d(points)), axis=1)

    def contains(self, points) -> np.ndarray:
        """(N,) bool: which points (N, 3) lie strictly inside the solid the mirror bounds (nearer the
        axis than `radius`, within `height` along it). Nothing there is seen by reflection off the
        outer surface: a cube estimated there is no cube."""
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        return (self.distance_to_axis(p) < self.radius) & (np.abs(self.axial(p)) < self.height / 2)

    @property
    def frame(self) -> np.ndarray:
        """(3, 3) float64 rows e1, e2, axis: an orthonormal frame with the axis last."""
        a = self.axis
        helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(a, helper)
        e1 /= np.linalg.norm(e1)
        return np.stack([e1, np.cross(a, e1), a])

    def _local_roots(self, o: np.ndarray, d: np.ndarray):
        """Rays in the local frame (axis = z); both roots t0 <= t1 of x² + y² = R² (NaN if none)."""
        B3 = self.frame
        ol = (o - self.center) @ B3.T
        dl = d @ B3.T
        ox, oy, oz = ol[:, 0], ol[:, 1], ol[:, 2]
        dx, dy, dz = dl[:, 0], dl[:, 1], dl[:, 2]
        A = dx * dx + dy * dy
        Bq = 2.0 * (ox * dx + oy * dy)
        C = ox * ox + oy * oy - self.radius**2
        disc = Bq * Bq - 4.0 * A * C
        ok = (disc >= 0) & (A > 1e-300)
        sq = np.sqrt(np.where(ok, disc, 0.0))
        q = -0.5 * (Bq + np.copysign(sq, Bq))
        with np.errstate(divide="ignore", invalid="ignore"):
            ta = np.where(ok, q / A, np.nan)
            tb = np.where(ok & (q != 0), C / q, ta)
        t0, t1 = np.fmin(ta, tb), np.fmax(ta, tb)
        half = self.height / 2
        with np.errstate(invalid="ignore"):
            v0 = (t0 > EPS_T) & (np.abs(oz + t0 * dz) <= half)
            v1 = (t1 > EPS_T) & (np.abs(oz + t1 * dz) <= half)
        return ol, dl, t0, t1, v0, v1

    def _finish(self, ol, dl, t, hit):
        """World t, hit, points and outward normals from local rays and chosen roots."""
        B3 = self.frame
        tt = np.where(hit, t, 0.0)
        pl = ol + tt[:, None] * dl
        nl = pl / self.radius
        nl[:, 2] = 0.0
        pts = pl @ B3 + self.center
        nrm = nl @ B3
        pts[~hit] = np.nan
        nrm[~hit] = np.nan
        return np.where(hit, t, np.inf), hit, pts, nrm

    def intersect(self, origins, directions):
        """First hit with the lateral surface, analytic in float64.

        Parameters
        ----------
        origins : (N, 3) float64
        directions : (N, 3) float64, unit

        Returns
        -------
        t : (N,) float64, ray parameter (inf where no hit)
        hit : (N,) bool, a root with t > EPS_T within the height
        points : (N, 3) float64, NaN where no hit
        normals : (N, 3) float64, unit, pointing away from the axis (outward), NaN where no hit
        """
        o, d = as_rays(origins, directions)
        ol, dl, t0, t1, v0, v1 = self._local_roots(o, d)
        t = np.where(v0, t0, t1)
        return self._finish(ol, dl, t, v0 | v1)

    def hits(self, origins, directions) -> np.ndarray:
        """(N,) bool: `intersect`'s `hit` alone, without its points and normals (`raytrace.truth.mirror_mask`
        asks only this of the pixels it traces)."""
        o, d = as_rays(origins, directions)
        *_, v0, v1 = self._local_roots(o, d)
        return v0 | v1

    def first_hits(self, o: np.ndarray, d: np.ndarray):
        """Renderer fast path of `intersect`: rows that hit, with their exact float64 hits.

        The same quadratic as `intersect`, on contiguous per-component arrays; points and
        normals are computed only for the rays that hit.

        Parameters
        ----------
        o, d : (N, 3) float64, unit directions (not validated here)

        Returns
        -------
        rows : (M,) int64, indices of the rays that hit, increasing
        t : (M,) float64, ray parameter of the first hit (t > EPS_T, within the height)
        points : (M, 3) float64
        normals : (M, 3) float64, unit, outward
        """
        B3 = self.frame
        e1, e2, a = B3
        oc = B3 @ self.center
        ox, oy, oz = o @ e1 - oc[0], o @ e2 - oc[1], o @ a - oc[2]
        dx, dy, dz = d @ e1, d @ e2, d @ a
        A = dx * dx + dy * dy
        Bq = 2.0 * (ox * dx + oy * dy)
        C = ox * ox + oy * oy - self.radius**2
        disc = Bq * Bq - 4.0 * A * C
        ok = (disc >= 0) & (A > 1e-300)
        half = self.height / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            sq = np.sqrt(disc)  # NaN where disc < 0: those rows are not `ok`
            q = -0.5 * (Bq + np.copysign(sq, Bq))
            ta = q / A
            tb = np.where(q != 0, C / q, ta)
            t0, t1 = np.fmin(ta, tb), np.fmax(ta, tb)
            v0 = (t0 > EPS_T) & (np.abs(oz + t0 * dz) <= half)
            v1 = (t1 > EPS_T) & (np.abs(oz + t1 * dz) <= half)
        rows = np.flatnonzero(ok & (v0 | v1))
        t = np.where(np.take(v0, rows), np.take(t0, rows), np.take(t1, rows))
        plx = np.take(ox, rows) + t * np.take(dx, rows)
        ply = np.take(oy, rows) + t * np.take(dy, rows)
        points = np.take(o, rows, axis=0) + t[:, None] * np.take(d, rows, axis=0)
        normals = np.stack([plx / self.radius, ply / self.radius], axis=1) @ B3[:2]
        return rows, t, points, normals

    def refine(self, origins, directions, t_guess):
        """Refine approximate hits (e.g. Embree on `mesh()`) on the analytic surface.

        Takes the valid analytic root (t > EPS_T, within the height) nearest `t_guess`.

        Parameters
        ----------
        origins, directions : (N, 3) float64
        t_guess : (N,) float64

        Returns
        -------
        t, hit, points, normals : as `intersect`
        """
        o, d = as_rays(origins, directions)
        tg = np.asarray(t_guess, dtype=np.float64).reshape(-1)
        if tg.shape != (len(o),):
            raise RaytraceError(f"t_guess: expected shape ({len(o)},), got {tg.shape}")
        ol, dl, t0, t1, v0, v1 = self._local_roots(o, d)
        with np.errstate(invalid="ignore"):
            prefer1 = v1 & (~v0 | (np.abs(t1 - tg) < np.abs(t0 - tg)))
        t = np.where(prefer1, t1, t0)
        return self._finish(ol, dl, t, v0 | v1)

    def refine_hits(self, origins, directions, t_guess, prim_id=None, uv=None):
        """Renderer hook: exact hit from an Embree hit on `mesh()` (see `refine`)."""
        return self.refine(origins, directions, t_guess)

    def mesh(self, sections: int = 720) -> trimesh.Trimesh:
        """Tessellated open lateral surface, vertices on the analytic surface (inscribed).

        Rays that hit the facets are refined with `refine`; rays in the silhouette sliver
        between facets and circle (width R·(1 − cos(π/sections))) miss the mesh.
        """
        if int(sections) < 3:
            raise RaytraceError(f"sections: expected an integer >= 3, got {sections!r}")
        import trimesh  # imported on use: it costs ~0.5 s of start-up and rendering never needs it

        n = int(sections)
        e1, e2, a = self.frame
        phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
        ring = self.radius * (np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2))
        half = self.height / 2 * a
        verts = np.concatenate([self.center + ring - half, self.center + ring + half])
        i = np.arange(n)
        j = (i + 1) % n
        faces = np.concatenate([np.stack([i, j, j + n], 1), np.stack([i, j + n, i + n], 1)])
        return trimesh.Trimesh(verts, faces, process=False)


class MeshMirror:
    """Any triangle mesh as a perfect mirror, shaded with barycentric-interpolated vertex normals.

    Parameters
    ----------
    mesh : trimesh.Trimesh with at least one face
    """

    def __init__(self, mesh: trimesh.Trimesh):
        import trimesh

        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise RaytraceError("mesh: expected a trimesh.Trimesh with at least one face")
        self._mesh = mesh
        self._vertices = np.asarray(mesh.vertices, dtype=np.float64)
        self._faces = np.asarray(mesh.faces, dtype=np.int64)
        self._vertex_normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
        self._embree = None

    def mesh(self, sections: int | None = None) -> trimesh.Trimesh:
        """The mirror's own mesh (`sections` is ignored)."""
        return self._mesh

    def contains(self, points) -> np.ndarray:
        """(N,) bool: which points (N, 3) lie inside the mesh (`trimesh.Trimesh.contains`); all False
        for a mesh that bounds no volume (not watertight)."""
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        if not self._mesh.is_watertight:
            return np.zeros(len(p), dtype=bool)
        return np.asarray(self._mesh.contains(p), dtype=bool)

    def _shade(self, o, d, prim):
        """Exact float64 hit on triangles `prim` (N,) of rays o, d; returns t, points, normals."""
        tri = self._vertices[self._faces[prim]]  # (N, 3, 3)
        e1 = tri[:, 1] - tri[:, 0]
        e2 = tri[:, 2] - tri[:, 0]
        ng = np.cross(e1, e2)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.einsum("ij,ij->i", tri[:, 0] - o, ng) / np.einsum("ij,ij->i", d, ng)
        p = o + t[:, None] * d
        import trimesh

        bary = trimesh.triangles.points_to_barycentric(tri, p) if len(p) else np.zeros((0, 3))
        vn = self._vertex_normals[self._faces[prim]]
        n = np.einsum("ij,ijk->ik", bary, vn)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return t, p, n

    def intersect(self, origins, directions):
        """First hit (Embree, refined in float64), with interpolated normals; same returns as `CylinderMirror.intersect`."""
        o, d = as_rays(origins, directions)
        if self._embree is None:
            self._embree = build_scene(self._vertices[self._faces])
        prim = first_hits(self._embree, o, d)
        return self.refine_hits(o, d, np.zeros(len(o)), prim)

    def refine_hits(self, origins, directions, t_guess, prim_id=None, uv=None):
        """Exact hit on triangle `prim_id` (N,) int (−1: none); returns t, hit, points, normals."""
        o, d = as_rays(origins, directions)
        if prim_id is None:
            raise RaytraceError("prim_id: MeshMirror needs the triangle index of each hit")
        prim = np.asarray(prim_id, dtype=np.int64).reshape(-1)
        has = prim >= 0
        t = np.full(len(o), np.inf)
        pts = _nan_rows(len(o))
        nrm = _nan_rows(len(o))
        if np.any(has):
            th, ph, nh = self._shade(o[has], d[has], prim[has])
            t[has], pts[has], nrm[has] = th, ph, nh
        hit = has & np.isfinite(t) & (t > EPS_T)
        t[~hit] = np.inf
        pts[~hit] = np.nan
        nrm[~hit] = np.nan
        return t, hit, pts, nrm


MIRRORS = {"cylinder": CylinderMirror}
"""Registry: setup file `mirror.type` → mirror class."""
