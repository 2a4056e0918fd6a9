"""A camera whose images are demosaiced from an RGGB Bayer mosaic: `[camera] demosaiced` through `simulate` and
`reconstruct` (the built-in demo scene, 4 spp)."""

import json

import cv2
import numpy as np
import pytest

from catadioptric.cli import main
from catadioptric.setup import load_setup
from raytrace.chroma import bayer_mosaic


@pytest.fixture(scope="module")
def rendered(tmp_path_factory, demo_with_camera):
    folder = tmp_path_factory.mktemp("bayer")
    demo_with_camera(folder, "bayer.toml", lambda setup: {"demosaiced": True})
    assert main(["simulate", str(folder / "plain.toml"), "-o", str(folder / "plain.png"), "--spp", "4"]) == 0
    assert main(["simulate", str(folder / "bayer.toml"), "-o", str(folder / "mirror.png"), "--spp", "4"]) == 0
    return folder


def _rgb(path):
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)


def test_simulate_records_each_pixel_s_own_channel_and_interpolates_the_others(rendered):
    plain, bayer = _rgb(rendered / "plain.png"), _rgb(rendered / "mirror.png")
    np.testing.assert_array_equal(bayer_mosaic(bayer), bayer_mosaic(plain))  # the samples the sensor recorded
    assert np.mean(bayer != plain) > 0.05  # the other two channels of each pixel interpolated
    assert load_setup(rendered / "mirror.toml").camera.demosaiced is True


def test_reconstruct_reads_a_demosaiced_image_as_a_compressed_one(rendered):
    """The command passes `compressed` for such a camera (its edges read on luma): its result is the library's
    reading of the same image as compressed, and not the reading of it as full colour."""
    from depth.reconstruct import reconstruct
    setup = load_setup(rendered / "mirror.toml")
    image = _rgb(rendered / "mirror.png")
    camera, mirror = setup.camera.build(), setup.mirror.build()
    assert main(["reconstruct", str(rendered / "mirror.png"), "-o", str(rendered / "declared.json")]) == 0
    got = [c["center"] for c in json.loads((rendered / "declared.json").read_text())["cubes"]]
    as_compressed = [c.to_dict()["center"] for c in reconstruct(image, camera, mirror, compressed=True).cubes]
    as_colour = [c.to_dict()["center"] for c in reconstruct(image, camera, mirror, compressed=False).cubes]
    np.testing.assert_allclose(got, as_compressed, rtol=0, atol=1e-12)
    assert len(as_colour) != len(got) or not np.allclose(as_colour, got)
