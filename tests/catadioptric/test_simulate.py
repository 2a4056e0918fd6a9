"""simulate_to_files (what `catadioptric simulate` runs) writes what simulate + write_simulation write."""

import json
import zipfile

import numpy as np
import pytest

import raytrace.render
from catadioptric.setup import load_setup
from catadioptric.simulate import GT_KEYS, simulate, simulate_to_files, write_simulation


def test_files_written_in_place_equal_those_written_from_memory(tmp_path, valid_setup, write_setup):
    setup = load_setup(write_setup(valid_setup))
    sim, paths = simulate_to_files(setup, tmp_path / "a.png", spp=4, seed=2)
    assert [p.name for p in paths] == ["a.png", "a.toml", "a.truth.json", "a.gt.npz"]
    ref = simulate(setup, spp=4, seed=2)
    write_simulation(ref, tmp_path / "b.png")
    for ext in ("png", "toml"):
        assert (tmp_path / f"a.{ext}").read_bytes() == (tmp_path / f"b.{ext}").read_bytes()
    ta, tb = (json.loads((tmp_path / f"{s}.truth.json").read_text()) for s in "ab")
    assert ta["cubes"] == tb["cubes"] and ta["image"] == "a.png" and ta["setup"] == "a.toml"
    with zipfile.ZipFile(tmp_path / "a.gt.npz") as zf:
        assert zf.testzip() is None
    a, b = np.load(tmp_path / "a.gt.npz"), np.load(tmp_path / "b.gt.npz")
    assert a.files == b.files == list(GT_KEYS)
    for key in GT_KEYS:
        assert a[key].dtype == b[key].dtype and a[key].shape == b[key].shape
        assert np.array_equal(a[key], b[key], equal_nan=a[key].dtype.kind == "f")
    # the returned simulation holds what was written
    assert np.array_equal(sim.render.mirror_point, a["mirror_point"], equal_nan=True)
    assert sim.render.image.tobytes() == ref.render.image.tobytes()


def test_a_failed_render_leaves_no_file(tmp_path, valid_setup, write_setup, monkeypatch):
    setup = load_setup(write_setup(valid_setup))
    (tmp_path / "out").mkdir()
    old = tmp_path / "out" / "a.gt.npz"
    old.write_bytes(b"earlier result")

    def fail(*args, **kwargs):
        raise raytrace.render.RaytraceError("camera: broken")
    monkeypatch.setattr(raytrace.render, "render", fail)
    with pytest.raises(raytrace.render.RaytraceError):
        simulate_to_files(setup, tmp_path / "out" / "a.png")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["a.gt.npz"]
    assert old.read_bytes() == b"earlier result"
