"""Tests of depth.chroma.aligned_to_green: red and blue resampled onto green's rays, checked on images whose every
channel is written here from a smooth scene through that channel's own intrinsics."""

import numpy as np
import pytest

from depth.chroma import aligned_to_green
from depth.errors import DepthError
from raytrace.camera import PinholeCamera
from raytrace.chroma import ChannelLens
from raytrace.response import as_response, linear_to_srgb, srgb_to_linear

W, H, F = 160, 120, 150.0


def K(f, cx, cy):
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


def light(x, y, k):
    """A smooth scene, in linear light, as a function of the normalised image point (x, y) = (X/Z, Y/Z): waves 31 px
    long across the image, 39 px down it."""
    return 0.45 + 0.25 * np.sin(30.0 * x + 1.1 * k) * np.cos(24.0 * y - 0.7 * k) + 0.1 * x * y


def image_through(cams):
    """The float sRGB image whose channel k is what camera k's intrinsics image of `light`."""
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    out = np.empty((H, W, 3))
    for k, cam in enumerate(cams):
        x = (u - cam.K[0, 2]) / cam.K[0, 0]
        y = (v - cam.K[1, 2]) / cam.K[1, 1]
        out[..., k] = light(x, y, k)
    return linear_to_srgb(out)


@pytest.fixture()
def lensed():
    red = ChannelLens(K(F * 1.006, (W - 1) / 2 + 0.3, (H - 1) / 2 - 0.2))
    blue = ChannelLens(K(F * 0.995, (W - 1) / 2, (H - 1) / 2 + 0.25))
    return PinholeCamera.from_look_at((W, H), F, None, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), red=red, blue=blue)


def test_a_float_image_aligned_is_the_image_green_s_intrinsics_would_take(lensed):
    """Each channel's misalignment (up to 0.034 in light here) falls to a tenth or less; Lanczos's kernel, the
    widest, leaves the least, and linear interpolation no more than its bound for a wave: A (ω h)² / 8."""
    taken = image_through([lensed.channel_camera(c) for c in ("red", "green", "blue")])
    ideal = image_through([lensed.channel_camera("green")] * 3)
    inner = (slice(4, -4), slice(4, -4))  # (beyond the border the channels' edge pixels are repeated)
    before = np.abs(srgb_to_linear(taken[inner]) - srgb_to_linear(ideal[inner])).max()
    errors = {}
    for interpolation in ("linear", "cubic", "cubic-clamped", "lanczos"):
        got = aligned_to_green(taken, lensed, interpolation)
        errors[interpolation] = np.abs(srgb_to_linear(got[inner]) - srgb_to_linear(ideal[inner])).max()
        assert errors[interpolation] < before / 10, (interpolation, errors[interpolation], before)
        np.testing.assert_array_equal(got[..., 1], taken[..., 1])
    assert errors["lanczos"] < errors["linear"]
    omega = np.hypot(30.0, 24.0) / (F * 0.995)  # the wave's angular frequency per pixel, at the smallest focal
    assert errors["linear"] < 0.25 * omega ** 2 / 8 * 1.1  # (+10 %: the scene's slow x y term, and sRGB's rounding)


def test_an_8_bit_image_keeps_green_and_its_aligned_channels_are_the_float_reading_rounded(lensed):
    taken = np.round(image_through([lensed.channel_camera(c) for c in ("red", "green", "blue")]) * 255).astype(np.uint8)
    got = aligned_to_green(taken, lensed)
    assert got.dtype == np.uint8
    np.testing.assert_array_equal(got[..., 1], taken[..., 1])
    unrounded = aligned_to_green(taken / 255.0, lensed) * 255  # the same codes as floats: nothing rounded after
    assert np.abs(got.astype(float) - unrounded).max() <= 0.5 + 1e-9
    ideal = image_through([lensed.channel_camera("green")] * 3) * 255
    inner = (slice(4, -4), slice(4, -4))
    for k in (0, 2):  # two roundings (the image's, then the aligned value's) alone leave 1/3 of a code on average
        assert np.abs(taken[inner][..., k] - ideal[inner][..., k]).mean() > 1.0
        assert np.abs(got[inner][..., k] - ideal[inner][..., k]).mean() < 0.45


