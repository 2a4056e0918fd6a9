"""Shared fixtures: a valid setup dictionary, a writer of setup files, and the demo setup with camera keys."""

import copy

import pytest
import tomli_w

VALID = {
    "units": "m",
    "camera": {"resolution": [160, 120], "focal_px": [350.0, 350.0], "position": [0.0, 0.0, 0.55],
               "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]},
    "mirror": {"type": "cylinder", "radius": 0.1, "height": 0.49, "center": [0.0, 0.0, 0.0],
               "axis": [0.0, 1.0, 0.0]},
    "objects": [{"type": "cube", "size": 0.04, "center": [0.24, 0.03, 0.90],
                 "rotation_deg": [0.0, -165.0, 0.0], "color": [0.8, 0.1, 0.1]}],
}


@pytest.fixture
def valid_setup():
    return copy.deepcopy(VALID)


@pytest.fixture
def write_setup(tmp_path):
    def write(d, name="setup.toml"):
        p = tmp_path / name
        p.write_text(tomli_w.dumps(d))
        return p
    return write


@pytest.fixture(scope="session")
def demo_with_camera():
    """write(folder, name, camera): the built-in demo's setup as folder/plain.toml and, with the `[camera]` keys
    `camera(setup)` gives (setup: the demo's `Setup`), as folder/name, as a user would write them."""
    from importlib.resources import files

    from catadioptric.setup import load_setup, save_setup

    def write(folder, name, camera):
        setup = load_setup(files("catadioptric") / "data" / "demo.toml")
        save_setup(setup, folder / "plain.toml")
        d = setup.to_dict()
        d["camera"].update(camera(setup))
        (folder / name).write_text(tomli_w.dumps(d))
    return write
