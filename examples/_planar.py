"""Planar scenes for the examples: `Patch` (a textured planar shape) and `render_planar` (analytic ray casting).

The project's ray tracer renders cubes and a ground plane; the paper's arch, card, corridor and facade
scenes are planar shapes, so the examples cast every pixel's rays analytically against planes
(vectorised over pixels, a loop over patches and sub-pixel samples) through any camera with `rays`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass
class Patch:
    """A planar shape: points center + a·e1 + b·e2 with inside(a, b) true, of gray value shade(a, b).

    center : (3,), e1, e2 : (3,) orthonormal; inside, shade : callables on (N,) arrays.
    """

    center: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    inside: Callable
    shade: Callable

    def hit(self, o, d):
        """Ray parameter t (N,) (inf on a miss) and value (N,) of rays o, d (N, 3)."""
        n = np.cross(self.e1, self.e2)
        den = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((self.center - o) @ n) / den
        p = o + t[:, None] * d - self.center
        a, b = p @ self.e1, p @ self.e2
        ok = np.isfinite(t) & (t > 0) & self.inside(a, b)
        return np.where(ok, t, np.inf), np.where(ok, self.shade(a, b), 0.0)


def rect(center, e1, e2, half_a, half_b, shade=1.0):
    """An axis-aligned rectangle |a| <= half_a, |b| <= half_b (shade: a number or a callable)."""
    f = shade if callable(shade) else (lambda a, b, s=float(shade): np.full(a.shape, s))
    return Patch(np.asarray(center, float), np.asarray(e1, float), np.asarray(e2, float),
                 lambda a, b: (np.abs(a) <= half_a) & (np.abs(b) <= half_b), f)


def annulus(center, e1, e2, r_in, r_out, shade=1.0):
    """A ring r_in <= |(a, b)| <= r_out."""
    return Patch(np.asarray(center, float), np.asarray(e1, float), np.asarray(e2, float),
                 lambda a, b: (np.hypot(a, b) >= r_in) & (np.hypot(a, b) <= r_out),
                 lambda a, b: np.full(a.shape, float(shade)))


def render_planar(patches, camera_rays, resolution, samples=4, background=0.0, chunk=1 << 18):
    """Render gray patches: returns image (H, W) box-filtered over samples² sub-pixel rays, z (H, W) of the
    nearest hit's point along e_z=(0,0,1) at pixel centres (inf on a miss), id (H, W) int (−1 on a miss).

    camera_rays : callable pixels (N, 2) → origins (N, 3), unit directions (N, 3).
    """
    w, h = resolution
    vv, uu = np.mgrid[0:h, 0:w]
    pix = np.column_stack([uu.ravel(), vv.ravel()]).astype(np.float64)
    # A sheared n×n grid: n² distinct offsets along u and along v (edges resolve to 1/n² px).
    i, j = np.meshgrid(np.arange(samples), np.arange(samples), indexing="ij")
    offs = np.column_stack([((i + (j + 0.5) / samples) / samples - 0.5).ravel(),
                            ((j + (i + 0.5) / samples) / samples - 0.5).ravel()])
    image = np.zeros(len(pix))
    zbuf = np.full(len(pix), np.inf)
    ids = np.full(len(pix), -1)
    for s0 in range(0, len(pix), chunk):
        sl = slice(s0, s0 + chunk)
        for off in offs:
            o, d = camera_rays(pix[sl] + off)
            best_t = np.full(len(o), np.inf)
            val = np.full(len(o), float(background))
            for p in patches:
                t, v = p.hit(o, d)
                nearer = t < best_t
                best_t[nearer], val[nearer] = t[nearer], v[nearer]
            image[sl] += val
        o, d = camera_rays(pix[sl])
        best_t = np.full(len(o), np.inf)
        for k, p in enumerate(patches):
            t, _ = p.hit(o, d)
            nearer = t < best_t
            best_t[nearer] = t[nearer]
            ids[sl][nearer] = k
        zbuf[sl] = np.where(np.isfinite(best_t), o[:, 2] + best_t * d[:, 2], np.inf)
    return (image / samples ** 2).reshape(h, w), zbuf.reshape(h, w), ids.reshape(h, w)
