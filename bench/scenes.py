"""Benchmark scenes: `make_scenes(n, seed)` draws `BenchScene`s (a `Setup` plus per-cube labels) for the reconstruct bench.

Each scene is a vertical cylinder mirror seen by a pinhole camera looking at its axis, with 3–5
coloured cubes placed 2–10 mirror radii from the axis within ±60° of azimuth (measured from the
camera's side). A cube is kept only if its whole reflection (all vertices and edge samples, from
the exact reflection law of `raytrace.truth`) lies inside the mirror region and the image with a
margin, its image box does not overlap another cube's, and the camera cannot see it directly
(its vertices are outside the view frustum and no ray of a coarse pixel grid hits it). Otherwise
it is redrawn. Half the scenes have every cube facing the mirror axis ("axis"), half have every
cube turned 5–25° about the vertical from that ("turned").
"""

from __future__ import annotations

import colorsys
import hashlib
import math
from dataclasses import dataclass

import numpy as np

from catadioptric.setup import CameraConfig, CubeConfig, CylinderConfig, SceneConfig, Setup, setup_to_toml

__all__ = ["BenchScene", "make_scenes", "RESOLUTIONS", "scene_hash", "cube_image_points"]

RESOLUTIONS = ((1024, 768), (1280, 960), (1600, 1200), (2048, 1536))
MARGIN_PX = 6.0
"""Smallest distance, in pixels, from a cube's reflection to the mirror's edge, the image border or another cube."""


@dataclass(frozen=True)
class BenchScene:
    """One benchmark case: `setup` (camera, mirror, cubes, scene) and per-cube labels.

    name : str, e.g. "s07"
    kind : "axis" (cubes face the mirror axis) or "turned" (turned 5–25° about the vertical)
    turn_deg : tuple of float, per cube, the turn from facing the axis (0 for "axis" scenes)
    same_size : bool, every cube has the same edge length (the case of the `shape_prior` estimator)
    """

    name: str
    kind: str
    setup: Setup
    turn_deg: tuple
    same_size: bool = False

    @property
    def key(self) -> str:
        return scene_hash(self.setup)


def scene_hash(setup: Setup, extra: str = "") -> str:
    """A short content hash of a setup (keys the render cache)."""
    return hashlib.sha1((setup_to_toml(setup) + extra).encode()).hexdigest()[:16]


def cube_image_points(cube, samples: int = 9) -> np.ndarray:
    """(12·samples, 3) float64 points along the 12 edges of a `raytrace.scene.Cube`."""
    v = cube.vertices()
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    t = np.linspace(0.0, 1.0, samples)[:, None]
    return np.concatenate([v[a] + t * (v[b] - v[a]) for a, b in edges])


def _colors(rng, k: int) -> list:
    """k saturated linear-RGB colours with hues at least 360/(k+1) degrees apart."""
    h0 = rng.uniform(0, 1)
    hues = (h0 + np.arange(k) / k + rng.uniform(-0.15, 0.15, k) / k) % 1.0
    rng.shuffle(hues)
    out = []
    for h in hues:
        r, g, b = colorsys.hsv_to_rgb(h, rng.uniform(0.75, 0.9), rng.uniform(0.7, 0.9))
        out.append(tuple(round(float(c), 4) for c in (r, g, b)))
    return out


class _Checker:
    """Feasibility tests of one camera + mirror: the mirror mask and the direct-view grid."""

    def __init__(self, camera_cfg: CameraConfig, mirror_cfg: CylinderConfig):
        self.camera = camera_cfg.build()
        self.mirror = mirror_cfg.build()
        w, h = camera_cfg.resolution
        self.w, self.h = w, h
        gu, gv = np.meshgrid(np.linspace(0, w - 1, 96), np.linspace(0, h - 1, 72))
        self.grid_o, self.grid_d = self.camera.rays(np.column_stack([gu.ravel(), gv.ravel()]))

    def seen_directly(self, cube) -> bool:
        pix, zc = self.camera.project(cube_image_points(cube, 5))
        front = zc > 1e-6
        inside = front & (pix[:, 0] > -1) & (pix[:, 0] < self.w) & (pix[:, 1] > -1) & (pix[:, 1] < self.h)
        if inside.any():
            return True
        return bool(cube.hits(self.grid_o, self.grid_d).any())

    def image_box(self, cube):
        """(u0, v0, u1, v1) of the cube's reflection, or None if any part is not cleanly inside the mirror."""
        from raytrace.truth import reflection_pixels
        pix, valid = reflection_pixels(self.camera, self.mirror, cube_image_points(cube))
        if not valid.all():
            return None
        u, v = pix[:, 0], pix[:, 1]
        if u.min() < MARGIN_PX or v.min() < MARGIN_PX or u.max() > self.w - 1 - MARGIN_PX or v.max() > self.h - 1 - MARGIN_PX:
            return None
        offsets = MARGIN_PX * np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]], dtype=np.float64)
        around = (pix[None, :, :] + offsets[:, None, :]).reshape(-1, 2)
        if not self.mirror.intersect(*self.camera.rays(around))[1].all():
            return None  # within MARGIN_PX of the mirror's silhouette or its top/bottom rim
        return (u.min(), v.min(), u.max(), v.max())


