"""Tests of raytrace.lens and a distorted PinholeCamera: OpenCV's model, checked against OpenCV itself."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from raytrace.camera import PinholeCamera, distortion_fold
from raytrace.errors import RaytraceError
from raytrace.lens import as_distortion, distort, distortion_jacobian, undistort

# A machine-vision lens's barrel distortion and a pincushion one, each with some decentring, and a rational model.
COEFFS = [[-0.28, 0.09, 8e-4, -5e-4, -0.01], [0.12, -0.03, -6e-4, 9e-4], [-0.2, 0.05, 1e-4, 2e-4, 0.0, 0.1, 0.02, 0.0]]


@pytest.mark.parametrize("coeffs", COEFFS)
def test_distort_is_opencvs_project_points(coeffs):
    """Ideal normalised points through `distort` land where `cv2.projectPoints` puts them (K = I)."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(-0.45, 0.45, (2000, 2))
    got = distort(xy, as_distortion(coeffs))
    ref, _ = cv2.projectPoints(np.column_stack([xy, np.ones(len(xy))]), np.zeros(3), np.zeros(3), np.eye(3),
                               np.asarray(coeffs, dtype=np.float64))
    np.testing.assert_allclose(got, ref.reshape(-1, 2), rtol=0, atol=1e-14)


@pytest.mark.parametrize("coeffs", COEFFS)
def test_undistort_is_opencvs_undistort_points(coeffs):
    """`undistort` agrees with `cv2.undistortPoints` run to convergence, and its residual is what it says."""
    rng = np.random.default_rng(4)
    xy_d = rng.uniform(-0.4, 0.4, (2000, 2))
    c = as_distortion(coeffs)
    got, residual = undistort(xy_d, c)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-16)
    ref = cv2.undistortPoints(xy_d.reshape(-1, 1, 2), np.eye(3), np.asarray(coeffs, dtype=np.float64),
                              criteria=crit).reshape(-1, 2)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    back = distort(got, c) - xy_d
    np.testing.assert_allclose(residual, np.hypot(back[:, 0], back[:, 1]), rtol=0, atol=1e-16)
    assert residual.max() <= 1e-13


@settings(max_examples=60, deadline=None)
@given(k1=st.floats(-0.3, 0.3), k2=st.floats(-0.1, 0.1), p1=st.floats(-2e-3, 2e-3), p2=st.floats(-2e-3, 2e-3),
       seed=st.integers(0, 2**16))
def test_jacobian_is_the_central_difference_of_distort(k1, k2, p1, p2, seed):
    c = as_distortion([k1, k2, p1, p2, 0.0, 0.05, 0.0, 0.0])
    if c is None:
        return
    xy = np.random.default_rng(seed).uniform(-0.4, 0.4, (50, 2))
    h = 1e-6
    num = np.stack([(distort(xy + h * e, c) - distort(xy - h * e, c)) / (2 * h) for e in np.eye(2)], axis=2)
    np.testing.assert_allclose(distortion_jacobian(xy, c), num, rtol=0, atol=1e-8)


@settings(max_examples=40, deadline=None)
@given(k1=st.floats(-0.3, 0.15), k2=st.floats(-0.05, 0.12), p1=st.floats(-1e-3, 1e-3), p2=st.floats(-1e-3, 1e-3),
       f=st.floats(0.9, 3.0), seed=st.integers(0, 2**16))
def test_a_distorted_cameras_rays_project_back_to_their_pixels(k1, k2, p1, p2, f, seed):
    """rays() then project() returns each pixel (to 1e-9 px) over the whole image, for any lens the camera
    accepts; and project() is `cv2.projectPoints` with the camera's pose, K and coefficients."""
    w, h = 640, 480
    try:
        cam = PinholeCamera.from_look_at((w, h), f * w, (331.0, 236.5), [0.1, 0.2, 0.6], [0.0, 0.0, 0.0],
                                         [0.0, 1.0, 0.0], [k1, k2, p1, p2])
    except RaytraceError as exc:
        assert "folds near pixel" in str(exc)
        return
    rng = np.random.default_rng(seed)
    px = np.concatenate([rng.uniform([-0.5, -0.5], [w - 0.5, h - 0.5], (300, 2)), [[0, 0], [w - 1, h - 1]]])
    o, d = cam.rays(px)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-14)
    pts = o + rng.uniform(0.2, 3.0, (len(px), 1)) * d
    back, z = cam.project(pts)
    assert np.all(z > 0)
    np.testing.assert_allclose(back, px, rtol=0, atol=1e-9)
    coeffs = np.zeros(5) if cam.distortion is None else cam.distortion[:5]  # all zero: the ideal pinhole
    ref, _ = cv2.projectPoints(pts, cv2.Rodrigues(cam.R)[0], -cam.R @ cam.position, cam.K, coeffs)
    np.testing.assert_allclose(back, ref.reshape(-1, 2), rtol=0, atol=1e-8)


