"""A camera whose images are its raw Bayer frames: `[camera] mosaic` through `simulate`, `reconstruct` and `report`
(the built-in demo scene, 4 spp), and the frames such a setup refuses."""

import json

import cv2
import numpy as np
import pytest

from catadioptric.cli import main
from catadioptric.setup import load_setup
from raytrace.chroma import bayer_mosaic
from cli_errors import one_line_error as _bad


SAME_M = 1e-6
"""Two readings of one image agree to this (m): a process's first reading, whose faces its helper process fits, and
its later ones differ in the fits' last digits (6.7e-9 m at most on this scene, for any image)."""


@pytest.fixture(scope="module")
def rendered(tmp_path_factory, demo_with_camera):
    folder = tmp_path_factory.mktemp("raw")
    demo_with_camera(folder, "raw.toml", lambda setup: {"mosaic": "GRBG"})
    assert main(["simulate", str(folder / "plain.toml"), "-o", str(folder / "plain.png"), "--spp", "4"]) == 0
    assert main(["simulate", str(folder / "raw.toml"), "-o", str(folder / "mirror.png"), "--spp", "4"]) == 0
    demo_with_camera(folder, "levels.toml", lambda setup: {"mosaic": "GRBG", **LEVELS})
    assert main(["simulate", str(folder / "levels.toml"), "-o", str(folder / "levels.png"), "--spp", "4"]) == 0
    return folder


LEVELS = {"black_level": 64, "white_level": 4095, "white_balance": [2.0, 1.0, 1.6]}
"""A 12-bit sensor's frames stored in 16 bits, with its black level and white balance."""


def _srgb8(light):
    """IEC 61966-2-1's encoding to 8-bit codes, written out here."""
    light = np.clip(light, 0.0, 1.0)
    return np.round(255 * np.where(light <= 0.0031308, 12.92 * light, 1.055 * light ** (1 / 2.4) - 0.055))


def test_simulate_writes_the_frame_of_the_render_s_light_each_pixel_its_filter_s_channel(rendered):
    frame = cv2.imread(str(rendered / "mirror.png"), cv2.IMREAD_UNCHANGED)
    plain = cv2.cvtColor(cv2.imread(str(rendered / "plain.png")), cv2.COLOR_BGR2RGB)  # the same render, sRGB codes
    assert frame.dtype == np.uint16 and frame.shape == plain.shape[:2]
    # the frame's light, stored as sRGB codes, is the plain image's code of each pixel's own channel (a code apart
    # at most where the 16-bit light rounds across a code's half)
    apart = np.abs(_srgb8(frame / 65535.0) - bayer_mosaic(plain, "GRBG"))
    assert apart.max() <= 1 and np.mean(apart == 0) > 0.999
    coloured = np.ptp(plain.astype(int), axis=2) > 20  # (the cubes: where another tile would not match)
    assert coloured.sum() > 10000 and np.mean(apart[coloured] == 0) > 0.999
    assert np.mean(np.abs(_srgb8(frame / 65535.0) - bayer_mosaic(plain, "RGGB"))[coloured] == 0) < 0.5
    assert load_setup(rendered / "mirror.toml").camera.mosaic == "GRBG"


@pytest.fixture(scope="module")
def read(rendered):
    """The command's reading of the frame: rendered/raw.json and raw.overlay.png (made in each test process: the tests
    that read them may run in any)."""
    assert main(["reconstruct", str(rendered / "mirror.png"), "-o", str(rendered / "raw.json"),
                 "--overlay", str(rendered / "raw.overlay.png")]) == 0
    return rendered / "raw.json"


