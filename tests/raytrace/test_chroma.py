"""Tests of raytrace.chroma: a colour channel's own lens (lateral chromatic aberration), checked against formulas
written here and against OpenCV's own undistortion and projection."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from raytrace.camera import PinholeCamera
from raytrace.chroma import GRID_ERROR_PX, ChannelLens, channel_pixels
from raytrace.errors import RaytraceError
from raytrace.render import render
from raytrace.scene import Cube, Scene
from raytrace.mirror import CylinderMirror

W, H = 96, 72


def K(fx, fy, cx, cy):
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def camera(red=None, blue=None, distortion=None, size=(W, H), f=80.0):
    return PinholeCamera.from_look_at(size, f, None, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), distortion=distortion,
                                      red=red, blue=blue)


@settings(max_examples=30, deadline=None)
@given(m=st.floats(-0.01, 0.01), dx=st.floats(-2.0, 2.0), dy=st.floats(-2.0, 2.0))
def test_a_magnified_and_shifted_channel_images_each_ray_where_the_formula_puts_it(m, dx, dy):
    """Without distortion a channel of focal f(1 + m) and principal point c + d images green's pixel p at
    c + d + (p − c)(1 + m)."""
    cx, cy = (W - 1) / 2, (H - 1) / 2
    cam = camera(red=ChannelLens(K(80 * (1 + m), 80 * (1 + m), cx + dx, cy + dy)))
    at = channel_pixels(cam, "red")
    v, u = np.mgrid[0:H, 0:W].astype(float)
    np.testing.assert_allclose(at[..., 0], cx + dx + (u - cx) * (1 + m), atol=1e-9)
    np.testing.assert_allclose(at[..., 1], cy + dy + (v - cy) * (1 + m), atol=1e-9)
    np.testing.assert_array_equal(channel_pixels(cam, "blue")[..., 0], u)  # no lens of its own: the pixel itself


def test_channel_pixels_agree_with_opencv_undistorting_through_green_and_projecting_through_the_channel():
    size, f = (2048, 1536), 1500.0  # a wide-angle lens (68° across), red's distortion and centre its own
    green_d = np.array([-0.3, 0.12, 1e-3, -1e-3, 0.0])
    red_d = np.array([-0.29, 0.11, 1e-3, -1e-3, 0.0])
    red_K = K(1501.0, 1500.8, 1023.9, 767.2)
    cam = camera(red=ChannelLens(red_K, red_d), distortion=green_d, size=size, f=f)
    at = channel_pixels(cam, "red")
    rng = np.random.default_rng(0)
    px = np.column_stack([rng.integers(0, size[0], 4000), rng.integers(0, size[1], 4000)]).astype(np.float64)
    px = np.vstack([px, [[0, 0], [size[0] - 1, size[1] - 1], [0, size[1] - 1], [size[0] - 1, 0]]])
    ideal = cv2.undistortPoints(px.reshape(-1, 1, 2), cam.K, green_d,
                                criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14))
    rays = np.column_stack([ideal.reshape(-1, 2), np.ones(len(px))])
    expected, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), red_K, red_d)
    got = at[px[:, 1].astype(int), px[:, 0].astype(int)]
    err = np.abs(got - expected.reshape(-1, 2))
    assert err.max() < GRID_ERROR_PX, err.max()
    assert np.abs(got - px).max() > 1.0  # (the channels do differ there)


def test_a_channel_camera_has_the_channel_intrinsics_and_the_camera_pose():
    red = ChannelLens(K(81.0, 81.0, 47.0, 36.0), [0.01, 0, 0, 0])
    cam = camera(red=red, distortion=[-0.02, 0, 0, 0])
    own = cam.channel_camera("red")
    np.testing.assert_array_equal(own.K, red.K)
    np.testing.assert_array_equal(own.distortion[:4], [0.01, 0, 0, 0])
    np.testing.assert_array_equal(own.R, cam.R)
    np.testing.assert_array_equal(own.position, cam.position)
    assert not own.has_channel_lenses and cam.has_channel_lenses
    green = cam.channel_camera("green")
    np.testing.assert_array_equal(green.K, cam.K)
    np.testing.assert_array_equal(green.distortion, cam.distortion)
    np.testing.assert_array_equal(cam.channel_camera("blue").K, cam.K)
    with pytest.raises(RaytraceError, match="channel: expected red, green or blue"):
        cam.channel_camera("alpha")


def test_bad_channel_lenses_are_refused_with_the_channel_named():
    with pytest.raises(RaytraceError, match="K: expected positive focal lengths"):
        ChannelLens(K(-1.0, 80.0, 40.0, 30.0))
    with pytest.raises(RaytraceError, match="red: expected a raytrace.chroma.ChannelLens or None, got list"):
        camera(red=[1.0, 2.0])
    with pytest.raises(RaytraceError, match=r"blue\.distortion: expected coefficients whose distortion is one-to-one"):
        camera(blue=ChannelLens(K(80.0, 80.0, 47.5, 35.5), [-3.0, 0, 0, 0]))
    with pytest.raises(RaytraceError, match="channel: expected one of red, blue"):
        channel_pixels(camera(), "green")


def test_a_render_takes_each_channel_through_its_own_camera():
    """The image's red channel is the render through red's camera, green and the truth arrays the camera's own."""
    scene = Scene(mirror=CylinderMirror(radius=0.1, height=0.4, center=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0)),
                  objects=[Cube(size=0.04, center=(0.1, 0.0, 0.35), color=(0.8, 0.5, 0.2))])
    base = PinholeCamera.from_look_at((64, 48), 120.0, None, (0.0, 0.0, 0.55), (0.0, 0.0, 0.0))
    red = ChannelLens(K(126.0, 126.0, 31.5, 23.5))
    lensed = PinholeCamera.from_look_at((64, 48), 120.0, None, (0.0, 0.0, 0.55), (0.0, 0.0, 0.0), red=red)
    got = render(scene, lensed, spp=2, workers=1)
    plain = render(scene, base, spp=2, workers=1)
    through_red = render(scene, lensed.channel_camera("red"), spp=2, workers=1)
    np.testing.assert_array_equal(got.image[..., 0], through_red.image[..., 0])
    np.testing.assert_array_equal(got.image[..., 1:], plain.image[..., 1:])
    np.testing.assert_array_equal(got.object_id, plain.object_id)
    assert got.rays_traced == plain.rays_traced + through_red.rays_traced
    assert np.abs(got.image[..., 0] - plain.image[..., 0]).max() > 0.05  # (red does see the scene elsewhere)


