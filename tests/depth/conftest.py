"""Synthetic exact measurements of cube faces seen in a cylindrical mirror (no renderer involved).

Edge points come from `raytrace.truth.reflection_pixels` of points along the true 3D edges, an
exact reflection solve; face pixels are the pixel centres inside the imaged outline.
"""

import numpy as np
import pytest
from matplotlib.path import Path
from scipy.spatial.transform import Rotation

from depth.estimate import FaceMeasurement
from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube
from raytrace.truth import mirror_rays, reflection_pixels


class MirrorRig:
    def __init__(self, radius=0.1, distance=0.55, resolution=(800, 600), focal=1750.0):
        self.camera = PinholeCamera.from_look_at(resolution, (focal, focal), None, (0, 0, distance),
                                                 (0, 0, 0), (0, 1, 0))
        self.mirror = CylinderMirror(radius, 0.49, (0, 0, 0), (0, 1, 0))

    def rays(self, px):
        r = mirror_rays(self.camera, self.mirror, np.asarray(px, dtype=np.float64))
        return r.points, r.directions

    def cube(self, distance, azimuth_deg, height=0.01, size=0.04, yaw_deg=0.0, roll_deg=0.0):
        """A cube `distance` from the axis whose local +z face looks at the axis, then turned."""
        a = np.deg2rad(azimuth_deg)
        c = np.array([distance * np.sin(a), height, distance * np.cos(a)])
        yaw = np.arctan2(-c[0], -c[2]) + np.deg2rad(yaw_deg)
        rot = Rotation.from_euler("y", yaw).as_matrix() @ Rotation.from_euler("z", np.deg2rad(roll_deg)).as_matrix()
        return Cube(size, c, rot)

    def silhouette(self, cube, n=40):
        """`silhouette_measurement` of `cube` (a method, so that tests reach it through the `rig`
        fixture: importing `conftest` picks whichever conftest module was loaded first)."""
        return silhouette_measurement(self, cube, n)

    def measure(self, cube, n=50, noise_px=0.0, seed=0, gaps=False, side_offset_px=0.0, merged=False):
        """Exact (or noisy) FaceMeasurement of the cube's front face, with the silhouette of its back
        vertical edges where a side face shows (more than 0.75 px beyond the front face). `gaps`: also
        the silhouette's gaps to the front face (0 where the side face is hidden). `side_offset_px`:
        σ of a common outward offset added to each whole front side (as images give). `merged`: side
        faces as bright as the front face, so what is measured is the cube's outer contour: a seen
        side face's back edge instead of the front face's side (gap 0, no back side), and the top and
        bottom sides running on over that side face's top and bottom edges."""
        _, corners, centre = cube.front_face(self.mirror)
        n_out = (centre - cube.center) / np.linalg.norm(centre - cube.center)
        t = np.linspace(0.08, 0.92, n)[:, None]
        edges = [corners[i] * (1 - t) + corners[(i + 1) % 4] * t for i in range(4)]
        px = [reflection_pixels(self.camera, self.mirror, e)[0] for e in edges]
        back = [reflection_pixels(self.camera, self.mirror, e - cube.size * n_out)[0] for e in edges]
        rng = np.random.default_rng(seed)
        if noise_px:
            px = [p + rng.normal(0, noise_px, p.shape) for p in px]
            back = [p + rng.normal(0, noise_px, p.shape) for p in back]
        if side_offset_px:
            mid = np.mean(np.concatenate(px), axis=0)
            for i, p in enumerate(px):  # outward: away from the face's middle, along u or v
                k = int(np.argmax(np.abs(p.mean(0) - mid) / np.ptp(np.concatenate(px), axis=0)))
                px[i] = p + np.eye(2)[k] * np.sign(p.mean(0) - mid)[k] * rng.normal(0, side_offset_px)
        pairs = [(0, 2), (1, 3)]
        du = [abs(px[i][:, 0].mean() - px[j][:, 0].mean()) for i, j in pairs]
        lr, tb = pairs[int(np.argmax(du))], pairs[1 - int(np.argmax(du))]
        il, ir = sorted(lr, key=lambda i: px[i][:, 0].mean())
        top, bottom = sorted([px[tb[0]], px[tb[1]]], key=lambda p: p[:, 1].mean())
        back_sides, side_gaps, left_right = [], [], {}
        for i, sign in ((il, -1.0), (ir, 1.0)):
            gap = sign * (back[i][:, 0] - px[i][:, 0])
            left_right[i] = px[i]
            if merged and np.median(gap) > 0:  # the side face shows, merged: the contour is its back edge
                left_right[i] = back[i]
                ends = corners[[i, (i + 1) % 4]]
                ends_px = reflection_pixels(self.camera, self.mirror, ends)[0]
                upper, lower = ends[np.argmin(ends_px[:, 1])], ends[np.argmax(ends_px[:, 1])]
                t2 = np.linspace(0.05, 1.0, n // 2)[:, None] * cube.size
                top = np.concatenate([top, reflection_pixels(self.camera, self.mirror, upper - t2 * n_out)[0]])
                bottom = np.concatenate([bottom, reflection_pixels(self.camera, self.mirror, lower - t2 * n_out)[0]])
                gap = np.zeros(1)
            back_sides.append(back[i] if np.median(gap) > 0.75 else None)
            side_gaps.append(max(float(np.median(gap)), 0.0) if gaps or merged else float("nan"))
        outline = np.concatenate(px)
        lo, hi = np.floor(outline.min(0)), np.ceil(outline.max(0))
        gu, gv = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
        grid = np.column_stack([gu.ravel(), gv.ravel()])
        inside = Path(outline).contains_points(grid)
        corners_px = reflection_pixels(self.camera, self.mirror, corners)[0]
        return FaceMeasurement((left_right[il], left_right[ir], top, bottom), corners_px, grid[inside], max(noise_px, 0.0),
                               back_sides_px=tuple(back_sides), side_gaps_px=tuple(side_gaps))

    def depth(self, cube):
        return float(self.mirror.distance_to_axis(cube.center[None])[0])


@pytest.fixture(scope="session")
def rig():
    return MirrorRig()


def _ray_box_hit(points, directions, cube) -> np.ndarray:
    """(N,) bool: the rays meet the cube (slab test in the cube's frame)."""
    o = (points - cube.center) @ cube.rotation
    d = directions @ cube.rotation
    half = cube.size / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - o) / d, (half - o) / d
    near = np.nanmax(np.minimum(t1, t2), axis=1)
    far = np.nanmin(np.maximum(t1, t2), axis=1)
    return (far >= near) & (far > 0)


