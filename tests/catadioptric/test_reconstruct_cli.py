"""Tests of `catadioptric reconstruct`: the result contract, the overlay, and every bad input."""

import json

import cv2
import numpy as np
import pytest

from catadioptric.cli import main
from depth.estimate import EDGE_MISFIT_WARN_PX
from cli_errors import one_line_error as _bad

CONTRACT_KEYS = {"center", "size", "depth", "front_face_center", "front_face_corners_px", "aspect_ratio",
                 "method", "uncertainty"}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 640×480 render of two 4 cm cubes facing the mirror axis, with its truth."""
    import tomli_w
    folder = tmp_path_factory.mktemp("rec")
    setup = {
        "camera": {"resolution": [640, 480], "focal_px": [1400.0, 1400.0], "position": [0.0, 0.0, 0.55],
                   "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]},
        "mirror": {"type": "cylinder", "radius": 0.1, "height": 0.49, "center": [0.0, 0.0, 0.0],
                   "axis": [0.0, 1.0, 0.0]},
        "objects": [],
    }
    for r, az, color in ((0.35, -30.0, [0.85, 0.1, 0.1]), (0.5, 20.0, [0.1, 0.2, 0.85])):
        a = np.deg2rad(az)
        x, z = r * np.sin(a), r * np.cos(a)
        setup["objects"].append({"type": "cube", "size": 0.04, "center": [x, 0.0, z],
                                 "rotation_deg": [0.0, float(np.rad2deg(np.arctan2(-x, -z))), 0.0], "color": color})
    path = folder / "in.toml"
    path.write_text(tomli_w.dumps(setup))
    assert main(["simulate", str(path), "-o", str(folder / "mirror.png")]) == 0
    return folder


def test_result_follows_the_contract_and_is_accurate(scene, capsys):
    capsys.readouterr()
    out = scene / "r.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "-o", str(out), "--overlay", str(scene / "ov.png")]) == 0
    printed = capsys.readouterr().out
    assert "centre err" in printed  # the truth beside the image adds error columns
    result = json.loads(out.read_text())
    truth = json.loads((scene / "mirror.truth.json").read_text())
    assert result["image"] == "mirror.png" and result["setup"] == "mirror.toml"
    assert len(result["cubes"]) == 2
    for cube in result["cubes"]:
        assert CONTRACT_KEYS <= set(cube)
        assert cube["method"] == "exact" and cube["uncertainty"]["depth"] > 0
        t = min(truth["cubes"], key=lambda t: np.linalg.norm(np.subtract(t["center"], cube["center"])))
        # 640×480 renders: faces 20–30 px wide; a few percent at most
        assert np.linalg.norm(np.subtract(cube["center"], t["center"])) / t["depth"] < 0.05
        assert cube["size"] == pytest.approx(0.04, rel=0.05)
        assert cube["depth"] == pytest.approx(np.hypot(cube["center"][0], cube["center"][2]), rel=1e-9)
        # a clean render's edges fit a square to a tenth of a pixel: no flag
        assert 0.0 < cube["edge_misfit_px"] < EDGE_MISFIT_WARN_PX
    assert "misfit" in printed and "may be short" not in printed
    overlay = cv2.imread(str(scene / "ov.png"))
    assert overlay.shape == (480, 640, 3)
    b, g, r = overlay[..., 0].astype(int), overlay[..., 1].astype(int), overlay[..., 2].astype(int)
    assert np.count_nonzero((r > 200) & (g > 200) & (b < 100)) > 50  # the yellow face outlines


def test_a_known_size_s_sigma_widens_each_depth_sigma_by_the_fit_s_size_slope(scene):
    """`--cube-size 0.04 --cube-size-std 0.0004` (1 %): each depth σ is the known-size reading's own, added in
    quadrature to 0.0004 m times how far its depth moves per metre of size; the size σ is 0.0004 m; the readings
    themselves are the same. A cube's scale fixes its distance along the reflected rays, which meet the camera's
    pupil behind the mirror's surface: 1 % of the size moves the depth by more than 1 % of its distance from the
    surface (depth − radius 0.1 m) and less than 1 % of its distance from the camera (depth + 0.55 m)."""
    known, carried = scene / "known.json", scene / "known_sd.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "--cube-size", "0.04", "-o", str(known)]) == 0
    assert main(["reconstruct", str(scene / "mirror.png"), "--cube-size", "0.04", "--cube-size-std", "0.0004",
                 "-o", str(carried)]) == 0
    a, b = (json.loads(p.read_text())["cubes"] for p in (known, carried))
    assert len(a) == len(b) == 2
    for x, y in zip(a, b):
        assert y["center"] == x["center"] and y["depth"] == x["depth"] and y["size"] == x["size"] == 0.04
        assert x["uncertainty"]["size"] == 0.0 and y["uncertainty"]["size"] == 0.0004
        added = np.sqrt(y["uncertainty"]["depth"] ** 2 - x["uncertainty"]["depth"] ** 2)
        assert 0.01 * (x["depth"] - 0.1) < added < 0.01 * (x["depth"] + 0.55), (x["depth"], added)
        assert y["uncertainty"]["center"] > x["uncertainty"]["center"]


def test_the_setup_s_uncertainty_table_widens_each_sigma_by_its_share(scene, capsys):
    """A setup whose `[uncertainty]` says its camera's place is known to 1 mm: the cubes are the same; each
    depth σ is the image's own (the same setup without it) and the setup's share (`uncertainty_from_setup`) in
    quadrature, and the result names the σ carried (`setup_uncertainty`). That share is what whole runs of the
    command make of it: the root sum of squares of each depth's move when the setup's camera is moved 1 mm along
    x, y and z in turn, its look_at with it (within 10 %). With another method the table is not carried: the
    command says so."""
    import tomli_w, tomllib
    setup = tomllib.loads((scene / "mirror.toml").read_text())
    setup["uncertainty"] = {"camera_position": 0.001}
    (scene / "unsure.toml").write_text(tomli_w.dumps(setup))
    plain, unsure = scene / "plain.json", scene / "unsure.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "-o", str(plain)]) == 0
    capsys.readouterr()
    assert main(["reconstruct", str(scene / "mirror.png"), "--setup", str(scene / "unsure.toml"),
                 "-o", str(unsure)]) == 0
    printed = capsys.readouterr().out
    assert "±σ with the setup's uncertainty" in printed and "setup σ: the share (m) of ±σ" in printed
    a, b = (json.loads(p.read_text()) for p in (plain, unsure))
    assert "setup_uncertainty" not in a and b["setup_uncertainty"] == setup["uncertainty"]
    moves = []
    for k in range(3):
        moved = tomllib.loads((scene / "mirror.toml").read_text())
        moved["camera"]["position"][k] += 0.001
        moved["camera"]["look_at"][k] += 0.001  # (its turn held: `camera_rotation_deg` is the turn's own σ)
        (scene / f"moved{k}.toml").write_text(tomli_w.dumps(moved))
        assert main(["reconstruct", str(scene / "mirror.png"), "--setup", str(scene / f"moved{k}.toml"),
                     "-o", str(scene / f"moved{k}.json")]) == 0
        moves.append([c["depth"] for c in json.loads((scene / f"moved{k}.json").read_text())["cubes"]])
    assert len(a["cubes"]) == len(b["cubes"]) == 2 and all(len(m) == 2 for m in moves)
    for i, (x, y) in enumerate(zip(a["cubes"], b["cubes"])):
        assert y["center"] == x["center"] and y["size"] == x["size"] and "uncertainty_from_setup" not in x
        share = y["uncertainty_from_setup"]
        whole_runs = np.sqrt(sum((m[i] - x["depth"]) ** 2 for m in moves))
        assert share["depth"] == pytest.approx(whole_runs, rel=0.1), (share, whole_runs)
        assert y["uncertainty"]["depth"] == pytest.approx(np.hypot(x["uncertainty"]["depth"], share["depth"]))
        assert y["uncertainty"]["size"] == pytest.approx(np.hypot(x["uncertainty"]["size"], share["size"]))
    other = scene / "ddar_unsure.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "--setup", str(scene / "unsure.toml"), "--method", "ddar",
                 "-o", str(other)]) == 0
    assert ("[uncertainty] is carried through method exact's fit alone (exact, exact_shape_prior; not method "
            "ddar's)") in capsys.readouterr().out
    assert "setup_uncertainty" not in json.loads(other.read_text())


def test_cubes_of_one_size_carry_the_setup_s_uncertainty_through_their_common_size(scene, capsys):
    """`--method exact_shape_prior` with the camera's place known to 1 mm: the readings are the same as without the
    table; each cube's size is the common size, so the setup moves every size alike: each cube's size share is the
    same, and not 0 (a fit at a known size moves no size of its own). Each σ is the image's own and the setup's
    share in quadrature."""
    import tomli_w, tomllib
    img = str(scene / "mirror.png")
    setup = tomllib.loads((scene / "mirror.toml").read_text())
    setup["uncertainty"] = {"camera_position": 0.001}
    (scene / "prior_unsure.toml").write_text(tomli_w.dumps(setup))
    plain, unsure = scene / "prior_plain.json", scene / "prior_unsure.json"
    method = ["--method", "exact_shape_prior"]
    assert main(["reconstruct", img, *method, "-o", str(plain)]) == 0
    assert main(["reconstruct", img, *method, "--setup", str(scene / "prior_unsure.toml"), "-o", str(unsure)]) == 0
    capsys.readouterr()
    a, b = (json.loads(p.read_text()) for p in (plain, unsure))
    assert b["method"] == "exact_shape_prior" and b["setup_uncertainty"] == {"camera_position": 0.001}
    assert len(a["cubes"]) == len(b["cubes"]) == 2
    shares = [c["uncertainty_from_setup"] for c in b["cubes"]]
    assert shares[0]["size"] > 1e-6 and shares[0]["size"] == pytest.approx(shares[1]["size"], rel=1e-9)
    for x, y, share in zip(a["cubes"], b["cubes"], shares):
        assert y["center"] == x["center"] and y["size"] == x["size"]
        assert y["uncertainty"]["depth"] == pytest.approx(np.hypot(x["uncertainty"]["depth"], share["depth"]))
        assert y["uncertainty"]["size"] == pytest.approx(np.hypot(x["uncertainty"]["size"], share["size"]))


def test_a_bad_uncertainty_table_is_one_line_and_writes_nothing(scene, capsys, tmp_path):
    import tomli_w, tomllib
    setup = tomllib.loads((scene / "mirror.toml").read_text())
    setup["uncertainty"] = {"mirror_radius": -0.0002}
    bad = tmp_path / "bad.toml"
    bad.write_text(tomli_w.dumps(setup))
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--setup", str(bad), "-o",
                            str(tmp_path / "o.json")], "bad.toml: uncertainty.mirror_radius: expected a σ >= 0")


@pytest.fixture(scope="module")
def floor_scene(tmp_path_factory):
    """An 800×600 render (looking down at the mirror's lower half) of three cubes standing on the floor the mirror
    stands on (its lower end, y = -0.245 m; the checkered ground there), with its truth: 3 and 4 cm, 0.45–0.8 m
    from the axis, one turned 15°."""
    import tomli_w
    folder = tmp_path_factory.mktemp("floor")
    setup = {
        "camera": {"resolution": [800, 600], "focal_px": [1000.0, 1000.0], "position": [0.0, 0.0, 0.55],
                   "look_at": [0.0, -0.1, 0.0], "up": [0.0, 1.0, 0.0]},
        "mirror": {"type": "cylinder", "radius": 0.1, "height": 0.49, "center": [0.0, 0.0, 0.0],
                   "axis": [0.0, 1.0, 0.0]},
        "scene": {"ground": True},
        "objects": [],
    }
    for r, az, size, turn, color in ((0.45, -25.0, 0.04, 0.0, [0.85, 0.1, 0.1]),
                                     (0.6, 15.0, 0.03, 15.0, [0.1, 0.2, 0.85]),
                                     (0.8, -5.0, 0.04, 0.0, [0.1, 0.7, 0.15])):
        a = np.deg2rad(az)
        x, z = r * np.sin(a), r * np.cos(a)
        setup["objects"].append({"type": "cube", "size": size, "center": [x, -0.245 + size / 2, z],
                                 "rotation_deg": [0.0, float(np.rad2deg(np.arctan2(-x, -z))) + turn, 0.0],
                                 "color": color})
    path = folder / "in.toml"
    path.write_text(tomli_w.dumps(setup))
    assert main(["simulate", str(path), "-o", str(folder / "floor.png")]) == 0
    return folder


def test_cubes_on_the_floor_are_read_to_their_depth_with_the_floor_s_sigma(floor_scene, capsys):
    """`--on-floor`: every centre within 0.5 % (the floor fixes each scale), every size within 1 % (its top side
    read to a nominal 0.15 px on faces 28–60 px tall, the rest of its height on the floor); `--floor-height
    -0.245` is the same floor (the same result to the bit); `--floor-std 0.002` leaves the readings as they are and
    widens each depth σ, within 2 σ of the truth; the result says which floor, and so does the table."""
    capsys.readouterr()
    img = str(floor_scene / "floor.png")
    paths = {k: floor_scene / f"{k}.json" for k in ("flag", "height", "std")}
    assert main(["reconstruct", img, "--on-floor", "-o", str(paths["flag"])]) == 0
    assert "standing on a floor -0.2450 m along the mirror's axis" in capsys.readouterr().out
    assert main(["reconstruct", img, "--floor-height", "-0.245", "-o", str(paths["height"])]) == 0
    assert main(["reconstruct", img, "--on-floor", "--floor-std", "0.002", "-o", str(paths["std"])]) == 0
    flag, height, std = (json.loads(p.read_text()) for p in paths.values())
    truth = json.loads((floor_scene / "floor.truth.json").read_text())
    assert flag["floor"] == height["floor"] == {"height": -0.245, "std": 0.0} and std["floor"]["std"] == 0.002
    assert flag["cubes"] == height["cubes"] and len(flag["cubes"]) == 3
    for cube, wide in zip(flag["cubes"], std["cubes"]):
        t = min(truth["cubes"], key=lambda t: np.linalg.norm(np.subtract(t["center"], cube["center"])))
        assert np.linalg.norm(np.subtract(cube["center"], t["center"])) / t["depth"] < 0.005
        assert cube["size"] == pytest.approx(t["size"], rel=0.01) and cube["method"] == "exact"
        assert wide["center"] == cube["center"] and wide["uncertainty"]["depth"] > cube["uncertainty"]["depth"]
        assert abs(wide["depth"] - t["depth"]) < 2.0 * wide["uncertainty"]["depth"]


def test_cubes_on_the_floor_carry_the_setup_s_uncertainty_as_whole_runs_make_of_it(floor_scene, capsys):
    """`--on-floor` with a setup whose `[uncertainty]` says its camera's place is known to 1 mm: the readings are
    the same and each depth's σ is the image's own and the setup's share in quadrature; that share is the root sum
    of squares of each depth's move in whole `--on-floor` runs with the camera moved 1 mm along x, y and z in turn
    (its look_at with it), within 10 %."""
    import tomli_w, tomllib
    img = str(floor_scene / "floor.png")
    setup = tomllib.loads((floor_scene / "floor.toml").read_text())
    setup["uncertainty"] = {"camera_position": 0.001}
    (floor_scene / "floor_unsure.toml").write_text(tomli_w.dumps(setup))
    plain, unsure = floor_scene / "floor_plain.json", floor_scene / "floor_unsure.json"
    assert main(["reconstruct", img, "--on-floor", "-o", str(plain)]) == 0
    assert main(["reconstruct", img, "--on-floor", "--setup", str(floor_scene / "floor_unsure.toml"),
                 "-o", str(unsure)]) == 0
    capsys.readouterr()
    moves = []
    for k in range(3):
        moved = tomllib.loads((floor_scene / "floor.toml").read_text())
        moved["camera"]["position"][k] += 0.001
        moved["camera"]["look_at"][k] += 0.001
        (floor_scene / f"floor_moved{k}.toml").write_text(tomli_w.dumps(moved))
        out = floor_scene / f"floor_moved{k}.json"
        assert main(["reconstruct", img, "--on-floor", "--setup", str(floor_scene / f"floor_moved{k}.toml"),
                     "-o", str(out)]) == 0
        moves.append([c["depth"] for c in json.loads(out.read_text())["cubes"]])
    a, b = (json.loads(p.read_text()) for p in (plain, unsure))
    assert b["setup_uncertainty"] == {"camera_position": 0.001} and len(a["cubes"]) == len(b["cubes"]) == 3
    assert all(len(m) == 3 for m in moves)
    for i, (x, y) in enumerate(zip(a["cubes"], b["cubes"])):
        assert y["center"] == x["center"] and y["size"] == x["size"]
        share = y["uncertainty_from_setup"]
        assert share["depth"] == pytest.approx(np.sqrt(sum((m[i] - x["depth"]) ** 2 for m in moves)), rel=0.1)
        assert y["uncertainty"]["depth"] == pytest.approx(np.hypot(x["uncertainty"]["depth"], share["depth"]))
        assert share["size"] > 0  # (the floor's height over the camera moves each size)


def test_the_command_says_when_the_cubes_may_stand_on_the_floor(scene, floor_scene, capsys):
    """Without `--on-floor`, the cubes standing on the floor are read by `exact` with their bottoms within 2 σ of
    it, and the command says that `--on-floor` would fix their scale; the cubes floating 0.245 m over it are not."""
    for folder, image, said in ((floor_scene, "floor.png", True), (scene, "mirror.png", False)):
        capsys.readouterr()
        assert main(["reconstruct", str(folder / image), "-o", str(folder / "plain.json")]) == 0
        printed = " ".join(capsys.readouterr().out.split())
        assert ("the cubes' bottoms lie within 2 σ of the floor the mirror stands on" in printed) == said, printed
        assert ("--on-floor fixes each one's scale" in printed) == said


def test_the_floor_note_weighs_each_bottom_by_its_sigma():
    """`floor_note` on results made by hand (a mirror 0.49 m tall centred at the origin: its floor at y = -0.245):
    two cubes whose bottoms lie 1.5 σ and 0.5 σ from it get the note, naming each; one 2.5 σ off does not; nor a
    result read on a floor, at a known size (size σ 0), by another method, or with no cube."""
    from types import SimpleNamespace

    from catadioptric.reconstruct import floor_note
    mirror = SimpleNamespace(center=(0.0, 0.0, 0.0), axis=(0.0, 2.0, 0.0), height=0.49)

    def cube(bottom_mm, sd_centre_mm, size=0.04, sd_size_mm=2.0):
        centre_y = -0.245 + bottom_mm / 1e3 + size / 2.0
        return {"center": [0.1, centre_y, 0.7], "size": size,
                "uncertainty": {"center": sd_centre_mm / 1e3, "size": sd_size_mm / 1e3, "depth": 0.01}}
    sd = float(np.hypot(6.0, 1.0))  # mm: the centre's 6 and half the size's 2
    near = [cube(1.5 * sd, 6.0), cube(-0.5 * sd, 6.0)]
    note = floor_note({"method": "exact", "cubes": near}, mirror)
    assert note is not None and f"#0 +{1.5 * sd:.1f} ± {sd:.1f} mm" in note and f"#1 -{0.5 * sd:.1f}" in note
    assert floor_note({"method": "exact", "cubes": near + [cube(2.5 * sd, 6.0)]}, mirror) is None
    assert floor_note({"method": "exact", "cubes": near, "floor": {"height": -0.245, "std": 0.0}}, mirror) is None
    assert floor_note({"method": "exact", "cubes": [cube(0.0, 6.0, sd_size_mm=0.0)]}, mirror) is None
    assert floor_note({"method": "ddar", "cubes": near}, mirror) is None
    assert floor_note({"method": "exact", "cubes": []}, mirror) is None


def test_cubes_off_the_floor_are_refused_not_read_at_the_floor_s_size(scene, capsys):
    """The two cubes of `scene` float at the camera's height, 0.245 m over the floor the mirror stands on: the size
    that would stand each on it (about 0.49 m) lies far beyond their edges' own 4 cm and its σ, so `--on-floor`
    refuses both, saying so, and writes a result with no cube."""
    capsys.readouterr()
    out = scene / "off_floor.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "--on-floor", "-o", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["cubes"] == [] and len(result["refused"]) == 2
    assert all("it does not stand on that floor" in r["reason"] for r in result["refused"]), result["refused"]
    assert "no cube could be estimated" in capsys.readouterr().out


@pytest.mark.parametrize("method", ["ddar", "shape_prior"])
def test_other_methods_run(scene, method):
    out = scene / f"{method}.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "--method", method, "-o", str(out)]) == 0
    cubes = json.loads(out.read_text())["cubes"]
    assert len(cubes) == 2 and all(c["method"] == method for c in cubes)
    assert all(c["edge_misfit_px"] is None for c in cubes)  # an edge misfit in pixels is `exact`'s


def test_exact_shape_prior_reads_both_cubes_at_one_size_with_exact_s_misfits(scene):
    out = scene / "exact_shape_prior.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "--method", "exact_shape_prior", "-o", str(out)]) == 0
    result = json.loads(out.read_text())
    truth = json.loads((scene / "mirror.truth.json").read_text())
    assert result["method"] == "exact_shape_prior" and len(result["cubes"]) == 2
    assert len({c["size"] for c in result["cubes"]}) == 1
    for cube in result["cubes"]:
        assert CONTRACT_KEYS <= set(cube) and cube["method"] == "exact_shape_prior"
        t = min(truth["cubes"], key=lambda t: np.linalg.norm(np.subtract(t["center"], cube["center"])))
        assert np.linalg.norm(np.subtract(cube["center"], t["center"])) / t["depth"] < 0.05
        assert cube["size"] == pytest.approx(0.04, rel=0.05)
        assert 0.0 < cube["edge_misfit_px"] < EDGE_MISFIT_WARN_PX and cube["uncertainty_scale"] >= 1.0


def test_the_table_flags_a_face_whose_edges_no_square_explains(scene):
    """A cube whose edge points miss the fitted square by more than EDGE_MISFIT_WARN_PX rms is marked,
    with a line saying what that means; the others are not."""
    import io

    from rich.console import Console

    from catadioptric.reconstruct import print_table
    out = scene / "flag.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "-o", str(out)]) == 0
    result = json.loads(out.read_text())
    for misfits, flagged in (((0.05, 0.08), False), ((0.05, 2.0 * EDGE_MISFIT_WARN_PX), True)):
        for c, m in zip(result["cubes"], misfits):
            c["edge_misfit_px"] = m
        buf = io.StringIO()
        print_table(Console(file=buf, width=200), result)
        text = buf.getvalue()
        assert ("may be short" in text) == flagged
        assert (f"{2.0 * EDGE_MISFIT_WARN_PX:.2f} !" in text) == flagged and "0.05 !" not in text


def test_the_table_marks_a_cube_whose_size_was_set_aside_from_the_common_size(scene):
    """exact_shape_prior: a cube whose own size was left out of the cubes' common size is marked by its size,
    with a line asking whether the cubes are all one size; none marked, no such line."""
    import io

    from rich.console import Console

    from catadioptric.reconstruct import print_table
    out = scene / "aside.json"
    assert main(["reconstruct", str(scene / "mirror.png"), "--method", "exact_shape_prior", "-o", str(out)]) == 0
    result = json.loads(out.read_text())
    assert [c["size_set_aside"] for c in result["cubes"]] == [False, False]
    for aside in ((False, False), (False, True)):
        for c, a in zip(result["cubes"], aside):
            c["size_set_aside"] = a
        buf = io.StringIO()
        print_table(Console(file=buf, width=200), result)
        text = buf.getvalue()
        assert ("* #1: its own size lay over 3 σ from the others'" in text) == any(aside)
        assert ("Are the cubes all one size?" in text) == any(aside)
        assert text.count(" *") == sum(aside)


def test_bad_inputs_exit_1_with_one_line_and_write_nothing(scene, capsys, tmp_path):
    img = cv2.imread(str(scene / "mirror.png"))
    setup = scene / "mirror.toml"
    out = str(tmp_path / "o.json")
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "nope.png"), "--setup", str(setup), "-o", out],
         "nope.png: no such image file")
    cv2.imwrite(str(tmp_path / "small.png"), img[:100, :100])
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "small.png"), "--setup", str(setup), "-o", out],
         "expected 640×480 pixels")
    cv2.imwrite(str(tmp_path / "gray.png"), cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "gray.png"), "--setup", str(setup), "-o", out],
         "grayscale")
    cv2.imwrite(str(tmp_path / "deep.png"), img.astype(np.uint16) * 257)
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "deep.png"), "--setup", str(setup), "-o", out],
         "expected an 8-bit image, got 16-bit")
    cv2.imwrite(str(tmp_path / "blank.png"), np.full_like(img, 128))
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "blank.png"), "--setup", str(setup), "-o", out],
         "no mirror content")
    (tmp_path / "junk.png").write_bytes(b"not an image")
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "junk.png"), "--setup", str(setup), "-o", out],
         "cannot read the image")
    import tomllib

    import tomli_w
    d = tomllib.loads(setup.read_text())
    del d["mirror"]
    nomirror = tmp_path / "nomirror.toml"
    nomirror.write_text(tomli_w.dumps(d))
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--setup", str(nomirror), "-o", out],
         "mirror: missing table [mirror]")
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--method", "magic", "-o", out],
         "--method: expected one of")
    # the arguments are checked before the image's own errors (it is read beside the first imports)
    _bad(capsys, tmp_path, ["reconstruct", str(tmp_path / "junk.png"), "--method", "magic", "-o", out],
         "--method: expected one of")
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--cube-size", "-1", "-o", out],
         "--cube-size: expected a positive edge length")
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--cube-size", "0.04", "--method",
                            "exact_shape_prior", "-o", out], "--cube-size: exact_shape_prior estimates the cubes'")
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--cube-size-std", "0.0002", "-o", out],
         "--cube-size-std: the σ of a known --cube-size, carried through the exact estimator's fit: give "
         "--cube-size and --method exact")
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--cube-size", "0.04", "--cube-size-std",
                            "0.0002", "--method", "ddar", "-o", out], "give --cube-size and --method exact, not ddar")
    for sd in ("-0.001", "nan"):
        _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--cube-size", "0.04", "--cube-size-std",
                                sd, "-o", out], "--cube-size-std: expected the σ of the edge length in metres, >= 0")
    for argv, message in (
            (["--on-floor", "--floor-height", "-0.2"], "--on-floor, --floor-height: give one"),
            (["--floor-height", "nan"], "--floor-height: expected a height in metres along the mirror's axis"),
            (["--floor-std", "0.001"], "--floor-std: the σ of the floor's height: give --on-floor or --floor-height"),
            (["--on-floor", "--floor-std", "-0.001"], "--floor-std: expected the σ of the floor's height in metres"),
            (["--on-floor", "--method", "ddar"], "--on-floor: cubes standing on a floor are fitted by --method exact"),
            (["--floor-height", "-0.2", "--cube-size", "0.04"], "--floor-height: the floor fixes each cube's size")):
        _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), *argv, "-o", out], message)
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--blur-domain", "gamma", "-o", out],
         "--blur-domain: expected one of auto, encoded, linear")
    _bad(capsys, tmp_path, ["reconstruct", str(scene / "mirror.png"), "--workers", "0", "-o", out],
         "--workers: expected an integer >= 1, got 0")


def test_a_one_shot_reconstruct_runs_without_the_cycle_collector(scene, capsys, tmp_path):
    # The console script's `reconstruct` (`main(..., one_shot=True)`) runs with the cycle collector off:
    # not one collection from the start of `main` on. Called as a library, `main` leaves it alone.
    import gc

    collections = []

    def count(phase, info):
        if phase == "start":
            collections.append(info["generation"])

    gc.callbacks.append(count)
    try:
        assert main(["reconstruct", str(scene / "mirror.png"), "-o", str(tmp_path / "a.json")]) == 0
        assert gc.isenabled() and collections  # (the check below can see collections)
        collections.clear()
        assert main(["reconstruct", str(scene / "mirror.png"), "-o", str(tmp_path / "b.json")], one_shot=True) == 0
        assert not gc.isenabled()
        assert collections == []
        library, one_shot = (json.loads((tmp_path / n).read_text())["cubes"] for n in ("a.json", "b.json"))
        assert library == one_shot
    finally:
        gc.enable()
        gc.callbacks.remove(count)
    capsys.readouterr()


def test_image_without_cubes_says_so(scene, capsys, tmp_path):
    # The mirror region with the cubes painted over by the background, plus noise: nothing to find, not an
    # error.
    img = cv2.imread(str(scene / "mirror.png"))
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    cubes = cv2.dilate((hsv[..., 1] > 40).astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    img[cubes] = np.median(img[~cubes], axis=0)  # the background's colour (grey patches would be objects)
    noise = np.random.default_rng(0).normal(0.0, 2.0, img.shape)  # sensor noise: the mirror is not blank
    img = np.clip(np.round(img + noise), 0, 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "empty.png"), img)
    out = tmp_path / "e.json"
    assert main(["reconstruct", str(tmp_path / "empty.png"), "--setup", str(scene / "mirror.toml"), "-o", str(out)]) == 0
    assert "no cube found" in capsys.readouterr().out
    assert json.loads(out.read_text())["cubes"] == []


def test_jpeg_files_are_recognised_by_their_bytes(scene, tmp_path):
    from catadioptric.reconstruct import is_jpeg
    img = cv2.imread(str(scene / "mirror.png"))
    cv2.imwrite(str(tmp_path / "a.png"), img)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    (tmp_path / "b.png").write_bytes(buf.tobytes())  # a JPEG under a .png name
    assert not is_jpeg(tmp_path / "a.png") and is_jpeg(tmp_path / "b.png")


def _grey_cubes(folder):
    """`grey.toml` in `folder`, rendered by `simulate` to `grey.png`: two 4 cm cubes of the default grey,
    facing the mirror axis 0.35 m and 0.5 m from it, on a darker grey background. Returns the setup's path."""
    import tomli_w
    setup = {
        "scene": {"background": [0.3, 0.3, 0.3]},
        "camera": {"resolution": [640, 480], "focal_px": [1400.0, 1400.0], "position": [0.0, 0.0, 0.55],
                   "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]},
        "mirror": {"type": "cylinder", "radius": 0.1, "height": 0.49, "center": [0.0, 0.0, 0.0],
                   "axis": [0.0, 1.0, 0.0]},
        "objects": [],
    }
    for r, az in ((0.35, -30.0), (0.5, 20.0)):
        a = np.deg2rad(az)
        x, z = r * np.sin(a), r * np.cos(a)
        setup["objects"].append({"type": "cube", "size": 0.04, "center": [x, 0.0, z],
                                 "rotation_deg": [0.0, float(np.rad2deg(np.arctan2(-x, -z))), 0.0]})
    path = folder / "grey.toml"
    path.write_text(tomli_w.dumps(setup))
    assert main(["simulate", str(path), "-o", str(folder / "grey.png")]) == 0
    return path


def test_cubes_of_the_default_grey_are_reconstructed(tmp_path, capsys):
    """A setup whose cubes give no `color` renders them in the default grey; on a darker grey background
    `reconstruct` finds them by their difference from it (it found none before), each within 5 % of the
    truth and with its depth within 3 reported σ. (On the default background, as bright as a grey
    front face under the default light, that face can vanish: nothing tells it from the background.)"""
    _grey_cubes(tmp_path)
    out = tmp_path / "r.json"
    assert main(["reconstruct", str(tmp_path / "grey.png"), "-o", str(out)]) == 0
    result = json.loads(out.read_text())
    truth = json.loads((tmp_path / "grey.truth.json").read_text())
    assert len(result["cubes"]) == 2
    for cube in result["cubes"]:
        t = min(truth["cubes"], key=lambda t: np.linalg.norm(np.subtract(t["center"], cube["center"])))
        assert np.linalg.norm(np.subtract(cube["center"], t["center"])) / t["depth"] < 0.05
        assert abs(cube["depth"] - t["depth"]) < 3.0 * cube["uncertainty"]["depth"]


def test_the_overlay_draws_a_flagged_face_in_orange(scene):
    """A cube whose edges miss its fitted face by more than EDGE_MISFIT_WARN_PX is outlined in
    OVERLAY_FLAGGED, not OVERLAY_FACE; the others keep the usual colour."""
    import dataclasses

    from catadioptric.reconstruct import (
        OVERLAY_FACE,
        OVERLAY_FLAGGED,
        draw_overlay,
        read_image,
    )
    from catadioptric.setup import load_setup
    from depth.reconstruct import reconstruct
    setup = load_setup(scene / "in.toml")
    image = read_image(scene / "mirror.png")
    rec = reconstruct(image, setup.camera.build(), setup.mirror.build())
    assert len(rec.cubes) == 2

    def count(img, rgb):  # drawn pixels (anti-aliased) within 40 of the colour
        near = np.linalg.norm(img.astype(float) - np.array(rgb, dtype=float), axis=-1) < 40
        return int(np.count_nonzero(near & np.any(img != image, axis=-1)))

    plain = draw_overlay(image, rec)
    assert count(plain, OVERLAY_FACE) > 20 and count(plain, OVERLAY_FLAGGED) == 0
    bad = dataclasses.replace(rec.cubes[0], estimate=dataclasses.replace(rec.cubes[0].estimate,
                                                                         rms_residual=2.0 * EDGE_MISFIT_WARN_PX))
    marked = draw_overlay(image, dataclasses.replace(rec, cubes=[bad, rec.cubes[1]]))
    assert count(marked, OVERLAY_FLAGGED) > 20 and count(marked, OVERLAY_FACE) > 20


def _refusal_of_painted_shadow(folder, polygon):
    """Render `_grey_cubes`, find its two cubes, paint `polygon` (px) in as a shadow (`_shadowed`,
    where the mirror shows only background, away from the cubes) and reconstruct again: the same two
    cubes must come out. Returns the one refusal whose box holds the polygon's centre."""
    from catadioptric.setup import load_setup
    from depth.reconstruct import reconstruct
    path = _grey_cubes(folder)
    img = cv2.cvtColor(cv2.imread(str(folder / "grey.png")), cv2.COLOR_BGR2RGB).astype(np.float64) / 255.0
    loaded = load_setup(path)
    camera, mirror = loaded.camera.build(), loaded.mirror.build()
    found = reconstruct(img, camera, mirror).cubes
    assert len(found) == 2
    centre = polygon.mean(axis=0)
    assert all(np.linalg.norm(np.mean(c.corners_px, axis=0) - centre) > 60 for c in found)
    rec = reconstruct(_shadowed(img, polygon), camera, mirror)
    assert len(rec.cubes) == len(found)
    for cube in rec.cubes:
        assert min(np.linalg.norm(np.mean(cube.corners_px, axis=0) - np.mean(c.corners_px, axis=0))
                   for c in found) < 1.0
    shadow = [r for r in rec.refused if r.bbox[0] <= centre[0] <= r.bbox[2] and r.bbox[1] <= centre[1] <= r.bbox[3]]
    assert len(shadow) == 1
    return shadow[0]


def _shadowed(img, polygon):
    """`img` (float, 480 × 640) with `polygon` (px) painted in as a shadow: the background × 0.6,
    anti-aliased by 8 × 8 supersampling, then quantised to 8 bits."""
    s = 8
    big = np.zeros((480 * s, 640 * s), np.uint8)
    cv2.fillPoly(big, [np.round((polygon + 0.5) * s - 0.5).astype(np.int32)], 1)
    cover = big.reshape(480, s, 640, s).mean(axis=(1, 3))
    assert img[cover > 0].std() < 0.01  # painted over uniform background only
    return np.round(img * (1.0 - 0.4 * cover[..., None]) * 255.0) / 255.0


def test_a_shadow_on_a_grey_background_is_not_taken_for_a_grey_cube(tmp_path):
    """A cube's shadow on a floor, seen in the mirror, is a darker region of the background's own
    colour, as a grey cube's face is; but it is a hexagon, not the image of a square face. Painted
    into a render of two grey cubes (a hexagon 24 px wide and 62 px tall, the background × 0.6,
    anti-aliased by 8 × 8 supersampling), it is refused as a shadow while both cubes are still found
    (before, it came out as a third cube 1 cm across, as 5 cube shadows did on the lighting bench)."""
    # a hexagon: a cube's shadow cast by a sun from the side
    hexagon = np.array([320.0, 380.0]) + np.array([[-10, -25], [4, -31], [12, -20], [10, 25], [-4, 31], [-12, 20]],
                                                   dtype=np.float64)
    reason = _refusal_of_painted_shadow(tmp_path, hexagon).reason
    assert "shadow" in reason and "no square face" in reason


def test_a_quadrilateral_shadow_is_not_taken_for_a_cube_before_the_mirror(tmp_path):
    """A shadow that is a quadrilateral (a sun along a cube's face) fits a square face as well as a grey
    cube does; the estimate then puts a cube 5 mm across in front of the mirror, where the camera would
    see it straight (as 3 cube shadows on the lighting bench's floor2 case came out). Painted into the
    grey-cube render (a rectangle 16 × 26 px), it is refused as standing between the camera and the
    mirror, with no blob there, while both cubes are still found (before, it came out as a third cube)."""
    rectangle = np.array([320.0, 380.0]) + np.array([[-8, -13], [8, -13], [8, 13], [-8, 13]], dtype=np.float64)
    assert "between the camera and the mirror" in _refusal_of_painted_shadow(tmp_path, rectangle).reason


def test_faces_estimated_in_worker_processes_give_the_results_of_one_process(scene):
    from catadioptric.setup import load_setup
    from depth.errors import DepthError
    from depth.reconstruct import reconstruct
    setup = load_setup(scene / "in.toml")
    img = cv2.cvtColor(cv2.imread(str(scene / "mirror.png")), cv2.COLOR_BGR2RGB)
    calls = {1: [], 2: []}
    runs = [reconstruct(img, setup.camera.build(), setup.mirror.build(), workers=w,
                        progress=lambda done, total, w=w: calls[w].append((done, total))) for w in (1, 2)]
    one, two = ([c.to_dict() for c in r.cubes] + [x.to_dict() for x in r.refused] for r in runs)
    assert len(runs[0].cubes) == 2 and one == two
    # the progress runs through the outlines, then the estimates (the longer part): each blob twice
    blobs = len(runs[0].cubes) + len(runs[0].refused)
    for seen in calls.values():
        assert seen[-1] == (2 * blobs, 2 * blobs) and {t for _, t in seen} == {2 * blobs}
        done = [d for d, _ in seen]
        assert done == sorted(done) and len([d for d in done if d > blobs]) >= len(runs[0].cubes)
    joint = []  # shape_prior: the faces solved jointly, each then checked in turn
    reconstruct(img, setup.camera.build(), setup.mirror.build(), method="shape_prior",
                progress=lambda done, total: joint.append((done, total)))
    assert joint[-1] == (2 * blobs, 2 * blobs) and [d for d, _ in joint] == sorted(d for d, _ in joint)
    with pytest.raises(DepthError, match="workers: expected an integer >= 1, got 0"):
        reconstruct(img, setup.camera.build(), setup.mirror.build(), workers=0)


@pytest.mark.parametrize("acted", ["encoded", "linear"])
def test_the_blur_domain_pooled_from_the_workers_is_the_verdict_on_the_image(scene, acted):
    # each blurred face's evidence is computed in its outline worker and pooled after: the verdict must be
    # `blur_domain_verdict`'s on the same outlines, in one process, and say where the blur acted
    from scipy import ndimage

    from catadioptric.setup import load_setup
    from depth.measure import blur_domain_verdict, detect_cubes, face_outline, srgb_to_linear
    from depth.reconstruct import reconstruct
    from raytrace.render import linear_to_srgb8
    from raytrace.truth import mirror_mask
    setup = load_setup(scene / "in.toml")
    camera, mirror = setup.camera.build(), setup.mirror.build()
    img = cv2.cvtColor(cv2.imread(str(scene / "mirror.png")), cv2.COLOR_BGR2RGB) / 255.0
    blur = lambda x: ndimage.gaussian_filter(x, sigma=(0.7, 0.7, 0))  # noqa: E731
    if acted == "encoded":
        img = np.round(np.clip(blur(img), 0, 1) * 255).astype(np.uint8)
    else:
        img = linear_to_srgb8(blur(srgb_to_linear(img)))
    img = img / 255.0
    runs = [reconstruct(img, camera, mirror, workers=w) for w in (1, 2)]
    assert [len(r.cubes) for r in runs] == [2, 2]
    dets = detect_cubes(img, mirror_mask(camera, mirror))
    outlines = [face_outline(img, d.front_face_mask, blur_domain="linear") for d in dets]
    assert runs[0].blur_domain == runs[1].blur_domain == blur_domain_verdict(img, outlines) == acted


def test_the_command_in_a_fresh_process_gives_the_results_of_this_one(scene, capsys):
    # A fresh process imports the estimators' scipy modules in a thread while it detects the cubes
    # (`depth.workers.import_in_background`); in this process they are imported already.
    import subprocess
    import sys
    out = scene / "fresh.json"
    done = subprocess.run([sys.executable, "-c", "from catadioptric.cli import console; console()", "reconstruct",
                           str(scene / "mirror.png"), "--setup", str(scene / "in.toml"), "-o", str(out)],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    capsys.readouterr()
    assert main(["reconstruct", str(scene / "mirror.png"), "--setup", str(scene / "in.toml"),
                 "-o", str(scene / "here.json")]) == 0
    fresh, here = (json.loads(p.read_text()) for p in (out, scene / "here.json"))
    assert len(fresh["cubes"]) == 2 and fresh["cubes"] == here["cubes"] and fresh["refused"] == here["refused"]


def test_the_console_script_ends_without_the_interpreters_teardown_but_with_its_output(scene, tmp_path):
    # `console` ends the process once `main` returns: the atexit functions run and the piped (so
    # block-buffered) output arrives whole, after the written files' paths, but objects still alive
    # are not finalised one by one (the teardown would print "finalised").
    import subprocess
    import sys
    out = tmp_path / "r.json"
    code = ("import atexit; atexit.register(print, 'atexit ran')\n"
            "class Alive:\n    def __del__(self): print('finalised')\n"
            "alive = Alive()\nfrom catadioptric.cli import console; console()")
    done = subprocess.run([sys.executable, "-c", code, "reconstruct", str(scene / "mirror.png"), "--setup",
                           str(scene / "in.toml"), "-o", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[-1] == "atexit ran" and lines[-2] == str(out)
    assert "finalised" not in done.stdout
    assert len(json.loads(out.read_text())["cubes"]) == 2


@pytest.mark.parametrize("command", ["reconstruct", "design"])
def test_a_closed_output_pipe_ends_the_command_quietly(scene, tmp_path, command):
    # stdout is a pipe nobody reads (`| head` gone): exit status 1, no traceback, nothing on stderr, with
    # the output written by rich (reconstruct's table) or by print (design's JSON; a traceback before).
    import os
    import subprocess
    import sys
    args = {"reconstruct": ["reconstruct", str(scene / "mirror.png"), "--setup", str(scene / "in.toml"),
                            "-o", str(tmp_path / "r.json")],
            "design": ["design", str(scene / "in.toml"), "--json"]}[command]
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        done = subprocess.run([sys.executable, "-c", "from catadioptric.cli import console; console()", *args],
                              stdout=write_end, stderr=subprocess.PIPE, text=True, check=False)
    finally:
        os.close(write_end)
    assert done.returncode == 1
    assert done.stderr == ""


def test_a_broken_pipe_of_the_commands_own_is_reported_not_taken_for_the_output_closing(scene, tmp_path):
    # a BrokenPipeError from a pipe of the command's own (its helper's, say) while its output is still read:
    # one line on stderr and exit status 1, not the quiet end of a closed output pipe (a helper that had died
    # ended the command so, with no word, before `Helper.run` read the error it had sent)
    import subprocess
    import sys
    script = ("import catadioptric.reconstruct as rc\n"
              "def broken(*args, **kwargs):\n"
              "    raise BrokenPipeError(32, 'Broken pipe')\n"
              "rc.run_reconstruction = broken\n"
              "from catadioptric.cli import console\n"
              "console()\n")
    done = subprocess.run([sys.executable, "-c", script, "reconstruct", str(scene / "mirror.png"), "--setup",
                           str(scene / "in.toml"), "-o", str(tmp_path / "r.json")],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == ["catadioptric: error: [Errno 32] Broken pipe"]
    assert not (tmp_path / "r.json").exists()


def _white_cube_before_a_bright_sky():
    """(sRGB image (H, W, 3) uint8, its setup, the share (H, W, 1) of sky in each pixel) of a white cube
    turned 20° before a sky shading from linear 0.6 (left) to 0.95 (right) across the image: its front
    face (sRGB 237) lies within the sky's range. The sky is composited in linear light from two renders
    of our renderer on backgrounds 0.2 and 0.6 (their difference gives each pixel's share of sky)."""
    from catadioptric.setup import Setup
    from catadioptric.simulate import simulate
    from raytrace.render import linear_to_srgb8

    def setup(background):
        a = np.deg2rad(-30.0)
        x, z = 0.35 * np.sin(a), 0.35 * np.cos(a)
        return Setup.from_dict({
            "scene": {"background": [background] * 3},
            "camera": {"resolution": [640, 480], "focal_px": [1400.0, 1400.0], "position": [0.0, 0.0, 0.55],
                       "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]},
            "mirror": {"type": "cylinder", "radius": 0.1, "height": 0.49, "center": [0.0, 0.0, 0.0],
                       "axis": [0.0, 1.0, 0.0]},
            "objects": [{"type": "cube", "size": 0.04, "center": [x, 0.0, z], "color": [0.8, 0.8, 0.8],
                         "rotation_deg": [0.0, float(np.rad2deg(np.arctan2(-x, -z))) + 20.0, 0.0]}]},
            source="white-cube")

    dark, light = (simulate(setup(b), spp=4, seed=0).render.image for b in (0.2, 0.6))
    share = np.clip((light - dark)[..., :1] / 0.4, 0.0, 1.0)
    sky = np.linspace(0.6, 0.95, dark.shape[1])[None, :, None]
    return linear_to_srgb8(dark + share * (sky - 0.2)), setup(0.2), share


def test_a_white_cube_as_bright_as_the_sky_behind_it_is_found_whole():
    """The white cube of `_white_cube_before_a_bright_sky`: the sky shades across the mirror, so detection
    looks for regions enclosed by edges, and finds the whole cube, its front face 24 px wide (before the
    thirty-first session it took the sky for one colour and found only the dark side face, which no cube's
    front face explains, and the blob had to be grown across the faint edges by
    `depth.measure.faint_regrowth`). The cube comes out within 2 % of the truth and within 3 reported σ."""
    from depth.measure import detect_cubes
    from depth.reconstruct import reconstruct
    from raytrace.truth import cube_truth, mirror_mask

    image, s, _ = _white_cube_before_a_bright_sky()
    camera, mirror = s.camera.build(), s.mirror.build()
    truth = cube_truth(camera, mirror, s.objects[0].build())
    (found,) = detect_cubes(image / 255.0, mirror_mask(camera, mirror))
    assert found.usable and found.bbox[2] - found.bbox[0] > 24  # the front and side faces
    rec = reconstruct(image, camera, mirror)
    assert len(rec.cubes) == 1 and not rec.refused
    cube = rec.cubes[0]
    assert np.linalg.norm(cube.estimate.center - truth["center"]) / truth["depth"] < 0.02
    assert abs(cube.depth - truth["depth"]) < 3.0 * cube.depth_std


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_white_cube_as_noisy_as_a_path_tracers_is_found_whole(seed):
    """The white cube of `_white_cube_before_a_bright_sky` with a path tracer's sampling noise on it:
    Gaussian, σ = 0.02 of sRGB value on the cube's pixels only (Mitsuba at 16 samples a pixel left a grey
    face 0.017 from pixel to pixel under a sky map, and the sky nearly smooth). Blurred over 1 px, that
    noise makes edges inside the face at `faint_regrowth`'s faint steps; blurred over 1.5 px (the second
    of `FAINT_EDGE_SMOOTHING_PX`), the face is whole. The cube is found within 3 % and 3 reported σ."""
    from depth.reconstruct import reconstruct
    from raytrace.truth import cube_truth

    clean, s, share = _white_cube_before_a_bright_sky()
    noisy = clean / 255.0 + (1.0 - share) * np.random.default_rng(seed).normal(0.0, 0.02, clean.shape)
    image = np.round(np.clip(noisy, 0.0, 1.0) * 255.0).astype(np.uint8)
    camera, mirror = s.camera.build(), s.mirror.build()
    truth = cube_truth(camera, mirror, s.objects[0].build())
    rec = reconstruct(image, camera, mirror)
    assert len(rec.cubes) == 1 and not rec.refused
    cube = rec.cubes[0]
    assert np.linalg.norm(cube.estimate.center - truth["center"]) / truth["depth"] < 0.03
    assert abs(cube.depth - truth["depth"]) < 3.0 * cube.depth_std


def _as_in_a_fresh_process(tmp_path, monkeypatch, name):
    """`depth.reconstruct` set to fork its helper as in a fresh process: here the estimators' modules are imported
    already, so a module `name` not yet imported is added to the ones the helper imports. Returns the list of
    the helpers forked (`fork_helper`'s answers), filled as they are."""
    import sys

    import depth.reconstruct as dr
    (tmp_path / f"{name}.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, name, raising=False)
    monkeypatch.setattr(dr, "SOLVER_MODULES", dr.SOLVER_MODULES + (name,))
    monkeypatch.setattr(dr, "_HELPER_FORKED", False)
    monkeypatch.setattr(dr, "_STARTED", None)
    forked = []
    real = dr.fork_helper
    monkeypatch.setattr(dr, "fork_helper", lambda *a: forked.append(real(*a)) or forked[-1])
    return forked


@pytest.mark.parametrize("compressed", [False, True])
def test_the_faces_outlined_in_a_helper_process_give_the_results_of_this_one(scene, tmp_path, monkeypatch, compressed):
    # A fresh process forks a helper that imports the estimators' modules while this one detects the cubes,
    # then outlines and estimates the faces (`depth.workers.fork_helper`). Here those modules are imported
    # already, so a module not yet imported is added to the list to make `reconstruct` fork one. The helper
    # is told of the image before the 8-bit image is converted (and, read as JPEG, despeckled) into memory it
    # shares with this process (`depth.workers.SharedMemory`); the second and third calls convert it as
    # `check_image` and `despeckled` do, in memory of their own.
    import sys

    import depth.reconstruct as dr
    from catadioptric.setup import load_setup
    setup = load_setup(scene / "in.toml")
    camera, mirror = setup.camera.build(), setup.mirror.build()
    img = cv2.cvtColor(cv2.imread(str(scene / "mirror.png")), cv2.COLOR_BGR2RGB)
    calls = {"here": [], "helper": []}
    here = dr.reconstruct(img, camera, mirror, compressed=compressed,
                          progress=lambda d, t: calls["here"].append((d, t)))
    forked = _as_in_a_fresh_process(tmp_path, monkeypatch, "not_yet_imported")
    shared = []  # the arrays mapped here in shared memory
    real_arrays = dr.SharedMemory.arrays
    monkeypatch.setattr(dr.SharedMemory, "arrays", lambda self, specs: shared.extend(real_arrays(self, specs))
                        or shared[-len(specs):])
    there = dr.reconstruct(img, camera, mirror, compressed=compressed,
                           progress=lambda d, t: calls["helper"].append((d, t)))
    assert len(forked) == 1 and forked[0] is not None and forked[0]._process is None  # it ran and was closed
    assert len(shared) == 1 + compressed  # the image, and the despeckled one
    assert "not_yet_imported" not in sys.modules and dr._STARTED is None
    # a second call in this process forks no helper again: it imports the modules here, beside the detection
    again = dr.reconstruct(img, camera, mirror, compressed=compressed)
    assert len(shared) == 1 + compressed
    assert len(forked) == 1 and "not_yet_imported" in sys.modules
    assert [c.estimate.center.tolist() for c in again.cubes] == [c.estimate.center.tolist() for c in here.cubes]
    assert len(here.cubes) == len(there.cubes) == 2
    for a, b in zip(here.cubes, there.cubes):
        np.testing.assert_array_equal(a.estimate.center, b.estimate.center)
        np.testing.assert_array_equal(a.corners_px, b.corners_px)
        assert (a.depth, a.depth_std, a.bbox) == (b.depth, b.depth_std, b.bbox)
    assert here.refused == there.refused and here.blur_domain == there.blur_domain
    np.testing.assert_array_equal(here.mirror_mask, there.mirror_mask)
    assert calls["helper"] == calls["here"] and calls["here"][-1] == (4, 4)


def test_a_helper_started_before_the_inputs_are_read_serves_the_next_call_or_ends_unused(scene, tmp_path,
                                                                                         monkeypatch):
    # `catadioptric reconstruct` forks the helper before it reads the image and the setup (`helper_started`),
    # so that its imports start sooner; the `reconstruct` call then takes it rather than forking its own. Where
    # the inputs are refused it is ended, unused. As above, a module not yet imported makes a helper worth
    # forking here.
    import sys

    import depth.reconstruct as dr
    from catadioptric import reconstruct as rc
    from catadioptric.errors import CatadioptricError
    from catadioptric.setup import load_setup
    setup = load_setup(scene / "in.toml")
    camera, mirror = setup.camera.build(), setup.mirror.build()
    img = cv2.cvtColor(cv2.imread(str(scene / "mirror.png")), cv2.COLOR_BGR2RGB)
    here = dr.reconstruct(img, camera, mirror)
    forked = _as_in_a_fresh_process(tmp_path, monkeypatch, "not_yet_imported3")
    with dr.helper_started():
        assert len(forked) == 1 and dr._STARTED is not None
        process = forked[0]._process
        assert dr.start_helper() and len(forked) == 1  # one at a time
        there = dr.reconstruct(img, camera, mirror)
        assert dr._STARTED is None
    assert len(forked) == 1 and forked[0]._process is None and not process.is_alive()  # taken, run and closed
    assert len(here.cubes) == len(there.cubes) == 2
    for a, b in zip(here.cubes, there.cubes):
        np.testing.assert_array_equal(a.estimate.center, b.estimate.center)
        assert (a.depth, a.depth_std, a.bbox, a.estimate.size) == (b.depth, b.depth_std, b.bbox, b.estimate.size)
    assert here.refused == there.refused
    # the command's inputs refused: the helper it forked first is ended, unused
    monkeypatch.setattr(dr, "_HELPER_FORKED", False)
    with pytest.raises(CatadioptricError, match="missing.png"):
        rc.run_reconstruction(str(tmp_path / "missing.png"), scene / "in.toml")
    assert len(forked) == 2 and forked[1]._process is None and dr._STARTED is None
    assert "not_yet_imported3" not in sys.modules


def test_the_helper_estimates_the_coloured_faces_while_the_grey_search_still_runs(scene, tmp_path, monkeypatch):
    # `detect_cubes` hands the coloured cubes over before it searches for grey ones (`coloured_found`), and the
    # helper outlines and estimates them meanwhile. Here the grey search waits until the helper has estimated
    # both faces (or 60 s): each estimate is logged before the search ends, and the results are this
    # process's own.
    import sys
    import time

    import depth.measure as dm
    import depth.reconstruct as dr
    from catadioptric.setup import load_setup
    setup = load_setup(scene / "in.toml")
    camera, mirror = setup.camera.build(), setup.mirror.build()
    img = cv2.cvtColor(cv2.imread(str(scene / "mirror.png")), cv2.COLOR_BGR2RGB)
    here = dr.reconstruct(img, camera, mirror)
    log = tmp_path / "log"
    log.write_text("")
    real_estimate, real_search = dr.estimate_face, dm._achromatic_regions

    def estimate(*args, **kwargs):  # in the helper's workers
        est = real_estimate(*args, **kwargs)
        with open(log, "a") as f:
            f.write("estimate\n")
        return est

    def search(*args, **kwargs):  # here
        deadline = time.perf_counter() + 60.0
        while log.read_text().count("estimate") < 2 and time.perf_counter() < deadline:
            time.sleep(0.02)
        with open(log, "a") as f:
            f.write("searched\n")
        return real_search(*args, **kwargs)

    _as_in_a_fresh_process(tmp_path, monkeypatch, "not_yet_imported2")
    monkeypatch.setattr(dr, "estimate_face", estimate)
    monkeypatch.setattr(dm, "_achromatic_regions", search)
    there = dr.reconstruct(img, camera, mirror)
    assert dr._HELPER_FORKED
    assert log.read_text().split() == ["estimate", "estimate", "searched"]
    assert len(here.cubes) == len(there.cubes) == 2
    for a, b in zip(here.cubes, there.cubes):
        np.testing.assert_array_equal(a.estimate.center, b.estimate.center)
        assert (a.depth, a.depth_std, a.bbox, a.estimate.size) == (b.depth, b.depth_std, b.bbox, b.estimate.size)
    assert here.refused == there.refused
