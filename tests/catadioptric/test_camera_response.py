"""A camera that does not store sRGB: `[camera] response` through `simulate` and `reconstruct`.

The built-in demo scene is rendered twice by `catadioptric simulate`: as sRGB, and by a camera whose values roll
its highlights off (the light y (1 + k) / (1 + k y), k = 1.5, then sRGB-encoded: a camera's tone curve), declared
as a table of the light of each code, scaled by 5 as a calibration gives it in any scale.
"""

import json
from importlib.resources import files

import numpy as np
import pytest

from catadioptric.cli import main
from catadioptric.setup import load_setup, save_setup

K = 1.5


def _tone_table() -> list:
    """The light of each code of the roll-off camera, times 5: sRGB-decoded code y → y / (1 + k − k y)."""
    s = np.arange(256) / 255.0
    y = np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)  # IEC 61966-2-1, written out here
    return list(5.0 * y / (1.0 + K - K * y))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """plain.png (sRGB) and tone.png (the roll-off camera, declared in declared.toml as a user would write it)."""
    import tomli_w
    folder = tmp_path_factory.mktemp("response")
    setup = load_setup(files("catadioptric") / "data" / "demo.toml")
    save_setup(setup, folder / "plain.toml")
    d = setup.to_dict()
    d["camera"]["response"] = _tone_table()
    (folder / "declared.toml").write_text(tomli_w.dumps(d))
    assert main(["simulate", str(folder / "plain.toml"), "-o", str(folder / "plain.png")]) == 0
    assert main(["simulate", str(folder / "declared.toml"), "-o", str(folder / "tone.png")]) == 0
    return folder


def _image(path):
    import cv2
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)


def test_simulate_stores_the_light_as_the_camera_does(rendered):
    """Each code c of the roll-off image holds the light of the sRGB image's pixel (decoded by the standard's
    formula) between the declared table's light at c − 0.5 and c + 0.5, one code more either way where the sRGB
    image's own rounding moved it; and the setup written beside it keeps the table."""
    srgb, tone = _image(rendered / "plain.png") / 255.0, _image(rendered / "tone.png").astype(int)
    light = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    table = np.array(_tone_table()) / _tone_table()[-1]
    at = lambda c: np.interp(c, np.arange(256), table)  # the table's light between codes
    assert np.all((at(tone - 1.5) <= light) & (light <= at(tone + 1.5)))
    assert np.mean((at(tone - 0.5) <= light) & (light <= at(tone + 0.5))) > 0.9
    assert np.mean(tone != np.round(srgb * 255)) > 0.3  # not the sRGB image: the roll-off moved most values
    written = load_setup(rendered / "tone.toml").camera.response
    np.testing.assert_allclose(written.table[:, 0], table, rtol=1e-15)


def _depths(path) -> dict:
    """Depth of each cube read, keyed by its front face's centre rounded to 10 px."""
    cubes = json.loads(path.read_text())["cubes"]
    return {tuple(np.round(np.mean(c["front_face_corners_px"], axis=0) / 10).astype(int)): c["depth"] for c in cubes}


def test_reconstruct_reads_the_declared_response_as_it_reads_srgb(rendered):
    """Read with its response (the setup `simulate` wrote beside it), the roll-off image gives every cube the
    sRGB image's depth within 0.4 %; read as sRGB (a setup without the key) the same image puts a cube's depth
    further off than that."""
    assert main(["reconstruct", str(rendered / "plain.png"), "-o", str(rendered / "plain.json")]) == 0
    assert main(["reconstruct", str(rendered / "tone.png"), "-o", str(rendered / "declared.json")]) == 0
    assert main(["reconstruct", str(rendered / "tone.png"), "--setup", str(rendered / "plain.toml"),
                 "-o", str(rendered / "ignored.json")]) == 0
    plain, declared, ignored = (_depths(rendered / f"{n}.json") for n in ("plain", "declared", "ignored"))
    assert len(plain) == 5 and declared.keys() == plain.keys() and ignored.keys() == plain.keys()
    off_declared = max(abs(declared[k] / plain[k] - 1) for k in plain)
    off_ignored = max(abs(ignored[k] / plain[k] - 1) for k in plain)
    assert off_declared < 0.004
    assert off_ignored > 0.006 and off_ignored > 2 * off_declared


def test_a_float_image_out_of_range_is_refused_through_a_response(rendered):
    """The response's re-encoding clips: a float image beyond [0, 1] is refused first, as without one."""
    from depth.errors import DepthError
    from depth.reconstruct import reconstruct
    setup = load_setup(rendered / "tone.toml")
    bad = np.full((setup.camera.resolution[1], setup.camera.resolution[0], 3), 1.5)
    with pytest.raises(DepthError, match="expected values in \\[0, 1\\]"):
        reconstruct(bad, setup.camera.build(), setup.mirror.build())
