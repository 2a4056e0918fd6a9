"""Tests of raytrace.camera: pinhole conventions, XSlit and pushbroom projections, sample offsets."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from raytrace.camera import PinholeCamera, PushbroomCamera, XSlitCamera, pixel_sample_offsets, sample_offsets
from raytrace.errors import RaytraceError


def test_pinhole_matches_setup_format_formula():
    """u = fx·Xc/Zc + cx with the frame z = unit(look_at − pos), x = unit(z × up), y = z × x."""
    cam = PinholeCamera.from_look_at((1600, 1200), [3500.0, 3400.0], None, [0.1, 0.2, 0.55], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    z = -np.array([0.1, 0.2, 0.55]) / np.linalg.norm([0.1, 0.2, 0.55])
    x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(20, 3)) * 0.1
    rel = pts - [0.1, 0.2, 0.55]
    xc, yc, zc = rel @ x, rel @ y, rel @ z
    expected = np.stack([3500.0 * xc / zc + 799.5, 3400.0 * yc / zc + 599.5], axis=1)
    got, depth = cam.project(pts)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(depth, zc, atol=1e-15)


def test_pinhole_image_orientation():
    """Looking along −z with up = +y (the OpenGL default view): world +y is up (toward row 0), world +x is right."""
    cam = PinholeCamera.from_look_at((100, 80), 100.0, None, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    pix, _ = cam.project([[0.0, 0.1, 0.0], [0.1, 0.0, 0.0]])
    assert pix[0, 1] < 39.5  # above the centre row
    assert pix[1, 0] > 49.5  # right of the centre column


def test_pixel_grid_order_and_rays_roundtrip():
    cam = PinholeCamera.from_look_at((7, 5), 10.0, (3.2, 1.9), [0.3, -0.1, 2.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    grid = cam.pixel_grid()
    assert grid.shape == (35, 2)
    np.testing.assert_array_equal(grid[8], [1.0, 1.0])
    o, d = cam.rays(grid)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-15)
    back, z = cam.project(o + 1.7 * d)
    np.testing.assert_allclose(back, grid, atol=1e-9)
    assert np.all(z > 0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(up=[0.0, 0.0, 0.0]), "up: expected a non-zero"),
        (dict(up=[0.0, 0.0, -2.0]), "up: expected a direction not parallel"),
        (dict(focal_px=0.0), "focal_px: expected positive"),
        (dict(focal_px=[100.0, -1.0]), "focal_px: expected positive"),
        (dict(look_at=[0.0, 0.0, 0.55]), "look_at: expected a point different"),
        (dict(resolution=(0, 10)), "resolution: expected two positive integers"),
        (dict(position=[0.0, np.nan, 0.55]), "position: expected finite"),
    ],
)
def test_pinhole_validation(kwargs, match):
    args = dict(resolution=(16, 12), focal_px=100.0, principal_px=None, position=[0.0, 0.0, 0.55], look_at=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0])
    args.update(kwargs)
    with pytest.raises(RaytraceError, match=match):
        PinholeCamera.from_look_at(**args)


@settings(max_examples=40, deadline=None)
@given(
    z1=st.floats(-0.9, -0.02),
    ratio=st.floats(1.5, 20.0),
    th1=st.floats(-1.0, 1.0),
    dth=st.floats(0.3, 2.8),
    seed=st.integers(0, 1000),
)
def test_xslit_rays_meet_both_slits_and_project_back(z1, ratio, th1, dth, seed):
    """Each ray crosses slit i at z = z_i (independent line-line check), and `project` inverts `rays`."""
    z2 = z1 * ratio
    th2 = th1 + dth
    cam = XSlitCamera((64, 48), z1, z2, th1, th2, pitch=2e-4)
    rng = np.random.default_rng(seed)
    px = rng.uniform(0, 64, size=(10, 2))
    o, d = cam.rays(px)
    for z, th in ((z1, th1), (z2, th2)):
        lam = (z - o[:, 2]) / d[:, 2]
        p = o + lam[:, None] * d
        np.testing.assert_allclose(p[:, 0] * np.sin(th) - p[:, 1] * np.cos(th), 0.0, atol=1e-12)
    back, depth = cam.project(o + 0.8 * d)
    np.testing.assert_allclose(back, px, atol=1e-7)
    assert np.all(depth > 0)


def test_xslit_validation():
    with pytest.raises(RaytraceError, match="z1, z2: expected two different"):
        XSlitCamera((10, 10), -0.1, -0.1)
    with pytest.raises(RaytraceError, match="theta1, theta2: expected non-parallel"):
        XSlitCamera((10, 10), -0.1, -0.5, 0.2, 0.2 + np.pi)
    with pytest.raises(RaytraceError, match="pitch: expected a positive"):
        XSlitCamera((10, 10), -0.1, -0.5, pitch=0.0)


def test_pushbroom_is_orthographic_along_motion_and_perspective_across():
    cam = PushbroomCamera((40, 30), focal_px=50.0, step=0.01)
    o, d = cam.rays([[0.0, 14.5], [39.0, 14.5], [19.5, 0.0]])
    np.testing.assert_allclose(d[0], d[1])  # same direction along the motion
    np.testing.assert_allclose(o[1, 0] - o[0, 0], 39 * 0.01)
    np.testing.assert_allclose(d[2, 1] / d[2, 2], -14.5 / 50.0)
    pix, _ = cam.project(o + 2.0 * d)
    np.testing.assert_allclose(pix, [[0.0, 14.5], [39.0, 14.5], [19.5, 0.0]], atol=1e-12)


def test_sample_offsets_reproducible_and_stratified():
    a = sample_offsets(16, seed=3)
    assert a.tobytes() == sample_offsets(16, seed=3).tobytes()
    assert a.tobytes() != sample_offsets(16, seed=4).tobytes()
    cells = np.floor((a + 0.5) * 4).astype(int)
    assert len({tuple(c) for c in cells}) == 16  # one per cell of the 4×4 grid
    b = sample_offsets(6, seed=0)
    for axis in (0, 1):  # N-rooks: one sample per sixth along each axis
        assert sorted(np.floor((b[:, axis] + 0.5) * 6).astype(int)) == list(range(6))
    assert np.all(np.abs(b) <= 0.5)
    with pytest.raises(RaytraceError, match="spp: expected a positive integer"):
        sample_offsets(0)


def test_pixel_sample_offsets_are_the_pattern_rotated_per_pixel():
    """Each pixel gets the stratified pattern shifted on the torus; the shift depends on the pixel
    and the seed only (not on which pixels are asked for together)."""
    pix = np.array([0, 1, 2, 5000, 123456])
    a = pixel_sample_offsets(pix, 4, seed=2)
    assert a.shape == (5, 4, 2) and a.dtype == np.float64
    assert np.all((a >= -0.5) & (a < 0.5))
    np.testing.assert_array_equal(a[3:], pixel_sample_offsets(pix[3:], 4, seed=2))
    assert not np.array_equal(a, pixel_sample_offsets(pix, 4, seed=3))
    base = sample_offsets(4, seed=2)
    rel = np.mod(a - a[:, :1], 1.0)  # differences on the torus: the pattern's own
    np.testing.assert_allclose(np.minimum(rel, 1 - rel), np.minimum(np.mod(base - base[:1], 1.0),
                               1 - np.mod(base - base[:1], 1.0))[None].repeat(5, axis=0), atol=1e-12)
    assert len({tuple(np.round(r[0], 9)) for r in a}) == 5  # every pixel shifted differently
    np.testing.assert_array_equal(pixel_sample_offsets(pix, 1), np.zeros((5, 1, 2)))


@settings(max_examples=30, deadline=None)
@given(phase=st.floats(0.02, 0.98), spp=st.sampled_from([2, 4, 6, 9, 16]), seed=st.integers(0, 1000))
def test_pixel_sample_offsets_estimate_edge_coverage_without_bias(phase, spp, seed):
    """A straight vertical edge covering `phase` of every pixel along it: the mean of the per-pixel
    sample estimates over 4000 pixels is the true coverage. (One pattern shared by all pixels gives
    every pixel the same estimate, off by up to 1/(2·√spp): the aliased edge this replaces.)"""
    off = pixel_sample_offsets(np.arange(4000) * 7919, spp, seed)
    covered = np.mean(off[..., 0] < phase - 0.5, axis=1)
    assert abs(covered.mean() - phase) < 4.5 * np.sqrt(0.25 / spp / 4000)  # ≤ 4.5 σ of a binomial bound
    assert covered.std() > 0  # pixels differ: their errors average out along an edge
