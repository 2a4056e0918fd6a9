"""Tests of catadioptric.report, .views and .plots: pictures exist, are not blank and show what they
should; bad inputs write nothing; the page loads in headless Chromium (skipped without it)."""

import json
import re
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
import tomli_w

from catadioptric.cli import main
from catadioptric.errors import CatadioptricError

pv = pytest.importorskip("pyvista")


from small_demo import SMALL_DEMO as SMALL  # noqa: E402

WINDOW = (480, 320)
PICTURES = ("view3d.png", "view_top.png", "aspect_ratio.png", "tile_map.png", "annotated.png")


@pytest.fixture(autouse=True)
def _off_screen():
    """Force off-screen rendering and restore pyvista's global state afterwards."""
    old = pv.OFF_SCREEN
    pv.OFF_SCREEN = True
    yield
    pv.OFF_SCREEN = old
    pv.close_all()


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """s.png, s.toml, s.truth.json from `catadioptric simulate` of the small setup."""
    d = tmp_path_factory.mktemp("sim")
    (d / "small.toml").write_text(tomli_w.dumps(SMALL))
    assert main(["simulate", str(d / "small.toml"), "-o", str(d / "s.png"), "--spp", "1"]) == 0
    (d / "s.gt.npz").unlink()
    return d


@pytest.fixture(scope="module")
def rep(sim, tmp_path_factory):
    """The report of s.png written by the CLI."""
    out = tmp_path_factory.mktemp("rep") / "report"
    assert main(["report", str(sim / "s.png"), "-o", str(out)]) == 0
    return out


