"""Rendering: `render` a `Scene` through any camera into a `Render` (image plus exact per-pixel truth).

Embree (embreex) finds first hits on the cubes and the ground; a `CylinderMirror` is intersected
analytically (a float64 quadratic over the rays, `CylinderMirror.first_hits`), any other mirror is
tessellated into Embree and refined. Every hit is recomputed in float64 (cube face planes, the
ground plane, the mirror's surface) and shaded Lambertian with a directional light plus ambient light. The numpy twin (`backend="numpy"`) replaces Embree with
analytic slab and cylinder tests and shares everything else. Large images are split in tiles
over worker processes (Embree holds the GIL). Supersampling is adaptive: the `spp` stratified (per-pixel rotated)
samples are traced only for pixels whose 3×3 neighbourhood shows an edge (a change of object,
cube face, checker cell or mirror/direct view) in the pixel-centre pass; elsewhere the surface
is flat-shaded so the centre sample is the pixel's exact average.
"""

from __future__ import annotations

import contextlib
import ctypes
import mmap
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from ._embree import build_scene, commit, first_hits
from .camera import pixel_sample_offsets
from .errors import RaytraceError
from .mirror import EPS_T, CylinderMirror, reflect
from .scene import Scene

__all__ = ["Render", "render", "linear_to_srgb8", "trace_paths", "keep_freed_memory", "plain_pages",
           "single_threaded_blas"]

TILE_PIXELS = 1 << 15
"""Pixels per tile of the pixel-centre pass (fixed, so results do not depend on `workers`).

Small enough that a tile's float64 temporaries (256 KiB each) stay in cache: 1.5-2x faster than 1 << 17."""
BATCH_RAYS = 1 << 15
"""Rays traced at once in the supersampling pass (same cache reason)."""
CHUNK_PIXELS = 1 << 15
"""Edge pixels per chunk of the supersampling pass."""
MIN_PARALLEL_PIXELS = 1 << 16
"""Images smaller than this render in the calling process."""
REFLECT_OFFSET = 1e-6
"""Metres a reflected ray's origin is moved off the mirror (along the normal) before tracing."""


@dataclass
class Render:
    """The image and exact per-pixel truth of a render (pixel-centre rays for the truth arrays).

    Attributes
    ----------
    image : (H, W, 3) float64, linear RGB
    object_id : (H, W) int32, index into `scene.objects` seen directly or in the mirror; −1 for
        the background, the ground plane and rays that run out of bounces
    via_mirror : (H, W) bool, the pixel-centre ray reflected off the mirror at least once
    ray_distance : (H, W) float32, path length from the camera to the seen surface (inf if none)
    mirror_point : (H, W, 3) float64, first mirror point of the pixel-centre ray, NaN off the mirror
    reflected_dir : (H, W, 3) float64, unit reflected direction there, NaN off the mirror
    rays_traced : int, number of rays traced, all bounces included
    supersampled : (H, W) bool, pixels that received the `spp` samples
    """

    image: np.ndarray
    object_id: np.ndarray
    via_mirror: np.ndarray
    ray_distance: np.ndarray
    mirror_point: np.ndarray
    reflected_dir: np.ndarray
    rays_traced: int
    supersampled: np.ndarray


SRGB_BLOCK = 1 << 16
"""Values converted at once by `linear_to_srgb8`: its float64 temporaries stay small enough to be
reused rather than freshly mapped (and zero-filled by the kernel) for every image."""


def linear_to_srgb8(image) -> np.ndarray:
    """Linear RGB in [0, 1] (H, W, 3) float → sRGB-encoded (H, W, 3) uint8 (clipped, rounded)."""
    image = np.asarray(image)
    flat = image.reshape(-1)
    out = np.empty(flat.shape, dtype=np.uint8)
    for a in range(0, len(flat), SRGB_BLOCK):
        x = np.clip(np.asarray(flat[a : a + SRGB_BLOCK], dtype=np.float64), 0.0, 1.0)
        s = np.power(x, 1 / 2.4)  # in place from here on: the same arithmetic with no temporaries
        s *= 1.055
        s -= 0.055
        np.multiply(x, 12.92, out=s, where=x <= 0.0031308)
        s *= 255.0
        out[a : a + SRGB_BLOCK] = np.round(s, out=s)
    return out.reshape(image.shape)