def silhouette_measurement(rig, cube, n=40):
    """FaceMeasurement of a cube whose faces all look alike (lit by a uniform sky): its outline is the
    cube's whole silhouette, found by bisecting, along rows (left/right) and columns (top/bottom)
    through the front face's middle 80 %, where the exact reflected rays stop meeting the cube. No
    edge of the model is used: only ray–box hits."""
    _, corners, _ = cube.front_face(rig.mirror)
    cpx = reflection_pixels(rig.camera, rig.mirror, corners)[0]
    lo, hi = cpx.min(axis=0), cpx.max(axis=0)
    mid, span = (lo + hi) / 2.0, hi - lo
    sides = []
    for axis, sign in ((0, -1.0), (0, 1.0), (1, -1.0), (1, 1.0)):  # left, right, top, bottom
        other = 1 - axis
        t = mid[other] + np.linspace(-0.4, 0.4, n) * span[other]
        inside, outside = np.full(n, mid[axis]), np.full(n, mid[axis] + sign * 3.0 * span.max())
        for _ in range(50):
            half = (inside + outside) / 2.0
            px = np.empty((n, 2))
            px[:, axis], px[:, other] = half, t
            hit = _ray_box_hit(*rig.rays(px), cube)
            inside, outside = np.where(hit, half, inside), np.where(hit, outside, half)
        px = np.empty((n, 2))
        px[:, axis], px[:, other] = (inside + outside) / 2.0, t
        sides.append(px)
    outline = np.concatenate([sides[0], sides[3], sides[1][::-1], sides[2][::-1]])
    gu, gv = np.meshgrid(np.arange(np.floor(lo[0]), np.ceil(hi[0]) + 1), np.arange(np.floor(lo[1]), np.ceil(hi[1]) + 1))
    grid = np.column_stack([gu.ravel(), gv.ravel()])
    order = np.argsort(np.arctan2(outline[:, 1] - mid[1], outline[:, 0] - mid[0]))
    face = grid[Path(outline[order]).contains_points(grid)]
    return FaceMeasurement(tuple(sides), cpx, face, 0.0, side_gaps_px=(0.0, 0.0, 0.0, 0.0))