def test_reconstruct_reads_the_frame_demosaiced_as_a_compressed_image(rendered, read):
    """The command's result is the library's reading of the frame demosaiced (two-colour by default, as the result
    says) as compressed; and every cube of the demo is found, none invented, about where it is."""
    from depth.chroma import from_raw_frame
    from depth.reconstruct import reconstruct
    setup = load_setup(rendered / "mirror.toml")
    frame = cv2.imread(str(rendered / "mirror.png"), cv2.IMREAD_UNCHANGED)
    result = json.loads(read.read_text())
    assert result["demosaic"] == "two-colour"
    got = np.array([c["center"] for c in result["cubes"]])
    image = from_raw_frame(frame, "GRBG", "two-colour")
    want = reconstruct(image, setup.camera.build(), setup.mirror.build(), compressed=True).cubes
    np.testing.assert_allclose(got, [c.to_dict()["center"] for c in want], rtol=0, atol=SAME_M)
    truth = np.array([c["center"] for c in json.loads((rendered / "mirror.truth.json").read_text())["cubes"]])
    nearest = np.argmin(np.linalg.norm(got[:, None] - truth[None], axis=2), axis=1)
    assert len(got) == len(truth) == 5 and sorted(nearest) == list(range(5))
    centre_err = np.linalg.norm(got - truth[nearest], axis=1) / np.linalg.norm(truth[nearest][:, [0, 2]], axis=1)
    assert np.median(centre_err) < 0.03 and centre_err.max() < 0.15, centre_err
    overlay = cv2.imread(str(rendered / "raw.overlay.png"))
    assert overlay.shape == image.shape  # drawn on the demosaiced frame


def test_a_frame_s_levels_and_white_balance_are_written_and_read_back(rendered, tmp_path, capsys):
    """`simulate` records each pixel's light over its gain between the black and white levels; `reconstruct` reads
    that light back (each channel times its gain) and finds the demo's cubes as in the plain frame."""
    from depth.chroma import raw_light
    frame = cv2.imread(str(rendered / "levels.png"), cv2.IMREAD_UNCHANGED)
    plain = cv2.imread(str(rendered / "mirror.png"), cv2.IMREAD_UNCHANGED) / 65535.0  # (the same render's light)
    assert frame.dtype == np.uint16 and frame.min() >= 64 and frame.max() <= 4095
    gains = np.asarray(LEVELS["white_balance"])
    sample = plain / gains[np.tile([[1, 0], [2, 1]], (600, 800))]  # (GRBG's channels, written out)
    apart = np.abs(frame - np.round(64 + sample * (4095 - 64)))  # (a code apart where the plain frame's own
    assert apart.max() <= 1 and np.mean(apart == 0) > 0.9999   # rounding of the light crosses a half)
    light = raw_light(frame, "GRBG", 64, 4095, gains)
    assert np.abs(light - plain).max() <= 0.5 / (4095 - 64) * gains.max() + 1e-12
    assert main(["reconstruct", str(rendered / "levels.png"), "-o", str(tmp_path / "levels.json")]) == 0
    got = np.array([c["center"] for c in json.loads((tmp_path / "levels.json").read_text())["cubes"]])
    truth = np.array([c["center"] for c in json.loads((rendered / "levels.truth.json").read_text())["cubes"]])
    nearest = np.argmin(np.linalg.norm(got[:, None] - truth[None], axis=2), axis=1)
    assert len(got) == 5 and sorted(nearest) == list(range(5))
    cv2.imwrite(str(tmp_path / "eight.png"), (frame >> 4).astype(np.uint8))
    capsys.readouterr()
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "eight.png"), "--setup",
                            str(rendered / "levels.toml"), "-o", str(tmp_path / "o.json")],
         f"eight.png: an 8-bit frame's values reach 255, under {rendered / 'levels.toml'}: "
         "camera.white_level 4095")


def test_reconstruct_takes_another_demosaic_and_refuses_one_for_an_rgb_camera(rendered, capsys, tmp_path):
    from depth.chroma import from_raw_frame
    from depth.reconstruct import reconstruct
    setup = load_setup(rendered / "mirror.toml")
    frame = cv2.imread(str(rendered / "mirror.png"), cv2.IMREAD_UNCHANGED)
    assert main(["reconstruct", str(rendered / "mirror.png"), "-o", str(tmp_path / "vng.json"),
                 "--demosaic", "VNG"]) == 0
    result = json.loads((tmp_path / "vng.json").read_text())
    assert result["demosaic"] == "VNG"
    want = reconstruct(from_raw_frame(frame, "GRBG", "VNG"), setup.camera.build(), setup.mirror.build(),
                       compressed=True).cubes
    np.testing.assert_allclose([c["center"] for c in result["cubes"]], [c.to_dict()["center"] for c in want],
                               rtol=0, atol=SAME_M)
    capsys.readouterr()
    _bad(capsys, tmp_path, ["reconstruct", str(rendered / "plain.png"), "-o", str(tmp_path / "o.json"),
                            "--demosaic", "VNG"],
         f"--demosaic: {rendered / 'plain.toml'} has no [camera] mosaic: its camera's images are RGB, not raw Bayer "
         "frames")
    _bad(capsys, tmp_path, ["reconstruct", str(rendered / "mirror.png"), "-o", str(tmp_path / "o.json"),
                            "--demosaic", "AHD"],
         "--demosaic: expected one of VNG, bilinear, edge-aware, two-colour, got 'AHD'")