# ---------------------------------------------------------------------------------------
# Geometry shared by both tracers: ids, exact planes, shading data
# ---------------------------------------------------------------------------------------
class _Geometry:
    """Geometry ids: cubes 0..K−1, then the ground (if any), then the mirror (if any)."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.cubes = scene.objects
        k = len(self.cubes)
        self.ground_gid = k if scene.ground is not None else -10
        self.mirror_gid = k + (scene.ground is not None) if scene.mirror is not None else -10
        if k:
            self.face_n = np.concatenate([c.face_normals for c in self.cubes])  # (6K, 3)
            centers = np.repeat(np.stack([c.center for c in self.cubes]), 6, axis=0)
            half = np.repeat([c.size / 2 for c in self.cubes], 6)
            self.face_off = np.einsum("ij,ij->i", self.face_n, centers) + half
            self.colors = np.stack([c.color for c in self.cubes])
        else:
            self.face_n = np.zeros((0, 3))
            self.face_off = np.zeros(0)
            self.colors = np.zeros((0, 3))


_ROW = np.dtype((np.void, 24))


def _set_rows(a: np.ndarray, rows: np.ndarray, values) -> None:
    """a[rows] = values for a C-contiguous (N, 3) float64 `a`; values (M, 3) or (3,) float64.

    Rows are moved as 24-byte items: 4-5x faster than numpy's row-wise fancy assignment.
    """
    v = np.ascontiguousarray(values, dtype=np.float64)
    if not a.flags.c_contiguous or a.dtype != np.float64 or a.shape[1:] != (3,):
        a[rows] = v
        return
    item = a.view(_ROW).reshape(len(a))
    if v.ndim == 1:
        item[rows] = v.view(_ROW)[0]
    else:
        item[rows] = v.view(_ROW).reshape(len(v))


def _object_t(geo: _Geometry, o, d, geom, prim) -> np.ndarray:
    """Exact float64 ray parameter (N,) of hits `geom`, `prim` (N,) on cubes or the ground."""
    t = np.full(len(o), np.inf)
    is_c = (geom >= 0) & (geom < len(geo.cubes))
    if np.any(is_c):
        ci = np.flatnonzero(is_c)
        nf = geo.face_n[geom[ci] * 6 + prim[ci] // 2]
        oc, dc = np.take(o, ci, axis=0), np.take(d, ci, axis=0)
        t[ci] = (geo.face_off[geom[ci] * 6 + prim[ci] // 2] - np.einsum("ij,ij->i", nf, oc)) / np.einsum("ij,ij->i", nf, dc)
    is_g = geom == geo.ground_gid
    if np.any(is_g):
        gi = np.flatnonzero(is_g)
        g = geo.scene.ground
        t[gi] = ((g.point - np.take(o, gi, axis=0)) @ g.normal) / (np.take(d, gi, axis=0) @ g.normal)
    return t


def _refine_mirror(tracer, o, d, geom, prim, t_guess):
    """Exact mirror hits of rays whose approximate first hit (`geom`, `prim`) is the mirror.

    Rays that hit a mirror facet but not the exact surface are traced again without the
    mirror (their `geom`, `prim` are updated in place). Returns (rows, t, points, normals), rays.
    """
    geo = tracer.geo
    mi = np.flatnonzero(geom == geo.mirror_gid)
    if len(mi) == 0:
        return None, 0
    tg = t_guess[mi] if t_guess is not None else np.zeros(len(mi))
    m_t, m_hit, m_p, m_n = geo.scene.mirror.refine_hits(o[mi], d[mi], tg, prim[mi])
    miss = mi[~m_hit]
    rays = 0
    if len(miss):  # hit a facet but not the exact surface: look behind the mirror
        g2, p2, _ = tracer.first_hit(o[miss], d[miss], False)
        rays = len(miss)
        geom[miss], prim[miss] = g2, p2
    return (mi[m_hit], m_t[m_hit], m_p[m_hit], m_n[m_hit]), rays


class _EmbreeTracer:
    """Cubes and ground merged in one Embree mesh (a primitive-id lookup gives geometry and face).

    A `CylinderMirror` stays analytic (a float64 quadratic per ray, `CylinderMirror.first_hits`);
    any other mirror is tessellated into the Embree mesh and its hits refined.
    """

    def __init__(self, geo: _Geometry, mirror_sections: int = 720):
        self.geo = geo
        scene = geo.scene
        self.analytic_mirror = isinstance(scene.mirror, CylinderMirror)
        parts = []  # (triangles (T, 3, 3), gid, local prim ids)
        for gid, cube in enumerate(geo.cubes):
            parts.append((_cube_triangles(cube), gid, np.arange(12)))
        if scene.ground is not None:
            parts.append((_ground_triangles(scene.ground), geo.ground_gid, np.arange(2)))
        n_obj = len(parts)
        if scene.mirror is not None and not self.analytic_mirror:
            mm = scene.mirror.mesh(mirror_sections)
            parts.append((mm.triangles, geo.mirror_gid, np.arange(len(mm.faces))))
        self.scenes = {}
        self.lookups = {}
        for with_mirror, sel in ((False, parts[:n_obj]), (True, parts)):
            if with_mirror and len(sel) == n_obj:
                self.scenes[True], self.lookups[True] = self.scenes[False], self.lookups.get(False)
                continue
            if not sel:
                self.scenes[with_mirror] = None
                continue
            tris = np.concatenate([p[0] for p in sel])
            gids = np.concatenate([np.full(len(p[0]), p[1]) for p in sel])
            local = np.concatenate([p[2] for p in sel])
            self.scenes[with_mirror] = build_scene(tris)
            self.lookups[with_mirror] = (np.append(gids, -1), np.append(local, -1))

    def commit(self) -> None:
        """Every Embree scene's BVH built now, in this process (`raytrace._embree.commit`)."""
        for es in self.scenes.values():
            if es is not None:
                commit(es)

    def first_hit(self, o, d, with_mirror: bool):
        """geom (N,) int (−1 none), prim (N,) int (local triangle index), t (N,) float64 or None.

        With an analytic mirror, mirror hits are not reported here (see `hits`).
        """
        es = self.scenes[with_mirror]
        if es is None or len(o) == 0:
            return np.full(len(o), -1), np.full(len(o), -1), None
        prim = first_hits(es, o, d)
        gids, local = self.lookups[with_mirror]
        return gids[prim], local[prim], None

    def hits(self, o, d, with_mirror: bool):
        """First hits with exact mirror data: geom, prim (N,), mirror (rows, t, points, normals) or None, rays."""
        if not self.analytic_mirror:
            geom, prim, tg = self.first_hit(o, d, with_mirror)
            mirror, extra = _refine_mirror(self, o, d, geom, prim, tg) if with_mirror else (None, 0)
            return geom, prim, mirror, len(o) + extra
        geom, prim, _ = self.first_hit(o, d, False)
        if not with_mirror or self.geo.scene.mirror is None:
            return geom, prim, None, len(o)
        rows, t, p, n = self.geo.scene.mirror.first_hits(o, d)
        both = np.flatnonzero(geom[rows] >= 0)
        if len(both):  # an object and the mirror on the same ray: the nearer one wins
            r = rows[both]
            behind = both[_object_t(self.geo, o[r], d[r], geom[r], prim[r]) < t[both]]
            if len(behind):
                keep = np.ones(len(rows), dtype=bool)
                keep[behind] = False
                rows, t, p, n = rows[keep], t[keep], p[keep], n[keep]
        geom[rows] = self.geo.mirror_gid
        prim[rows] = 0
        return geom, prim, (rows, t, p, n), len(o)