def test_no_or_zero_distortion_is_the_ideal_pinhole_to_the_bit():
    args = ((320, 240), [300.0, 310.0], None, [0.1, 0.0, 0.5], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    ideal = PinholeCamera.from_look_at(*args)
    zero = PinholeCamera.from_look_at(*args, distortion=[0.0, 0.0, 0.0, 0.0, 0.0])
    assert ideal.distortion is None and zero.distortion is None
    px = np.random.default_rng(5).uniform(0, 240, (100, 2))
    assert np.array_equal(ideal.rays(px)[1], zero.rays(px)[1])


def test_a_distorted_camera_moves_pixels_by_the_models_amount():
    """Against the ideal camera, a point imaged at normalised radius r moves by f·k1·r³ (k1 alone, to first
    order in k1): the distortion is applied, not merely carried."""
    args = ((800, 600), 600.0, None, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    ideal, bent = PinholeCamera.from_look_at(*args), PinholeCamera.from_look_at(*args, distortion=[-0.01, 0, 0, 0])
    pts = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [0.2, 0.25, 0.0]])
    p0, _ = ideal.project(pts)
    p1, _ = bent.project(pts)
    xy = (p0 - [399.5, 299.5]) / 600.0
    r = np.linalg.norm(xy, axis=1)
    np.testing.assert_allclose(p1 - p0, 600.0 * -0.01 * r[:, None] ** 2 * xy, rtol=1e-12)


@pytest.mark.parametrize("coeffs, match", [
    ([0.1, 0.2, 0.3], "distortion: expected 4, 5 or 8 numbers"),
    ([0.1, np.nan, 0.0, 0.0], "distortion: expected finite numbers"),
    ([-3.0, 0.0, 0.0, 0.0], r"distortion: expected coefficients whose distortion is one-to-one over the image; "
                            r"it folds near pixel \("),
])
def test_bad_distortion_is_refused_naming_it(coeffs, match):
    with pytest.raises(RaytraceError, match=match):
        PinholeCamera.from_look_at((640, 480), 500.0, None, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                                   coeffs)


def test_the_fold_is_where_the_radial_map_turns_back():
    """k1 < 0 alone: r_d = r (1 + k1 r²) rises until r = 1/√(−3 k1), where it reaches (2/3)/√(−3 k1); a
    pixel at normalised distorted radius beyond that has no ideal point. The check finds the fold exactly
    when the image reaches past it."""
    k1 = -0.5
    r_max = (2.0 / 3.0) / np.sqrt(-3.0 * k1)  # 0.544
    K = np.array([[500.0, 0.0, 319.5], [0.0, 500.0, 239.5], [0.0, 0.0, 1.0]])
    corner = np.hypot(320.5, 240.5) / 500.0  # the grid's farthest point, 1 px beyond the corner: 0.801
    assert corner > r_max
    assert distortion_fold((640, 480), K, as_distortion([k1, 0, 0, 0])) is not None
    K_long = K * [[corner / r_max * 1.01], [corner / r_max * 1.01], [1.0]]  # the same lens, a longer focal length
    K_long[:2, 2] = [319.5, 239.5]
    assert distortion_fold((640, 480), K_long, as_distortion([k1, 0, 0, 0])) is None


@pytest.mark.parametrize("coeffs", COEFFS)
def test_plain_newton_steps_alone_undistort_a_lens_over_its_field(coeffs):
    """`undistort`'s fast path (plain Newton steps from x_d / g(r_d²), the whole image's points at once) reaches
    the tolerance by itself for these lenses; the safeguarded steps after it are for the rest."""
    from raytrace.lens import _PLAIN_STEPS, UNDISTORT_TOL, _newton
    c = as_distortion(coeffs)
    xy_d = np.random.default_rng(6).uniform(-0.35, 0.35, (5000, 2))
    res = distort(_newton(xy_d, c, _PLAIN_STEPS), c) - xy_d
    assert np.hypot(res[:, 0], res[:, 1]).max() <= UNDISTORT_TOL


