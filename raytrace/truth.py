"""Exact ground truth: the per-pixel ray map `mirror_rays`, `reflection_pixels` of 3D points and `cube_truth`.

Everything here is analytic float64 geometry (no rasterisation): the reflected ray of each
pixel, and for each 3D point the pixel where its mirror image appears, found by solving the
reflection law on the cylinder exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_points
from .errors import RaytraceError
from .mirror import CylinderMirror, reflect

__all__ = ["MirrorRays", "mirror_rays", "mirror_mask", "reflection_pixels", "cube_truth"]


@dataclass(frozen=True)
class MirrorRays:
    """Reflected rays of a set of pixels (the "ray map").

    Attributes
    ----------
    points : (N, 3) float64, exact mirror points, NaN where the pixel misses the mirror
    directions : (N, 3) float64, unit reflected directions (toward the scene), NaN on misses
    hit : (N,) bool, pixel sees the mirror
    """

    points: np.ndarray
    directions: np.ndarray
    hit: np.ndarray


def mirror_rays(camera, mirror, pixels=None) -> MirrorRays:
    """The exact reflected ray of each pixel's centre ray.

    Parameters
    ----------
    camera : any camera with `rays(pixels)` (e.g. PinholeCamera)
    mirror : CylinderMirror or MeshMirror
    pixels : (N, 2) float64 (u, v), or None for every pixel in row-major order (N = H·W)

    Returns
    -------
    MirrorRays
    """
    if pixels is None:
        pixels = camera.pixel_grid()
    origins, directions = camera.rays(pixels)
    _, hit, points, normals = mirror.intersect(origins, directions)
    reflected = reflect(directions, normals)  # NaN where normals are NaN
    return MirrorRays(points=points, directions=reflected, hit=hit)


def mirror_mask(camera, mirror, block: int = 8) -> np.ndarray:
    """(H, W) bool: pixels whose centre ray hits the mirror, the same as `mirror_rays(...).hit`.

    Traces one ray per `block`×`block` block corner first, then every pixel only in blocks whose
    corners disagree or touch a disagreeing block, so the cost follows the mirror's outline rather
    than the image area. A mirror feature smaller than a block between hits could be missed; the
    cylinder's image is a smooth region many blocks wide.
    """
    w, h = camera.resolution
    # the mirror's hit test alone where it has one (`CylinderMirror.hits`), else `intersect`'s
    hits = getattr(mirror, "hits", None) or (lambda o, d: mirror.intersect(o, d)[1])
    gx = np.arange(0, w + block, block).clip(max=w - 1).astype(np.float64)
    gy = np.arange(0, h + block, block).clip(max=h - 1).astype(np.float64)
    uu, vv = np.meshgrid(gx, gy)
    o, d = camera.rays(np.column_stack([uu.ravel(), vv.ravel()]))
    corner_hit = hits(o, d).reshape(len(gy), len(gx))
    # A block is uniform when its four corners agree; mixed blocks and their neighbours are traced.
    c = corner_hit
    all_in = c[:-1, :-1] & c[1:, :-1] & c[:-1, 1:] & c[1:, 1:]
    any_in = c[:-1, :-1] | c[1:, :-1] | c[:-1, 1:] | c[1:, 1:]
    mixed = any_in & ~all_in
    grow = mixed.copy()
    grow[1:, :] |= mixed[:-1, :]
    grow[:-1, :] |= mixed[1:, :]
    grow[:, 1:] |= grow[:, :-1].copy()
    grow[:, :-1] |= grow[:, 1:].copy()
    mask = np.repeat(np.repeat(all_in & ~grow, block, axis=0), block, axis=1)[:h, :w]
    by, bx = np.nonzero(grow)
    if len(by):
        ys = (by[:, None] * block + np.arange(block)[None, :])
        xs = (bx[:, None] * block + np.arange(block)[None, :])
        py = np.repeat(ys, block, axis=1).ravel()
        px = np.tile(xs, (1, block)).ravel()
        keep = (py < h) & (px < w)
        py, px = py[keep], px[keep]
        o, d = camera.rays(np.column_stack([px, py]).astype(np.float64))
        mask[py, px] = hits(o, d)
    return mask


def _perp_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def cylinder_reflection_points(mirror: CylinderMirror, eye, points) -> tuple[np.ndarray, np.ndarray]:
    """Mirror points where rays from `eye` reflect to `points`, on an open cylinder.

    The normal is radial, so the reflection law splits: in the cross-section the 2-D law
    holds on the circle (a 1-D root in the azimuth φ, found by vectorised bisection to machine
    precision), and along the axis the height varies linearly with unfolded in-plane path
    length.

    Parameters
    ----------
    mirror : CylinderMirror
    eye : (3,) float64, the centre of projection
    points : (N, 3) float64

    Returns
    -------
    mirror_points : (N, 3) float64 (NaN where invalid)
    valid : (N,) bool, both eye and point are outside the cylinder, the reflection point is
        seen by both on the outer surface and lies within the mirror's height
    """
    P = as_points(points, "points")
    C = np.asarray(eye, dtype=np.float64)
    R = mirror.radius
    a = mirror.axis
    e1, e2 = _perp_basis(a)
    rel_c = C - mirror.center
    rel_p = P - mirror.center
    c2 = np.array([rel_c @ e1, rel_c @ e2])
    p2 = np.stack([rel_p @ e1, rel_p @ e2], axis=1)
    hc = rel_c @ a
    hp = rel_p @ a
    rc = np.linalg.norm(c2)
    rp = np.linalg.norm(p2, axis=1)
    if not rc > R:
        raise RaytraceError("camera: expected the camera outside the mirror cylinder")
    outside = rp > R
    alpha_c = np.arctan2(c2[1], c2[0])
    alpha_p = np.arctan2(p2[:, 1], p2[:, 0])
    delta = np.angle(np.exp(1j * (alpha_p - alpha_c)))  # wrapped to (-π, π]
    sgn = np.where(delta >= 0, 1.0, -1.0)
    beta_c = np.arccos(np.clip(R / rc, -1, 1))
    beta_p = np.arccos(np.clip(R / np.where(outside, rp, 2 * R), -1, 1))
    lo = np.maximum(0.0, np.abs(delta) - beta_p)
    hi = np.minimum(np.abs(delta), beta_c)
    valid = outside & (lo <= hi)

    def residual(s):
        phi = alpha_c + sgn * s
        m = R * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        n = m / R
        uc = c2 - m
        up = p2 - m
        uc /= np.linalg.norm(uc, axis=1, keepdims=True)
        up /= np.linalg.norm(up, axis=1, keepdims=True)
        g = (n[:, 0] * uc[:, 1] - n[:, 1] * uc[:, 0]) + (n[:, 0] * up[:, 1] - n[:, 1] * up[:, 0])
        return sgn * g  # > 0 on the camera's side of the solution

    with np.errstate(invalid="ignore", divide="ignore"):
        f_lo, f_hi = residual(lo), residual(hi)
        exact_lo = np.abs(f_lo) == 0
        valid &= exact_lo | ((f_lo > 0) & (f_hi <= 0))
        a_, b_ = lo.copy(), hi.copy()
        for _ in range(64):  # interval halves each time: 2^-64 of at most π
            mid = 0.5 * (a_ + b_)
            pos = residual(mid) > 0
            a_ = np.where(pos, mid, a_)
            b_ = np.where(pos, b_, mid)
        s = np.where(exact_lo, lo, 0.5 * (a_ + b_))
        phi = alpha_c + sgn * s
        m2 = R * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        lc = np.linalg.norm(c2 - m2, axis=1)
        lp = np.linalg.norm(p2 - m2, axis=1)
        hm = hc + (hp - hc) * lc / (lc + lp)
    valid &= np.abs(hm) <= mirror.height / 2
    M = mirror.center + np.outer(m2[:, 0], e1) + np.outer(m2[:, 1], e2) + np.outer(hm, a)
    M[~valid] = np.nan
    return M, valid


def reflection_pixels(camera, mirror, points) -> tuple[np.ndarray, np.ndarray]:
    """Pixels where 3D points appear in the mirror, from the exact reflection law.

    Parameters
    ----------
    camera : PinholeCamera (a central camera: `position` is the centre of projection)
    mirror : CylinderMirror
    points : (N, 3) float64

    Returns
    -------
    pixels : (N, 2) float64, (u, v); NaN where not valid (may lie outside the image)
    valid : (N,) bool, a reflection exists on the mirror (see `cylinder_reflection_points`)
        and the mirror point is in front of the camera. Occlusion by other objects is not
        considered.
    """
    if not getattr(camera, "is_central", False):
        raise RaytraceError("camera: reflection_pixels needs a central (pinhole) camera")
    if not isinstance(mirror, CylinderMirror):
        raise RaytraceError(f"mirror: reflection_pixels supports CylinderMirror, got {type(mirror).__name__}")
    M, valid = cylinder_reflection_points(mirror, camera.position, points)
    pix = np.full((len(M), 2), np.nan)
    if np.any(valid):
        p, z = camera.project(M[valid])
        ok = z > 0
        idx = np.flatnonzero(valid)
        pix[idx[ok]] = p[ok]
        valid[idx[~ok]] = False
    return pix, valid


def cube_truth(camera, mirror, cube) -> dict:
    """Ground truth of one cube with the keys of the reconstruct result (SETUP_FORMAT.md).

    Returns
    -------
    dict with plain-Python values (JSON-ready):
      center : [x, y, z], size : float, depth : float (distance from the mirror axis to the
      centre), front_face_center : [x, y, z], front_face_corners_px : 4×[u, v] in the order
      of `Cube.front_face` (NaN where a corner has no reflection), front_face_corners_valid :
      4 bools, front_face_corners : 4×[x, y, z] world corners, method : "exact".
    """
    _, corners, face_center = cube.front_face(mirror)
    pix, valid = reflection_pixels(camera, mirror, corners)
    return {
        "center": [float(x) for x in cube.center],
        "size": float(cube.size),
        "depth": float(mirror.distance_to_axis(cube.center[None, :])[0]),
        "front_face_center": [float(x) for x in face_center],
        "front_face_corners_px": [[float(u), float(v)] for u, v in pix],
        "front_face_corners_valid": [bool(x) for x in valid],
        "front_face_corners": [[float(x) for x in c] for c in corners],
        "method": "exact",
    }
