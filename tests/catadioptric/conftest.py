"""Shared fixtures: a valid setup dictionary and a writer of setup files."""

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
