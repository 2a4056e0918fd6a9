"""Broken image files given to the commands that read images: one line on the process's own stderr.

`capfd` reads file descriptor 2 itself, so a warning OpenCV's C++ code prints there (a truncated PNG, a path it
cannot open) is caught, which `capsys` does not see.
"""

import os

import cv2
import numpy as np
import pytest

from catadioptric.cli import main


@pytest.fixture()
def files(tmp_path):
    rng = np.random.default_rng(3)
    whole = tmp_path / "whole.png"
    cv2.imwrite(str(whole), rng.integers(0, 256, (120, 160, 3), dtype=np.uint8))
    data = whole.read_bytes()
    (tmp_path / "cut.png").write_bytes(data[:len(data) // 3])
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "folder.png").mkdir()
    setup = tmp_path / "setup.toml"
    setup.write_text("[xslit]\nz1 = 0.1\nz2 = 0.5\ntheta1_deg = 30.0\ntheta2_deg = 120.0\npitch = 0.0005\n")
    return tmp_path, setup


def _commands(name, tmp_path, setup):
    path = str(tmp_path / name)
    return {
        "reconstruct": ["reconstruct", path, "--setup", str(setup), "-o", str(tmp_path / "r.json")],
        "depthmap": ["depthmap", path, "--setup", str(setup), "-o", str(tmp_path / "d.png")],
        "response": ["response", path, str(tmp_path / "whole.png"), "--times", "1", "2"],
    }


@pytest.mark.parametrize("verb", ["reconstruct", "depthmap", "response"])
@pytest.mark.parametrize("name, message", [
    ("cut.png", "cut.png: cannot read the image (expected "),
    ("missing.png", "missing.png: no such image file"),
    ("empty.png", "empty.png: expected an image file, got an empty file"),
    ("folder.png", "folder.png: expected an image file, got a folder"),
])
def test_a_broken_image_file_gets_one_line_on_stderr_and_nothing_written(capfd, files, verb, name, message):
    tmp_path, setup = files
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(_commands(name, tmp_path, setup)[verb])
    out, err = capfd.readouterr()
    assert code == 1
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("catadioptric: error: ") and message in lines[0], lines[0]
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_stderr_is_the_process_own_again_after_a_broken_file(capfd, files):
    tmp_path, setup = files
    main(_commands("cut.png", tmp_path, setup)["reconstruct"])
    capfd.readouterr()
    os.write(2, b"written by C\n")
    assert capfd.readouterr().err == "written by C\n"
