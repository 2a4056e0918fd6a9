"""Tests of catadioptric.design and the fit/design commands: slit positions, sensitivity, errors."""

import json

import numpy as np
import pytest

from catadioptric import design
from catadioptric.cli import main
from catadioptric.setup import Setup


def mirror_setup(radius, distance, resolution=(320, 240), focal=None, objects=()):
    focal = focal or 0.8 * resolution[0] * distance / (2 * radius)  # the mirror spans ~80 % of the width
    return Setup.from_dict({
        "camera": {"resolution": list(resolution), "focal_px": [focal, focal], "position": [0.0, 0.0, distance],
                   "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]},
        "mirror": {"type": "cylinder", "radius": radius, "height": 1.0, "center": [0.0, 0.0, 0.0],
                   "axis": [0.0, 1.0, 0.0]},
        "objects": list(objects)})


@pytest.mark.parametrize("radius, distance", [(0.1, 0.6), (0.05, 0.4), (0.15, 1.0)])
def test_centre_fit_puts_the_slits_where_the_mirror_geometry_says(radius, distance):
    s = mirror_setup(radius, distance, resolution=(640, 480), focal=1500.0)
    fit = design.fit_region(s, design.centre_roi(s))  # a 40×40 px ROI at the image centre
    assert fit["ok"] and fit["glc_type"] == "xslit"
    do = distance - radius
    # Independent geometry (GEOMETRY_NOTES): the axis-parallel slit is the convex-mirror image of the
    # camera in the cross-section, R·do/(2·do + R) behind the surface; the other is do behind it.
    axis_slit = next(sl for sl in fit["slits"] if abs(sl["direction"][1]) > 0.99)
    other = next(sl for sl in fit["slits"] if abs(sl["direction"][1]) < 0.01)
    assert radius - axis_slit["point"][2] == pytest.approx(radius * do / (2 * do + radius), rel=0.01)
    assert radius - other["point"][2] == pytest.approx(do, rel=0.01)
    assert abs(other["point"][1]) < 1e-3 * distance  # at the camera's height


def _measured_ar(setup, frame, square_depth):
    """AR of a frontal square `square_depth` from the axis at the image centre, from the simulator's
    exact corner pixels (the front face of a 4 cm cube centred 2 cm further away)."""
    from raytrace.scene import Cube
    from raytrace.truth import cube_truth, mirror_rays
    cam, mir = setup.camera.build(), setup.mirror.build()
    rot = np.array([[-1.0, 0, 0], [0, 1, 0], [0, 0, -1]])  # local +z face looks at the axis (-z)
    truth = cube_truth(cam, mir, Cube(0.04, np.array([0.0, 0.0, square_depth + 0.02]), rot))
    px = np.array(truth["front_face_corners_px"])
    r = mirror_rays(cam, mir, px)
    k = frame.kappa(frame.rays_to_plane(r.points, r.directions))
    ext = np.ptp(k, axis=0)
    return ext[0] / ext[1]


def test_design_sensitivity_matches_finite_differences_of_simulated_corners():
    s = mirror_setup(0.1, 0.55, resolution=(640, 480))
    des = design.design_setup(s, (0.65, 1.0), n=8)
    _, frame = design._fit_frame(s, design.centre_roi(s))
    for depth, sens, ar in zip(des.depths[1:-1], des.sensitivity[1:-1], des.aspect_ratio[1:-1]):
        h = 0.01
        fd = (_measured_ar(s, frame, depth + h) - _measured_ar(s, frame, depth - h)) / (2 * h)
        assert sens == pytest.approx(fd, rel=0.05)
        assert ar == pytest.approx(_measured_ar(s, frame, depth), rel=0.01)


def test_design_expected_error_grows_with_depth_and_bad_range_is_refused():
    s = mirror_setup(0.1, 0.55)
    des = design.design_setup(s, (0.3, 1.0))
    assert np.all(np.diff(des.expected_error) > 0)
    assert des.max_depth_01px > des.max_depth_1px > 1.0
    with pytest.raises(Exception, match="--depth-range: expected"):
        design.design_setup(s, (0.05, 1.0))


@pytest.mark.parametrize("radius, distance, focal", [(0.1, 0.55, 400.0), (0.075, 0.45, 350.0), (0.15, 0.9, 420.0)])
def test_the_floor_depth_error_is_the_unfolded_pinhole_s(radius, distance, focal):
    """A vertical cylinder's normals are horizontal, so a reflection keeps a ray's slope: unfolded, the camera
    (0.5 m over the floor the mirror stands on, looking level at the mirror's centre) sees the floor point at
    depth d along its own azimuth at the horizontal range L = D + d − 2R, tan(elevation) = H / L, a = H f / L px
    below the image centre. One pixel either way moves it to H f / (a ∓ 1), half the span H f / (a² − 1): the
    design's σ agrees to 1e-4, and is NaN exactly where a lies beyond the image's last row."""
    s = mirror_setup(radius, distance, resolution=(640, 480), focal=focal)
    edge = [0.5 * focal / a - distance + 2 * radius for a in (239.0, 241.5)]  # imaged half a row in, two rows out
    depths = np.sort(np.r_[np.linspace(0.8 * distance, 2.2 * distance, 8), edge])
    got = design.floor_depth_error(s, depths)
    height, L = 0.5, distance + depths - 2 * radius
    a = height * focal / L
    seen = 239.5 + a <= 479
    assert np.array_equal(np.isfinite(got), seen) and seen.sum() >= 5
    assert got[seen] == pytest.approx(height * focal / (a[seen] ** 2 - 1), rel=1e-4)
    des = design.design_setup(s, (depths[0], depths[-1]), n=8)
    assert np.array_equal(des.floor_error, design.floor_depth_error(s, des.depths), equal_nan=True)
    curve = des.to_dict()["curve"]
    assert [c["expected_depth_error_on_floor"] is None for c in curve] == list(~np.isfinite(des.floor_error))
    assert np.isfinite(des.floor_error).any() and not np.isfinite(des.floor_error).all()


def test_fit_and_design_commands(capsys, valid_setup, write_setup, tmp_path):
    setup = write_setup(valid_setup)
    assert main(["fit", str(setup), "--roi", "60", "40", "100", "80", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["glc_type"] == "xslit" and len(out["slits"]) == 2 and out["z1"] < 0 and out["z2"] < out["z1"]
    assert main(["fit", str(setup), "--roi", "0", "0", "999", "10"]) == 1
    assert "--roi: expected" in capsys.readouterr().err
    plot = tmp_path / "design.png"
    assert main(["design", str(setup), "--depth-range", "0.3", "1.0", "--plot", str(plot)]) == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    printed = capsys.readouterr().out
    assert str(plot) in printed and "on the floor (%)" in printed
    assert main(["design", str(setup), "--depth-range", "0.3", "1.0", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert len(d["curve"]) > 3 and d["max_discernible_depth"]["eps_1px"] > 0
    assert main(["design", str(setup), "--optimize"]) == 1
    assert "--optimize: expected --depth-range" in capsys.readouterr().err


def test_design_report_is_written_and_a_bad_folder_writes_nothing(capsys, valid_setup, write_setup, tmp_path):
    setup = write_setup(valid_setup)
    out = tmp_path / "rep"
    assert main(["design", str(setup), "--depth-range", "0.3", "1.0", "--report", str(out)]) == 0
    html = (out / "index.html").read_text()
    assert "<img" in html and all((out / name).exists() for name in ("view3d.png", "tile_map.png"))
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "keep.txt").write_text("mine")
    plot = tmp_path / "p.png"
    assert main(["design", str(setup), "--depth-range", "0.3", "1.0", "--plot", str(plot), "--report", str(busy)]) == 1
    assert not plot.exists() and sorted(p.name for p in busy.iterdir()) == ["keep.txt"]


def test_the_setup_s_depth_error_is_what_whole_fits_through_a_moved_setup_make_of_it():
    """`setup_depth_error` on a 640×480 setup: the cube's exact edges (`_exact_edges`) read by `exact` through the
    true setup give its depth to 1e-6; the mirror's radius and the focal lengths moved by ±δ, whole fits of those
    edges move the depth by what it reports for that number at σ = δ (within 3 %); the camera's place and the
    mirror's centre give the same share (a setup moved as a whole moves no depth); and a setup taken as exact
    gives none."""
    from depth.estimate import estimate_face
    from depth.setup_error import SetupStd, moved
    from raytrace.scene import Cube
    from raytrace.truth import mirror_rays
    setup = mirror_setup(0.1, 0.55, resolution=(640, 480), focal=1400.0)
    camera, mirror = setup.camera.build(), setup.mirror.build()
    depths = np.array([0.3, 0.5, 0.8])
    std = SetupStd(focal_px=4.0, mirror_radius=0.0003, camera_position=0.001, mirror_center=0.001)
    out = design.setup_depth_error(setup, depths, std, cube_size=0.04)
    assert set(out) == {"focal_px", "mirror_radius", "camera_position", "mirror_center", "total"}
    assert np.all(np.isfinite(out["total"])) and np.all(np.diff(out["total"]) > 0)
    assert np.allclose(out["camera_position"], out["mirror_center"], rtol=1e-3)
    assert np.allclose(out["total"] ** 2, sum(out[k] ** 2 for k in std.__dataclass_fields__ if k in out))

    def read(cam, mir, meas):
        def rays(px):
            r = mirror_rays(cam, mir, np.asarray(px, dtype=np.float64))
            return r.points, r.directions
        est = estimate_face(rays, meas, "exact", up=mir.axis)
        assert est, est.reason
        return float(mir.distance_to_axis(est.center[None])[0])
    up, heading = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])  # the camera looks down −z at the axis
    for i, depth in enumerate(depths):
        cube = Cube(0.04, depth * heading, np.column_stack([np.cross(up, -heading), up, -heading]))
        meas = design._exact_edges(camera, mirror, cube)
        assert abs(read(camera, mirror, meas) - depth) < 1e-6

        def half_move(name, k, delta):
            ends = [read(*moved(camera, mirror, name, k, sgn * delta), meas) for sgn in (1.0, -1.0)]
            return 0.5 * (ends[0] - ends[1])
        assert out["mirror_radius"][i] == pytest.approx(abs(half_move("mirror_radius", 0, 0.0003)), rel=0.03)
        # fx and fy in quadrature: the root sum of squares of both moves
        both = np.hypot(half_move("focal_px", 0, 4.0), half_move("focal_px", 1, 4.0))
        assert out["focal_px"][i] == pytest.approx(both, rel=0.03)
    none = design.setup_depth_error(setup, depths, SetupStd(), cube_size=0.04)
    assert set(none) == {"total"} and np.all(none["total"] == 0.0)


def test_the_design_command_gives_the_setup_s_depth_error_where_the_setup_has_an_uncertainty_table(
        capsys, valid_setup, write_setup):
    plain = write_setup(valid_setup)
    assert main(["design", str(plain), "--depth-range", "0.3", "1.0", "--json"]) == 0
    assert "expected_depth_error_from_setup" not in json.loads(capsys.readouterr().out)["curve"][0]
    valid_setup["uncertainty"] = {"focal_px": 2.0, "mirror_radius": 0.0002}
    unsure = write_setup(valid_setup, "unsure.toml")
    assert main(["design", str(unsure), "--depth-range", "0.3", "1.0", "--json"]) == 0
    curve = json.loads(capsys.readouterr().out)["curve"]
    seen = [p["expected_depth_error_from_setup"] for p in curve if p["expected_depth_error_from_setup"]["total"]]
    assert seen and set(seen[0]) == {"focal_px", "mirror_radius", "total"}
    for p in seen:
        assert p["total"] == pytest.approx(np.hypot(p["focal_px"], p["mirror_radius"]))
    assert main(["design", str(unsure), "--depth-range", "0.3", "1.0"]) == 0
    printed = capsys.readouterr().out
    assert "setup σ (mm)" in printed and "depth σ (mm) per [uncertainty] number" in printed
    assert "mirror_radius" in printed and "focal_px" in printed
