"""Tests of raytrace.truth: the ray map and exact reflection pixels against independent solves."""

import numpy as np
import pytest
from rt_scenes import cylinder, small_camera, three_cubes
from scipy.optimize import root

from raytrace.camera import PinholeCamera
from raytrace.errors import RaytraceError
from raytrace.mirror import CylinderMirror
from raytrace.truth import cube_truth, mirror_rays, reflection_pixels

FULL_CAMERA = PinholeCamera.from_look_at((1600, 1200), 3500.0, None, [0.0, 0.0, 0.55], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])


def _fermat_point(mirror, eye, point, x0):
    """Independent solve: stationary path length |eye − M| + |M − point| over M(φ, h) on the cylinder."""
    e1, e2, a = mirror.frame

    def surface(x):
        phi, h = x
        return mirror.center + mirror.radius * (np.cos(phi) * e1 + np.sin(phi) * e2) + h * a

    def grad(x):
        phi, h = x
        m = surface(x)
        g = (m - eye) / np.linalg.norm(m - eye) + (m - point) / np.linalg.norm(m - point)
        dphi = mirror.radius * (-np.sin(phi) * e1 + np.cos(phi) * e2)
        return [g @ dphi, g @ a]

    sol = root(grad, x0, method="hybr", tol=1e-14)
    assert np.max(np.abs(sol.fun)) < 1e-12  # stationary: the gradient of the path length vanishes
    return surface(sol.x)


def test_reflection_pixels_match_fermat_solve():
    m = cylinder()
    rng = np.random.default_rng(11)
    e1, e2, a = m.frame
    pts = np.concatenate([c.vertices() for c in three_cubes()] + [rng.uniform([-0.4, -0.15, 0.5], [0.4, 0.15, 1.2], size=(20, 3))])
    pix, valid = reflection_pixels(FULL_CAMERA, m, pts)
    assert valid.sum() >= 30
    for p, px, ok in zip(pts, pix, valid):
        if not ok:
            continue
        # start the independent solver at the azimuth halfway between eye and point
        rel = p - m.center
        phi0 = np.arctan2((rel @ e2 + 0.55 * (np.array([0, 0, 1.0]) @ e2)) / 2, (rel @ e1 + 0.55 * (np.array([0, 0, 1.0]) @ e1)) / 2)
        M = _fermat_point(m, FULL_CAMERA.position, p, [phi0, 0.0])
        ref, _ = FULL_CAMERA.project(M[None])
        assert np.max(np.abs(ref[0] - px)) < 0.01


def test_reflection_pixels_rays_pass_through_the_points():
    """The reflected ray of each truth pixel (via `mirror_rays`, an independent code path) meets its 3D point."""
    m = CylinderMirror(0.08, 0.4, [0.01, 0.0, -0.02], [0.1, 1.0, 0.05])
    rng = np.random.default_rng(3)
    pts = rng.uniform([-0.5, -0.2, 0.3], [0.5, 0.2, 1.5], size=(300, 3))
    pix, valid = reflection_pixels(FULL_CAMERA, m, pts)
    assert valid.sum() > 50
    rays = mirror_rays(FULL_CAMERA, m, pix[valid])
    assert np.all(rays.hit)
    v = pts[valid] - rays.points
    dist = np.linalg.norm(np.cross(v, rays.directions), axis=1)
    assert np.max(dist) < 1e-9
    assert np.all(np.sum(v * rays.directions, axis=1) > 0)  # in front of the mirror, not behind
    # a point inside the cylinder, and one hidden straight behind it, have no reflection
    _, bad = reflection_pixels(FULL_CAMERA, m, [[0.01, 0.0, -0.02], [0.0, 0.0, -1.0]])
    assert not bad.any()


def test_mirror_rays_obey_reflection_law_per_pixel():
    cam = small_camera()
    m = cylinder()
    rays = mirror_rays(cam, m)
    o, d = cam.rays(cam.pixel_grid())
    assert rays.points.shape == (160 * 120, 3) and rays.hit.mean() > 0.5
    h = rays.hit
    n = m.radial_vectors(rays.points[h]) / m.radius
    np.testing.assert_allclose(np.sum(rays.directions[h] * n, axis=1), -np.sum(d[h] * n, axis=1), atol=1e-13)
    np.testing.assert_allclose(rays.directions[h] @ m.axis, d[h] @ m.axis, atol=1e-13)
    assert np.all(np.isnan(rays.directions[~h]))


def test_cube_truth_keys_and_values():
    m = cylinder()
    cube = three_cubes()[0]
    t = cube_truth(FULL_CAMERA, m, cube)
    for key in ("center", "size", "depth", "front_face_center", "front_face_corners_px"):
        assert key in t
    np.testing.assert_allclose(t["depth"], np.hypot(0.24, 0.90))  # axis is y through the origin
    assert len(t["front_face_corners_px"]) == 4 and all(t["front_face_corners_valid"])
    # front face centre is half an edge from the cube centre, toward the axis side
    fc = np.array(t["front_face_center"])
    np.testing.assert_allclose(np.linalg.norm(fc - cube.center), 0.02, atol=1e-15)
    assert np.hypot(fc[0], fc[2]) < np.hypot(0.24, 0.90)


def test_reflection_pixels_needs_central_camera():
    from raytrace.camera import XSlitCamera

    with pytest.raises(RaytraceError, match="camera: reflection_pixels needs a central"):
        reflection_pixels(XSlitCamera((10, 10), -0.1, -0.5), cylinder(), [[0.2, 0.0, 0.8]])
