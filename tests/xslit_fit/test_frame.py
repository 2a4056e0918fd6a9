"""Tests of xslit_fit.frame: the XSlit frame of CONVENTIONS, κ coordinates, the DDAR aspect ratio, sub-pixel rays."""

import numpy as np
import pytest
from xslit_rays import (cylinder_rays, cylinder_rays_at, random_rotation,
                        ray_through_point_and_slits, unit, xslit_rays)

from xslit_fit import FitError, XSlitFrame, fit_two_slits, frame_for_pixels, interpolate_rays


def ideal_xslit(rng, z1, z2, theta1, theta2):
    """True slits of an XSlit with the given frame values, placed by a random rigid motion.

    Returns (rotation with rows e_x, e_y, e_z), origin, slit1, slit2 (point, direction)."""
    rot = random_rotation(rng).T                 # rows are the frame axes
    origin = rng.normal(size=3)
    def slit(z, th):
        return origin + z * rot[2], np.cos(th) * rot[0] + np.sin(th) * rot[1]
    return rot, origin, slit(z1, theta1), slit(z2, theta2)


def bundle_near_plane(rng, s1, s2, rot, origin, n=400):
    """Rays of the XSlit whose points lie on the true image plane (z = 0), scene side +e_z."""
    p, d = xslit_rays(s1, s2, n, rng, span=0.2)
    d = np.where(((d @ rot[2]) > 0)[:, None], d, -d)
    t = -((p - origin) @ rot[2]) / (d @ rot[2])
    return p + t[:, None] * d, d


@pytest.mark.parametrize("seed, z1, z2, th2", [
    (0, -0.05, -0.5, np.pi / 2), (1, -0.02, -0.3, 1.2), (2, 0.1, 0.7, 2.0)])
def test_frame_values_match_the_true_xslit(seed, z1, z2, th2):
    rng = np.random.default_rng(seed)
    rot, origin, s1, s2 = ideal_xslit(rng, z1, z2, 0.0, th2)
    p, d = bundle_near_plane(rng, s1, s2, rot, origin)
    fit = fit_two_slits(p, d)
    frame = XSlitFrame.from_fit(fit, plane_point=origin)
    assert frame.z1 == pytest.approx(z1, abs=1e-9) and frame.z2 == pytest.approx(z2, abs=1e-9)
    assert frame.theta1 == 0.0
    assert frame.theta2 == pytest.approx(th2 if abs(rot[0] @ frame.e_x - 1) < 1e-6
                                         else np.pi - th2, abs=1e-9)
    assert np.allclose(frame.e_z, rot[2], atol=1e-9)          # scene side
    assert np.allclose(frame.origin, origin, atol=1e-9)
    # Slit i in frame coordinates is {t·(cos θi, sin θi, 0) + (0, 0, z_i)}.
    for s, z, th in ((frame.slits[0], frame.z1, frame.theta1), (frame.slits[1], frame.z2, frame.theta2)):
        pts = frame.to_frame(np.array([s.point, s.point + 0.7 * s.direction]))
        assert np.allclose(pts[:, 2], z, atol=1e-12)
        assert np.allclose(unit(pts[1] - pts[0]), [np.cos(th), np.sin(th), 0], atol=1e-9)
        assert np.abs(pts[0, :2] @ [-np.sin(th), np.cos(th)]) < 1e-9   # through the origin's axis
    x = rng.normal(size=(5, 3))
    assert np.allclose(frame.to_world(frame.to_frame(x)), x)


def test_custom_e_x_changes_angles_not_depths():
    rng = np.random.default_rng(5)
    rot, origin, s1, s2 = ideal_xslit(rng, -0.05, -0.5, 0.0, 1.3)
    p, d = bundle_near_plane(rng, s1, s2, rot, origin)
    fit = fit_two_slits(p, d)
    a = XSlitFrame.from_fit(fit, plane_point=origin)
    ex = np.cos(0.2) * a.e_x - np.sin(0.2) * a.e_y                 # rotate e_x by −0.2 rad
    b = XSlitFrame.from_fit(fit, plane_point=origin, e_x=ex)
    assert (b.z1, b.z2) == pytest.approx((a.z1, a.z2))
    assert b.theta1 == pytest.approx(0.2) and b.theta2 - b.theta1 == pytest.approx(a.theta2)
    with pytest.raises(FitError, match="e_x: expected a direction not normal"):
        XSlitFrame.from_fit(fit, e_x=a.e_z)


def test_projection_in_kappa_follows_eqn_pinproj():
    """κ_u = −z2/(z − z2)·κ_x and κ_v = −z1/(z − z1)·κ_y for scene points (docs/CONVENTIONS.md)."""
    rng = np.random.default_rng(6)
    z1, z2 = -0.04, -0.45
    rot, origin, s1, s2 = ideal_xslit(rng, z1, z2, 0.0, 1.1)
    p, d = bundle_near_plane(rng, s1, s2, rot, origin)
    frame = XSlitFrame.from_fit(fit_two_slits(p, d), plane_point=origin)
    kx = rng.uniform(-0.1, 0.1, (20, 2))
    z = rng.uniform(0.2, 2.0, 20)
    scene_frame = np.c_[frame.from_kappa(kx), z]
    scene = frame.to_world(scene_frame)
    dirs = ray_through_point_and_slits(scene, s1, s2)
    kuv = frame.kappa(frame.rays_to_plane(scene, dirs))
    assert np.allclose(kuv[:, 0], -frame.z2 / (z - frame.z2) * kx[:, 0], rtol=1e-9, atol=1e-12)
    assert np.allclose(kuv[:, 1], -frame.z1 / (z - frame.z1) * kx[:, 1], rtol=1e-9, atol=1e-12)
    assert np.allclose(frame.kappa(frame.from_kappa(kx)), kx)


