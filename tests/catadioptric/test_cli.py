"""Tests of the CLI: exit codes, one-line errors, nothing written on bad input, simulate outputs."""

import json

import numpy as np
import pytest

from catadioptric.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_every_verb_has_help(capsys):
    for verb in ("simulate", "fit", "design", "reconstruct", "report", "demo"):
        with pytest.raises(SystemExit) as info:
            main([verb, "--help"])
        assert info.value.code == 0
        assert verb in capsys.readouterr().out


def test_the_console_script_is_console_which_exits_with_mains_status(tmp_path):
    """`catadioptric` runs `console` (main in a process of its own): its exit status and one-line error
    are main's."""
    import subprocess
    import sys
    from importlib.metadata import entry_points

    from catadioptric import cli
    (script,) = entry_points(group="console_scripts", name="catadioptric")
    assert script.load() is cli.console
    missing = tmp_path / "missing.png"
    done = subprocess.run([sys.executable, "-c", "from catadioptric.cli import console; console()", "reconstruct",
                           str(missing)], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 1
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("catadioptric: error: ") and str(missing) in done.stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("preset, seen", [(None, "1"), ("3", "3")])
def test_the_console_script_runs_one_openblas_thread_unless_the_environment_says(preset, seen):
    """`console` sets OPENBLAS_NUM_THREADS before numpy loads OpenBLAS (the command's work is spread over
    processes; an idle OpenBLAS thread spins on the core another process needs), and leaves a value the
    user set. In the process, OpenBLAS then reports that many threads."""
    import os
    import subprocess
    import sys
    code = ("import os, sys; import catadioptric.cli as cli\n"
            "def main(one_shot):\n"
            "    loaded = 'numpy' in sys.modules\n"
            "    from raytrace.render import _openblas_thread_controls\n"
            "    print(os.environ.get('OPENBLAS_NUM_THREADS'), loaded, [get() for get, _ in _openblas_thread_controls()])\n"
            "    return 0\n"
            "cli.main = main\n"
            "cli.console()\n")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if preset is not None:
        env["OPENBLAS_NUM_THREADS"] = preset
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stderr
    value, loaded, threads = done.stdout.strip().split(maxsplit=2)
    assert (value, loaded) == (seen, "False")  # numpy not loaded before `console` set it
    # numpy's OpenBLAS took it (capped at the cores it finds: 3 is 2 on a 2-core machine)
    assert threads == "[1]" if seen == "1" else (threads != "[1]" or os.cpu_count() == 1)


@pytest.mark.parametrize("key, value, message", [
    ("camera", {"focal_px": [0.0, 350.0]}, "camera.focal_px: expected a list of 2 positive numbers"),
    ("mirror", {"axis": [0.0, 0.0, 0.0]}, "mirror.axis: expected a non-zero vector"),
    ("camera", {"position": [0.0, 0.0, 0.02]}, "camera.position: expected a point outside the mirror"),
    ("camera", {"look_at": [0.0, 0.0, 2.0]}, "camera.look_at: expected the camera to look at the mirror"),
])
def test_simulate_bad_setup_exits_1_with_one_line_and_writes_nothing(
        capsys, tmp_path, valid_setup, write_setup, key, value, message):
    valid_setup[key].update(value)
    setup = write_setup(valid_setup, "bad.toml")
    out_png = tmp_path / "out.png"
    out_png.write_bytes(b"previous")  # must not be overwritten
    code, out, err = run(capsys, "simulate", str(setup), "-o", str(out_png))
    assert code == 1
    assert err.count("\n") == 1 and "Traceback" not in err
    assert str(setup) in err and message in err
    assert out_png.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "out.png"]


def test_simulate_rejects_bad_arguments(capsys, tmp_path, valid_setup, write_setup):
    setup = write_setup(valid_setup)
    code, _, err = run(capsys, "simulate", str(setup), "-o", str(tmp_path / "out.jpg"))
    assert code == 1 and "expected an output file name ending in .png" in err
    code, _, err = run(capsys, "simulate", str(setup), "-o", str(tmp_path / "o.png"), "--spp", "0")
    assert code == 1 and "--spp: expected an integer >= 1" in err
    code, _, err = run(capsys, "simulate", str(tmp_path / "missing.toml"), "-o", str(tmp_path / "o.png"))
    assert code == 1 and "missing.toml: no such setup file" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["setup.toml"]


def test_simulate_writes_four_files_reproducibly(capsys, tmp_path, valid_setup, write_setup):
    setup = write_setup(valid_setup)
    code, out, _ = run(capsys, "simulate", str(setup), "-o", str(tmp_path / "a.png"), "--seed", "3")
    assert code == 0
    for name in ("a.png", "a.toml", "a.truth.json", "a.gt.npz"):
        assert (tmp_path / name).stat().st_size > 0
    truth = json.loads((tmp_path / "a.truth.json").read_text())
    assert truth["image"] == "a.png" and truth["setup"] == "a.toml"
    cube = truth["cubes"][0]
    for key in ("center", "size", "depth", "front_face_center", "front_face_corners_px"):
        assert key in cube
    # depth = distance from the mirror axis (the y axis through the origin) to the centre
    assert cube["depth"] == pytest.approx(np.hypot(0.24, 0.90), rel=1e-12)
    gt = np.load(tmp_path / "a.gt.npz")
    assert gt["object_id"].dtype == np.int32 and gt["object_id"].shape == (120, 160)
    assert gt["via_mirror"].dtype == bool and gt["mirror_point"].shape == (120, 160, 3)
    on_mirror = np.isfinite(gt["mirror_point"]).all(axis=2)
    assert 0 < on_mirror.sum() < on_mirror.size
    assert np.isnan(gt["reflected_dir"][~on_mirror]).all()
    np.testing.assert_allclose(np.linalg.norm(gt["reflected_dir"][on_mirror], axis=1), 1.0, atol=1e-12)
    assert not gt["via_mirror"][~on_mirror].any()
    # Same seed, same bytes.
    assert run(capsys, "simulate", str(setup), "-o", str(tmp_path / "b.png"), "--seed", "3")[0] == 0
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
    assert (tmp_path / "a.gt.npz").read_bytes() == (tmp_path / "b.gt.npz").read_bytes()
    # The rendered setup round-trips through the loader.
    from catadioptric.setup import load_setup
    assert load_setup(tmp_path / "a.toml") == load_setup(setup)
