"""Tests of catadioptric.setup: round trips, and one-line errors naming the file and the key."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.spatial.transform import Rotation

from catadioptric.errors import SetupError
from catadioptric.setup import Setup, load_setup, save_setup, setup_to_toml
from catadioptric import setup as setup_mod


def test_contract_example_loads_with_defaults(valid_setup, write_setup):
    s = load_setup(write_setup(valid_setup))
    assert s.camera.principal == (79.5, 59.5)
    assert s.mirror.type == "cylinder" and s.mirror.radius == 0.1
    cube = s.objects[0]
    np.testing.assert_allclose(cube.rotation, Rotation.from_euler("xyz", [0, -165, 0], degrees=True).as_matrix())


def test_round_trip_dict_and_toml(valid_setup, tmp_path):
    s = Setup.from_dict(valid_setup)
    assert Setup.from_dict(s.to_dict()) == s
    p = tmp_path / "again.toml"
    save_setup(s, p)
    assert load_setup(p) == s
    assert "[camera]" in setup_to_toml(s)


def test_the_lens_distortion_is_optional_and_round_trips(valid_setup, write_setup, tmp_path):
    """`[camera] distortion` (an extension): OpenCV's coefficients, kept through a round trip and built into the
    camera, whose pixels then move by them."""
    assert load_setup(write_setup(valid_setup)).camera.distortion is None
    valid_setup["camera"]["distortion"] = [-0.2, 0.05, 1e-3, -1e-3, 0.01]
    s = load_setup(write_setup(valid_setup))
    assert s.camera.distortion == (-0.2, 0.05, 1e-3, -1e-3, 0.01)
    p = tmp_path / "again.toml"
    save_setup(s, p)
    assert load_setup(p) == s and "distortion = [" in p.read_text()
    cam = s.camera.build()
    np.testing.assert_array_equal(cam.distortion, [-0.2, 0.05, 1e-3, -1e-3, 0.01, 0.0, 0.0, 0.0])
    del valid_setup["camera"]["distortion"]
    ideal = load_setup(write_setup(valid_setup)).camera.build()
    corner = np.array([[0.0, 0.0]])
    assert np.linalg.norm(cam.project(ideal.rays(corner)[0] + ideal.rays(corner)[1])[0] - corner) > 1.0


def test_the_camera_response_is_optional_and_round_trips(valid_setup, write_setup, tmp_path):
    """`[camera] response` (an extension): "srgb" (the default, as absent), "linear", a gamma or a table of the light
    of each code, kept through a round trip (a table scaled so that code 255 is 1) and built into the camera."""
    assert load_setup(write_setup(valid_setup)).camera.response is None
    valid_setup["camera"]["response"] = "srgb"
    assert load_setup(write_setup(valid_setup)).camera.response is None
    x = np.arange(256) / 255.0
    for value, light_of_128 in [(2.2, (128 / 255) ** 2.2), ("linear", 128 / 255),
                                ([list(4.0 * x ** 2.0), list(4.0 * x ** 2.2), list(4.0 * x ** 2.4)],
                                 np.array([x[128] ** 2.0, x[128] ** 2.2, x[128] ** 2.4]))]:
        valid_setup["camera"]["response"] = value
        s = load_setup(write_setup(valid_setup))
        p = tmp_path / "again.toml"
        save_setup(s, p)
        assert load_setup(p) == s and "response = " in p.read_text()
        cam = s.camera.build()
        np.testing.assert_allclose(cam.response.to_linear(np.full((1, 3), 128, dtype=np.uint8))[0],
                                   np.broadcast_to(light_of_128, (3,)), rtol=1e-13)


def test_a_channel_s_own_lens_is_optional_round_trips_and_defaults_to_the_camera_s(valid_setup, write_setup,
                                                                                      tmp_path):
    """`[camera.red]` / `[camera.blue]` (an extension): that channel's focal_px, principal_px and distortion, each
    defaulting to the camera's (green's), kept through a round trip and built into the camera's channel lenses."""
    assert load_setup(write_setup(valid_setup)).camera.build().has_channel_lenses is False
    valid_setup["camera"]["distortion"] = [-0.1, 0.0, 0.0, 0.0]
    valid_setup["camera"]["red"] = {"focal_px": [350.2, 350.3]}
    valid_setup["camera"]["blue"] = {"principal_px": [79.0, 60.0], "distortion": [-0.11, 0.0, 0.0, 0.0, 0.001]}
    s = load_setup(write_setup(valid_setup))
    p = tmp_path / "again.toml"
    save_setup(s, p)
    assert load_setup(p) == s and "[camera.red]" in p.read_text() and "[camera.blue]" in p.read_text()
    cam = s.camera.build()
    fx, fy = valid_setup["camera"]["focal_px"]
    np.testing.assert_array_equal(cam.red.K, [[350.2, 0.0, 79.5], [0.0, 350.3, 59.5], [0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(cam.red.distortion[:4], [-0.1, 0.0, 0.0, 0.0])  # the camera's
    np.testing.assert_array_equal(cam.blue.K, [[fx, 0.0, 79.0], [0.0, fy, 60.0], [0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(cam.blue.distortion[:5], [-0.11, 0.0, 0.0, 0.0, 0.001])
    np.testing.assert_array_equal(cam.K, [[fx, 0.0, 79.5], [0.0, fy, 59.5], [0.0, 0.0, 1.0]])  # green's, as given


def test_a_demosaiced_camera_is_optional_and_round_trips(valid_setup, write_setup, tmp_path):
    assert load_setup(write_setup(valid_setup)).camera.demosaiced is False
    valid_setup["camera"]["demosaiced"] = True
    s = load_setup(write_setup(valid_setup))
    assert s.camera.demosaiced is True
    p = tmp_path / "again.toml"
    save_setup(s, p)
    assert load_setup(p) == s and "demosaiced = true" in p.read_text()
    valid_setup["camera"]["demosaiced"] = False
    assert "demosaiced" not in setup_to_toml(load_setup(write_setup(valid_setup)))


def test_a_raw_frame_camera_s_mosaic_is_optional_any_case_and_round_trips(valid_setup, write_setup, tmp_path):
    assert load_setup(write_setup(valid_setup)).camera.mosaic is None
    valid_setup["camera"]["mosaic"] = "gbrg"
    s = load_setup(write_setup(valid_setup))
    assert s.camera.mosaic == "GBRG"
    p = tmp_path / "again.toml"
    save_setup(s, p)
    assert load_setup(p) == s and 'mosaic = "GBRG"' in p.read_text()


def test_a_raw_frame_s_levels_and_gains_are_optional_and_round_trip(valid_setup, write_setup, tmp_path):
    valid_setup["camera"].update(mosaic="RGGB")
    plain = load_setup(write_setup(valid_setup)).camera
    assert (plain.black_level, plain.white_level, plain.white_balance) == (0.0, None, None)
    assert "level" not in setup_to_toml(load_setup(write_setup(valid_setup)))
    valid_setup["camera"].update(black_level=64, white_level=4095, white_balance=[2.1, 1, 1.6])
    s = load_setup(write_setup(valid_setup))
    assert (s.camera.black_level, s.camera.white_level, s.camera.white_balance) == (64.0, 4095.0, (2.1, 1.0, 1.6))
    p = tmp_path / "again.toml"
    save_setup(s, p)
    assert load_setup(p) == s


RAW_BAD = [
    ({"black_level": 64}, "camera.black_level: expected no raw frame's level or gains without camera.mosaic"),
    ({"mosaic": "RGGB", "black_level": -1}, "camera.black_level: expected a number in \\[0.0, 65535.0\\], got -1"),
    ({"mosaic": "RGGB", "white_level": 70000}, "camera.white_level: expected a number in \\[0.0, 65535.0\\]"),
    ({"mosaic": "RGGB", "black_level": 512, "white_level": 256},
     "camera.white_level: expected a value above camera.black_level \\(512\\), got 256"),
    ({"mosaic": "RGGB", "white_balance": [2.0, 0.0, 1.5]},
     "camera.white_balance: expected a list of 3 positive numbers"),
    ({"mosaic": "RGGB", "white_balance": [2.0, 1.5]}, "camera.white_balance: expected a list of 3 finite numbers"),
]


@pytest.mark.parametrize("keys, message", RAW_BAD, ids=[str(k) for k, _ in RAW_BAD])
def test_bad_raw_frame_levels_and_gains_are_one_line_errors(valid_setup, write_setup, keys, message):
    valid_setup["camera"].update(keys)
    path = write_setup(valid_setup, "bad.toml")
    with pytest.raises(SetupError, match=f"^{path}: {message}"):
        load_setup(path)


@pytest.mark.parametrize("other, value, why", [("response", "linear", "a raw frame's values are light, linear"),
                                               ("demosaiced", True, "a raw frame is demosaiced by reconstruct")])
def test_a_raw_frame_camera_takes_no_response_nor_demosaiced_key(valid_setup, write_setup, other, value, why):
    valid_setup["camera"].update({"mosaic": "RGGB", other: value})
    path = write_setup(valid_setup, "bad.toml")
    with pytest.raises(SetupError, match=f"^{path}: camera.{other}: expected no {other} key with camera.mosaic "
                                         f"\\({why}\\), got {value!r}$"):
        load_setup(path)


def test_builtin_demo_setup_is_valid():
    from importlib.resources import files
    s = load_setup(files("catadioptric") / "data" / "demo.toml")
    assert len(s.objects) == 5
    # Each demo cube's local +z face looks at the mirror axis (the face the reconstruction measures).
    for cube in s.objects:
        normal = cube.rotation @ np.array([0.0, 0.0, 1.0])
        to_axis = -np.array([cube.center[0], 0.0, cube.center[2]])
        assert np.dot(normal, to_axis / np.linalg.norm(to_axis)) > 0.999


def _set(d, dotted, value):
    keys = dotted.split(".")
    for k in keys[:-1]:
        d = d[int(k)] if k.isdigit() else d[k]
    if value is _DELETE:
        del d[keys[-1]]
    else:
        d[keys[-1]] = value


class _Deleted:
    """The value that deletes a key (`BAD`); its repr names the test alike in every pytest process."""

    def __repr__(self) -> str:
        return "<deleted>"


_DELETE = _Deleted()

BAD = [
    ("camera.focal_px", [0.0, 350.0], "camera.focal_px: expected a list of 2 positive numbers"),
    ("camera.focal_px", _DELETE, "camera.focal_px: expected a list of 2 numbers \\(missing key\\)"),
    ("camera.resolution", [160.5, 120], "camera.resolution: expected a list of 2 integers"),
    ("camera.position", [0.0, "a", 0.5], "camera.position: expected a list of 3 finite numbers"),
    ("camera.position", [0.0, math.nan, 0.5], "camera.position: expected a list of 3 finite numbers"),
    ("camera.up", [0.0, 0.0, 0.0], "camera.up: expected a non-zero vector"),
    ("camera.up", [0.0, 0.0, -1.0], "camera.up: expected a direction not parallel"),
    ("camera.fov", 40.0, "camera.fov: unknown key"),
    ("camera.distortion", [0.1, 0.2], "camera.distortion: expected a list of 4, 5 or 8 numbers"),
    ("camera.distortion", [0.1, math.inf, 0.0, 0.0], "camera.distortion: expected a list of finite numbers"),
    ("camera.distortion", [-5.0, 0.0, 0.0, 0.0], "camera.distortion: expected coefficients whose distortion is "
                                                  "one-to-one over the image \\(these fold near pixel"),
    ("camera.response", "gamma", 'camera.response: expected "srgb", "linear", a gamma or a table of 256 values'),
    ("camera.response", -2.2, "camera.response: expected a gamma in \\(0, 10\\]"),
    ("camera.response", [0.0, 0.5, 1.0], "camera.response: expected .* a table of 256 numbers .* got an array of "
                                         "shape \\(3,\\)"),
    ("camera.response", [1.0] * 256, "camera.response: expected a table rising with the code .* channel 0 is flat"),
    ("camera.demosaiced", "yes", "camera.demosaiced: expected true or false \\(true where the camera's images are "
                                 "demosaiced from an RGGB Bayer mosaic\\), got 'yes'"),
    ("camera.mosaic", "RGBG", 'camera.mosaic: expected a Bayer filter tile, its 2 × 2 colours row by row: "RGGB", '
                              '"BGGR", "GRBG", "GBRG", got \'RGBG\''),
    ("camera.mosaic", True, "camera.mosaic: expected a Bayer filter tile, .* got True"),
    ("camera.red", [1.0], "camera.red: expected a table, got list"),
    ("camera.red", {}, "camera.red: expected at least one of focal_px, principal_px, distortion"),
    ("camera.red", {"focal": [350.0, 350.0]}, "camera.red.focal: unknown key"),
    ("camera.blue", {"focal_px": [350.0, -1.0]}, "camera.blue.focal_px: expected a list of 2 positive numbers"),
    ("camera.blue", {"principal_px": [79.5]}, "camera.blue.principal_px: expected a list of 2 finite numbers"),
    ("camera.blue", {"distortion": [0.1]}, "camera.blue.distortion: expected a list of 4, 5 or 8 numbers"),
    ("camera.red", {"distortion": [-5.0, 0.0, 0.0, 0.0]}, "camera.red.distortion: expected coefficients whose "
                                                           "distortion is one-to-one over the image \\(these fold"),
    ("camera.position", [0.0, 0.0, 0.05], "camera.position: expected a point outside the mirror"),
    ("camera.look_at", [0.0, 0.0, 1.5], "camera.look_at: expected the camera to look at the mirror"),
    ("mirror.radius", -0.1, "mirror.radius: expected a positive number"),
    ("mirror.axis", [0.0, 0.0, 0.0], "mirror.axis: expected a non-zero vector"),
    ("mirror.type", "paraboloid", 'mirror.type: expected one of "cylinder"'),
    ("mirror.height", True, "mirror.height: expected a finite number"),
    ("objects.0.size", 0.0, "objects\\[0\\].size: expected a positive number"),
    ("objects.0.color", [1.5, 0.0, 0.0], "objects\\[0\\].color: expected a list of 3 numbers in \\[0.0, 1.0\\]"),
    ("objects.0.type", "sphere", 'objects\\[0\\].type: expected one of "cube"'),
    ("units", "mm", 'units: expected one of "m"'),
    ("extra", 1, "extra: unknown key"),
]


@pytest.mark.parametrize("key, value, message", BAD, ids=[f"{k}={v!r}" for k, v, _ in BAD])
def test_bad_setups_give_one_line_errors_naming_file_and_key(valid_setup, write_setup, key, value, message):
    _set(valid_setup, key, value)
    path = write_setup(valid_setup, "bad.toml")
    with pytest.raises(SetupError, match=message) as info:
        load_setup(path)
    text = str(info.value)
    assert text.startswith(str(path) + ": ")
    assert "\n" not in text


def test_missing_mirror_file_and_invalid_toml(tmp_path, valid_setup, write_setup):
    with pytest.raises(SetupError, match="nope.toml: no such setup file"):
        load_setup(tmp_path / "nope.toml")
    bad = tmp_path / "broken.toml"
    bad.write_text("[camera\nresolution = 3")
    with pytest.raises(SetupError, match="broken.toml: invalid TOML"):
        load_setup(bad)
    del valid_setup["mirror"]
    with pytest.raises(SetupError, match="mirror: missing table \\[mirror\\]"):
        load_setup(write_setup(valid_setup))
    assert load_setup(write_setup(valid_setup, "nomirror.toml"), require_mirror=False).mirror is None


def test_registries_are_keyed_by_type():
    assert setup_mod.MIRROR_TYPES["cylinder"] is setup_mod.CylinderConfig
    assert setup_mod.OBJECT_TYPES["cube"] is setup_mod.CubeConfig


@settings(max_examples=200, deadline=None)
@given(st.tuples(*[st.floats(-360.0, 360.0)] * 3))
def test_rotation_is_scipys_extrinsic_xyz_euler(angles):
    from catadioptric.setup import euler_xyz_matrix
    np.testing.assert_allclose(euler_xyz_matrix(angles),
                               Rotation.from_euler("xyz", angles, degrees=True).as_matrix(), atol=1e-12)


def test_the_uncertainty_table_is_optional_and_round_trips(valid_setup, write_setup, tmp_path):
    """`[uncertainty]` (an extension): absent, none; given, each key its σ (0 where left out), kept through a
    round trip (`simulate` writes the setup it rendered), and built into `depth.setup_error.SetupStd`."""
    assert load_setup(write_setup(valid_setup)).uncertainty is None
    valid_setup["uncertainty"] = {"camera_position": 0.001, "focal_px": 5, "mirror_axis_deg": 0.1}
    s = load_setup(write_setup(valid_setup))
    assert s.uncertainty.camera_position == 0.001 and s.uncertainty.focal_px == 5.0
    assert s.uncertainty.mirror_radius == 0.0 and s.uncertainty.principal_px == 0.0
    p = tmp_path / "again.toml"
    save_setup(s, p)
    assert load_setup(p) == s and "[uncertainty]" in p.read_text()
    std = s.uncertainty.build()
    assert dict(std.items()) == {"camera_position": 0.001, "focal_px": 5.0, "mirror_axis_deg": 0.1}
    valid_setup["uncertainty"]["distortion"] = [0.01, 0.0, 2e-4]  # the σ of k1, k2, p1
    s = load_setup(write_setup(valid_setup))
    save_setup(s, p)
    assert load_setup(p) == s and s.uncertainty.distortion == (0.01, 0.0, 2e-4)
    assert dict(s.uncertainty.build().items())["distortion"] == [0.01, 0.0, 2e-4]
    assert [(n, k) for n, k, _ in s.uncertainty.build().components() if n == "distortion"] == [("distortion", 0),
                                                                                               ("distortion", 2)]


@pytest.mark.parametrize("table, message", [
    ({"focal_px": -1.0}, "uncertainty.focal_px: expected a σ >= 0, got -1.0"),
    ({"mirror_radius": "0.1"}, "uncertainty.mirror_radius: expected a finite number"),
    ({"camera_position": math.inf}, "uncertainty.camera_position: expected a finite number"),
    ({"camera_position": [0.001, 0.001, 0.001]}, "uncertainty.camera_position: expected a finite number"),
    ({"focal": 1.0}, "uncertainty.focal: unknown key"),
    ({"distortion": [0.01, -0.001]}, "uncertainty.distortion: expected a list of 1 to 8 σ >= 0"),
    ({"distortion": [0.0] * 9}, "uncertainty.distortion: expected a list of 1 to 8 σ >= 0"),
    ({"distortion": 0.01}, "uncertainty.distortion: expected a list of 1 to 8 σ >= 0"),
    (0.1, "uncertainty: expected a table"),
])
def test_a_bad_uncertainty_table_gives_a_one_line_error_naming_file_and_key(valid_setup, write_setup, table, message):
    valid_setup["uncertainty"] = table
    path = write_setup(valid_setup, "bad.toml")
    with pytest.raises(SetupError, match=message) as info:
        load_setup(path)
    assert str(info.value).startswith(str(path) + ": ") and "\n" not in str(info.value)
