"""Each colour channel's intrinsics from chessboard views: `raytrace.chroma.calibrate_channels` and `catadioptric
lens`, on views rendered here (each pixel's ray through that channel's own K and distortion, met with the board's
plane: 9 samples a pixel, averaged in light), the lens's red magnified 0.2 % over green and blue 0.15 % under, each
centre a few tenths of a pixel apart and each k1 its own."""

import tomllib

import cv2
import numpy as np
import pytest

from catadioptric.cli import main
from catadioptric.setup import Setup
from raytrace.camera import PinholeCamera
from raytrace.chroma import ChannelLens, calibrate_channels, channel_pixels
from raytrace.errors import RaytraceError
from raytrace.lens import as_distortion, undistort
from raytrace.response import linear_to_srgb

SIZE, F, BOARD, SQUARE = (480, 360), 525.0, (9, 6), 0.025
GREEN = (np.array([[F, 0.0, 239.5], [0.0, F, 179.5], [0.0, 0.0, 1.0]]), [-0.12, 0.05, 0.0, 0.0, 0.0])
RED = (np.array([[F * 1.002, 0.0, 239.8], [0.0, F * 1.002, 179.3], [0.0, 0.0, 1.0]]), [-0.118, 0.05, 0.0, 0.0, 0.0])
BLUE = (np.array([[F * 0.9985, 0.0, 239.4], [0.0, F * 0.9985, 179.7], [0.0, 0.0, 1.0]]), [-0.123, 0.05, 0.0, 0.0, 0.0])


def _channel_view(K, dist, rvec, tvec, samples=3):
    """A channel's light: the board's (cols + 1) × (rows + 1) squares, dark 0.03, light 0.85, on a light margin."""
    w, h = SIZE
    R, _ = cv2.Rodrigues(rvec)
    coeffs = as_distortion(dist)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    light = np.zeros(h * w)
    for i in range(samples):
        for j in range(samples):
            x = (u.ravel() + (i + 0.5) / samples - 0.5 - K[0, 2]) / K[0, 0]
            y = (v.ravel() + (j + 0.5) / samples - 0.5 - K[1, 2]) / K[1, 1]
            xy, _ = undistort(np.column_stack([x, y]), coeffs)
            d = np.column_stack([xy, np.ones(len(xy))])
            on_board = ((d * ((R[:, 2] @ tvec) / (d @ R[:, 2]))[:, None]) - tvec) @ R / SQUARE
            bx, by = on_board[:, 0], on_board[:, 1]
            inside = (bx >= -1) & (bx < BOARD[0]) & (by >= -1) & (by < BOARD[1])
            light += np.where(inside & ((np.floor(bx) + np.floor(by)) % 2 == 0), 0.03, 0.85)
    return (light / samples ** 2).reshape(h, w)


def _views(n=10, seed=1):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        rvec = rng.uniform(-0.35, 0.35, 3)
        R, _ = cv2.Rodrigues(rvec)
        place = np.array([rng.uniform(-0.09, 0.09), rng.uniform(-0.06, 0.06), rng.uniform(0.4, 0.55)])
        tvec = place - R @ np.array([(BOARD[0] - 1) * SQUARE / 2, (BOARD[1] - 1) * SQUARE / 2, 0.0])
        light = np.stack([_channel_view(*lens, rvec, tvec) for lens in (RED, GREEN, BLUE)], axis=-1)
        out.append(np.round(linear_to_srgb(light) * 255).astype(np.uint8))
    return out


@pytest.fixture(scope="module")
def views():
    return _views()


def _camera(K, dist, red, blue):
    return PinholeCamera(SIZE, K, np.eye(3), np.zeros(3), dist, red=red, blue=blue)