def _cube_triangles(cube) -> np.ndarray:
    """(12, 3, 3) float64 triangles of `cube`, as `Cube.mesh()` (triangles 2f, 2f+1 make face f)."""
    c = np.stack([cube.face_corners(f) for f in range(6)])  # (6, 4, 3)
    return np.stack([c[:, [0, 1, 2]], c[:, [0, 2, 3]]], axis=1).reshape(12, 3, 3)


def _ground_triangles(ground) -> np.ndarray:
    """(2, 3, 3) float64 triangles of `ground`, as `GroundPlane.mesh()`."""
    e1, e2 = ground.basis * (ground.extent / 2)
    p = ground.point
    v = np.array([p - e1 - e2, p + e1 - e2, p + e1 + e2, p - e1 + e2])
    return v[[[0, 1, 2], [0, 2, 3]]]


class _NumpyTracer:
    """Analytic twin: slab test per cube, plane test for the ground, analytic mirror."""

    def __init__(self, geo: _Geometry):
        self.geo = geo

    def hits(self, o, d, with_mirror: bool):
        """As `_EmbreeTracer.hits`."""
        geom, prim, tg = self.first_hit(o, d, with_mirror)
        mirror, extra = _refine_mirror(self, o, d, geom, prim, tg) if with_mirror else (None, 0)
        return geom, prim, mirror, len(o) + extra

    def first_hit(self, o, d, with_mirror: bool):
        geo = self.geo
        n = len(o)
        best = np.full(n, np.inf)
        geom = np.full(n, -1)
        prim = np.full(n, -1)
        for gid, cube in enumerate(geo.cubes):
            ol = (o - cube.center) @ cube.rotation
            dl = d @ cube.rotation
            half = cube.size / 2
            with np.errstate(divide="ignore", invalid="ignore"):
                t1 = (-half - ol) / dl
                t2 = (half - ol) / dl
            tmin = np.fmin(t1, t2)
            tmax = np.fmax(t1, t2)
            tmin = np.where(np.isnan(tmin), -np.inf, tmin)  # dl == 0 inside the slab
            tmax = np.where(np.isnan(tmax), np.inf, tmax)
            inside_slab = (np.abs(ol) <= half) | (dl != 0)
            axis = np.argmax(tmin, axis=1)
            tn = np.max(tmin, axis=1)
            tf = np.min(tmax, axis=1)
            hit = np.all(inside_slab, axis=1) & (tn <= tf) & (tn > EPS_T) & (tn < best)
            sign_out = -np.sign(dl[np.arange(n), axis])  # entering face faces the ray
            face = 2 * axis + (sign_out < 0)
            best = np.where(hit, tn, best)
            geom = np.where(hit, gid, geom)
            prim = np.where(hit, 2 * face, prim)
        g = geo.scene.ground
        if g is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = ((g.point - o) @ g.normal) / (d @ g.normal)
            pc = g.plane_coords(o + np.where(np.isfinite(t), t, 0.0)[:, None] * d)
            hit = (t > EPS_T) & (t < best) & np.all(np.abs(pc) <= g.extent / 2, axis=1)
            best = np.where(hit, t, best)
            geom = np.where(hit, geo.ground_gid, geom)
            prim = np.where(hit, 0, prim)
        if with_mirror and geo.scene.mirror is not None:
            t, hit, _, _ = geo.scene.mirror.intersect(o, d)
            hit &= t < best
            best = np.where(hit, t, best)
            geom = np.where(hit, geo.mirror_gid, geom)
            prim = np.where(hit, 0, prim)
        return geom, prim, best