@pytest.mark.parametrize("th2, depth", [(np.pi / 2, 0.3), (np.pi / 2, 1.0), (1.2, 0.6), (2.1, 2.5)])
@pytest.mark.parametrize("default_plane", [True, False])
def test_aspect_ratio_of_a_frontal_square_gives_its_depth(th2, depth, default_plane):
    rng = np.random.default_rng(int(depth * 10) + int(th2 * 100))
    z1_true, z2_true = -0.05, -0.5
    rot, origin, s1, s2 = ideal_xslit(rng, z1_true, z2_true, 0.0, th2)
    p, d = bundle_near_plane(rng, s1, s2, rot, origin)
    p = p + rng.uniform(-0.03, 0.03, (len(p), 1)) * d           # mirror-like spread of origins
    frame = XSlitFrame.from_fit(fit_two_slits(p, d), plane_point=None if default_plane else origin)
    # A frontal "square" of side 0.04 (sides along v1 and v2 with equal length: r_o = 1),
    # at true depth `depth` from the true plane, generated in the true frame.
    v1 = np.array([1.0, 0.0])
    v2 = np.array([np.cos(th2), np.sin(th2)])
    corner0 = np.array([0.013, -0.021])
    corners2d = np.array([corner0, corner0 + 0.04 * v1, corner0 + 0.04 * (v1 + v2), corner0 + 0.04 * v2])
    corners = origin + corners2d @ rot[:2] + depth * rot[2]
    rays = ray_through_point_and_slits(corners, s1, s2)
    start = corners - rng.uniform(0.5, 1.5, (4, 1)) * rays          # ray points near the mirror
    kappa = frame.kappa(frame.rays_to_plane(start, rays))
    r_i = (kappa[1, 0] - kappa[0, 0]) / (kappa[3, 1] - kappa[0, 1])
    z1, z2 = frame.z1, frame.z2
    z = frame.to_frame(corners)[:, 2].mean()                      # depth in the fitted frame
    assert np.ptp(frame.to_frame(corners)[:, 2]) < 1e-9
    assert r_i == pytest.approx(z2 * (z - z1) / (z1 * (z - z2)), rel=1e-3)   # Eqn. ardef, r_o = 1
    z_from_ar = z1 * z2 * (r_i - 1) / (z1 * r_i - z2)                          # Eqn. getz
    assert z_from_ar == pytest.approx(z, rel=1e-3)
    if not default_plane:
        assert z == pytest.approx(depth, rel=1e-9)


def test_rays_to_plane_puts_points_on_the_plane():
    rng = np.random.default_rng(7)
    rot, origin, s1, s2 = ideal_xslit(rng, -0.05, -0.5, 0.0, 1.5)
    p, d = bundle_near_plane(rng, s1, s2, rot, origin)
    frame = XSlitFrame.from_fit(fit_two_slits(p, d))
    q = p + rng.uniform(-1, 1, (len(p), 1)) * d
    uv = frame.rays_to_plane(q, d)
    on_plane = frame.to_world(np.c_[uv, np.zeros(len(uv))])
    assert np.max(np.linalg.norm(np.cross(on_plane - q, d), axis=1)) < 1e-12


def test_interpolated_subpixel_rays_are_close_to_exact_rays():
    radius, distance, focal = 0.1, 0.6, 1500.0
    p, d, valid = cylinder_rays(radius, distance, focal=focal)
    pix = np.array([[310.25, 228.5], [331.75, 250.1], [319.5, 239.5]])
    pts, dirs, ok = interpolate_rays(p, d, pix, valid)
    assert ok.all()
    ex_p, ex_d, _ = cylinder_rays_at(radius, distance, pix[:, 0], pix[:, 1], focal, 319.5, 239.5)
    # One pixel spans ~(distance − radius)/focal on the mirror; interpolation error is
    # second order, far below a hundredth of that.
    footprint = (distance - radius) / focal
    assert np.max(np.linalg.norm(np.cross(pts - ex_p, ex_d), axis=1)) < 1e-2 * footprint
    assert np.max(np.linalg.norm(np.cross(dirs, ex_d), axis=1)) < 1e-5
    res = frame_for_pixels(p, d, pix, valid)
    assert res and res.frame.z1 < 0 and res.frame.z2 < 0 and abs(res.frame.z1) < abs(res.frame.z2)
    assert np.allclose(res.uv, res.frame.rays_to_plane(ex_p, ex_d), atol=1e-2 * footprint)
    outside = interpolate_rays(p, d, [[-1.0, 5.0], [0.0, 0.0]], valid)[2]
    assert not outside[0]
    assert not frame_for_pixels(p, d, [[-3.0, 3.0]], valid)


def test_from_fit_rejects_a_failed_fit():
    fit = fit_two_slits(np.zeros((2, 3)), np.ones((2, 3)))
    with pytest.raises(FitError, match="fit: expected a successful SlitFit"):
        XSlitFrame.from_fit(fit)