def test_the_channels_maps_come_back_within_a_few_hundredths_of_a_pixel(views):
    """Where red and blue image each of green's rays: the calibrated lens's map against the true lens's, over the
    whole image (the true shift: 0.4 px median, 1.1 px at most)."""
    cal = calibrate_channels(views, BOARD, SQUARE)
    assert len(cal.views) >= 8 and all(rms < 0.2 for rms in cal.rms_px.values()), (cal.views, cal.rms_px)
    true = _camera(*GREEN, ChannelLens(*RED), ChannelLens(*BLUE))
    got = _camera(cal.K, cal.distortion, cal.red, cal.blue)
    plain = _camera(*GREEN, None, None)
    for name in ("red", "blue"):
        shift = np.linalg.norm(channel_pixels(true, name) - channel_pixels(plain, name), axis=-1)
        err = np.linalg.norm(channel_pixels(got, name) - channel_pixels(true, name), axis=-1)
        assert np.median(shift) > 0.3
        assert np.median(err) < 0.02 and np.percentile(err, 95) < 0.06, (name, np.median(err), err.max())
    # a magnification of its own each: red's over green's, blue's under (the truth: 1.002, 0.9985)
    assert abs(cal.red.K[0, 0] / cal.K[0, 0] - 1.002) < 3e-4 and abs(cal.blue.K[0, 0] / cal.K[0, 0] - 0.9985) < 3e-4
    for lens, (K, dist) in ((cal.red, RED), (cal.blue, BLUE)):  # a centre and a k1 of its own, against green's
        np.testing.assert_allclose(lens.K[:2, 2] - cal.K[:2, 2], K[:2, 2] - GREEN[0][:2, 2], atol=0.05)
        assert abs((lens.distortion[0] - cal.distortion[0]) - (dist[0] - GREEN[1][0])) < 1e-3
        np.testing.assert_array_equal(lens.distortion[1:5], cal.distortion[1:5])
    assert 0.3 < cal.coverage < 1.0


def test_bad_calibration_inputs_are_one_line_errors(views):
    noise = [np.random.default_rng(k).integers(0, 256, views[0].shape, dtype=np.uint8) for k in range(3)]
    for images, board, square, message in [
        (views[:2], BOARD, SQUARE, "images: expected at least 3 views of the chessboard, got 2"),
        (noise, BOARD, SQUARE, r"images: the chessboard \(9×6 inner corners\) was found in 0 of 3 views"),
        (views[:3], (2, 6), SQUARE, "board: expected the inner corners' columns and rows"),
        (views[:3], BOARD, 0.0, "square: expected the squares' side, > 0, got 0.0"),
        ([views[0], views[1][:100], views[2]], BOARD, SQUARE, r"images\[1\]: expected the size of images\[0\]"),
    ]:
        with pytest.raises(RaytraceError, match=message):
            calibrate_channels(images, board, square)


def test_the_lens_command_prints_camera_lines_a_setup_takes(views, tmp_path, capsys, valid_setup):
    paths = []
    for k, im in enumerate(views[:8]):
        paths.append(tmp_path / f"board{k}.png")
        cv2.imwrite(str(paths[-1]), cv2.cvtColor(im, cv2.COLOR_RGB2BGR))
    assert main(["lens", *map(str, paths), "--board", "9x6", "--square", str(SQUARE)]) == 0
    out = capsys.readouterr().out
    printed = tomllib.loads(out)["camera"]
    assert set(printed) == {"focal_px", "principal_px", "distortion", "red", "blue"}
    # the same calibration run here: OpenCV's sums over its threads make runs differ in the 8th digit (4.5e-8 seen)
    cal = calibrate_channels(views[:8], BOARD, SQUARE)
    np.testing.assert_allclose(printed["red"]["focal_px"], np.diag(cal.red.K)[:2], rtol=1e-6)
    np.testing.assert_allclose(printed["blue"]["principal_px"], cal.blue.K[:2, 2], rtol=1e-6)
    np.testing.assert_allclose(printed["distortion"], cal.distortion[:5], rtol=1e-6, atol=1e-12)
    valid_setup["camera"].update(printed)
    valid_setup["camera"]["resolution"] = list(SIZE)
    camera = Setup.from_dict(valid_setup).camera.build()
    np.testing.assert_array_equal(np.diag(camera.red.K)[:2], printed["red"]["focal_px"])  # built as printed
    np.testing.assert_array_equal(camera.blue.K[:2, 2], printed["blue"]["principal_px"])
    assert "# rms reprojection error: green" in out and "of 8 views of a 9×6 chessboard" in out


def test_the_lens_command_refuses_bad_arguments_in_one_line(views, tmp_path, capsys):
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    cv2.imwrite(str(a), views[0])
    cv2.imwrite(str(b), views[1][:200])
    for argv, message in [
        ([str(a), str(b), str(a), "--board", "9x6"], f"{b}: expected the size of {a}, 480×360 pixels, got 480×200"),
        ([str(a), str(a), str(a), "--board", "9x6", "--square", "0"], "--square: expected the squares' side, > 0"),
        ([str(tmp_path / "none.png"), str(a), str(a), "--board", "9x6"], "none.png: no such image file"),
    ]:
        assert main(["lens", *argv]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err