# ---------------------------------------------------------------------------------------
# Path tracing of a batch of rays (shared by both backends)
# ---------------------------------------------------------------------------------------
def trace_paths(tracer, origins, directions, bounces: int) -> dict:
    """Follow rays through up to `bounces` mirror reflections and shade what they reach.

    Parameters
    ----------
    tracer : _EmbreeTracer or _NumpyTracer (built on one scene)
    origins, directions : (N, 3) float64, unit directions
    bounces : int >= 0, the most mirror reflections followed

    Returns
    -------
    dict with color (N, 3) float64, object_id (N,) int32, via_mirror (N,) bool,
    distance (N,) float64, mirror_point (N, 3), reflected_dir (N, 3) float64 (first
    reflection, NaN if none), key (N,) int64 (surface identity for edge detection), rays (int).
    """
    n = len(origins)
    res = {
        "color": np.empty((n, 3)),
        "object_id": np.empty(n, dtype=np.int32),
        "via_mirror": np.empty(n, dtype=bool),
        "distance": np.empty(n),
        "mirror_point": np.empty((n, 3)),
        "reflected_dir": np.empty((n, 3)),
        "key": np.empty(n, dtype=np.int64),
    }
    res["rays"] = _trace_into(tracer, origins, directions, bounces, res)
    return res