def test_report_draws_on_the_frame_demosaiced_as_the_result_says(rendered, read, tmp_path, capsys):
    """Its annotated image is the frame demosaiced (in colour, where the frame itself is one channel) by the demosaic
    the result names; one it does not know is a one-line error."""
    from depth.chroma import from_raw_frame
    frame = cv2.imread(str(rendered / "mirror.png"), cv2.IMREAD_UNCHANGED)
    result = json.loads(read.read_text())
    for demosaic in ("two-colour", "bilinear"):
        result["demosaic"] = demosaic
        (rendered / f"{demosaic}.json").write_text(json.dumps(result))
        assert main(["report", str(rendered / f"{demosaic}.json"), "-o", str(tmp_path / demosaic)]) == 0
        drawn = cv2.cvtColor(cv2.imread(str(tmp_path / demosaic / "annotated.png")), cv2.COLOR_BGR2RGB)
        image = np.round(np.asarray(from_raw_frame(frame, "GRBG", demosaic)) * 255).astype(np.uint8)
        assert drawn.shape == image.shape
        assert np.mean(np.all(np.abs(drawn.astype(int) - image) <= 1, axis=2)) > 0.9  # (the outlines drawn on it)
    result["demosaic"] = "AHD"
    (rendered / "ahd.json").write_text(json.dumps(result))
    capsys.readouterr()
    _bad(capsys, tmp_path, ["report", str(rendered / "ahd.json"), "-o", str(tmp_path / "ahd")],
         "ahd.json: demosaic: expected one of VNG, bilinear, edge-aware, two-colour, got 'AHD'")


def test_frames_a_raw_frame_camera_cannot_read_get_one_line(rendered, read, tmp_path, capsys):
    setup = str(rendered / "mirror.toml")
    out = ["-o", str(tmp_path / "o.json")]
    frame = cv2.imread(str(rendered / "mirror.png"), cv2.IMREAD_UNCHANGED)
    key = f"({setup}: camera.mosaic GRBG)"
    _bad(capsys, tmp_path, ["reconstruct", str(rendered / "plain.png"), "--setup", setup, *out],
         f"plain.png: expected a one-channel raw Bayer frame {key}, got an image of 3 channels")
    cv2.imwrite(str(tmp_path / "float.tiff"), (frame / 65535.0).astype(np.float32))
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "float.tiff"), "--setup", setup, *out],
         f"float.tiff: expected an 8- or 16-bit raw Bayer frame {key}, got 32-bit floats")
    cv2.imwrite(str(tmp_path / "frame.jpg"), (frame >> 8).astype(np.uint8))
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "frame.jpg"), "--setup", setup, *out],
         f"frame.jpg: expected a raw Bayer frame stored losslessly, PNG or TIFF {key}, got a JPEG file")
    cv2.imwrite(str(tmp_path / "small.png"), frame[:100, :120])
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "small.png"), "--setup", setup, *out],
         "small.png: expected 1600×1200 pixels")
    # (a report of a result whose frame is of another size: the same line, before any demosaic)
    result = json.loads(read.read_text())
    (tmp_path / "small.json").write_text(json.dumps(dict(result, image="small.png", setup=setup)))
    _bad(capsys, tmp_path, ["report", str(tmp_path / "small.json"), "-o", str(tmp_path / "rep")],
         f"small.png: expected 1600×1200 pixels ({setup}: camera.resolution), got 120×100")
    # and a frame read without the key: the error says what it lacks
    cv2.imwrite(str(tmp_path / "frame.png"), frame)
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "frame.png"), "--setup", str(rendered / "plain.toml"), *out],
         "frame.png: expected an RGB colour image, got a grayscale image (a camera's raw Bayer frame? its setup says "
         "so: [camera] mosaic)")
