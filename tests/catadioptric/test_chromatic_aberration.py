"""A lens whose red and blue images are magnified apart from green's: `[camera.red]` / `[camera.blue]` through
`simulate` and `reconstruct`.

The built-in demo scene, its red channel magnified so that it images the image's corner 1 px farther out than
green, blue 1 px farther in (a lens's lateral chromatic aberration), rendered by `catadioptric simulate` (each
channel through its own camera) and read with the channels' lenses declared, and as if the lens had none.
"""

import json

import numpy as np
import pytest

from catadioptric.cli import main
from catadioptric.setup import load_setup

SHIFT_PX = 1.0


@pytest.fixture(scope="module")
def rendered(tmp_path_factory, demo_with_camera):
    folder = tmp_path_factory.mktemp("chromatic")

    def lenses(setup):
        (w, h), (fx, fy) = setup.camera.resolution, setup.camera.focal_px
        corner = np.hypot((w - 1) / 2, (h - 1) / 2)
        return {"red": {"focal_px": [fx * (1 + SHIFT_PX / corner), fy * (1 + SHIFT_PX / corner)]},
                "blue": {"focal_px": [fx * (1 - SHIFT_PX / corner), fy * (1 - SHIFT_PX / corner)]}}

    demo_with_camera(folder, "lensed.toml", lenses)
    assert main(["simulate", str(folder / "lensed.toml"), "-o", str(folder / "mirror.png"), "--spp", "4"]) == 0
    for name, setup_file in (("declared", "mirror.toml"), ("ignored", "plain.toml")):
        assert main(["reconstruct", str(folder / "mirror.png"), "--setup", str(folder / setup_file),
                     "-o", str(folder / f"{name}.json")]) == 0
    return folder


def _readings(folder, name):
    """(true cube index, centre error, depth error in σ) of each cube read, and the refusals' count."""
    truth = json.loads((folder / "mirror.truth.json").read_text())["cubes"]
    result = json.loads((folder / f"{name}.json").read_text())
    out = []
    for cube in result["cubes"]:
        errors = [np.linalg.norm(np.subtract(cube["center"], t["center"])) / t["depth"] for t in truth]
        j = int(np.argmin(errors))
        out.append((j, errors[j], (cube["depth"] - truth[j]["depth"]) / cube["uncertainty"]["depth"]))
    return sorted(out), len(result["refused"])


def test_simulate_writes_the_channel_lenses_into_the_setup_it_rendered(rendered):
    written = load_setup(rendered / "mirror.toml").camera
    given = load_setup(rendered / "lensed.toml").camera
    assert written.red == given.red and written.blue == given.blue and written.red is not None


def test_declared_lenses_find_every_cube_within_its_sigma_where_ignoring_them_reads_fringes_as_blobs(rendered):
    declared, refused_declared = _readings(rendered, "declared")
    ignored, refused_ignored = _readings(rendered, "ignored")
    assert [j for j, _, _ in declared] == [0, 1, 2, 3, 4]
    assert all(abs(z) <= 3.0 for _, _, z in declared), declared
    # ignored, the channels' fringes beside every edge of the checkered floor seen in the mirror come out as
    # coloured blobs (refused, each touching another), and cubes are lost among them
    assert refused_ignored > 3 * max(refused_declared, 1), (refused_ignored, refused_declared)
    assert len(ignored) < len(declared)