def _trace_into(tracer, origins, directions, bounces: int, dest: dict) -> int:
    """`trace_paths` writing into the (N, ...) arrays of `dest` (its keys but "rays"); returns the rays traced.

    Without "object_id" in `dest` only "color" is written (the supersampling pass).
    """
    geo = tracer.geo
    scene = geo.scene
    light = scene.light
    color = dest["color"]
    truth = "object_id" in dest
    if truth:
        object_id, via, distance = dest["object_id"], dest["via_mirror"], dest["distance"]
        mirror_point, reflected_dir, key = dest["mirror_point"], dest["reflected_dir"], dest["key"]
        object_id.fill(-1)
        via.fill(False)
        distance.fill(np.inf)
        mirror_point.fill(np.nan)
        reflected_dir.fill(np.nan)
        key.fill(0)
    idx = None  # rows of the current rays in the outputs (None: all, in order)
    o = np.asarray(origins, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    travelled = None
    rays = 0
    with_mirror = True
    n_cubes = len(geo.cubes)
    for bounce in range(bounces + 1):
        if len(o) == 0:
            break
        geom, prim, mirror, traced = tracer.hits(o, d, with_mirror)
        rays += traced

        # --- objects: exact float64 hit on the face plane, Lambertian shading
        ci = np.flatnonzero((geom >= 0) & (geom < n_cubes))
        if len(ci):
            gc, fc = geom[ci], prim[ci] // 2
            fidx = gc * 6 + fc
            nf = geo.face_n[fidx]
            dn = np.einsum("ij,ij->i", nf, np.take(d, ci, axis=0))
            t = (geo.face_off[fidx] - np.einsum("ij,ij->i", nf, np.take(o, ci, axis=0))) / dn
            nf = np.where(dn[:, None] > 0, -nf, nf)
            lam = light.ambient + light.intensity * np.maximum(0.0, nf @ light.to_light)
            out = ci if idx is None else idx[ci]
            _set_rows(color, out, geo.colors[gc] * lam[:, None])
            if truth:
                object_id[out] = gc
                distance[out] = t if travelled is None else travelled[ci] + t
                key[out] = 4 + gc * 8 + fc
        if scene.ground is not None:
            gi = np.flatnonzero(geom == geo.ground_gid)
            if len(gi):
                g = scene.ground
                og, dg = np.take(o, gi, axis=0), np.take(d, gi, axis=0)
                dn = dg @ g.normal
                t = ((g.point - og) @ g.normal) / dn
                p = og + t[:, None] * dg
                parity = g.cell_parity(p)
                ng = np.where(dn[:, None] > 0, -g.normal, g.normal)
                lam = light.ambient + light.intensity * np.maximum(0.0, ng @ light.to_light)
                albedo = np.where(parity[:, None] == 0, g.colors[0], g.colors[1])
                out = gi if idx is None else idx[gi]
                _set_rows(color, out, albedo * lam[:, None])
                if truth:
                    distance[out] = t if travelled is None else travelled[gi] + t
                    key[out] = 4 + n_cubes * 8 + parity
        bg = np.flatnonzero(geom == -1)
        if len(bg):
            out = bg if idx is None else idx[bg]
            _set_rows(color, out, scene.background)
            if truth:
                key[out] = 1

        # --- mirror: record the first reflection, continue the reflected rays
        if mirror is None or len(mirror[0]) == 0:
            break
        mi, m_t, m_p, m_n = mirror
        out = mi if idx is None else idx[mi]
        r = reflect(np.take(d, mi, axis=0), m_n)
        if truth:
            if bounce == 0:
                _set_rows(mirror_point, out, m_p)
                _set_rows(reflected_dir, out, r)
            via[out] = True
        if bounce == bounces:  # out of bounces: black, no object
            _set_rows(color, out, np.zeros(3))
            if truth:
                key[out] = 2
            break
        side = np.sign(np.einsum("ij,ij->i", r, m_n))
        # a ray leaving the outside of a convex cylinder cannot meet it again
        with_mirror = not (isinstance(scene.mirror, CylinderMirror) and np.all(side > 0))
        o = m_p + (REFLECT_OFFSET * side)[:, None] * m_n
        d = r
        travelled = m_t if travelled is None else travelled[mi] + m_t
        idx = out
    if truth:
        key *= 2
        key += via
    return rays


# ---------------------------------------------------------------------------------------
# Tiles and processes
# ---------------------------------------------------------------------------------------
_STATE: dict = {}
_TRACER_CACHE: dict = {}


def _tracer():
    """The tracer of the render's scene and backend: made once and kept with the scene it was made of (compared by
    identity, the scene held so that its id cannot name another), so that the workers forked after `render` made it
    use the parent's (`render` builds its BVHs before it forks: `_EmbreeTracer.commit`)."""
    st = _STATE
    cached = _TRACER_CACHE
    if cached.get("scene") is not st["scene"] or cached.get("backend") != st["backend"]:
        cached.clear()
        geo = _Geometry(st["scene"])
        tr = _EmbreeTracer(geo) if st["backend"] == "embree" else _NumpyTracer(geo)
        cached.update(scene=st["scene"], backend=st["backend"], tracer=tr)
    return cached["tracer"]


def _centre_tile(start: int, stop: int) -> int:
    """Pixel-centre pass for flat pixel indices [start, stop); writes the shared outputs."""
    st = _STATE
    cam = st["camera"]
    w = cam.resolution[0]
    flat = np.arange(start, stop)
    v, u = np.divmod(flat, w)
    px = np.stack([u, v], axis=1).astype(np.float64)
    o, d = cam.rays(px)
    out = st["out"]
    dest = {"color": out["image"][start:stop], "distance": out["ray_distance"][start:stop]}
    for name in ("object_id", "via_mirror", "mirror_point", "reflected_dir", "key"):
        dest[name] = out[name][start:stop]
    return _trace_into(_tracer(), o, d, st["bounces"], dest)


def _sample_chunk(start: int, stop: int) -> int:
    """Supersampling pass for edge pixels edge_index[start:stop]; writes their mean colour."""
    st = _STATE
    cam = st["camera"]
    w = cam.resolution[0]
    flat = st["edge_index"][start:stop]
    spp = st["spp"]
    v, u = np.divmod(flat, w)
    centres = np.stack([u, v], axis=1).astype(np.float64)
    px = (centres[:, None, :] + pixel_sample_offsets(flat, spp, st["seed"])).reshape(-1, 2)
    o, d = cam.rays(px)
    color = np.empty((len(px), 3))
    rays = 0
    for a in range(0, len(px), BATCH_RAYS):
        b = min(a + BATCH_RAYS, len(px))
        rays += _trace_into(_tracer(), o[a:b], d[a:b], st["bounces"], {"color": color[a:b]})
    st["out"]["image"][flat] = color.reshape(len(flat), spp, 3).mean(axis=1)
    return rays


def _shared(shape, dtype) -> np.ndarray:
    """An array in anonymous shared memory, visible to forked workers."""
    dtype = np.dtype(dtype)
    nbytes = int(np.prod(shape)) * dtype.itemsize
    buf = mmap.mmap(-1, max(nbytes, 1))
    return np.frombuffer(buf, dtype=dtype, count=int(np.prod(shape))).reshape(shape)


OUTPUTS = {
    "image": ((3,), np.dtype(np.float64)),
    "object_id": ((), np.dtype(np.int32)),
    "via_mirror": ((), np.dtype(bool)),
    "ray_distance": ((), np.dtype(np.float32)),
    "mirror_point": ((3,), np.dtype(np.float64)),
    "reflected_dir": ((3,), np.dtype(np.float64)),
}
"""The `Render` arrays: per-pixel trailing shape and dtype."""


def _check_out(out, h: int, w: int) -> dict:
    if out is None:
        return {}
    if not isinstance(out, dict):
        raise RaytraceError(f"out: expected a dict of arrays or None, got {type(out).__name__}")
    for name, arr in out.items():
        if name not in OUTPUTS:
            raise RaytraceError(f"out: unknown array {name!r}; expected some of {', '.join(OUTPUTS)}")
        tail, dtype = OUTPUTS[name]
        if not isinstance(arr, np.ndarray) or arr.shape != (h, w) + tail or arr.dtype != dtype:
            got = f"{arr.dtype} {arr.shape}" if isinstance(arr, np.ndarray) else type(arr).__name__
            raise RaytraceError(f"out[{name!r}]: expected a {dtype} array of shape {(h, w) + tail}, got {got}")
        if not (arr.flags.c_contiguous and arr.flags.writeable):
            raise RaytraceError(f"out[{name!r}]: expected a C-contiguous writeable array")
    return dict(out)


def _in_shared_memory(arr: np.ndarray) -> bool:
    """Whether forked workers' writes to `arr` reach this process: an `np.memmap` opened "r+" or
    "w+" (a shared file mapping). Anything else, even an anonymous mmap (its flags are not
    visible from Python), is rendered to shared memory and copied."""
    base = arr
    while base is not None:
        if isinstance(base, np.memmap):
            return base.mode in ("r+", "w+")
        base = getattr(base, "base", None)
    return False


def _edges(key: np.ndarray) -> np.ndarray:
    """(H, W) bool: some pixel of the 3×3 neighbourhood has a different key."""
    edge = np.zeros(key.shape, dtype=bool)
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):  # each neighbour pair once, marked on both sides
        ys, yd = slice(0, key.shape[0] - dy), slice(dy, None)
        xs, xd = (slice(0, key.shape[1] - dx), slice(dx, None)) if dx >= 0 else (slice(-dx, None), slice(0, dx))
        diff = key[ys, xs] != key[yd, xd]
        edge[ys, xs] |= diff
        edge[yd, xd] |= diff
    return edge