def test_channels_are_resampled_in_light_through_the_camera_s_response(lensed):
    """A gamma-1.8 camera: its codes decoded through the curve, resampled, and stored through it again, which
    lands nearer the codes green's intrinsics would have stored than the same codes resampled as sRGB."""
    curve = as_response(1.8)
    cams = [lensed.channel_camera(c) for c in ("red", "green", "blue")]
    taken = np.round(srgb_to_linear(image_through(cams)) ** (1 / 1.8) * 255).astype(np.uint8)
    camera = PinholeCamera(lensed.resolution, lensed.K, lensed.R, lensed.position, response=curve, red=lensed.red,
                           blue=lensed.blue)
    ideal = srgb_to_linear(image_through([lensed.channel_camera("green")] * 3)) ** (1 / 1.8) * 255
    inner = (slice(4, -4), slice(4, -4))
    through_curve = np.abs(aligned_to_green(taken, camera, "lanczos")[inner] - ideal[inner])[..., [0, 2]]
    as_srgb = np.abs(aligned_to_green(taken, lensed, "lanczos")[inner] - ideal[inner])[..., [0, 2]]
    before = np.abs(taken[inner] - ideal[inner])[..., [0, 2]]
    # two roundings: 1/3 of a code on average, 1 at most; the interpolation: up to half a code more
    assert before.mean() > 1.0 and through_curve.mean() < 0.45 and through_curve.max() <= 1.5
    assert through_curve.mean() < as_srgb.mean()
    # the same stored values as floats (unrounded): decoded and stored again through the curve, no code between
    stored = srgb_to_linear(image_through(cams)) ** (1 / 1.8)
    got = aligned_to_green(stored, camera, "lanczos")
    err = np.abs(got[inner] ** 1.8 - ideal[inner] ** 1.8 / 255 ** 1.8)[..., [0, 2]]
    assert err.max() < 0.004 and err.mean() < np.abs(stored[inner] ** 1.8 - (ideal[inner] / 255) ** 1.8).mean() / 5


def test_the_clamped_cubic_leaves_no_ringing_beside_a_one_pixel_step(lensed):
    """A sharp vertical step (0.05 → 0.8 in light over one pixel) where each channel images it: the clamped cubic
    keeps every aligned value within the step's two levels, where OpenCV's cubic overshoots; both put the step
    (its coverage summed across it) where green images that edge, within a twentieth of a pixel."""
    light = np.full((H, W, 3), 0.05)
    light[:, 100:] = 0.8
    light[:, 99] = 0.05 + 0.75 * 0.4  # the step at 99.1 in each channel's own image: 40 % of pixel 99 bright
    taken = linear_to_srgb(light)
    rows = slice(30, 90)
    for interpolation in ("cubic-clamped", "cubic"):
        got = srgb_to_linear(aligned_to_green(taken, lensed, interpolation))[rows]
        for k, lens in ((0, lensed.red), (2, lensed.blue)):
            ring = max(0.05 - got[..., k].min(), got[..., k].max() - 0.8)
            assert ring <= 1e-6 if interpolation == "cubic-clamped" else ring > 0.005, (interpolation, k, ring)
            step = 109.5 - (got[:, 90:110, k] - 0.05).sum(axis=1) / 0.75  # the bright part's left end, per row
            green_sees = lensed.K[0, 2] + (99.1 - lens.K[0, 2]) * lensed.K[0, 0] / lens.K[0, 0]
            assert abs(np.median(step) - green_sees) < 0.05, (interpolation, k, np.median(step), green_sees)


def test_a_camera_without_channel_lenses_gets_its_image_back_and_bad_interpolations_are_refused(lensed):
    plain = lensed.channel_camera("green")
    img = np.random.default_rng(1).integers(0, 256, (H, W, 3), dtype=np.uint8)
    assert aligned_to_green(img, plain) is img
    with pytest.raises(DepthError, match="interpolation: expected one of linear, cubic, cubic-clamped, lanczos, "
                                         "got 'nearest'"):
        aligned_to_green(img, lensed, "nearest")
