"""Tests of xslit_fit.panorama: stitched rays of a translating pinhole, their derived slits vs a fit."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from depth.xslit import XSlit
from raytrace.camera import PinholeCamera
from xslit_fit import FitError, XSlitFrame, fit_two_slits
from xslit_fit.panorama import LinearPanorama
from xslit_fit.plucker import ray_line_distance


def camera(tilt=0.1, yaw=0.0, res=(64, 48), f=50.0):
    """A small pinhole, pitched by `tilt` (look-at slope) and turned by `yaw` (radians)."""
    look = np.array([np.sin(yaw), tilt, np.cos(yaw)])
    return PinholeCamera.from_look_at(res, f, position=(0.1, 0.2, 0.0), look_at=np.array([0.1, 0.2, 0.0]) + look,
                                      up=(0, 1, 0))


def grid(pan, step=3):
    vv, kk = np.mgrid[0:pan.height:step, 0:pan.n_frames:step]
    return np.column_stack([kk.ravel(), vv.ravel()]).astype(np.float64)


def test_rays_are_the_frames_pinhole_rays():
    cam = camera()
    pan = LinearPanorama.from_camera(cam, cam.R[0], 0.01, 5.0, 0.5, 40)
    for k in (0, 7, 39):
        frame_cam = PinholeCamera(cam.resolution, cam.K, cam.R, cam.position + k * 0.01 * cam.R[0])
        v = np.arange(0, 48, 5.0)
        o_ref, d_ref = frame_cam.rays(np.column_stack([np.full(len(v), 5.0 + 0.5 * k), v]))
        o, d = pan.rays(np.column_stack([np.full(len(v), float(k)), v]))
        np.testing.assert_allclose(o, o_ref, atol=1e-14)
        np.testing.assert_allclose(d, d_ref, atol=1e-14)


@settings(max_examples=30, deadline=None)
@given(step=st.floats(1e-3, 0.1), rate=st.floats(-2.0, 2.0).filter(lambda r: abs(r) > 0.05),
       col0=st.floats(0.0, 63.0), tilt=st.floats(-0.5, 0.5), yaw=st.floats(-0.7, 0.7),
       zp=st.floats(0.2, 3.0), along_y=st.floats(-0.5, 0.5))
def test_derived_slits_meet_every_stitched_ray(step, rate, col0, tilt, yaw, zp, along_y):
    cam = camera(tilt, yaw)
    motion = cam.R[0] + along_y * cam.R[1]        # any direction perpendicular to the optical axis
    pan = LinearPanorama.from_camera(cam, motion, step, col0, rate, 30)
    if abs(pan.slit_depth() - zp) < 1e-3:
        return
    frame = pan.slits(zp)
    o, d = pan.rays(grid(pan) + 0.37)
    scale = np.abs(o - o.mean(axis=0)).max() + abs(pan.slit_depth()) + zp
    for s in frame.slits:
        assert ray_line_distance(o, d, s.point, s.direction).max() < 1e-10 * scale
    assert abs(frame.z1) < abs(frame.z2)
    assert frame.e_z @ cam.R[2] == pytest.approx(1.0)
    # slit depths measured directly: the trajectory lies at camera depth 0, slit B at Z_B = −s·m_x·fx/α
    assert sorted([frame.z1, frame.z2]) == pytest.approx(sorted([-zp, -step * np.linalg.norm(motion) ** -1
                                                                 * cam.K[0, 0] / rate - zp]))


@pytest.mark.parametrize("rate, zp", [(0.5, 1.0), (0.25, 0.3), (-0.8, 0.5)])
def test_derived_slits_agree_with_a_fit_of_the_stitched_rays(rate, zp):
    cam = camera(0.2)
    pan = LinearPanorama.from_camera(cam, cam.R[0], 0.01, 30.0, rate, 40)
    frame = pan.slits(zp)
    o, d = pan.rays(grid(pan))
    fit = fit_two_slits(o, d)
    assert fit, getattr(fit, "reason", "")
    fitted = XSlitFrame.from_fit(fit, plane_point=frame.origin, e_x=frame.e_x)
    assert fitted.z1 == pytest.approx(frame.z1, rel=1e-9)
    assert fitted.z2 == pytest.approx(frame.z2, rel=1e-9)
    assert fitted.theta2 == pytest.approx(frame.theta2, abs=1e-9)
    for a, b in zip(fitted.slits, frame.slits):
        assert abs(a.direction @ b.direction) == pytest.approx(1.0, abs=1e-12)
        assert b.distance_to(a.point[None])[0] < 1e-9


def test_pinproj_through_the_plane_map_lands_on_the_pixel_that_sees_the_point():
    """A 3D point projected by Eqn. pinproj (depth.xslit) onto the plane, mapped to a panorama pixel
    by pitch_and_principal: that pixel's stitched ray passes through the point."""
    rng = np.random.default_rng(3)
    cam = camera(0.0)
    pan = LinearPanorama.from_camera(cam, cam.R[0], 0.01, 10.0, 0.5, 60)
    zp = 0.5
    frame = pan.slits(zp)
    pitch, principal = pan.pitch_and_principal(zp)
    xs = XSlit(frame.z1, frame.z2, frame.theta1, frame.theta2)
    pts = np.column_stack([rng.uniform(-0.3, 0.3, 20), rng.uniform(-0.3, 0.3, 20), rng.uniform(0.5, 4.0, 20)])
    assert frame.theta2 == pytest.approx(np.pi / 2)      # PO: plane = diag(p1, p2)·(pixel − c)
    px = xs.project(pts) / pitch + principal
    o, d = pan.rays(px)
    world = frame.to_world(pts)
    dist = np.linalg.norm(np.cross(world - o, d), axis=1)
    assert dist.max() < 1e-10


def test_refuses_motion_along_the_optical_axis_and_a_fixed_column():
    cam = camera()
    pan = LinearPanorama.from_camera(cam, cam.R[0] + 0.1 * cam.R[2], 0.01, 5.0, 0.5, 40)
    with pytest.raises(FitError, match="perpendicular to the optical axis"):
        pan.slits()
    with pytest.raises(FitError, match="column_rate"):
        LinearPanorama.from_camera(cam, cam.R[0], 0.01, 5.0, 0.0, 40)
    with pytest.raises(FitError, match="step"):
        LinearPanorama.from_camera(cam, cam.R[0], -0.01, 5.0, 0.5, 40)
    pan = LinearPanorama.from_camera(cam, cam.R[0] + 0.3 * cam.R[1], 0.01, 5.0, 0.5, 40)
    with pytest.raises(FitError, match="not along the slits"):
        pan.pitch_and_principal()