def _run_jobs(func, ranges, pool, progress, done, total):
    rays = 0
    if pool is None:
        for a, b in ranges:
            rays += func(a, b)
            done += 1
            if progress is not None:
                progress(done, total)
        return rays, done
    futures = [pool.submit(func, a, b) for a, b in ranges]
    for fut in as_completed(futures):
        rays += fut.result()
        done += 1
        if progress is not None:
            progress(done, total)
    return rays, done


def _openblas_thread_controls() -> list:
    """(get, set) ctypes functions of every OpenBLAS library loaded in this process (Linux; else [])."""
    try:
        with open("/proc/self/maps") as f:
            fields = (line.split(maxsplit=5) for line in f if "openblas" in line.lower())
            paths = sorted({x[5].strip() for x in fields if len(x) == 6 and os.path.isfile(x[5].strip())})
    except OSError:
        return []
    controls = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in ("scipy_openblas_{}_num_threads64_", "scipy_openblas_{}_num_threads", "openblas_{}_num_threads64_",
                     "openblas_{}_num_threads"):
            get, put = getattr(lib, name.format("get"), None), getattr(lib, name.format("set"), None)
            if get is not None and put is not None:
                get.restype, get.argtypes = ctypes.c_int, []
                put.restype, put.argtypes = None, [ctypes.c_int]
                controls.append((get, put))
                break
    return controls


