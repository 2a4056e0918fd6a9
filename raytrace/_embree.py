"""Embree access: `build_scene`, `commit` and `first_hits`, the one place where rays become float32.

Everything else in `raytrace` stays float64; hits found here are refined in float64 by callers.
"""

from __future__ import annotations

import numpy as np


def build_scene(triangles: np.ndarray):
    """An embreex EmbreeScene holding `triangles` (T, 3, 3) as one mesh (primitive id = row)."""
    from embreex import mesh_construction, rtcore_scene

    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, np.ascontiguousarray(triangles, dtype=np.float32))
    return scene


def first_hits(scene, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Index of the first triangle hit by each ray, (N,) int64, −1 where none.

    origins, directions : (N, 3) float64, cast to float32 here and only here.
    """
    if len(origins) == 0:
        return np.zeros(0, dtype=np.int64)
    o32 = np.ascontiguousarray(origins, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    return np.asarray(scene.run(o32, d32), dtype=np.int64)


def commit(scene) -> None:
    """Build `scene`'s BVH now (embreex builds it on the first query otherwise). Done before processes fork, their
    queries then only read it: a forked process that builds one itself runs Embree's task scheduler (TBB) as the
    parent left it, whose worker threads it does not have, and can wait for them for ever."""
    scene.run(np.zeros((1, 3), np.float32), np.array([[0.0, 0.0, 1.0]], np.float32))