def read_png(path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert img is not None, f"{path} is not a readable PNG"
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def colour_fraction(img: np.ndarray, rgb, tol: int = 12) -> float:
    """Fraction of pixels within `tol` (per channel) of an RGB colour in [0, 1]."""
    target = np.round(np.asarray(rgb) * 255)
    return float(np.mean(np.all(np.abs(img.astype(int) - target) <= tol, axis=2)))


# -- the report of an image with truth ------------------------------------------------------------

def test_report_writes_every_picture_and_none_is_blank(rep, capsys):
    names = {p.name for p in rep.iterdir()}
    assert {"index.html", "result.json", *PICTURES} <= names
    assert not [n for n in names if n.endswith(".partial")]
    for name in PICTURES:
        img = read_png(rep / name)
        assert img.shape[0] >= 200 and img.shape[1] >= 300, name
        # Not blank: many distinct colours and a real spread of intensities.
        assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50, name
        assert img.std() > 10, name


def test_html_references_only_files_beside_it(rep):
    page = (rep / "index.html").read_text()
    refs = re.findall(r'(?:src|href)="([^"]*)"', page)
    assert sorted(r for r in refs if r.endswith(".png")) == sorted(PICTURES)
    for r in refs:
        assert "://" not in r and not r.startswith("/"), r  # no network, no absolute paths
        assert (rep / r).is_file(), r
    assert "<script" not in page


def test_report_table_has_errors_against_truth(rep, sim):
    page = (rep / "index.html").read_text()
    result = json.loads((rep / "result.json").read_text())
    truth = json.loads((sim / "s.truth.json").read_text())
    assert result["cubes"], "the small setup must give at least one cube"
    assert "true depth (m)" in page and "depth error" in page
    # The listed true depth is the simulation's, and the error is computed from it (not copied).
    c = result["cubes"][0]
    t = min(truth["cubes"], key=lambda t: abs(t["depth"] - c["depth"]))
    assert f"{t['depth']:.4f}" in page
    assert f"{100 * (c['depth'] / t['depth'] - 1):+.2f} %" in page
    # The refused cube is listed with its reason.
    for r in result["refused"]:
        assert r["reason"].split(":")[0] in page


def test_annotated_image_is_the_overlay_of_the_image(rep, sim):
    from catadioptric.reconstruct import draw_overlay, read_image, run_reconstruction
    _, _, image, rec = run_reconstruction(sim / "s.png")
    np.testing.assert_array_equal(read_png(rep / "annotated.png"), draw_overlay(image, rec))
    assert not np.array_equal(read_png(rep / "annotated.png"), read_image(sim / "s.png"))


def test_report_pictures_use_the_cube_colour(rep):
    from catadioptric.views import cube_palette
    first = cube_palette(1)[0]
    # The AR plot draws cube 0's curve in its colour; the 3D views draw the cube in it (shaded).
    assert colour_fraction(read_png(rep / "aspect_ratio.png"), first, tol=10) > 5e-4


# -- 3D views: what lands where --------------------------------------------------------------------

@pytest.fixture(scope="module")
def small_scene():
    from catadioptric.setup import Setup
    from catadioptric import views
    s = Setup.from_dict(SMALL)
    camera, mirror = s.camera.build(), s.mirror.build()
    true_cubes = []
    for o in s.objects:
        cube = o.build()
        _, corners, _ = cube.front_face(mirror)
        true_cubes.append(views.cube_from_truth({"front_face_corners": corners.tolist(),
                                                 "center": cube.center.tolist()}))
    return camera, mirror, true_cubes


def test_top_view_shows_mirror_colour_at_the_projected_axis(small_scene):
    from catadioptric import views
    camera, mirror, true_cubes = small_scene
    model = views.scene_model(camera, mirror, truth=true_cubes)
    view = views.render_view(model, "top", WINDOW)
    u, v = np.round(view.project(mirror.center[None])[0]).astype(int)
    h, w = view.image.shape[:2]
    assert 0 <= u < w and 0 <= v < h
    patch = view.image[v - 2:v + 3, u - 2:u + 3].reshape(-1, 3).astype(float)
    colour = np.median(patch, axis=0)
    # Same hue as the mirror colour (lighting only scales it), and clearly not the white background.
    expected = np.asarray(views.MIRROR_COLOR) / max(views.MIRROR_COLOR)
    np.testing.assert_allclose(colour / colour.max(), expected, atol=0.08)
    assert colour.min() < 200
    # Off the mirror, far from everything drawn: background.
    corner = view.image[2:8, 2:8].reshape(-1, 3)
    assert np.all(corner == 255)


def test_perspective_view_shows_mirror_and_camera_where_projected(small_scene):
    from catadioptric import views
    camera, mirror, true_cubes = small_scene
    model = views.scene_model(camera, mirror, truth=true_cubes)
    view = views.render_view(model, "perspective", WINDOW)
    img = view.image.astype(float)
    # A point of the mirror surface facing the viewpoint, high up (away from the ray fan).
    radial = mirror.radial_vectors(view.eye[None])[0]
    p = mirror.center + 0.18 * mirror.axis + mirror.radius * radial / np.linalg.norm(radial)
    u, v = np.round(view.project(p[None])[0]).astype(int)
    c = np.median(img[v - 1:v + 2, u - 1:u + 2].reshape(-1, 3), axis=0)
    assert c[2] > c[0] + 40 and c[2] > c[1] + 15, c  # the mirror's blue (blended, shaded)
    # The camera centre is drawn as a dark sphere.
    u, v = np.round(view.project(camera.position[None])[0]).astype(int)
    assert img[v - 1:v + 2, u - 1:u + 2].max() < 90
    # A true cube's outline: black pixels near its projected centre.
    u, v = np.round(view.project(true_cubes[0].mean(axis=0)[None])[0]).astype(int)
    assert (img[v - 15:v + 16, u - 15:u + 16].max(axis=2) < 60).any()


def test_view_projection_agrees_with_a_second_rendering_of_a_marker(small_scene):
    """The projection a View reports is where pyvista draws: a lone sphere at a chosen point."""
    from catadioptric import views
    camera, mirror, _ = small_scene
    model = views.scene_model(camera, mirror, fan=(1, 1))
    model.incident = model.incident[:0]
    model.reflected = model.reflected[:0]
    target = mirror.center + np.array([0.0, 0.0, 0.3])
    model.cubes = [views.CubeSolid(target + 0.01 * np.array(
        [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]]),
        (1.0, 0.0, 0.0))]
    view = views.render_view(model, "top", WINDOW)
    red = (view.image[:, :, 0] > 150) & (view.image[:, :, 1] < 80) & (view.image[:, :, 2] < 80)
    assert red.sum() > 4
    ys, xs = np.nonzero(red)
    np.testing.assert_allclose([xs.mean(), ys.mean()], view.project(target[None])[0], atol=2.0)


def test_cube_from_truth_is_a_cube_with_the_true_corners():
    from catadioptric.views import cube_from_truth
    rng = np.random.default_rng(3)
    from scipy.spatial.transform import Rotation
    r = Rotation.random(random_state=rng).as_matrix()
    c, s = rng.normal(size=3), 0.07
    face = np.array([[-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]]) * s / 2 @ r.T + c
    v = cube_from_truth({"front_face_corners": face.tolist(), "center": c.tolist()})
    np.testing.assert_allclose(v[:4], face)
    np.testing.assert_allclose(v.mean(axis=0), c, atol=1e-12)
    # Each back corner is one edge length behind its front corner.
    np.testing.assert_allclose(np.linalg.norm(v[4:] - v[:4], axis=1), s)
    d = np.linalg.norm(v[:, None] - v[None], axis=2)
    assert np.isclose(np.sort(d.ravel())[8:8 + 24], s).all()  # 12 edges, counted twice
    assert cube_from_truth({"front_face_corners": [[np.nan] * 3] * 4, "center": [0, 0, 0]}) is None