@contextlib.contextmanager
def single_threaded_blas():
    """Run the block with one OpenBLAS thread (restored afterwards).

    The renderer's matrix products are tiny ((N, 3) @ (3, 3)); with OpenBLAS's own threads on
    top of the worker processes they spin for the cores and run 10–100× slower on a busy machine.
    """
    controls = _openblas_thread_controls()
    old = [get() for get, _ in controls]
    for _, put in controls:
        put(1)
    try:
        yield
    finally:
        for (_, put), n in zip(controls, old):
            put(n)


_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc <malloc.h>
KEEP_MMAP_THRESHOLD = 32 << 20
"""Bytes above which glibc still maps a fresh block (its largest allowed threshold)."""
KEEP_TRIM_THRESHOLD = 1 << 30
"""Free bytes a process's heap keeps before it returns memory to the kernel."""


def keep_freed_memory() -> bool:
    """Make glibc's malloc keep freed memory for reuse instead of returning it to the kernel.

    Process-wide: call it only in a process you own (the render workers do; the `catadioptric`
    command does). By default glibc maps every block above a moving threshold afresh and trims
    the heap as soon as it is freed, so each tile's numpy temporaries are zero-filled by the
    kernel again: on this project's 2-core VM that was 140 k page faults and 0.3 s of system
    time per 1600×1200 render. Returns False (and changes nothing) where there is no glibc.
    """
    try:
        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.restype, mallopt.argtypes = ctypes.c_int, [ctypes.c_int, ctypes.c_int]
    return bool(mallopt(_M_MMAP_THRESHOLD, KEEP_MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, KEEP_TRIM_THRESHOLD))


def plain_pages() -> bool:
    """Stop numpy from advising transparent huge pages for its large arrays.

    Process-wide, like `keep_freed_memory`: call it only in a process you own (the `catadioptric`
    command does). numpy advises huge pages (madvise) for every array of 4 MiB or more. Where the
    kernel's THP defrag setting is `madvise` (this VM's, and a common default), a page fault in such
    an array may compact memory on the spot to find 2 MiB of it: on this project's 2-core VM, one
    100 MB array took 17 ms to fill fresh with huge pages when they were at hand and 110–260 ms in
    half the fresh processes, against 40–45 ms in 4 KiB pages every time; one reconstruct of a
    2048×1536 image, which fills 280 MB of arrays afresh, took 0.1–0.3 s longer with the advice.
    Returns False (and changes nothing) where numpy has no such switch or where the environment
    variable NUMPY_MADVISE_HUGEPAGE, numpy's own, says what to do.
    """
    if "NUMPY_MADVISE_HUGEPAGE" in os.environ:
        return False
    try:
        from numpy._core.multiarray import _set_madvise_hugepage
    except ImportError:  # numpy 1.x
        try:
            from numpy.core.multiarray import _set_madvise_hugepage
        except ImportError:
            return False
    _set_madvise_hugepage(False)
    return True


def _check_int(value, name, lo):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise RaytraceError(f"{name}: expected an integer >= {lo}, got {value!r}")
    return int(value)


def _render_channels(scene, camera, spp, seed, bounces, progress, workers, backend, adaptive, out) -> Render:
    """`render` of a camera whose red or blue channel has a lens of its own (`raytrace.chroma`): the scene rendered
    through green's camera (the image, every truth array and the rays counted), then through each such channel's,
    whose render gives that channel of the image. The progress runs once over the renders."""
    lensed = [(k, name) for k, name in ((0, "red"), (2, "blue")) if getattr(camera, name) is not None]
    parts = 1 + len(lensed)

    def part(i):
        if progress is None:
            return None
        return lambda done, total: progress(i * total + done, parts * total)

    result = render(scene, camera.channel_camera("green"), spp, seed, bounces, part(0), workers, backend, adaptive,
                    out)
    for i, (k, name) in enumerate(lensed, start=1):
        other = render(scene, camera.channel_camera(name), spp, seed, bounces, part(i), workers, backend, adaptive)
        result.image[..., k] = other.image[..., k]
        result.rays_traced += other.rays_traced
    return result