def _overlaps(a, b) -> bool:
    m = MARGIN_PX
    return not (a[2] + m < b[0] or b[2] + m < a[0] or a[3] + m < b[1] or b[3] + m < a[1])


def _draw_scene(rng, index: int, kind: str, resolution, same_size: bool = False,
                standing: bool = False, distance=(4.0, 7.0)) -> BenchScene | None:
    from raytrace.scene import Cube
    w, h = resolution
    R = float(rng.uniform(0.075, 0.15))
    D = float(R * rng.uniform(*distance))
    fill = rng.uniform(0.55, 0.8)  # fraction of the image width the mirror spans
    f = float(fill * w * math.sqrt(D * D - R * R) / (2 * R))
    cam_h = float(rng.uniform(-0.5, 0.5) * R)
    camera = CameraConfig(resolution=(int(w), int(h)), focal_px=(round(f, 3), round(f, 3)),
                          position=(0.0, round(cam_h, 5), round(D, 5)), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    height = float(round(R * rng.uniform(4.5, 6.0), 5))
    mirror = CylinderConfig(radius=round(R, 5), height=height, center=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0))
    checker = _Checker(camera, mirror)
    n_cubes = int(rng.integers(3, 6))
    colours = _colors(rng, n_cubes)
    cubes, boxes, turns = [], [], []
    common = float(round(rng.uniform(0.025, 0.06), 4))
    for k in range(n_cubes):
        for _attempt in range(300):
            size = common if same_size else float(round(rng.uniform(0.02, 0.08), 4))
            dist = float(rng.uniform(2.0, 10.0) * R)
            az = math.radians(rng.uniform(-60.0, 60.0))
            y = float(rng.uniform(-0.25, 0.25) * height)
            if standing:  # on the floor the mirror stands on (the same draws made, the height replaced)
                y = -height / 2 + size / 2
            centre = (round(dist * math.sin(az), 5), round(y, 5), round(dist * math.cos(az), 5))
            facing = math.degrees(math.atan2(-centre[0], -centre[2]))  # local +z toward the axis
            turn = 0.0 if kind == "axis" else float(rng.choice([-1.0, 1.0]) * rng.uniform(5.0, 25.0))
            rot = (0.0, round(facing + turn, 4), 0.0)
            cube = Cube.from_euler_deg(size, centre, rot, colours[k])
            if dist - size * math.sqrt(3) / 2 < R * 1.3:
                continue
            if checker.seen_directly(cube):
                continue
            box = checker.image_box(cube)
            if box is None or any(_overlaps(box, b) for b in boxes):
                continue
            cubes.append(CubeConfig(size=size, center=centre, rotation_deg=rot, color=colours[k]))
            boxes.append(box)
            turns.append(round(turn, 4))
            break
        else:
            return None
    ground = bool(rng.uniform() < 0.4) or standing
    to_light = np.array([rng.uniform(-0.5, 0.5), 1.0, -rng.uniform(0.2, 1.0)])
    if rng.uniform() < 0.3:  # the library default: light from the camera's side
        light = SceneConfig.light_direction
    else:
        light = tuple(round(float(x), 4) for x in -to_light)
    scene = SceneConfig(background=tuple([round(float(rng.uniform(0.55, 0.85)), 3)] * 3), ground=ground,
                        light_direction=light, ambient=round(float(rng.uniform(0.3, 0.45)), 3))
    setup = Setup(camera=camera, mirror=mirror, objects=tuple(cubes), scene=scene)
    return BenchScene(name=f"s{index:02d}", kind=kind, setup=setup, turn_deg=tuple(turns), same_size=same_size)


def make_scenes(n: int = 24, seed: int = 5, standing: bool = False, distance=(4.0, 7.0)) -> list[BenchScene]:
    """`n` seeded scenes alternating "axis" / "turned"; each kind cycles through RESOLUTIONS (every fourth scene is
    2048×1536).

    Every third scene (index 2, 5, 8, ...) has cubes of one common size, for `shape_prior`. With `standing`, every
    cube stands on the floor the mirror stands on (its lower end; the scene has the ground plane there). The camera
    stands `distance` (a range, in mirror radii) from the axis: the default 4–7 sees the mirror through a lens about
    30° across; nearer, through a wider one (the mirror spans 55–80 % of the image width either way).

    A draw whose cubes cannot all be
    placed is discarded and redrawn (with the same generator, so the list is reproducible).
    """
    rng = np.random.default_rng(seed)
    out = []
    i = 0
    while len(out) < n:
        kind = "axis" if len(out) % 2 == 0 else "turned"
        j = len(out)
        res = RESOLUTIONS[(j // 2 + 2 * (j % 2)) % len(RESOLUTIONS)]
        s = _draw_scene(rng, len(out), kind, res, same_size=j % 3 == 2, standing=standing, distance=distance)
        i += 1
        if s is not None:
            out.append(s)
        if i > 20 * n:  # pragma: no cover - the ranges above always admit scenes
            raise RuntimeError("bench.scenes: could not place the cubes; widen the ranges")
    return out