# -- plots -----------------------------------------------------------------------------------------

def test_aspect_ratio_plot_draws_curve_colours_and_nothing_else_without_curves():
    from catadioptric.plots import CubeCurve, aspect_ratio_plot
    green, purple = (0.0, 0.8, 0.0), (0.6, 0.0, 0.9)
    curves = [CubeCurve(-0.045, -0.45, 0.4, 5.3, 0.01, 0.41, green, "a"),
              CubeCurve(-0.04, -0.46, 0.8, 6.8, 0.02, float("nan"), purple, "b")]
    img = cv2.cvtColor(cv2.imdecode(np.frombuffer(aspect_ratio_plot(curves), np.uint8), cv2.IMREAD_COLOR),
                       cv2.COLOR_BGR2RGB)
    assert colour_fraction(img, green, 8) > 1e-3 and colour_fraction(img, purple, 8) > 1e-3
    empty = cv2.cvtColor(cv2.imdecode(np.frombuffer(aspect_ratio_plot([]), np.uint8), cv2.IMREAD_COLOR),
                         cv2.COLOR_BGR2RGB)
    assert colour_fraction(empty, green, 8) == 0 and colour_fraction(empty, purple, 8) == 0


def test_measured_point_lies_on_its_curve_for_ddar(sim, tmp_path):
    """With DDAR the depth comes from r_i by Eqn. getz, so (z, r_i) must lie on r_i(z) of the cube's
    local XSlit as the report rebuilds it from the result file (frame from the slits)."""
    from catadioptric.report import xslit_frame_of
    from depth import ddar
    out = tmp_path / "r.json"
    assert main(["reconstruct", str(sim / "s.png"), "--method", "ddar", "-o", str(out)]) == 0
    cubes = json.loads(out.read_text())["cubes"]
    assert cubes
    for c in cubes:
        origin, n, z1, z2 = xslit_frame_of(c["local_xslit"])
        z = (np.asarray(c["front_face_center"]) - origin) @ n
        assert z1 < 0 and z2 < 0 and z > 0  # virtual slits behind the image plane, scene in front
        assert ddar.aspect_ratio(z, z1, z2) == pytest.approx(c["aspect_ratio"], rel=2e-3)


def test_xslit_frame_of_recovers_a_known_frame():
    from catadioptric.report import xslit_frame_of
    rng = np.random.default_rng(5)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    origin, z1, z2 = rng.normal(size=3), -0.04, -0.5
    d1 = np.cross(n, rng.normal(size=3))
    d2 = np.cross(n, d1) + 0.3 * d1  # slits need not be perpendicular
    # Each slit's point anywhere on its line, as a fit reports it.
    p1, p2 = origin + z1 * n + 0.7 * d1, origin + z2 * n - 1.3 * d2
    lx = {"z1": z1, "z2": z2, "slits": [{"point": p1.tolist(), "direction": d1.tolist()},
                                        {"point": p2.tolist(), "direction": d2.tolist()}]}
    o, e, a, b = xslit_frame_of(lx)
    np.testing.assert_allclose(o, origin, atol=1e-12)
    np.testing.assert_allclose(e, n, atol=1e-12)
    assert (a, b) == (z1, z2)
    # Slit depths that contradict the slits' positions, or missing keys: no frame.
    assert xslit_frame_of(dict(lx, z2=-0.6)) is None
    assert xslit_frame_of({}) is None