def render(
    scene: Scene,
    camera,
    spp: int = 4,
    seed: int = 0,
    bounces: int = 2,
    progress=None,
    workers: int = 2,
    backend: str = "embree",
    adaptive: bool = True,
    out: dict | None = None,
) -> Render:
    """Render `scene` through `camera`.

    Parameters
    ----------
    scene : Scene
    camera : PinholeCamera, XSlitCamera or PushbroomCamera (anything with `resolution` and `rays`)
    spp : int >= 1, stratified jittered samples per (edge) pixel, from
        `pixel_sample_offsets(pixel, spp, seed)` (a pattern rotated differently in every pixel)
    seed : int >= 0; the same seed gives the same bytes
    bounces : int >= 0, the most mirror reflections followed per ray
    progress : callable progress(done: int, total: int) or None
    workers : int >= 1, processes for large images (forked; Embree holds the GIL)
    backend : "embree" (default) or "numpy" (the analytic twin)
    adaptive : trace the `spp` samples only where the pixel-centre pass shows an edge;
        False traces them for every pixel
    out : optional {name: array} to render into, for any of the `Render` arrays (same name,
        shape and dtype; C-contiguous and writeable). An `np.memmap` of a file opened "r+" or "w+"
        (memory the worker processes share) is written in place, so a render can go straight into
        its output file; any other array is filled by a copy at the end. The returned `Render`
        holds these arrays.

    Returns
    -------
    Render
    """
    if not isinstance(scene, Scene):
        raise RaytraceError(f"scene: expected a raytrace.scene.Scene, got {type(scene).__name__}")
    if not hasattr(camera, "rays") or not hasattr(camera, "resolution"):
        raise RaytraceError("camera: expected a camera with `resolution` and `rays(pixels)`")
    if getattr(camera, "has_channel_lenses", False):
        return _render_channels(scene, camera, spp, seed, bounces, progress, workers, backend, adaptive, out)
    spp = _check_int(spp, "spp", 1)
    seed = _check_int(seed, "seed", 0)
    bounces = _check_int(bounces, "bounces", 0)
    workers = _check_int(workers, "workers", 1)
    if backend not in ("embree", "numpy"):
        raise RaytraceError(f"backend: expected 'embree' or 'numpy', got {backend!r}")
    w, h = camera.resolution
    npx = w * h
    given = _check_out(out, h, w)
    out = {"key": _shared((npx,), np.int32)}
    for name, (tail, dtype) in OUTPUTS.items():
        arr = given.get(name)
        out[name] = arr.reshape((npx,) + tail) if arr is not None and _in_shared_memory(arr) else _shared((npx,) + tail, dtype)
    # Everything the workers read exists before they fork (one pool for both passes); the
    # edge pixels found after pass 1 go to shared memory.
    edge_index = _shared((npx,), np.int64)
    _STATE.clear()
    _STATE.update(scene=scene, camera=camera, bounces=bounces, backend=backend, out=out,
                  edge_index=edge_index, spp=spp, seed=seed)
    tiles = [(a, min(a + TILE_PIXELS, npx)) for a in range(0, npx, TILE_PIXELS)]
    parallel = workers > 1 and npx >= MIN_PARALLEL_PIXELS
    pool = None
    try:
        with single_threaded_blas():
            if parallel:
                if backend == "embree":  # its BVHs built here, before any worker forks (`raytrace._embree.commit`)
                    _tracer().commit()
                pool = ProcessPoolExecutor(max_workers=min(workers, len(tiles)),
                                           mp_context=multiprocessing.get_context("fork"),
                                           initializer=keep_freed_memory)
            # Pass 1: pixel centres. The total is re-estimated once the edge count is known.
            rays, done = _run_jobs(_centre_tile, tiles, pool, progress, 0, len(tiles) + 1)
            key = out["key"].reshape(h, w)
            if spp == 1:
                samp = np.zeros((h, w), dtype=bool)
            else:
                samp = _edges(key) if adaptive else np.ones((h, w), dtype=bool)
            found = np.flatnonzero(samp.reshape(-1))
            edge_index[: len(found)] = found
            chunks = [(a, min(a + CHUNK_PIXELS, len(found))) for a in range(0, len(found), CHUNK_PIXELS)]
            if chunks:
                # one chunk: trace it here rather than pay a round trip to a worker
                more, done = _run_jobs(_sample_chunk, chunks, pool if len(chunks) > 1 else None, progress, done,
                                       len(tiles) + len(chunks))
                rays += more
            elif progress is not None:
                progress(len(tiles) + 1, len(tiles) + 1)
    finally:
        if pool is not None:
            pool.shutdown()
        _STATE.clear()
    arrays = {}
    for name, (tail, _) in OUTPUTS.items():
        arrays[name] = out[name].reshape((h, w) + tail)
        if name in given and not np.shares_memory(given[name], arrays[name]):
            given[name][...] = arrays[name]
            arrays[name] = given[name]
    return Render(**arrays, rays_traced=int(rays), supersampled=samp)