def test_a_bayer_mosaic_keeps_each_pixel_s_own_filter_channel_and_demosaicing_keeps_those_samples():
    from raytrace.chroma import bayer_mosaic, demosaiced
    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)
    raw = bayer_mosaic(img)
    np.testing.assert_array_equal(raw, np.take_along_axis(img, channel_of(6, 8)[..., None], axis=2)[..., 0])
    smooth = np.broadcast_to(np.array([200, 90, 20], np.uint8), (32, 40, 3)).copy()
    np.testing.assert_array_equal(demosaiced(smooth)[4:-4, 4:-4], smooth[4:-4, 4:-4])  # one colour stays itself
    edge = np.full((32, 40, 3), 40, np.uint8)
    edge[:, 20:] = (220, 180, 60)
    made = demosaiced(edge)
    own = np.take_along_axis(made, channel_of(32, 40)[..., None], axis=2)
    np.testing.assert_array_equal(own[..., 0], bayer_mosaic(edge))  # the samples recorded are kept as they are
    with pytest.raises(RaytraceError, match=r"image: expected an \(H, W, 3\) RGB image \(uint8, uint16 or float\), "
                                            r"got uint8 \(4, 4\)$"):
        bayer_mosaic(np.zeros((4, 4), np.uint8))
    with pytest.raises(RaytraceError, match=r"image: expected an \(H, W, 3\) uint8 RGB image, got uint16"):
        demosaiced(np.zeros((4, 4, 3), np.uint16))


@pytest.mark.parametrize("pattern, first_row, second_row", [("RGGB", (0, 1), (1, 2)), ("BGGR", (2, 1), (1, 0)),
                                                            ("GRBG", (1, 0), (2, 1)), ("GBRG", (1, 2), (0, 1))])
def test_each_bayer_pattern_records_its_tile_and_demosaics_a_colour_back_to_itself(pattern, first_row, second_row):
    """A pattern's 2 × 2 tile, read row by row: its samples where the tile says, and OpenCV's code for it (which
    names its tiles otherwise in older releases) giving a flat colour back in its channels' order."""
    from raytrace.chroma import BAYER_PATTERNS, bayer_mosaic, demosaiced
    assert pattern in BAYER_PATTERNS
    img = np.zeros((4, 6, 3), np.uint16)
    img[..., 0], img[..., 1], img[..., 2] = 1000, 2000, 3000
    raw = bayer_mosaic(img, pattern)
    assert raw.dtype == np.uint16
    want = np.array([[1000, 2000, 3000][c] for c in first_row + second_row]).reshape(2, 2)
    np.testing.assert_array_equal(raw, np.tile(want, (2, 3)))
    flat = np.broadcast_to(np.array([200, 90, 20], np.uint8), (32, 40, 3)).copy()
    np.testing.assert_array_equal(demosaiced(flat, pattern)[4:-4, 4:-4], flat[4:-4, 4:-4])
    with pytest.raises(RaytraceError, match=r"pattern: expected one of RGGB, BGGR, GRBG, GBRG, got 'RGBG'"):
        bayer_mosaic(img, "RGBG")


def channel_of(h, w):
    """Each pixel's filter of an RGGB mosaic: red (0) at even rows and columns, blue (2) at odd ones, green (1)."""
    rows, cols = np.mgrid[0:h, 0:w]
    return np.where((rows % 2 == 0) & (cols % 2 == 0), 0, np.where((rows % 2 == 1) & (cols % 2 == 1), 2, 1))