def test_tile_map_plot_leaves_invalid_tiles_blank():
    from xslit_fit.tiles import TileMap
    from catadioptric.plots import tile_map_plot
    ny, nx = 3, 4
    valid = np.ones((ny, nx), bool)
    valid[:, 0] = False
    rms = np.full((ny, nx), 1e-4)
    bounds = np.array([[[j * 80, i * 80, (j + 1) * 80, (i + 1) * 80] for j in range(nx)] for i in range(ny)])
    nan = np.full((ny, nx), np.nan)
    tm = TileMap(z1=nan, z2=nan, baseline=nan, ratio=np.full((ny, nx), 10.0), theta2=nan, rms=rms,
                 max_distance=rms, n_rays=np.ones((ny, nx), int), valid=valid, bounds=bounds,
                 reasons=np.full((ny, nx), "", object), frames=[[None] * nx] * ny)
    img = cv2.imdecode(np.frombuffer(tile_map_plot(tm, (320, 240)), np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.std() > 10


# -- other inputs ----------------------------------------------------------------------------------

def test_report_without_truth_beside_the_image(sim, tmp_path, capsys):
    shutil.copy(sim / "s.png", tmp_path / "s.png")
    shutil.copy(sim / "s.toml", tmp_path / "s.toml")
    out = tmp_path / "rep"
    assert main(["report", str(tmp_path / "s.png"), "-o", str(out)]) == 0
    assert capsys.readouterr().out.strip() == str(out / "index.html")
    page = (out / "index.html").read_text()
    assert "no ground truth" in page and "true depth" not in page
    for name in PICTURES:
        assert read_png(out / name).std() > 10


def test_report_from_result_json_and_without_the_image(sim, tmp_path):
    from catadioptric import report
    res = tmp_path / "s.result.json"
    shutil.copy(sim / "s.png", tmp_path / "s.png")
    shutil.copy(sim / "s.toml", tmp_path / "s.toml")
    assert main(["reconstruct", str(tmp_path / "s.png"), "-o", str(res)]) == 0
    index = report.report(res, tmp_path / "a", window_size=WINDOW)
    assert (tmp_path / "a" / "annotated.png").is_file() and index.is_file()
    # A cube the result flags (edge misfit above EDGE_MISFIT_WARN_PX) is outlined in orange there too.
    from catadioptric.reconstruct import OVERLAY_FLAGGED
    from depth.estimate import EDGE_MISFIT_WARN_PX
    plain = read_png(tmp_path / "a" / "annotated.png").astype(float)
    data = json.loads(res.read_text())
    assert "standing on a floor" not in (tmp_path / "a" / "index.html").read_text()
    data["cubes"][0]["edge_misfit_px"] = 2.0 * EDGE_MISFIT_WARN_PX
    data["floor"] = {"height": -0.245, "std": 0.001}  # as `reconstruct --on-floor --floor-std 0.001` writes it
    data["setup_uncertainty"] = {"camera_position": 0.001, "mirror_axis_deg": 0.1}  # as a setup's [uncertainty] gives
    res.write_text(json.dumps(data))
    report.report(res, tmp_path / "f", window_size=WINDOW)
    page = (tmp_path / "f" / "index.html").read_text()
    assert "standing on a floor -0.2450 m along the mirror's axis (±0.0010 m)" in page
    assert "±σ including the setup's own σ (camera_position 0.001, mirror_axis_deg 0.1)" in page
    assert "setup's own σ" not in (tmp_path / "a" / "index.html").read_text()
    marked = read_png(tmp_path / "f" / "annotated.png").astype(float)
    for img, n in ((plain, 0), (marked, 20)):
        orange = np.linalg.norm(img - np.array(OVERLAY_FLAGGED, dtype=float), axis=-1) < 40
        assert (np.count_nonzero(orange) > n) == (n > 0)
    # Without the image beside it: a note and no annotated picture, the rest as usual.
    (tmp_path / "s.png").unlink()
    report.report(res, tmp_path / "b", window_size=WINDOW)
    page = (tmp_path / "b" / "index.html").read_text()
    assert "not beside the result" in page and not (tmp_path / "b" / "annotated.png").exists()
    assert 'src="annotated.png"' not in page
    # A previous report may be overwritten.
    report.report(res, tmp_path / "b", window_size=WINDOW)


@pytest.mark.parametrize("content, message", [
    (None, "no such file"),
    ("{bad", "invalid JSON"),
    ("[1, 2]", "expected a reconstruct result"),
    ('{"setup": "s.toml", "cubes": [{"center": [0, 0, 0]}]}', r"cubes\[0\]\.size: missing key"),
    ('{"cubes": []}', "no setup named"),
])
def test_bad_input_exits_1_with_one_line_and_writes_nothing(tmp_path, capsys, content, message):
    src = tmp_path / "in.json"
    if content is not None:
        src.write_text(content)
    out = tmp_path / "rep"
    assert main(["report", str(src), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and re.search(message, err), err
    assert not out.exists()


def test_refuses_a_non_empty_folder_that_is_not_a_report(sim, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(["report", str(sim / "s.png"), "-o", str(out)]) == 1
    assert "not empty" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_refuses_a_missing_parent_folder_and_a_file_as_output(sim, tmp_path, capsys):
    assert main(["report", str(sim / "s.png"), "-o", str(tmp_path / "no" / "rep")]) == 1
    assert "does not exist" in capsys.readouterr().err and not (tmp_path / "no").exists()
    (tmp_path / "f").write_text("x")
    assert main(["report", str(sim / "s.png"), "-o", str(tmp_path / "f")]) == 1
    assert "got a file" in capsys.readouterr().err and (tmp_path / "f").read_text() == "x"


def test_render_view_rejects_an_unknown_kind(small_scene):
    from catadioptric import views
    from catadioptric.errors import CatadioptricError
    camera, mirror, _ = small_scene
    with pytest.raises(CatadioptricError, match="kind: expected"):
        views.render_view(views.scene_model(camera, mirror), "side", WINDOW)


def test_failure_while_writing_leaves_no_folder(tmp_path, monkeypatch):
    from catadioptric import report
    files = {"index.html": b"<html></html>", "a.png": b"1", "b.png": b"2", "c.png": b"3"}
    calls = {"n": 0}
    real = Path.write_bytes

    def flaky(self, data):
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError("disk full")
        return real(self, data)
    monkeypatch.setattr(Path, "write_bytes", flaky)
    with pytest.raises(CatadioptricError, match=r"rep/b\.png: cannot write \(disk full\)$"):
        report.write_report(files, tmp_path / "rep")
    assert not (tmp_path / "rep").exists()


def test_design_report(sim, tmp_path):
    from catadioptric import report
    index = report.design_report(sim / "s.toml", tmp_path / "design", window_size=WINDOW)
    page = index.read_text()
    for name in re.findall(r'src="([^"]+)"', page):
        assert read_png(index.parent / name).std() > 10
    assert {"view3d.png", "tile_map.png", "design_curves.png"} <= {p.name for p in index.parent.iterdir()}


# -- headless Chromium -------------------------------------------------------------------------------

CHECK_JS = ('<script>window.addEventListener("load",function(){var r=[];for(const i of document.images)'
            '{r.push(i.getAttribute("src")+"="+(i.complete&&i.naturalWidth>0?i.naturalWidth:0));}'
            'var p=document.createElement("pre");p.id="imgcheck";p.textContent=r.join(";");'
            'document.body.appendChild(p);});</script>')


def _loaded_images(html_path: Path, profile: Path) -> dict:
    out = subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", f"--user-data-dir={profile}",
                          "--virtual-time-budget=5000", "--dump-dom", html_path.as_uri()],
                         capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="imgcheck">([^<]*)</pre>', out.stdout)
    assert m, out.stderr[-2000:]
    return {k: int(v) for k, v in (item.rsplit("=", 1) for item in m.group(1).split(";") if item)}


def test_every_image_loads_in_headless_chromium(rep, tmp_path):
    if shutil.which("chromium") is None:
        pytest.skip("chromium is not installed")
    page = (rep / "index.html").read_text()
    check = rep / "_check.html"  # the same page in the same folder, plus a script reporting each image
    check.write_text(page.replace("</body>", CHECK_JS + "</body>"))
    broken = rep / "_broken.html"  # control: the check does see a missing picture
    broken.write_text(page.replace("</body>", '<img src="missing.png">' + CHECK_JS + "</body>"))
    try:
        loaded = _loaded_images(check, tmp_path / "profile")
        control = _loaded_images(broken, tmp_path / "profile")
    finally:
        check.unlink()
        broken.unlink()
    assert set(loaded) == set(PICTURES)
    for name, width in loaded.items():
        assert width == read_png(rep / name).shape[1], name
    assert control["missing.png"] == 0


def test_report_table_marks_a_size_set_aside_from_the_common_size():
    # exact_shape_prior: the cube whose own size was left out of the common size is marked, with a note asking
    # whether the cubes are all one size; none marked, no note
    from catadioptric.report import _table_html

    def cube(depth, aside):
        return {"depth": depth, "uncertainty": {"depth": 0.01}, "size": 0.04, "center": [0.0, 0.0, depth],
                "aspect_ratio": 5.0, "method": "exact_shape_prior", "size_set_aside": aside,
                "front_face_corners_px": [[0, 0], [1, 0], [1, 1], [0, 1]]}
    colours = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
    for aside in ((False, False), (False, True)):
        page = _table_html({"cubes": [cube(0.4, aside[0]), cube(0.7, aside[1])], "refused": []}, None, colours)
        assert ("<td>0.0400 *</td>" in page) == any(aside) and page.count("0.0400 *") == sum(aside)
        assert ("* #1: its own size lay over 3 σ from the others' and was left out of their common size" in page) \
            == any(aside)