def test_undistort_converges_near_a_fold_to_the_inner_root():
    """k1 = −0.5 alone: r_d = r − 0.5 r³ rises to 0.544 at r = 0.816. Points just inside that reach the
    root of the cubic on the rising branch (numpy's roots), where plain steps alone are still far off."""
    from raytrace.lens import _PLAIN_STEPS, UNDISTORT_TOL, _newton
    c = as_distortion([-0.5, 0.0, 0.0, 0.0])
    rd = np.array([0.45, 0.5, 0.52, 0.535, 0.54, 0.543])
    ang = np.linspace(0.1, 2.9, rd.size)
    xy_d = rd[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    xy, residual = undistort(xy_d, c)
    assert residual.max() <= UNDISTORT_TOL
    inner = [min(r.real for r in np.roots([-0.5, 0.0, 1.0, -v]) if abs(r.imag) < 1e-9 and r.real > 0) for v in rd]
    np.testing.assert_allclose(np.hypot(xy[:, 0], xy[:, 1]), inner, rtol=1e-10)
    plain = distort(_newton(xy_d, c, _PLAIN_STEPS), c) - xy_d
    assert np.hypot(plain[:, 0], plain[:, 1]).max() > 1e-6


def test_a_point_beyond_the_fold_stays_finite_and_reports_its_residual():
    """k1 = −0.5: no ideal point images beyond r_d = 0.544; undistort says so by its residual, not by a NaN
    that would pass for converged."""
    c = as_distortion([-0.5, 0.0, 0.0, 0.0])
    xy, residual = undistort(np.array([[0.6, 0.0], [0.0, 0.9], [0.3, 0.0]]), c)
    assert np.all(np.isfinite(xy)) and np.all(np.isfinite(residual))
    assert residual[0] > 1e-3 and residual[1] > 1e-3 and residual[2] <= 1e-13


def _srgb_decode(v):
    v = np.asarray(v, dtype=np.float64) / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def test_distorted_image_with_no_distortion_averages_each_pixels_block_in_linear_light():
    """With the identity map, pixel (u, v) averages the factor × factor block of the finer canvas that covers it
    (the canvas pixel I at (I + 0.5) / factor − 0.5 − pad), in linear light."""
    from raytrace.lens import distorted_image
    from raytrace.render import linear_to_srgb8
    cam = PinholeCamera.from_look_at((12, 8), 20.0, None, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    f, pad = 3, 2
    hi = np.random.default_rng(7).integers(0, 256, (f * (8 + 2 * pad), f * (12 + 2 * pad), 3)).astype(np.uint8)
    got = distorted_image(hi, cam, pad, f, lambda px: px)
    block = _srgb_decode(hi[f * pad:f * (pad + 8), f * pad:f * (pad + 12)]).reshape(8, f, 12, f, 3).mean(axis=(1, 3))
    np.testing.assert_array_equal(got, linear_to_srgb8(block))


def test_distorted_image_through_our_undistortion_is_through_opencvs():
    from raytrace.lens import distorted_image
    cam = PinholeCamera.from_look_at((64, 48), 50.0, None, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                                     [-0.2, 0.05, 1e-3, -1e-3])
    f, pad = 2, 10
    yy, xx = np.mgrid[0:f * (48 + 2 * pad), 0:f * (64 + 2 * pad)]
    hi = np.dstack([(xx * 7 + yy * 3) % 256, (xx * 2 + yy * 5) % 256, (xx * yy) % 256]).astype(np.uint8)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    opencv = distorted_image(hi, cam, pad, f, lambda px: cv2.undistortPoints(
        px.reshape(-1, 1, 2), cam.K, cam.distortion, P=cam.K, criteria=crit).reshape(-1, 2))
    ours = distorted_image(hi, cam, pad, f)
    assert np.abs(ours.astype(int) - opencv).max() <= 1
    assert np.abs(ours.astype(int) - distorted_image(hi, cam, pad, f, lambda px: px)).max() > 20  # it moved them
    with pytest.raises(RaytraceError, match=r"ideal: expected an image of 168×136 px \(factor 2, pad 10 over 64×48\)"):
        distorted_image(hi[:-1], cam, pad, f)
