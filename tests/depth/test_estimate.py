"""Tests of depth.estimate on exact synthetic measurements: exact recovery, model error, refusals."""

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, example, given, settings, strategies as st

from depth.errors import DepthError
from depth.estimate import NO_SIDE_FACE_GAP_PX, NO_SIDE_FACE_GAP_PX_SHARP, FaceMeasurement, estimate_face, expected_work


def _crop_setup(path, crop_size, focal, principal, position, radius, height):
    """A crop of a held-out render and its setup: the image (RGB), the render's camera (looking at the
    mirror's centre, y up) with its principal point moved to the crop's, and the mirror about the y axis."""
    import cv2

    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror

    image = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    camera = PinholeCamera.from_look_at(crop_size, (focal, focal), principal, position, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    return image, camera, CylinderMirror(radius, height, (0, 0, 0), (0, 1, 0))


def _crop_cube(path, crop_size, focal, principal, position, radius, height, compressed=False):
    """The one cube `reconstruct` finds in a crop of a held-out render (`_crop_setup`), and the crop's mirror:
    the whole pipeline, in this process."""
    from depth.reconstruct import reconstruct

    image, camera, mirror = _crop_setup(path, crop_size, focal, principal, position, radius, height)
    rec = reconstruct(image, camera, mirror, compressed=compressed, workers=1)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    return rec.cubes[0], mirror


def centre_error(rig, est, cube):
    return np.linalg.norm(est.center - cube.center) / rig.depth(cube)


@pytest.mark.parametrize("distance, azimuth, yaw, roll", [
    (0.35, -35.0, 0.0, 0.0), (0.6, 10.0, 0.0, 0.0), (0.9, 30.0, 0.0, 0.0),
    (0.5, 10.0, 25.0, 0.0), (0.5, -30.0, -25.0, 0.0), (0.45, 15.0, 10.0, 35.0),
])
def test_exact_estimator_recovers_any_pose_exactly(rig, distance, azimuth, yaw, roll):
    cube = rig.cube(distance, azimuth, yaw_deg=yaw, roll_deg=roll)
    est = estimate_face(rig.rays, rig.measure(cube), method="exact", up=rig.mirror.axis)
    assert est, getattr(est, "reason", "")
    assert centre_error(rig, est, cube) < 1e-6
    assert est.size == pytest.approx(cube.size, rel=1e-6)
    # The recovered front-face normal points at the mirror like the true one.
    true_normal = cube.rotation @ np.array([0.0, 0.0, 1.0])
    assert np.dot(est.normal, true_normal) > 1 - 1e-9
    # at the known edge length, which is then no parameter of the fit (its σ exactly 0), upright or tilted alike
    known = estimate_face(rig.rays, rig.measure(cube), method="exact", cube_size=cube.size, up=rig.mirror.axis)
    assert known, getattr(known, "reason", "")
    assert centre_error(rig, known, cube) < 1e-6 and known.size == cube.size and known.std["size"] == 0.0
    assert np.dot(known.normal, true_normal) > 1 - 1e-9


@given(st.floats(0.45, 0.9), st.floats(-30.0, 30.0), st.floats(0.02, 0.045), st.floats(7.5, 12.0),
       st.sampled_from([-1, 1]), st.integers(0, 1000))
@settings(max_examples=25, deadline=None, derandomize=True)
@example(0.6559108, 27.027822, 0.02360399, 10.767587, 1, 0)  # the sweep's first refusal: a side face 0.84 px wide
def test_a_side_face_a_pixel_wide_fixes_the_turn_under_noise(rig, distance, azimuth, size, yaw, sign, seed):
    """A face turned 7.5–12° whose side face images 0.75–2 px wide, its back edge measured (the rig's silhouette
    gives one beyond 0.75 px), under 0.08 px of noise: `exact` reads it within 3 % of its centre. At the ddar
    pose such a side face is often hidden, and its back edge's points had no pixel scale there: dropped, they
    left the turn to the front sides' noise, and the fit could finish at the turn's bound, the back edge 8 px
    off, refused (7 of 67 such faces in a sweep; holdout 9090 s5/3)."""
    cube = rig.cube(distance, azimuth, size=size, yaw_deg=sign * yaw)
    meas = rig.measure(cube, n=40, noise_px=0.08, seed=seed, gaps=True)
    gaps = [g for g, back in zip(meas.side_gaps_px, meas.back_sides_px) if back is not None]
    assume(len(gaps) == 1 and gaps[0] <= 2.0)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est, est.reason
    assert centre_error(rig, est, cube) < 0.03


@pytest.mark.parametrize("distance, azimuth", [(0.35, -35.0), (0.6, 10.0), (0.9, 30.0), (0.5, 0.0)])
def test_ddar_model_error_on_axis_facing_cubes_is_small(rig, distance, azimuth):
    # GEOMETRY_NOTES: with exact corners and r_o = 1, faces looking at the axis cost 0.2-1.3 %
    # (3.9 % beside the mirror) through the frontal-parallel assumption.
    cube = rig.cube(distance, azimuth)
    est = estimate_face(rig.rays, rig.measure(cube), method="ddar")
    assert est
    assert centre_error(rig, est, cube) < 0.02
    assert est.size == pytest.approx(cube.size, rel=0.02)
    assert est.aspect_ratio > 1.0  # tall, narrow images: r_i = κ_u/κ_v along the mirror axis


def test_ddar_with_known_size_uses_scale(rig):
    cube = rig.cube(0.6, 10.0)
    est = estimate_face(rig.rays, rig.measure(cube), method="ddar", cube_size=0.04)
    assert est and est.size == 0.04
    assert centre_error(rig, est, cube) < 0.02


@pytest.mark.parametrize("theta_deg", [0.0, 12.0, -25.0, 40.0])
@pytest.mark.parametrize("vertical", [0, 1])
def test_turned_extents_are_an_xslit_image_of_the_turned_square(theta_deg, vertical):
    """A square of edge s centred on the frame's axis at depth z, turned by θ about its vertical: its
    corners lie at depths z ± δ, δ = (s/2)·|sin θ|, the horizontal ones (s/2)·cos θ off the axis, and an
    XSlit scales each κ coordinate by its own slit's factor at the corner's depth (κ = s(z)·κ_xy, Eqn.
    pinproj), so the extents are the means of those at z − δ and z + δ (worked out here by hand, not
    with the projection `_turned_extents` uses)."""
    from depth.estimate import LocalXSlit, _turned_extents
    from depth.xslit import XSlit
    xs = XSlit(z1=-0.05, z2=-0.4, theta1=0.0, theta2=np.pi / 2)
    local = LocalXSlit(np.zeros(3), np.eye(3), xs, 0.0, (), vertical)
    z, size, theta = 0.5, 0.04, np.deg2rad(theta_deg)
    e1, e2 = _turned_extents(local, {"corners": np.zeros((4, 2))}, z, size, theta)
    d = 0.5 * size * abs(np.sin(theta))
    s1 = lambda zz: -xs.z2 / (zz - xs.z2)  # κ_1's factor (slit 2's depth sets it)
    s2 = lambda zz: -xs.z1 / (zz - xs.z1)
    turn = (1.0, np.cos(theta)) if vertical == 0 else (np.cos(theta), 1.0)  # the horizontal one shortens
    assert e1 == pytest.approx(0.5 * size * turn[0] * (s1(z - d) + s1(z + d)), rel=1e-12)
    assert e2 == pytest.approx(0.5 * size * turn[1] * (s2(z - d) + s2(z + d)), rel=1e-12)


def test_ddar_sigma_covers_the_turn_it_reads_as_depth(rig, monkeypatch):
    """ddar takes every face for one facing its local XSlit (r_o = 1). Cubes turned up to ±25° from facing
    the axis, measured exactly from the true mirror rays: their centre errors (up to 37 %) mostly fall
    within the σ that allows for such a turn; the σ of the extents alone covered far fewer."""
    import depth.estimate as est_mod

    def coverage():
        z = []
        for distance, azimuth in [(0.5, 10.0), (0.7, -20.0), (0.4, 25.0), (0.35, -35.0), (0.9, 30.0)]:
            for yaw in np.linspace(-25.0, 25.0, 11):
                cube = rig.cube(distance, azimuth, yaw_deg=yaw)
                est = estimate_face(rig.rays, rig.measure(cube), method="ddar")
                assert est
                z.append(np.linalg.norm(est.center - cube.center) / est.std["center"])
        z = np.array(z)
        return np.mean(z <= 1.0), np.mean(z <= 2.0), np.mean(z <= 3.0)

    one, two, three = coverage()
    assert one >= 0.5 and two >= 0.8 and three >= 0.9
    monkeypatch.setattr(est_mod, "DDAR_TURN_PRIOR_DEG", 0.0)
    _, two_without, three_without = coverage()
    assert two_without < 0.6 and three_without < 0.75


def test_dds_on_a_square_turned_in_its_plane(rig):
    cube = rig.cube(0.45, 15.0, roll_deg=35.0)
    est = estimate_face(rig.rays, rig.measure(cube), method="dds")
    assert est
    assert centre_error(rig, est, cube) < 0.02
    assert est.size == pytest.approx(cube.size, rel=0.02)


def test_dds_refuses_edges_parallel_to_the_slits(rig):
    est = estimate_face(rig.rays, rig.measure(rig.cube(0.5, 5.0)), method="dds")
    assert not est and "parallel to a slit" in est.reason


def test_uncertainty_covers_noisy_measurements(rig):
    """Independent point noise only: the point-scatter term alone (no per-side bias) covers it."""
    cube = rig.cube(0.5, 12.0)
    errs, stds = [], []
    for seed in range(12):
        meas = dataclasses.replace(rig.measure(cube, noise_px=0.2, seed=seed), edge_bias_px=0.0)
        est = estimate_face(rig.rays, meas, method="exact")
        assert est
        errs.append(abs(est.size - cube.size))
        stds.append(est.std["size"])
    # First-order σ is the right order of magnitude: errors mostly within 3σ, σ not absurdly large.
    errs, stds = np.array(errs), np.array(stds)
    assert np.mean(errs <= 3 * stds) >= 0.8
    assert np.median(stds) < 10 * np.median(errs) + 1e-6


def _shift_sides(meas, offsets):
    """Each whole side moved outward by its offset (px): left −u, right +u, top −v, bottom +v."""
    outward = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
    sides = tuple(p + o * n for p, o, n in zip(meas.sides_px, offsets, outward))
    return dataclasses.replace(meas, sides_px=sides)


def test_uncertainty_covers_whole_side_offsets(rig):
    """Sides offset as a whole by N(0, EDGE_BIAS_PX) (what `python -m bench edges` measures on
    renders): the per-side bias term makes σ cover the errors; without it σ is far too small."""
    from depth.estimate import EDGE_BIAS_PX
    cube = rig.cube(0.5, 12.0)
    rng = np.random.default_rng(4)
    z, z_without = [], []
    for _ in range(40):
        meas = _shift_sides(rig.measure(cube), rng.normal(0.0, EDGE_BIAS_PX, 4))
        meas = dataclasses.replace(meas, edge_noise_px=0.02)
        for bias, out in ((EDGE_BIAS_PX, z), (0.0, z_without)):
            est = estimate_face(rig.rays, dataclasses.replace(meas, edge_bias_px=bias), method="exact")
            assert est
            out.append(abs(est.size - cube.size) / est.std["size"])
    z, z_without = np.array(z), np.array(z_without)
    assert 0.5 <= np.mean(z <= 1) <= 0.9  # about 68 % within 1σ
    assert np.mean(z <= 2) >= 0.85  # about 95 % within 2σ
    assert np.median(z_without) > 5 * np.median(z)


def _move_side_ends(meas, ends):
    """Each side's two ends moved outward by ends[k] (px; left/right: top end first, top/bottom: left end
    first), the points between them by the straight line between the two."""
    outward = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
    sides = []
    for k, (p, n) in enumerate(zip(meas.sides_px, outward)):
        along = p[:, 1] if k < 2 else p[:, 0]
        t = (along - along.min()) / np.ptp(along)
        sides.append(p + (ends[k, 0] * (1.0 - t) + ends[k, 1] * t)[:, None] * n)
    return dataclasses.replace(meas, sides_px=tuple(sides))


@pytest.mark.parametrize("distance, azimuth", [(0.9, 30.0), (0.7, 20.0)])
def test_the_sigma_covers_sides_whose_slopes_are_read_off_too(rig, distance, azimuth):
    """Each side offset outward by N(0, b) and tilted about its middle, its ends moved ±N(0, b/2), b = 0.15 px
    (offsets and tilts as `python -m bench edges` measures them, see `SIDE_TILT_SHARE`). On faces 7 and 9 px
    wide the slopes of the short top and bottom fix the turn, and through it the depth (median errors of
    11–22 % here). Over 24 draws the depth must come within 3 σ in at least 90 % of them, and the median
    |error|/σ must be under 1 (0.67 for a Gaussian). With common side offsets alone in the σ model: median
    1.78 and 1.85, within 3 σ 96 and 79 %."""
    cube = rig.cube(distance, azimuth)
    exact = rig.measure(cube, gaps=True)
    assert np.ptp(exact.sides_px[2][:, 0]) < 10.0  # a narrow face
    rng = np.random.default_rng(3)
    z = []
    for _ in range(24):
        offset, tilt = rng.normal(0.0, 0.15, 4), rng.normal(0.0, 0.075, 4)
        meas = _move_side_ends(exact, np.stack([offset - tilt, offset + tilt], axis=1))
        meas = dataclasses.replace(meas, edge_bias_px=0.15, edge_noise_px=0.02)
        est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
        assert est, est.reason
        depth = float(rig.mirror.distance_to_axis(est.center[None])[0])
        z.append(abs(depth - distance) / est.std["z"])
    assert np.mean(np.array(z) <= 3.0) >= 0.9
    assert np.median(z) < 1.0


@pytest.mark.parametrize("distance, azimuth, yaw", [(0.5, 12.0, 0.0), (0.6, -20.0, 0.0), (0.45, 5.0, 15.0),
                                                     (0.7, 25.0, -10.0)])
def test_uncertainty_covers_edges_that_no_square_explains(rig, distance, azimuth, yaw):
    """The upper half of the left side read 1.5 px out (as on a neighbouring face's edge): no square
    explains the edges (rms misfit ≈ 0.35 px, over twice the image's edge bias of 0.15 px). The per-side
    bias is then at least that misfit, and σ covers the error: within 3σ (with the bias alone the
    error was 3.5–4.1σ)."""
    cube = rig.cube(distance, azimuth, yaw_deg=yaw)
    meas = rig.measure(cube, gaps=True)
    left = meas.sides_px[0].copy()
    left[left[:, 1] < np.median(left[:, 1]), 0] -= 1.5
    meas = dataclasses.replace(meas, sides_px=(left,) + tuple(meas.sides_px[1:]), edge_bias_px=0.15,
                               edge_noise_px=0.02)
    est = estimate_face(rig.rays, meas, method="exact")
    assert est and est.rms_residual > 2 * 0.15
    assert np.linalg.norm(est.center - cube.center) <= 3 * est.std["center"]
    assert abs(est.size - cube.size) <= 3 * est.std["size"]


def test_the_sigma_covers_a_short_side_whose_points_scatter_far_more_than_the_others(rig):
    """The top side of a face 0.9 m away read with a quarter of its points, each off by N(0, 0.4 px),
    while the other sides' points scatter by 0.02 px (a JPEG image's short side over a fine checkered
    floor): the pooled point scatter, dominated by the long sides, says the top side's slope is known
    far better than it is. Each side taken at its own scatter, the depth σ covers the errors as a
    normal σ would (with the pooled scatter alone, 70 % of the 30 draws fell within 2 σ)."""
    cube = rig.cube(0.9, 30.0)
    base = rig.measure(cube, gaps=True)
    rng = np.random.default_rng(7)
    z = []
    for _ in range(30):
        sides = [p + rng.normal(0.0, 0.02, p.shape) for p in base.sides_px]
        top = sides[2][::4].copy()
        top[:, 1] += rng.normal(0.0, 0.4, len(top))
        meas = dataclasses.replace(base, sides_px=(sides[0], sides[1], top, sides[3]), edge_bias_px=0.15,
                                   edge_noise_px=0.02)
        est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
        assert est, est.reason
        depth = float(rig.mirror.distance_to_axis(est.center[None])[0])
        z.append(abs(depth - rig.depth(cube)) / est.std["z"])
    z = np.array(z)
    assert np.mean(z <= 2) >= 0.9
    assert np.mean(z <= 1) <= 0.9  # and σ is not blown up past the errors


def _top_band_px(rig, cube):
    """Height (px) of the top face's image above the front face's top corners, from the exact reflection
    of its far edge (> 0: the top face is seen)."""
    from raytrace.truth import reflection_pixels
    _, corners, centre = cube.front_face(rig.mirror)
    back = corners - cube.size * (centre - cube.center) / np.linalg.norm(centre - cube.center)
    front_px = reflection_pixels(rig.camera, rig.mirror, corners)[0]
    back_px = reflection_pixels(rig.camera, rig.mirror, back)[0]
    top = np.argsort(front_px[:, 1])[:2]
    return float(np.mean(front_px[top, 1] - back_px[top, 1]))


@pytest.mark.parametrize("distance, azimuth, height", [(0.9, 30.0, -0.06), (0.6, -20.0, -0.05), (0.5, 0.0, -0.04)])
def test_the_sigma_covers_a_top_side_read_anywhere_across_a_thin_top_face(rig, monkeypatch, distance, azimuth, height):
    """A cube below the camera shows its top face as a band 1.8–2.3 px tall above the front face, within the
    edge profile's reach: the top side's reading can land anywhere across it. Its common offset then has σ
    = band/√3 (uniform over the band), and the depth σ² grows by (∂depth/∂offset · band/√3)², the slope
    measured here by fitting again with the top side moved ±0.2 px and the band from the exact reflection
    of the top face's far edge (neither is what `exact` computes)."""
    import depth.estimate as E
    cube = rig.cube(distance, azimuth, height=height)
    band = _top_band_px(rig, cube)
    assert 1.5 < band < E.UNRESOLVED_BAND_PX
    meas = dataclasses.replace(rig.measure(cube, gaps=True), edge_bias_px=0.15, edge_noise_px=0.02)

    def depth_and_sigma(m, unresolved=E.UNRESOLVED_BAND_PX):
        monkeypatch.setattr(E, "UNRESOLVED_BAND_PX", unresolved)
        est = estimate_face(rig.rays, m, method="exact", up=rig.mirror.axis)
        assert est, est.reason
        return float(rig.mirror.distance_to_axis(est.center[None])[0]), est.std["z"]

    def top_moved(dv):
        sides = list(meas.sides_px)
        sides[2] = sides[2] + [0.0, dv]
        return dataclasses.replace(meas, sides_px=tuple(sides))

    _, sigma = depth_and_sigma(meas)
    _, sigma_without = depth_and_sigma(meas, 0.0)
    slope = (depth_and_sigma(top_moved(-0.2), 0.0)[0] - depth_and_sigma(top_moved(0.2), 0.0)[0]) / 0.4
    assert sigma == pytest.approx(np.hypot(sigma_without, slope * band / np.sqrt(3.0)), rel=0.1)
    # the band's own part, isolated: it adds to the turn profile's spread where that sets the σ (at 0.6 m,
    # once the sides' tilts widened the profile's likelihood scale, 0.018 m of its 0.022 m was left under the
    # profile's spread)
    assert np.sqrt(sigma ** 2 - sigma_without ** 2) == pytest.approx(slope * band / np.sqrt(3.0), rel=0.1)
    # read as a thin strip beside the side, the band is resolved: no term
    strip = dataclasses.replace(meas, strip_px=(0.0, 0.0, band, 0.0))
    assert depth_and_sigma(strip)[1] == pytest.approx(sigma_without, rel=1e-6)


def test_a_top_face_taller_than_the_edge_profile_reaches_adds_nothing_to_the_sigma(rig, monkeypatch):
    """A top face 3.5 px tall lies beyond the edge profile's reach: its far edge is an edge of its own, not
    a band the front face's top side is read across."""
    import depth.estimate as E
    cube = rig.cube(0.9, 30.0, height=-0.1)
    assert _top_band_px(rig, cube) > E.UNRESOLVED_BAND_PX
    meas = dataclasses.replace(rig.measure(cube, gaps=True), edge_bias_px=0.15, edge_noise_px=0.02)
    sigmas = []
    for unresolved in (E.UNRESOLVED_BAND_PX, 0.0):
        monkeypatch.setattr(E, "UNRESOLVED_BAND_PX", unresolved)
        sigmas.append(estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis).std["z"])
    assert sigmas[0] == pytest.approx(sigmas[1], rel=1e-6)


def test_bad_arguments(rig):
    meas = rig.measure(rig.cube(0.5, 5.0))
    with pytest.raises(DepthError, match="method: expected one of ddar, dds, exact"):
        estimate_face(rig.rays, meas, method="magic")
    with pytest.raises(DepthError, match="cube_size"):
        estimate_face(rig.rays, meas, cube_size=-1.0)


def test_a_side_too_short_to_fit_is_refused_by_name(rig):
    # a bottom side of two edge points (holdout 6060 s3/4: its refusal said they missed the mirror)
    meas = rig.measure(rig.cube(0.5, 5.0))
    short = dataclasses.replace(meas, sides_px=tuple(meas.sides_px[:3]) + (np.asarray(meas.sides_px[3])[:2],))
    for method in ("ddar", "exact"):
        est = estimate_face(rig.rays, short, method=method)
        assert not est
        assert "the bottom side has 2 edge point(s), need 3" in est.reason


def test_a_side_whose_points_miss_the_mirror_is_refused_by_name(rig):
    meas = rig.measure(rig.cube(0.5, 5.0))
    off = np.column_stack([np.linspace(2.0, 40.0, 7), np.full(7, 300.0)])  # left of the mirror's image
    assert not np.isfinite(rig.rays(off)[0]).any()
    moved = dataclasses.replace(meas, sides_px=(meas.sides_px[0], meas.sides_px[1], off, meas.sides_px[3]))
    est = estimate_face(rig.rays, moved, method="ddar")
    assert not est
    assert "only 0 of the top side's 7 edge points reflect off the mirror" in est.reason


def test_shape_prior_recovers_common_size_of_identical_cubes(rig):
    from depth.estimate import estimate_faces_shape_prior
    cubes = [rig.cube(0.35, -30.0, size=0.05), rig.cube(0.6, 5.0, size=0.05), rig.cube(0.85, 25.0, size=0.05)]
    ests = estimate_faces_shape_prior(rig.rays, [rig.measure(c) for c in cubes])
    for est, cube in zip(ests, cubes):
        assert est and est.method == "shape_prior"
        assert est.size == pytest.approx(0.05, rel=0.02)
        assert centre_error(rig, est, cube) < 0.02
    single = estimate_faces_shape_prior(rig.rays, [rig.measure(cubes[0])])
    assert not single[0] and "at least 2" in single[0].reason


def test_shape_prior_sigma_widens_where_the_cubes_disagree(rig):
    # the prior takes every cube for one facing its XSlit and all of one size; a turned cube images
    # narrower, a larger one wider, and the joint solution is off by more than the extents' noise. The
    # Birge ratio of its residuals scales σ to cover that: 12 sets of 4 turned cubes (±25°), then 12
    # of 4 facing cubes ±8 % in size, exact edges. With the scale held at 1, 24 / 62 / 72 % of the
    # depths fell within 1 / 2 / 3 σ (with it 62 / 82 / 96 %).
    from depth.estimate import estimate_faces_shape_prior
    rng = np.random.default_rng(1)
    z = []
    for turn, spread in [(25.0, 0.0)] * 12 + [(0.0, 0.08)] * 12:
        cubes = [rig.cube(d, az, yaw_deg=t, size=s) for d, az, t, s in zip(
            rng.uniform(0.35, 0.9, 4), np.linspace(-30, 30, 4) + rng.uniform(-4, 4, 4),
            rng.uniform(-turn, turn, 4), 0.04 * (1 + spread * rng.uniform(-1, 1, 4)))]
        for est, cube in zip(estimate_faces_shape_prior(rig.rays, [rig.measure(c) for c in cubes]), cubes):
            assert est and est.std["scale"] >= 1.0
            depth = float(rig.mirror.distance_to_axis(est.center[None])[0])
            z.append(abs(depth - rig.depth(cube)) / est.std["z"])
    z = np.array(z)
    assert len(z) == 96
    assert np.mean(z <= 1) >= 0.45 and np.mean(z <= 3) >= 0.88
    # identical cubes facing the axis agree: their σ is left as propagated
    same = [rig.cube(0.35, -30.0), rig.cube(0.6, 5.0), rig.cube(0.85, 25.0)]
    assert {e.std["scale"] for e in estimate_faces_shape_prior(rig.rays, [rig.measure(c) for c in same])} == {1.0}


def test_exact_shape_prior_recovers_identical_cubes_exactly(rig):
    from depth.estimate import estimate_faces_exact_shape_prior
    cubes = [rig.cube(0.35, -30.0, size=0.05), rig.cube(0.6, 5.0, size=0.05, yaw_deg=15.0),
             rig.cube(0.85, 25.0, size=0.05)]
    ests = estimate_faces_exact_shape_prior(rig.rays, [rig.measure(c) for c in cubes], up=rig.mirror.axis)
    for est, cube in zip(ests, cubes):
        assert est and est.method == "exact_shape_prior", getattr(est, "reason", "")
        assert est.size == ests[0].size == pytest.approx(0.05, rel=1e-6)
        assert centre_error(rig, est, cube) < 1e-6
        assert est.std["scale"] == 1.0 and est.std["size"] > 0.0
    single = estimate_faces_exact_shape_prior(rig.rays, [rig.measure(cubes[0])], up=rig.mirror.axis)
    assert len(single) == 1 and not single[0] and "at least 2 cubes" in single[0].reason


def test_at_common_size_adds_the_common_size_sigma_to_the_fit_s_own():
    from dataclasses import replace

    from depth.estimate import CubeEstimate, FailedEstimate, at_common_size
    from depth.priors import CommonSize

    def est(centre, z, std, slope=None):
        return CubeEstimate(method="exact", center=np.asarray(centre, float), size=0.04, z=z,
                            front_face_center=np.zeros(3), normal=np.array([0.0, 0.0, 1.0]), aspect_ratio=5.0,
                            std=std, rms_residual=0.05, size_slope=slope)
    # 12.5 m of z and (3, 0, 9) of centre per metre of size: +1 σ (0.4 mm) moves z 5 mm, the centre 3.79 mm
    at = est([0.1, 0.0, 0.5], 0.5, {"z": 0.012, "size": 0.0, "center": 0.0035},
             {"center": np.array([3.0, 0.0, 9.0]), "z": 12.5})
    fused = CommonSize(size=0.04, std=0.0004, birge_ratio=1.7, chi2=5.78)
    out = at_common_size(at, fused)
    assert out.method == "exact_shape_prior" and out.size == 0.04 and np.array_equal(out.center, at.center)
    assert out.std["z"] == pytest.approx(0.013, rel=1e-12)  # √(12² + 5²) mm
    assert out.std["center"] == pytest.approx(np.hypot(0.0035, 0.0004 * np.sqrt(90.0)), rel=1e-12)
    assert out.std["size"] == 0.0004 and out.std["scale"] == 1.7 and out.rms_residual == 0.05
    assert at_common_size(at, CommonSize(0.04, 0.0004, 0.6, 0.36)).std["scale"] == 1.0
    failed = at_common_size(FailedEstimate("exact", "no pose fits"), fused)
    assert not failed and failed.method == "exact_shape_prior"
    assert failed.reason == "at the common size 40.00 mm: no pose fits"
    assert not out.size_set_aside
    # its own reading set aside (3 cm deeper, 4 mm larger): the σ covers it as an even mixture, σ² + (d/2)²
    alone = replace(at, center=np.array([0.1, 0.0, 0.53]), size=0.044, z=0.53, size_slope=None)
    aside = at_common_size(at, fused, alone)
    assert aside.size_set_aside and aside.size == 0.04 and np.array_equal(aside.center, at.center)
    assert aside.std["z"] == pytest.approx(np.hypot(0.013, 0.015), rel=1e-12)
    assert aside.std["size"] == pytest.approx(np.hypot(0.0004, 0.002), rel=1e-12)


@pytest.mark.parametrize("distance, azimuth, yaw, roll, noise_px", [
    (0.35, -30.0, 0.0, 0.0, 0.0), (0.6, 5.0, 15.0, 0.0, 0.0), (0.85, 25.0, 0.0, 0.0, 0.05),
    (0.9, 3.0, -8.0, 0.0, 0.05), (0.5, 10.0, 5.0, 12.0, 0.1)])
def test_size_slope_is_how_far_the_fit_moves_when_the_known_size_does(rig, distance, azimuth, yaw, roll, noise_px):
    """At a known edge length 2.5 % over the true one, `exact`'s `size_slope` (the pose re-solved to first order)
    against two whole fits 0.1 % above and below that size: their difference over 0.2 % of it. Faces facing the
    axis, turned 15° and 8°, and one tilted 12° in its plane (read tilted), on exact and noisy edges. A free size
    has none."""
    cube = rig.cube(distance, azimuth, size=0.04, yaw_deg=yaw, roll_deg=roll)
    meas = rig.measure(cube, n=24, noise_px=noise_px, seed=3)
    size, eps = 0.041, 1e-3
    at = estimate_face(rig.rays, meas, "exact", cube_size=size, up=rig.mirror.axis)
    _slope_matches_two_fits(rig, meas, at, size, eps)
    assert estimate_face(rig.rays, meas, "exact", up=rig.mirror.axis).size_slope is None


def test_size_slope_weighs_each_edge_point_as_the_robust_loss_does(rig):
    """The left side's upper half read 1.5 px out (as on a neighbouring face's edge) on a face turned 15°, at its
    true size: the soft-l1 loss weighs those points down, and so must the re-solve (unweighted: 3.6 % off)."""
    cube = rig.cube(0.45, 5.0, yaw_deg=15.0)
    meas = rig.measure(cube, n=24, gaps=True)
    left = meas.sides_px[0].copy()
    left[left[:, 1] < np.median(left[:, 1]), 0] -= 1.5
    meas = dataclasses.replace(meas, sides_px=(left,) + tuple(meas.sides_px[1:]))
    at = estimate_face(rig.rays, meas, "exact", cube_size=cube.size, up=rig.mirror.axis)
    assert at and at.rms_residual > 0.3
    _slope_matches_two_fits(rig, meas, at, cube.size, 1e-3)


def test_with_size_std_covers_a_known_size_read_off_by_its_sigma(rig):
    """A known size is itself measured: 40 draws of it, each off the true 4 cm by N(0, 1 %), given to `exact` on
    a face's exact edges (four faces, near and far, facing the axis and turned 15°). The depth is then off by
    what the size error moves it; with the size's σ carried through the fit (`with_size_std`), its σ covers
    that as a Gaussian would, a little wider where the edges misfit at the size given (80 % within 1 σ, 39 of 40
    within 2 σ). Without, its σ is the edges' alone."""
    from depth.estimate import with_size_std
    cubes = [rig.cube(0.35, -30.0), rig.cube(0.6, 5.0, yaw_deg=15.0), rig.cube(0.85, 25.0), rig.cube(0.5, -10.0)]
    meas = [rig.measure(c, n=24) for c in cubes]
    rng = np.random.default_rng(7)
    z, z_alone = [], []
    for k in range(40):
        cube, m = cubes[k % 4], meas[k % 4]
        sd = 0.01 * cube.size
        given = cube.size + rng.normal(0.0, sd)
        est = estimate_face(rig.rays, m, "exact", cube_size=given, up=rig.mirror.axis)
        assert est
        carried = with_size_std(est, sd)
        assert carried.std["size"] == sd and carried.size == est.size and np.array_equal(carried.center, est.center)
        err = float(rig.mirror.distance_to_axis(est.center[None])[0]) - rig.depth(cube)
        z.append(abs(err) / carried.std["z"])
        z_alone.append(abs(err) / est.std["z"])
    z = np.array(z)
    assert 0.6 <= np.mean(z <= 1.0) <= 0.9 and np.mean(z <= 2.0) >= 0.9 and z.max() < 3.5, np.sort(z)
    # without it, the σ is the edges' alone (widened only by their misfit at the wrong size): 30 % within 1 σ
    z_alone = np.array(z_alone)
    assert np.mean(z_alone <= 2.0) < 0.6 and z_alone.max() > 5.0, np.sort(z_alone)


def _slope_matches_two_fits(rig, meas, at, size, eps):
    """`at`'s size_slope against the fits at size (1 ± eps): their difference over 2 eps size."""
    above, below = (estimate_face(rig.rays, meas, "exact", cube_size=size * (1 + e), up=rig.mirror.axis)
                    for e in (eps, -eps))
    assert at and above and below
    dz = (above.z - below.z) / (2 * eps * size)
    dc = (above.center - below.center) / (2 * eps * size)
    # (`at_common_size` reads z and how far the centre moves; its direction can turn a few degrees where the
    # turn rests on a kink of the cost, as for a face facing the axis, whose side faces start to show there)
    assert at.size_slope["z"] == pytest.approx(dz, rel=0.01)
    assert np.linalg.norm(at.size_slope["center"]) == pytest.approx(np.linalg.norm(dc), rel=0.01)


def test_exact_shape_prior_gives_a_narrow_face_the_scale_of_the_others(rig):
    """Three cubes 3 cm across: two near (0.35, 0.45 m), one far (0.9 m, turned up to 10°) whose face images
    narrow, each side offset as a whole by 0.1 px (σ) and each point by 0.05 px. Alone, `exact` reads the far
    cube's scale from its own edges: its depth σ runs to tens of %. Fitted at the common size, which the near
    cubes fix, its σ shrinks below its own (the near cubes' scale carried through its fit), its error at
    least halves in the median, and every depth stays within 3 σ."""
    from depth.estimate import estimate_faces_exact_shape_prior
    alone_err, joint_err = [], []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        cubes = [rig.cube(0.35, -25.0, size=0.03), rig.cube(0.45, 20.0, size=0.03),
                 rig.cube(0.9, rng.uniform(-5, 5), size=0.03, yaw_deg=rng.uniform(-10, 10))]
        meas = [rig.measure(c, n=24, gaps=True, noise_px=0.05, side_offset_px=0.1, seed=seed + 10 * k)
                for k, c in enumerate(cubes)]
        far = estimate_face(rig.rays, meas[2], method="exact", up=rig.mirror.axis)
        joint = estimate_faces_exact_shape_prior(rig.rays, meas, up=rig.mirror.axis)
        assert far and all(joint), [getattr(e, "reason", "") for e in (far, *joint)]
        assert len({e.size for e in joint}) == 1
        for est, cube in zip(joint, cubes):
            depth = float(rig.mirror.distance_to_axis(est.center[None])[0])
            assert abs(depth - rig.depth(cube)) <= 3.0 * est.std["z"]
        assert joint[2].std["z"] < far.std["z"]
        alone_err.append(centre_error(rig, far, cubes[2]))
        joint_err.append(centre_error(rig, joint[2], cubes[2]))
    assert np.median(joint_err) <= 0.5 * np.median(alone_err), (alone_err, joint_err)


@pytest.mark.parametrize("sizes, distances", [((0.02, 0.08), (0.35, 0.85)), ((0.03, 0.06), (0.5, 0.6))])
def test_shape_prior_refuses_cubes_of_other_sizes_whose_joint_size_comes_out_negative(rig, sizes, distances):
    # the joint least squares has no sign constraint: two cubes 4x (2x) apart in size drive the common
    # size below zero. That is no cube: refused, not returned (a negative size crashed `reconstruct`).
    from depth.estimate import estimate_faces_shape_prior
    cubes = [rig.cube(d, az, size=s) for d, az, s in zip(distances, (-20.0, 15.0), sizes)]
    ests = estimate_faces_shape_prior(rig.rays, [rig.measure(c) for c in cubes])
    assert len(ests) == 2
    for est in ests:
        assert not est and est.method == "shape_prior" and "not all one size" in est.reason


@pytest.mark.parametrize("yaw", [25.0, -25.0])
def test_exact_on_turned_cubes_with_noisy_edges_uses_the_back_edge(rig, yaw):
    # A face turned 25° shows a side face; its back vertical edge pins the turn. Without it the
    # front face alone leaves turn and depth trading off (tens of % at 0.1 px noise).
    cube = rig.cube(0.5, 12.0, yaw_deg=yaw)
    errors = []
    for seed in range(4):
        meas = rig.measure(cube, noise_px=0.1, seed=seed)
        assert sum(b is not None for b in meas.back_sides_px) == 1
        est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
        assert est
        errors.append(centre_error(rig, est, cube))
    assert np.median(errors) < 0.005 and max(errors) < 0.01


@pytest.mark.parametrize("distance, azimuth", [(0.35, -35.0), (0.6, 10.0), (0.9, 30.0)])
def test_exact_fits_sides_without_a_distinct_side_face_as_the_outer_contour(rig, distance, azimuth):
    """Axis-facing cubes whose sides show no distinct side face (gap 0, or a sliver merged with the
    front face): the outer contour is consistent with the true pose, so it is recovered exactly."""
    cube = rig.cube(distance, azimuth)
    meas = rig.measure(cube, merged=True)
    assert all(np.isfinite(meas.side_gaps_px)) and meas.back_sides_px == (None, None)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-6


@pytest.mark.parametrize("distance, azimuth, yaw", [(0.7, -10.0, 4.0), (0.5, 5.0, -3.0)])
def test_a_thin_distinct_side_face_is_not_read_as_the_outer_contour(rig, distance, azimuth, yaw):
    """A cube turned a few degrees shows a distinct side face only 0.3–0.6 px wide: the front face's
    own sides are measured, and the silhouette lies that far beyond one of them. With the sharp
    images' gap tolerance that side is the front face's edge, and the cube comes back exactly; with the
    blurred images' tolerance it is read as the outer contour, and the depth is off by percents."""
    cube = rig.cube(distance, azimuth, yaw_deg=yaw)
    meas = rig.measure(cube, gaps=True)
    assert meas.back_sides_px == (None, None) and 0.25 < max(meas.side_gaps_px) < 0.75
    sharp = estimate_face(rig.rays, dataclasses.replace(meas, no_side_face_gap_px=NO_SIDE_FACE_GAP_PX_SHARP),
                          method="exact", up=rig.mirror.axis)
    assert sharp and centre_error(rig, sharp, cube) < 1e-6
    loose = estimate_face(rig.rays, dataclasses.replace(meas, no_side_face_gap_px=NO_SIDE_FACE_GAP_PX),
                          method="exact", up=rig.mirror.axis)
    assert not loose or centre_error(rig, loose, cube) > 0.02


@pytest.mark.parametrize("height", [-0.06, -0.03])
def test_edge_points_beyond_a_corner_are_not_measured_against_the_face_merged_beyond_the_other_side(rig, height):
    """A cube below the camera turned 20°, its seen side face merged into the outline: that face's top edge
    rises above the front face's far top corner. The side opposite it (its face hidden) is read on past that
    corner by up to 1.2 px, on its own line (edge points near a corner, as a JPEG image gives them). Their
    rows miss the front face and cross only the merged face beyond the other side, whose edge lay a whole
    face width (20 px) away: the pose was refused (1.08 px rms misfit) or 0.42 % off. Such a face never
    bounds this side; the points keep their own side's residual, as beyond the outline's span, and the
    true pose fits them exactly."""
    from raytrace.truth import reflection_pixels
    cube = rig.cube(0.4, 30.0, height=height, yaw_deg=-20.0)
    meas = rig.measure(cube, merged=True, gaps=True)
    k = int(np.argmin(rig.measure(cube, gaps=True).side_gaps_px))  # the side whose face is hidden
    side = meas.sides_px[k][np.argsort(meas.sides_px[k][:, 1])]
    up = (side[0] - side[-1]) / np.linalg.norm(side[0] - side[-1])
    corners = reflection_pixels(rig.camera, rig.mirror, cube.front_face(rig.mirror)[1])[0]
    corner = corners[np.argmin(np.linalg.norm(corners - side[0], axis=1))]
    beyond = corner + np.outer(np.linspace(0.2, 1.2, 4), up)
    assert meas.sides_px[2][:, 1].min() < beyond[:, 1].max() - 0.2  # the merged face's top rises above them
    sides = list(meas.sides_px)
    sides[k] = np.vstack([beyond, side])
    est = estimate_face(rig.rays, dataclasses.replace(meas, sides_px=tuple(sides)), method="exact", up=rig.mirror.axis)
    assert est, est.reason
    assert centre_error(rig, est, cube) < 1e-4 and est.rms_residual < 0.01


@pytest.mark.parametrize("gap", [0.4, 0.65])
def test_a_merged_side_face_with_a_residual_gap_is_still_read_as_the_outer_contour(rig, gap):
    """A side face 3 px wide lit like the front face merges into the outline, but the silhouette lies a
    few tenths of a pixel beyond it (as on a Mitsuba render under sun: 0.66 px beside a 3.4 px face).
    Read as a distinct side face that thin, no pose shows it so: the contour reading is kept, exact."""
    cube = rig.cube(0.5, 5.0, yaw_deg=15.0)
    assert max(rig.measure(cube, gaps=True).side_gaps_px) > 2.0
    merged = rig.measure(cube, merged=True)
    k = int(np.argmax(rig.measure(cube, gaps=True).side_gaps_px))
    gaps = [0.0, 0.0]
    gaps[k] = gap
    meas = dataclasses.replace(merged, side_gaps_px=tuple(gaps), no_side_face_gap_px=NO_SIDE_FACE_GAP_PX_SHARP)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-4
    # the distinct reading alone (nothing to compare it with) is far off
    from depth.estimate import _exact, _ddar, _prepare
    local, kap = _prepare(rig.rays, meas, "exact", 0)
    alone = _exact(rig.rays, meas, _ddar(local, kap, None), local, None, rig.mirror.axis)
    assert not alone or centre_error(rig, alone, cube) > 0.02


@pytest.mark.parametrize("yaw", [20.0, -20.0])
def test_exact_recovers_a_turned_cube_whose_side_face_merges_with_the_front(rig, yaw):
    """A face turned 20° shows a side face several pixels wide, lit like the front face: the image
    gives only the outer contour (the side face's back edge, top and bottom edges running on over the
    side face). Fitted as such it is exact; read as the front face's own sides it is far off."""
    cube = rig.cube(0.5, 5.0, yaw_deg=yaw)
    assert max(rig.measure(cube, gaps=True).side_gaps_px) > 3.0  # a wide side face shows
    merged = rig.measure(cube, merged=True)
    assert merged.side_gaps_px == (0.0, 0.0) and merged.back_sides_px == (None, None)
    est = estimate_face(rig.rays, merged, method="exact", up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-4
    naive = estimate_face(rig.rays, dataclasses.replace(merged, side_gaps_px=(np.nan, np.nan)),
                          method="exact", up=rig.mirror.axis)
    assert not naive or centre_error(rig, naive, cube) > 0.02


@pytest.mark.parametrize("noise_px", [0.0, 0.1])
def test_a_side_face_as_bright_as_the_background_is_read_beyond_the_front_face(rig, noise_px):
    """A grey cube on a grey floor, turned 17°: its side face as bright as the floor behind it, so the blob
    ends at the front face's edge and the silhouette shows no side face on either side. Read as the outer
    contour, that side holds the turn so that no side face shows there, against the top and bottom sides'
    slopes: 24 % off, its misfit 0.32 px on this face of 61 × 263 px. Read as the front face's own edge, a side
    face free to show beyond it, the cube comes back exactly from exact edges, and within its σ from edges
    0.1 px noisy. The same face with its side face merged (as bright as the front face: the outline is the
    contour, its top and bottom sides running on over the side face) is still read as the contour."""
    big = type(rig)(resolution=(1600, 1200), focal=3500.0)
    cube = big.cube(0.35, 5.0, yaw_deg=17.0, size=0.05, height=-0.05)
    true = big.measure(cube, gaps=True, noise_px=noise_px, seed=3)
    assert max(true.side_gaps_px) > 10.0 and sum(b is not None for b in true.back_sides_px) == 1
    unseen = dataclasses.replace(true, side_gaps_px=(0.0, 0.0), back_sides_px=(None, None))
    est = estimate_face(big.rays, unseen, method="exact", up=big.mirror.axis)
    assert est
    if noise_px:
        depth = float(big.mirror.distance_to_axis(est.center[None])[0])
        assert abs(depth - big.depth(cube)) < 3.0 * est.std["z"] and centre_error(big, est, cube) < 0.02
    else:
        assert centre_error(big, est, cube) < 1e-6
    merged = big.measure(cube, merged=True, noise_px=noise_px, seed=3)
    assert merged.side_gaps_px == (0.0, 0.0) and merged.back_sides_px == (None, None)
    est = estimate_face(big.rays, merged, method="exact", up=big.mirror.axis)
    assert est and centre_error(big, est, cube) < (0.02 if noise_px else 1e-4)


@pytest.mark.xfail(strict=True, reason="open: the contour reading of a face whose side face is as bright as the "
                                       "background fits its exact edges closely at another turn, and its σ does not "
                                       "cover that (bench/README, eightieth session)")
def test_the_sigma_of_a_contour_reading_covers_a_side_face_as_bright_as_the_background(rig):
    """A cube turned 15° whose side face is as bright as the background: the silhouette shows no side face on
    either side, and `exact` reads both sides as the outer contour. On this rig's face (edges 0.02 px noisy) that
    reading fits them to 0.04 px at a turn that shows a side face 1.5 px wide merged with the front face (as
    bright as it), its depth 26 % far, under the misfit that has
    the sides read again (`_background_sides`: 0.25 px here), and its σ says 3.4 %: 7.6 σ. The σ should cover the
    depth (within 3 σ)."""
    cube = rig.cube(0.5, 10.0, yaw_deg=15.0)
    true = rig.measure(cube, gaps=True, noise_px=0.02, seed=1)
    unseen = dataclasses.replace(true, side_gaps_px=(0.0, 0.0), back_sides_px=(None, None))
    est = estimate_face(rig.rays, unseen, method="exact", up=rig.mirror.axis)
    assert est
    depth = float(rig.mirror.distance_to_axis(est.center[None])[0])
    assert abs(depth - rig.depth(cube)) < 3.0 * est.std["z"]


@pytest.mark.parametrize("yaw", [0.0, 20.0, -40.0])
def test_a_front_face_is_the_most_frontal_face_of_its_cube(rig, yaw):
    """`_most_frontal` against the cube's own geometry: the estimate of a cube turned up to 40° from facing the
    axis has its front face nearer to facing its rays than either side face; the same estimate turned a quarter
    turn about the vertical, its front face now a side face of the cube (at least 50° from facing), does not."""
    from scipy.spatial.transform import Rotation

    from depth.estimate import _most_frontal

    cube = rig.cube(0.5, 10.0, yaw_deg=yaw)
    meas = rig.measure(cube)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est and _most_frontal(rig.rays, meas, est, rig.mirror.axis)
    quarter = Rotation.from_rotvec(np.deg2rad(90.0) * np.asarray(rig.mirror.axis, dtype=float)).as_matrix()
    for turn in (quarter, quarter.T):
        assert not _most_frontal(rig.rays, meas, dataclasses.replace(est, normal=turn @ est.normal), rig.mirror.axis)


@pytest.mark.parametrize("seed, noise_px", [(1, 0.05), (3, 0.05), (3, 0.1)])
def test_the_turn_profile_does_not_replace_a_merged_fit_by_a_worse_one(rig, seed, noise_px):
    """A face of 61 × 263 px turned 17°, its side face merged into the outline, the edges noisy: the fit from
    the starting turns finds the true turn, and the turn profile compares the turns beside it with that fit.
    At the fit's own pixel scales, re-measured there, a point on the steep stretch where the merged bottom
    edge recedes has its column meet another edge of the outline, 28 px off; compared with that, a turn
    1.4° on replaced the fit: 1.0–2.4 % off, up to 223 σ. The fit is compared at the scales it was solved at
    too, and stands."""
    big = type(rig)(resolution=(1600, 1200), focal=3500.0)
    cube = big.cube(0.35, 5.0, yaw_deg=17.0, size=0.05, height=-0.05)
    merged = big.measure(cube, merged=True, noise_px=noise_px, seed=seed)
    est = estimate_face(big.rays, merged, method="exact", up=big.mirror.axis)
    assert est and centre_error(big, est, cube) < 0.002
    depth = float(big.mirror.distance_to_axis(est.center[None])[0])
    assert abs(depth - big.depth(cube)) < 3.0 * est.std["z"]


def _side_face_widths_px(rig, est):
    """How far (px) each side face of the estimated cube images beyond its front face (> 0: shown),
    {"L": …, "R": …}, from the exact reflection of the estimated cube's front and back vertical edges."""
    from raytrace.truth import reflection_pixels

    n = est.normal / np.linalg.norm(est.normal)
    v = np.array([0.0, 1.0, 0.0])
    h = np.cross(n, v)
    centre = reflection_pixels(rig.camera, rig.mirror, est.front_face_center[None])[0][0]
    widths = {}
    for side in (-1.0, 1.0):
        front = est.front_face_center + side * h * est.size / 2 + np.outer(np.linspace(-0.3, 0.3, 7) * est.size, v)
        pf = reflection_pixels(rig.camera, rig.mirror, front)[0]
        pb = reflection_pixels(rig.camera, rig.mirror, front - n * est.size)[0]
        outward = np.sign(pf[:, 0].mean() - centre[0])
        widths["L" if outward < 0 else "R"] = float(np.median(outward * (pb[:, 0] - pf[:, 0])))
    return widths


@pytest.mark.parametrize("yaw", [20.0, -20.0, 10.0])
def test_exact_keeps_a_side_face_hidden_opposite_a_distinct_one(rig, yaw):
    """Told that one side shows a distinct side face 1 px wide (its back edge) and the other side none,
    `exact` returns a pose that images the claimed face about that wide and the other no wider than the
    allowed slack: checked independently by reflecting the estimated cube's back edges. The true
    measurement (the opposite side face shown) gives the cube back exactly."""
    from depth.estimate import SIDE_WIDTH_SLACK_PX

    cube = rig.cube(0.5, 5.0, yaw_deg=yaw)
    true = rig.measure(cube, gaps=True)
    shown = 0 if true.back_sides_px[0] is not None else 1
    assert true.back_sides_px[1 - shown] is None and true.side_gaps_px[shown] > 1.5
    est = estimate_face(rig.rays, true, up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-6
    claimed = 1 - shown  # the claim: a 1 px side face here, none beside the truly shown one
    backs, gaps = [None, None], [0.0, 0.0]
    backs[claimed] = true.sides_px[claimed] + np.array([1.0 if claimed == 1 else -1.0, 0.0])
    gaps[claimed] = 1.0
    lied = dataclasses.replace(true, back_sides_px=tuple(backs), side_gaps_px=tuple(gaps))
    est = estimate_face(rig.rays, lied, up=rig.mirror.axis)
    assert est
    widths = _side_face_widths_px(rig, est)
    assert widths["LR"[claimed]] == pytest.approx(1.0, abs=0.2)
    assert widths["LR"[shown]] <= SIDE_WIDTH_SLACK_PX + 0.1


def test_exact_refuses_edges_that_no_square_explains(rig):
    """Edge points no square can pass through (a side zigzagging by ±2.5 px, as along a ragged
    border): refused, with the misfit."""
    cube = rig.cube(0.5, 10.0)
    meas = rig.measure(cube)
    sides = list(meas.sides_px)
    sides[0] = sides[0] + np.c_[2.5 * (-1.0) ** np.arange(len(sides[0])), np.zeros(len(sides[0]))]
    est = estimate_face(rig.rays, dataclasses.replace(meas, sides_px=tuple(sides)), up=rig.mirror.axis)
    assert not est and "do not fit one square face" in est.reason
    assert estimate_face(rig.rays, meas, up=rig.mirror.axis)  # the true outline is not refused


@pytest.mark.parametrize("height, yaw", [(-0.05, 0.0), (-0.05, 15.0), (0.06, -15.0)])
def test_exact_recovers_a_uniformly_lit_cube_from_its_silhouette(rig, height, yaw):
    """Every face lit alike (a sky, no sun): the image gives only the cube's silhouette, top or bottom
    face included. The silhouette comes from ray–box hits, not from the estimator's model; read as
    merged faces it gives the cube back; read as the front face alone it does not."""
    cube = rig.cube(0.5, 8.0, height=height, yaw_deg=yaw)
    meas = rig.silhouette(cube)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-3
    assert est.size == pytest.approx(cube.size, rel=1e-3)
    naive = estimate_face(rig.rays, dataclasses.replace(meas, side_gaps_px=(np.nan,) * 4),
                          method="exact", up=rig.mirror.axis)
    assert not naive or centre_error(rig, naive, cube) > 0.02


@pytest.mark.parametrize("height, yaw", [(-0.05, 0.0), (0.06, 0.0), (0.06, 15.0)])
def test_a_merged_top_or_bottom_face_is_tried_where_a_thin_strip_was_read_beside_it(rig, height, yaw):
    """A top or bottom face lit almost like the front face (0.05 darker under a path tracer's noise)
    merges with it, and the edge-spread pass may read the blur across the outline's edge there as a
    thin strip (lighting holdout: a 0.76 px strip beside an 8 px bottom face). The merged reading must
    still be tried, and stand where it explains the outline: before, a strip ruled it out and the
    cube came out 23 % off (6.7 σ)."""
    cube = rig.cube(0.5, 8.0, height=height, yaw_deg=yaw)
    meas = rig.silhouette(cube)
    strips = [0.0] * 4
    strips[2 if height < 0 else 3] = 0.76  # top for a cube below the camera, else bottom
    est = estimate_face(rig.rays, dataclasses.replace(meas, strip_px=tuple(strips)), method="exact",
                        up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-3
    assert est.size == pytest.approx(cube.size, rel=1e-3)


@pytest.mark.parametrize("height, yaw", [(-0.05, -12.0), (-0.05, 20.0), (0.06, -20.0), (0.06, 12.0)])
def test_a_merged_top_or_bottom_face_beside_a_distinct_side_face(rig, height, yaw):
    """A sun from the side sets one side face apart, while the top (cube below the camera) or bottom
    face takes the sky light the front face takes and merges with it: that side of the outline is the
    cube's silhouette, found from ray–box hits (`MirrorRig.silhouette`), the rest the front face's
    exact edges with the back edge of the distinct side face. Read as merged it gives the cube back;
    read as the front face's own edge (gap unknown) it does not."""
    cube = rig.cube(0.5, 8.0, height=height, yaw_deg=yaw)
    meas = rig.measure(cube, gaps=True)
    assert sum(b is not None for b in meas.back_sides_px) == 1  # one distinct side face
    k = 2 if height < 0 else 3  # the side whose face is seen: top for a cube below the camera
    sides = list(meas.sides_px)
    sides[k] = rig.silhouette(cube).sides_px[k]
    gaps = list(meas.side_gaps_px) + [np.nan, np.nan]
    gaps[k] = 0.0
    merged = dataclasses.replace(meas, sides_px=tuple(sides), side_gaps_px=tuple(gaps))
    est = estimate_face(rig.rays, merged, method="exact", up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-6
    assert est.size == pytest.approx(cube.size, rel=1e-6)
    gaps[k] = np.nan
    naive = estimate_face(rig.rays, dataclasses.replace(merged, side_gaps_px=tuple(gaps)),
                          method="exact", up=rig.mirror.axis)
    assert not naive or centre_error(rig, naive, cube) > 0.02


def _reconstructed(camera, mirror, cubes, light, grey, noise_seed=None):
    """`reconstruct` on our ray tracer's render (16 spp) of `cubes` under `light` on a `grey` background,
    with Gaussian noise of σ = 2/255 (the reconstruct bench's) drawn from `noise_seed` when given."""
    from depth.reconstruct import reconstruct
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import Scene

    scene = Scene(mirror=mirror, objects=tuple(cubes), light=light, background=(grey,) * 3)
    image = linear_to_srgb8(render(scene, camera, spp=16, seed=0).image)
    if noise_seed is not None:
        noise = np.random.default_rng(noise_seed).normal(0.0, 2.0, image.shape)
        image = np.clip(np.round(image + noise), 0, 255).astype(np.uint8)
    return reconstruct(image, camera, mirror)


def _found_under_uniform_light(camera, mirror, cube, grey):
    """`reconstruct` on our ray tracer's render of one cube under a uniform light (every face lit
    alike): the one cube found, and the distance of the cube's centre to the mirror axis."""
    from raytrace.scene import DirectionalLight

    rec = _reconstructed(camera, mirror, [cube], DirectionalLight(intensity=0.0, ambient=1.0), grey)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    return rec.cubes[0], float(mirror.distance_to_axis(cube.center[None])[0])


@pytest.mark.parametrize("yaw", [182.0, 186.7])
def test_a_turned_cube_seen_only_as_a_silhouette_is_found_at_its_turn(yaw):
    """Under a uniform light every face of a cube looks alike, so a turned cube's side face merges
    with its front face and only the silhouette is left: the turn shows only in the kinks where the
    faces meet. Rendered by our ray tracer (a scene of the lighting bench, its cube turned 8° or 13° from
    facing the axis, a side face a few pixels wide showing), `reconstruct` must find the turn: the centre within
    5 % and the depth within 3 of its reported σ. (Starts compared at pixel scales measured at other
    poses settled at a turn 6–11° off: 26 % and 36 %.)"""
    from scipy.spatial.transform import Rotation

    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.scene import Cube

    camera = PinholeCamera.from_look_at((1600, 1200), (2043.084, 2043.084), None, (0.0, -0.03375, 0.3586),
                                        (0, 0, 0), (0, 1, 0))
    mirror = CylinderMirror(0.08683, 0.41094, (0, 0, 0), (0, 1, 0))
    cube = Cube(0.0469, np.array([-0.07969, -0.03045, 0.72958]), Rotation.from_euler("y", yaw, degrees=True).as_matrix(),
                color=(0.8807, 0.5536, 0.1778))
    found, depth = _found_under_uniform_light(camera, mirror, cube, 0.637)
    assert np.linalg.norm(found.estimate.center - cube.center) / depth < 0.05
    assert abs(found.depth - depth) < 3.0 * found.depth_std


@pytest.mark.parametrize("resolution, focal, camera_yz, radius, height, size, centre, yaw, colour, grey", [
    ((1600, 1200), 2043.084, (-0.03375, 0.3586), 0.08683, 0.41094, 0.0737, (0.34781, 0.06726, 0.57357), -166.5816,
     (0.0954, 0.7819, 0.5566), 0.637),
    ((1024, 768), 1895.698, (-0.05057, 0.78655), 0.12497, 0.68814, 0.0415, (0.88853, 0.0287, 0.65093), -138.9079,
     (0.6687, 0.096, 0.8243), 0.621),
])
def test_a_silhouette_whose_best_turn_lies_far_from_the_fitted_one(resolution, focal, camera_yz, radius, height, size,
                                                                   centre, yaw, colour, grey):
    """Two cubes of an unseen scene (bench scenes seed 777) under a uniform light, rendered by our ray
    tracer: the side faces merge with the front face, and the turn that fits the silhouette best at
    its own pixel scales lies 6–15° from where the starting turns settle. The profile finds it, but a
    fit finished with the pixel scales held fixed between solves slid back to the first turn and the
    profile's turn was dropped (29.9 % and 28.6 % off, depth 26 σ and 6 σ off). Finished at its own
    pixel scales: 3.2 % and 4.8 % (the first now 1.7 %, its merged bottom face read: see
    `test_a_merged_bottom_face_with_a_residual_gap_is_read`). The centre must be within 6 % and the
    depth within 3 σ."""
    from scipy.spatial.transform import Rotation

    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.scene import Cube

    camera = PinholeCamera.from_look_at(resolution, (focal, focal), None, (0.0, *camera_yz), (0, 0, 0), (0, 1, 0))
    mirror = CylinderMirror(radius, height, (0, 0, 0), (0, 1, 0))
    cube = Cube(size, np.array(centre), Rotation.from_euler("y", yaw, degrees=True).as_matrix(), color=colour)
    found, depth = _found_under_uniform_light(camera, mirror, cube, grey)
    assert np.linalg.norm(found.estimate.center - cube.center) / depth < 0.06
    assert abs(found.depth - depth) < 3.0 * found.depth_std


def _sky_lit_scene():
    """A scene of the lighting bench (seed 777, scene 0): camera, mirror, and its cube 1, turned 39°
    from facing the axis and below the camera, so its top face images 22 px tall."""
    from scipy.spatial.transform import Rotation

    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.scene import Cube

    camera = PinholeCamera.from_look_at((1024, 768), (1810.109, 1810.109), None, (0.0, 0.05601, 0.6221), (0, 0, 0),
                                        (0, 1, 0))
    mirror = CylinderMirror(0.12083, 0.5793, (0, 0, 0), (0, 1, 0))
    cube = Cube(0.0394, np.array([0.21575, -0.10775, 0.26466]),
                Rotation.from_euler("y", -140.81, degrees=True).as_matrix(), color=(0.8403, 0.1244, 0.4448))
    return camera, mirror, cube


def test_silhouette_disagreement_against_embree_hits():
    """`_silhouette_disagreement` (ray–box slab test) against the cube's pixels as Embree sees them in
    our ray tracer's render (its object ids at one sample per pixel): the true cube disagrees nowhere
    more than a pixel deep; a cube grown by 10 %, or moved up by 5 % or 20 % of its size, does,
    and more the further it is moved."""
    from depth.estimate import SILHOUETTE_MARGIN_PX, _silhouette_disagreement
    from raytrace.render import render
    from raytrace.scene import Cube, Scene
    from raytrace.truth import mirror_rays

    camera, mirror, cube = _sky_lit_scene()
    r = render(Scene(mirror=mirror, objects=(cube,)), camera, spp=1, seed=0)
    blob = (r.object_id == 0) & r.via_mirror

    def rays(px):
        m = mirror_rays(camera, mirror, px)
        return m.points, m.directions

    off = _silhouette_disagreement(rays, blob)
    up = np.array([0.0, cube.size, 0.0])

    def moved(shift=0.0, scale=1.0):
        return Cube(scale * cube.size, cube.center + shift * up, cube.rotation)
    assert off(cube) == 0
    assert off(moved(scale=1.1)) >= 10 * SILHOUETTE_MARGIN_PX
    assert SILHOUETTE_MARGIN_PX <= off(moved(0.05)) < off(moved(0.2))


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 30), st.integers(1, 30), st.floats(0.0, 1.0), st.integers(0, 2**32 - 1))
def test_deep_pixels_count_scipy_binary_erosion(height, width, density, seed):
    """`_deep_pixels` (OpenCV's erosion, nothing beyond the array) against `scipy.ndimage.binary_erosion` by a
    3×3 square, on random masks down to one pixel wide: a pixel on the array's edge is never deep."""
    import scipy.ndimage

    from depth.estimate import _deep_pixels

    mask = np.random.default_rng(seed).random((height, width)) < density
    want = int(scipy.ndimage.binary_erosion(mask, np.ones((3, 3), dtype=bool)).sum())
    assert _deep_pixels(mask) == want
    assert _deep_pixels(np.ones((height, width), dtype=bool)) == max(height - 2, 0) * max(width - 2, 0)


def test_silhouette_disagreement_of_the_blob_alone():
    """With `blob_only`, only the blob's pixels outside the cube count: on the Embree render's blob of
    the true cube, an 8 × 8 px hole cut inside it (a face as bright as what is behind it, no part of the
    blob) disagrees by its 6 × 6 core both ways counted, and not at all counted from the blob; an 8 × 8
    px square added beside the blob disagrees by 36 px either way."""
    from depth.estimate import _silhouette_disagreement
    from raytrace.render import render
    from raytrace.scene import Scene
    from raytrace.truth import mirror_rays

    camera, mirror, cube = _sky_lit_scene()
    r = render(Scene(mirror=mirror, objects=(cube,)), camera, spp=1, seed=0)
    blob = (r.object_id == 0) & r.via_mirror
    ys, xs = np.nonzero(blob)

    def rays(px):
        m = mirror_rays(camera, mirror, px)
        return m.points, m.directions
    r0, c0 = int(np.median(ys)) - 4, int(np.median(xs)) - 4
    assert blob[r0 - 3:r0 + 11, c0 - 3:c0 + 11].all()  # the hole lies well inside the cube's pixels
    holed = blob.copy()
    holed[r0:r0 + 8, c0:c0 + 8] = False
    row = int(np.median(ys[xs == xs.max()]))
    patched = blob.copy()
    patched[row - 4:row + 4, xs.max() + 1:xs.max() + 9] = True
    assert _silhouette_disagreement(rays, holed)(cube) == 36
    assert _silhouette_disagreement(rays, holed, blob_only=True)(cube) == 0
    assert _silhouette_disagreement(rays, patched)(cube) == 36
    assert _silhouette_disagreement(rays, patched, blob_only=True)(cube) == 36


def test_a_tall_merged_top_face_is_told_by_the_silhouette():
    """Every face lit alike, the cube below the camera and turned 39°: its top face and a side face
    merge with the front face. Read as one tall front face (left side merged), the outline's edges fit
    at 0.06 px; read with the top face merged, at 0.10 px, the difference being a few edge points at
    the corners where the outline kinks, measured along a column across a steep edge. Those points'
    residuals are now taken across the edge, and the tall front face would show a 22 px top face where
    the blob has none: the silhouette picks the merged reading. Rendered by our ray tracer; before,
    24 % off with the depth 17.5 σ off. Now the centre must be within 3 % and the depth within 3 σ."""
    camera, mirror, cube = _sky_lit_scene()
    found, depth = _found_under_uniform_light(camera, mirror, cube, 0.643)
    assert np.linalg.norm(found.estimate.center - cube.center) / depth < 0.03
    assert abs(found.depth - depth) < 3.0 * found.depth_std


def test_a_merged_bottom_face_with_a_residual_gap_is_read():
    """The first cube of `test_a_silhouette_whose_best_turn_lies_far_from_the_fitted_one` lies above the
    camera: its bottom face, lit like the front face, merges with it and images 14 px tall, but the
    silhouette measured beyond the outline's bottom curve a 0.33 px gap, over the 0.25 px allowed for
    sharp faces, so the merged reading was never tried and the fit missed the bottom edge by 3.5 px
    rms (0.94 px over all points). Tried, it explains the edges (rms below `UPRIGHT_MISFIT_PX`) and
    the silhouette; the centre must be within 3 % and the depth within 3 σ."""
    from scipy.spatial.transform import Rotation

    from depth.estimate import UPRIGHT_MISFIT_PX
    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.scene import Cube

    camera = PinholeCamera.from_look_at((1600, 1200), (2043.084, 2043.084), None, (0.0, -0.03375, 0.3586),
                                        (0, 0, 0), (0, 1, 0))
    mirror = CylinderMirror(0.08683, 0.41094, (0, 0, 0), (0, 1, 0))
    cube = Cube(0.0737, np.array([0.34781, 0.06726, 0.57357]),
                Rotation.from_euler("y", -166.5816, degrees=True).as_matrix(), color=(0.0954, 0.7819, 0.5566))
    found, depth = _found_under_uniform_light(camera, mirror, cube, 0.637)
    assert found.estimate.rms_residual < UPRIGHT_MISFIT_PX
    assert np.linalg.norm(found.estimate.center - cube.center) / depth < 0.03
    assert abs(found.depth - depth) < 3.0 * found.depth_std


_BENCH_SCENES = {  # two scenes of the reconstruct bench (make_scenes(20, 5)): camera, mirror, cubes, light
    "s09": {"resolution": (1600, 1200), "focal": 3300.877, "camera_yz": (-0.05784, 0.79023), "radius": 0.11824,
            "height": 0.57103, "to_light": (0.12431864, 0.9577707, -0.25926853), "ambient": 0.309, "grey": 0.833,
            "cubes": [(0.0526, (-0.5384, 0.01968, 0.49053), 107.556, (0.7035, 0.1733, 0.8063)),
                      (0.0637, (-0.08099, 0.10558, 0.67294), 164.138, (0.7338, 0.5885, 0.0739)),
                      (0.0774, (0.54157, 0.00965, 0.66115), -146.502, (0.1056, 0.8145, 0.855))]},
    "s11": {"resolution": (2048, 1536), "focal": 2721.376, "camera_yz": (-0.00163, 0.46711), "radius": 0.10896,
            "height": 0.54911, "to_light": (-0.19768716, 0.74179048, -0.64083279), "ambient": 0.423, "grey": 0.829,
            "cubes": [(0.0367, (0.41966, 0.05195, 0.57284), -119.152, (0.7858, 0.1423, 0.6725))]},
}


def _bench_scene(name, which=None, noise_seed=None):
    """A `_BENCH_SCENES` scene (only its cubes `which`, when given) under its light, reconstructed:
    (the reconstruction, mirror, cubes)."""
    from scipy.spatial.transform import Rotation

    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.scene import Cube, DirectionalLight

    sc = _BENCH_SCENES[name]
    camera = PinholeCamera.from_look_at(sc["resolution"], (sc["focal"],) * 2, None, (0.0, *sc["camera_yz"]),
                                        (0, 0, 0), (0, 1, 0))
    mirror = CylinderMirror(sc["radius"], sc["height"], (0, 0, 0), (0, 1, 0))
    cubes = [Cube(size, np.array(c), Rotation.from_euler("y", yaw, degrees=True).as_matrix(), color=col)
             for size, c, yaw, col in sc["cubes"]]
    cubes = cubes if which is None else [cubes[k] for k in which]
    light = DirectionalLight(np.array(sc["to_light"]), 0.8, sc["ambient"])
    return _reconstructed(camera, mirror, cubes, light, sc["grey"], noise_seed), mirror, cubes


@pytest.mark.parametrize("name, k", [("s09", 0), ("s11", 0)])
def test_a_turned_cube_whose_side_face_merges_with_the_front_is_found(name, k):
    """Two cubes of the reconstruct bench (s09/0, s11/1), turned 25° with a side face lit like the front
    face: no contrast between them, so the face's outline is grown to the blob's, whose top and bottom
    kink where the two faces meet (rms 0.44 and 0.31 px about one curve). Such outlines were refused;
    `exact`'s outline of the merged faces has the kink. Rendered alone by our ray tracer under the bench's
    light, each must be found, its centre within 2 % and its depth within 3 σ."""
    rec, mirror, (cube,) = _bench_scene(name, which=[k])
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    found, depth = rec.cubes[0], float(mirror.distance_to_axis(cube.center[None])[0])
    assert np.linalg.norm(found.estimate.center - cube.center) / depth < 0.02
    assert abs(found.depth - depth) < 3.0 * found.depth_std


def test_a_side_face_split_off_by_a_faint_step_is_merged_back():
    """The reconstruct bench's scene s09 with its noise (σ = 2/255, its seed): detection split cube 0's
    side face (turned 25°, lit almost like the front face) from the front face by brightness, but the
    step between them is too faint to trace under the noise (4 consistent edge points on the right side),
    and the cube was refused. The face mask is now grown to the blob across that side, as across a side
    with no contrast at all: the cube must be found, its centre within 2 % and its depth within 3 σ."""
    rec, mirror, cubes = _bench_scene("s09", noise_seed=890176246)
    cube, depth = cubes[0], float(mirror.distance_to_axis(cubes[0].center[None])[0])
    found = min(rec.cubes, key=lambda c: np.linalg.norm(c.estimate.center - cube.center))
    assert np.linalg.norm(found.estimate.center - cube.center) / depth < 0.02
    assert abs(found.depth - depth) < 3.0 * found.depth_std


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), k=st.integers(1, 4))
@example(seed=471259, k=2)  # a ray near grazing a face (κ ≈ 1e5): failed a fixed 1e-12 on a fresh clone
def test_face_frame_helpers_batched_match_plane_intersections(seed, k):
    # `exact` evaluates a pose and its finite-difference neighbours in one call: each batch row of
    # the face-frame helpers must be the ray/plane intersection of that face, computed here point by
    # point from q = o + t·r with (q − c)·n = 0 (and (q − c)·h = ±size/2 for the side plane).
    from scipy.spatial.transform import Rotation

    from depth.estimate import _face_coords, _side_plane_w

    rng = np.random.default_rng(seed)
    origins = rng.normal(size=(7, 3))
    directions = rng.normal(size=(7, 3))
    c = rng.normal(size=(k, 3))
    axes = Rotation.random(k, random_state=seed).as_matrix()  # rows: vertical, horizontal, normal
    size = rng.uniform(0.1, 2.0, size=k)
    side_sign = rng.choice([-1.0, 1.0], size=7)
    a, b = _face_coords(origins, directions, c, axes)
    w = _side_plane_w(origins, directions, c, axes, side_sign, size)
    assert a.shape == b.shape == w.shape == (k, 7)
    eps = np.finfo(np.float64).eps
    for j in range(k):
        e_a, e_b, n = axes[j]
        # a ray near grazing the plane meets it far away, where rounding in r·n (summed in another
        # order) moves the point by ~ε·κ of its distance, κ = |r|/|r·n| (seed 471259: κ ≈ 1e5)
        kappa = np.linalg.norm(directions, axis=1) / np.abs(directions @ n)
        kappa_w = np.linalg.norm(directions, axis=1) / np.abs(directions @ e_b)
        for i in range(7):
            o, r = origins[i], directions[i]
            q = o + ((c[j] - o) @ n) / (r @ n) * r
            rel = max(1e-9, 64 * eps * kappa[i])
            assert a[j, i] == pytest.approx((q - c[j]) @ e_a, rel=rel, abs=1e-9)
            assert b[j, i] == pytest.approx((q - c[j]) @ e_b, rel=rel, abs=1e-9)
            q = o + ((c[j] - o) @ e_b + side_sign[i] * size[j] / 2.0) / (r @ e_b) * r
            assert w[j, i] == pytest.approx((q - c[j]) @ n, rel=max(1e-9, 64 * eps * kappa_w[i]), abs=1e-9)
        # one face at a time gives the same row, to rounding
        a1, b1 = _face_coords(origins, directions, c[j], axes[j])
        tol = 16 * eps * kappa * (np.abs(np.stack([a[j], b[j]])) + 1.0)
        assert np.all(np.abs(np.stack([a1, b1]) - np.stack([a[j], b[j]])) <= tol)


def test_a_fit_whose_size_runs_off_to_infinity_is_refused(rig, monkeypatch):
    """A least-squares run can leave the log size so large that the size overflows to infinity while
    every fitted number stays finite (a cube's shadow on a floor did, on the lighting bench's second
    set of suns). That is a divergence: refused, never reported as a cube of infinite size (it was, with
    a misfit of 0)."""
    import depth.estimate as E
    cube = rig.cube(0.5, 8.0)
    meas = rig.measure(cube)
    assert estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)  # a sound fit, untouched
    real = E.least_squares

    def runaway(*args, **kwargs):  # the solver's answer, its log size (the last parameter) sent to 800
        sol = real(*args, **kwargs)
        sol.x = np.r_[sol.x[:-1], 800.0]
        return sol
    monkeypatch.setattr(E, "least_squares", runaway)
    with warnings.catch_warnings():  # and quietly: the overflow is handled, not a warning for the user
        warnings.simplefilter("error")
        est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert not est and "diverged" in est.reason


@pytest.mark.parametrize("log_size", [5.0, 50.0, 705.0])
def test_a_fit_whose_size_runs_off_but_stays_finite_is_refused(rig, monkeypatch, log_size):
    """As above, the solver's answer sent to a size e^5, e^50 or e^705 times the start's: finite, but far beyond any
    face's (`depth.estimate.LOG_SIZE_RANGE`). It was read as a cube of that size (e^50: 2e20 m across), or the
    next solve could not start (e^705: its Jacobian infinite, a `ValueError`). Refused as diverged, quietly."""
    import depth.estimate as E
    meas = rig.measure(rig.cube(0.5, 8.0))
    real = E.least_squares

    def runaway(*args, **kwargs):
        sol = real(*args, **kwargs)
        sol.x = np.r_[sol.x[:-1], log_size]
        return sol
    monkeypatch.setattr(E, "least_squares", runaway)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert not est and "diverged" in est.reason


@pytest.mark.parametrize("distance, azimuth", [(0.4, -40.0), (0.5, -50.0), (0.4, 40.0)])
def test_a_narrow_face_with_a_merged_side_face_reports_a_sigma_that_covers_its_depth(distance, azimuth):
    """One red 4 cm cube facing the mirror axis, 0.4–0.5 m from it, rendered by our ray tracer at
    640×480 (the small-faces sweep, `python -m bench small_faces`): its front face is about 12 px wide
    and a side face about a pixel wide merges into its outline, so only the turn's effect on that
    outline fixes the depth, and the cost along the turn is flat. The reported σ must cover the depth
    within 3 σ (the first-order σ, from the slopes at the fitted pose alone, put these cubes 3.5–6.5 σ
    off: 6.6–12.5 % in depth)."""
    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.scene import Cube, DirectionalLight

    camera = PinholeCamera.from_look_at((640, 480), (1400.0, 1400.0), None, (0.0, 0.0, 0.55), (0.0, 0.0, 0.0),
                                        (0.0, 1.0, 0.0))
    mirror = CylinderMirror(0.1, 0.49, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    a = np.deg2rad(azimuth)
    x, z = distance * np.sin(a), distance * np.cos(a)
    cube = Cube.from_euler_deg(0.04, (x, 0.0, z), (0.0, float(np.rad2deg(np.arctan2(-x, -z))), 0.0),
                               color=(0.8, 0.1, 0.1))
    rec = _reconstructed(camera, mirror, [cube], DirectionalLight(), 0.85)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    found = rec.cubes[0]
    assert abs(found.depth - distance) < 3.0 * found.depth_std
    assert found.depth_std < 0.1 * distance  # covering, not giving up: the depth is still told



def _cast_shadow(lit, unlit, camera, mirror, cube, below, ss=8):
    """Our render `lit` (linear RGB) with the part of `cube`'s front face where `below(a, b)` holds (a
    across the face, b down it, both in edge lengths from its centre) in a cast shadow, as `unlit` (the
    same render, same samples, without the direct light) shows it: each pixel takes `unlit`'s share of
    its face by the share of its face's ss × ss samples lying in the shadow. Where the shadow covers
    a pixel's part of the face or none of it (everywhere but along the shadow's edge), the pixel is the
    renderer's own, edges and all."""
    from raytrace.truth import mirror_rays, reflection_pixels

    _, corners, centre = cube.front_face(mirror)
    normal = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    normal /= np.linalg.norm(normal)
    down = -np.asarray(mirror.axis, dtype=np.float64)
    down -= (down @ normal) * normal
    down /= np.linalg.norm(down)
    across = np.cross(normal, down)
    px, _ = reflection_pixels(camera, mirror, corners)
    (u0, v0), (u1, v1) = np.floor(px.min(axis=0)).astype(int) - 2, np.ceil(px.max(axis=0)).astype(int) + 2
    us, vs = np.meshgrid(np.arange(u0, u1 + 1), np.arange(v0, v1 + 1))
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    du, dv = np.meshgrid(offs, offs)
    sub = np.stack([(us[..., None] + du.ravel()).ravel(), (vs[..., None] + dv.ravel()).ravel()], axis=1)
    r = mirror_rays(camera, mirror, sub)
    ok = np.all(np.isfinite(r.points), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((centre - r.points) @ normal) / (r.directions @ normal)
    hit = r.points + t[:, None] * r.directions
    a, b = (hit - centre) @ across / cube.size, (hit - centre) @ down / cube.size
    face = ok & (t > 0) & (np.abs(a) <= 0.5) & (np.abs(b) <= 0.5)
    on_face = face.reshape(us.size, ss * ss).sum(axis=1)
    in_shadow = (face & below(a, b)).reshape(us.size, ss * ss).sum(axis=1)
    share = (in_shadow / np.maximum(on_face, 1)).reshape(us.shape)
    out = lit.copy()
    window = (slice(v0, v1 + 1), slice(u0, u1 + 1))
    out[window] -= share[..., None] * (lit[window] - unlit[window])
    return out, float(np.sum(in_shadow) / ss**2)


@pytest.mark.parametrize("depth, azimuth", [(0.35, 8.0), (0.45, -12.0)])
def test_a_front_face_cut_in_two_by_a_curved_shadow_edge_is_found_whole(rig, depth, azimuth):
    """A cube's shadow falling across another's front face (a holdout render: its lower part in the
    shadow of a neighbour, the shadow's edge an arc) splits that face by brightness into two parts of one
    colour. Neither part alone is the image of a square face, so the cube was refused (edge misfit
    1.7 px); the union of the parts is the face. Our render with that shadow (`_cast_shadow`): the cube
    is found, its centre within 1 % and its depth within 3 σ."""
    from depth.reconstruct import reconstruct
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import DirectionalLight, Scene

    cube = dataclasses.replace(rig.cube(depth, azimuth), color=(0.85, 0.8, 0.15))
    images = []
    for intensity in (0.8, 0.0):  # the sun on the face, and the sky alone (the shadow)
        light = DirectionalLight(to_light=np.array([0.3, 0.5, -0.8]), intensity=intensity)
        scene = Scene(mirror=rig.mirror, objects=(cube,), light=light, background=(0.6, 0.6, 0.6))
        images.append(render(scene, rig.camera, spp=16, seed=0).image)
    shadowed, area = _cast_shadow(*images, rig.camera, rig.mirror, cube, lambda a, b: b > -0.15 + 0.9 * a**2)
    assert area > 500  # the shadow covers a good part of the face
    rec = reconstruct(linear_to_srgb8(shadowed), rig.camera, rig.mirror)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    found = rec.cubes[0]
    dist = rig.depth(cube)
    assert np.linalg.norm(found.estimate.center - cube.center) / dist < 0.01
    assert abs(found.depth - dist) < 3.0 * found.depth_std


@pytest.mark.parametrize("azimuth, yaw", [(-20.0, -25.0), (-20.0, 25.0), (20.0, -25.0)])
def test_a_top_face_as_bright_as_the_sky_does_not_drag_the_fit_to_hide_it(rig, azimuth, yaw):
    """A grey cube turned 25° under a sun from straight above: its front and side faces take only the
    sky light and merge, its top face, lit by the sun, is exactly as bright as the background and no
    part of the blob. The pose that shows that top face (the true one) then disagrees with the blob,
    and the silhouette test chose the merged-top reading, which hides it but misses the edges by
    0.40–0.56 px rms against 0.04–0.07 px: 6.7 % off at −2.6 σ, or refused as a shadow (misfit over
    0.45 px). The silhouette decides only where the edges do not: each cube within 1 % and 3 σ."""
    from depth.reconstruct import reconstruct
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import DirectionalLight, Scene

    cube = dataclasses.replace(rig.cube(0.35, azimuth, height=-0.05, yaw_deg=yaw), color=(0.5, 0.5, 0.5))
    light = DirectionalLight(to_light=np.array([0.0, 1.0, 0.0]), intensity=0.8, ambient=0.25)
    top = 0.5 * (light.ambient + light.intensity)  # the top face's radiance: the background's
    scene = Scene(mirror=rig.mirror, objects=(cube,), light=light, background=(top, top, top))
    rec = reconstruct(linear_to_srgb8(render(scene, rig.camera, spp=16, seed=0).image), rig.camera, rig.mirror)
    found = [c for c in rec.cubes if np.linalg.norm(c.estimate.center - cube.center) < 0.05]
    assert len(found) == 1, [r.reason for r in rec.refused]
    dist = rig.depth(cube)
    assert np.linalg.norm(found[0].estimate.center - cube.center) / dist < 0.01
    assert abs(found[0].depth - dist) < 3.0 * found[0].depth_std


def test_a_blob_that_no_pose_the_edges_allow_explains_is_no_cube(rig):
    """Exact edges of a cube seen from above its top face (which images 10 px tall) and no gap at the
    top: the merged-top reading is tried, and the edges refute it (0.21 px rms against 0). With the
    cube's own blob (ray–box hits) the cube comes back exactly. With a blob 30 % larger than any pose
    the edges allow (a floor shadow's hexagon read as a grey face: 28 % of its pixels) neither reading
    is a cube, and `exact` says so instead of choosing one."""
    cube = rig.cube(0.35, -20.0, height=-0.08, yaw_deg=25.0)
    meas = rig.measure(cube, gaps=True)
    gaps = (meas.side_gaps_px[0], meas.side_gaps_px[1], 0.0, 0.0)
    w, h = rig.camera.resolution
    yy, xx = np.mgrid[0:h, 0:w]
    points, directions = rig.rays(np.column_stack([xx.ravel(), yy.ravel()]).astype(np.float64))
    seen = np.all(np.isfinite(points), axis=1)
    hit = np.zeros(len(seen), dtype=bool)
    hit[seen] = cube.hits(points[seen], directions[seen])
    blob = hit.reshape(h, w)
    est = estimate_face(rig.rays, dataclasses.replace(meas, side_gaps_px=gaps, blob_mask=blob), method="exact",
                        up=rig.mirror.axis)
    assert est and centre_error(rig, est, cube) < 1e-6
    ys, xs = np.nonzero(blob)
    wider = blob.copy()
    wider[ys.min():ys.max(), xs.max():xs.max() + int(0.3 * np.ptp(xs))] = True
    est = estimate_face(rig.rays, dataclasses.replace(meas, side_gaps_px=gaps, blob_mask=wider), method="exact",
                        up=rig.mirror.axis)
    assert not est and "no cube fits both the edges and the blob" in est.reason


def _cube_missing_its_top_face(rig, distance, azimuth, height, yaw, top_level):
    """The exact measurement of a cube seen from above (no gap at its top: the merged-top reading is
    tried), its blob without the top face, and an image of it: background 0.5, the blob's faces 0.3, the
    top face at `top_level`, with noise of σ 0.01 (seeded)."""
    cube = rig.cube(distance, azimuth, height=height, yaw_deg=yaw)
    meas = rig.measure(cube, gaps=True)
    w, h = rig.camera.resolution
    yy, xx = np.mgrid[0:h, 0:w]
    points, directions = rig.rays(np.column_stack([xx.ravel(), yy.ravel()]).astype(np.float64))
    seen = np.all(np.isfinite(points), axis=1)
    face = np.full(len(seen), -1)
    face[seen] = cube.entry_faces(points[seen], directions[seen])
    face = face.reshape(h, w)
    top = 2  # the local +y face (`raytrace.scene.FACE_AXES`): the cube is only turned about y
    assert np.allclose(cube.rotation[:, 1], [0.0, 1.0, 0.0])
    blob = (face >= 0) & (face != top)
    image = np.where(blob, 0.3, np.where(face == top, top_level, 0.5))[..., None].repeat(3, axis=2)
    image = image + np.random.default_rng(0).normal(0.0, 0.01, image.shape)
    gaps = (meas.side_gaps_px[0], meas.side_gaps_px[1], 0.0, 0.0)
    meas = dataclasses.replace(meas, side_gaps_px=gaps, blob_mask=blob, image=image)
    return cube, meas, np.count_nonzero(face == top)


@pytest.mark.parametrize("distance, azimuth, height, yaw", [(0.35, -20.0, -0.12, 25.0), (0.3, -10.0, -0.12, 15.0)])
def test_a_top_face_the_blob_leaves_out_but_the_image_shows_does_not_refuse_the_cube(rig, distance, azimuth,
                                                                                     height, yaw):
    """The scene of `test_a_blob_that_no_pose_the_edges_allow_explains_is_no_cube`, lower, so that the
    top face shows over 22 % and 54 % as many pixels as the rest of the cube, and a blob without it: a top
    face too near the background's brightness for the blob (0.46 against 0.5), which the image still shows
    over its pixels (holdout 5050 s7/1, a grey cube refused where the edges read it 0.8 % off). The edges
    refute the merged-top reading; the pose they allow explains every pixel of the blob and the top face
    left out is seen, so the cube is read, exactly. Refused before the seventy-ninth session, which counted
    the silhouette's pixels outside the blob against the pose."""
    cube, meas, n_top = _cube_missing_its_top_face(rig, distance, azimuth, height, yaw, 0.46)
    assert n_top > 0.2 * meas.blob_mask.sum()  # precondition: a top face the blob lacks, over 10 % of it
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est, est.reason
    assert centre_error(rig, est, cube) < 1e-6


@pytest.mark.parametrize("distance, azimuth, height, noise_px, seed", [
    (0.35, 10.0, -0.1, 0.05, 1), (0.4, -15.0, -0.1, 0.1, 2), (0.3, 20.0, -0.12, 0.2, 1)])
def test_a_top_face_the_blob_leaves_out_but_the_image_shows_does_not_choose_the_merged_reading(
        rig, distance, azimuth, height, noise_px, seed):
    """Cubes facing the axis, seen from above: the top face, too near the background's brightness for the blob
    (0.46 against 0.5), shows in the image; the edges are noisy (0.05–0.2 px), so that they do not refute the
    merged-top reading, and the silhouette decides between the readings. It counted the top face that the
    unmerged pose shows outside the blob against that pose, and chose the merged reading: 14–16 % off (holdout
    6060 all grey s2/1, a grey face 19 × 93 px under a top face 10 px tall: 17.5 % off, then refused as a
    flat mark). A face the blob leaves out whole but the image shows is not counted there either: within 1 %."""
    cube, meas, _ = _cube_missing_its_top_face(rig, distance, azimuth, height, 0.0, 0.46)
    noisy = rig.measure(cube, gaps=True, noise_px=noise_px, seed=seed)
    meas = dataclasses.replace(meas, sides_px=noisy.sides_px, corners_px=noisy.corners_px,
                               edge_noise_px=noisy.edge_noise_px)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est, est.reason
    assert centre_error(rig, est, cube) < 0.01


@pytest.mark.parametrize("step, spread, n, shown", [
    (1.0, 1.0, 2000, False),  # a smooth shading: 31 standard errors, but within the pixels' own spread
    (0.3, 0.7, 230, False),  # holdout 4040 all grey s6/2's top face read unmerged: 0.3 levels off, 5 errors
    (6.0, 2.3, 150, True),  # holdout 6060 all grey s2/1's top face: 6 levels darker than the floor
    (4.0, 0.0, 20, True),  # a noiseless render
    (1.0, 0.0, 5, False)])  # too few pixels to judge
def test_a_face_shows_apart_from_the_background_where_it_steps_beyond_its_pixels_spread(step, spread, n, shown):
    """`_shows_apart` on two regions of an image (levels of 255, three channels): a face's mean `step` from the
    background's, both with pixel noise `spread`. A mean that lies many standard errors off, but within the
    pixels' spread, is no face the image shows: the background's own shading passes that test over hundreds of
    pixels."""
    from depth.estimate import _shows_apart

    rng = np.random.default_rng(7)
    image = np.empty((2, n, 3))
    image[0] = 150.0 + step + spread * rng.standard_normal((n, 3))
    image[1] = 150.0 + spread * rng.standard_normal((n, 3))
    face = np.zeros((2, n), dtype=bool)
    face[0] = True
    assert _shows_apart(image / 255.0, face, ~face) is shown


def test_a_top_face_that_the_floor_shading_alone_sets_apart_is_no_face_the_image_shows():
    """The whole pipeline on a crop of holdout 4040 all grey, scene 6: a grey cube 4.78 cm across facing the
    axis, its front face 29 × 178 px. Its edges fit the merged and the unmerged reading of its top face nearly
    alike (0.058 against 0.056 px), and the silhouette chooses: the unmerged pose shows a top face of 247 px
    outside the blob, where the image is the floor, up to 0.34 levels of 255 off the floor beside it (5.1
    standard errors, under half the pixels' spread). Excused as a face the image shows (`whole_faces`), it left the
    silhouette no say and the unmerged reading was kept: 15.3 % off. Within 2 % and 2 σ."""
    from depth.reconstruct import reconstruct

    image, camera, mirror = _crop_setup(Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_4040_s6_2.png",
                                        (160, 320), 3262.832, (1023.5 - 800, 767.5 - 40), (0.0, 0.03993, 0.57644),
                                        0.10184, 0.59307)
    rec = reconstruct(image, camera, mirror, workers=1)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    centre = np.array([-0.25103, 0.13657, 0.56108])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(rec.cubes[0].estimate.center - centre) < 0.02 * depth
    assert abs(rec.cubes[0].depth - depth) < 2.0 * rec.cubes[0].depth_std


@pytest.mark.parametrize("name, compressed", [("mitsuba_grey_5050_s1_1.png", False),
                                              ("mitsuba_grey_5050_s1_1_jpeg.png", True)])
def test_the_silhouette_does_not_choose_a_merged_top_face_that_the_top_sides_points_refute(name, compressed):
    """The whole pipeline on a 96×144 crop, from (770, 760), of holdout 5050 all grey, scene 1 (Mitsuba 3, 16 spp;
    also through OpenCV's JPEG coder at quality 90): a grey cube 2.05 cm across, turned 13° so that its left side
    face shows 3.4 px wide, its front face 13 × 72 px and darker than the floor, its top face as bright as the floor
    behind it and so no part of the blob. The unmerged pose shows that top face outside the blob (51 px), the
    merged pose nothing (4.4 % of the blob), and the silhouette chose the merged reading over the edges (0.30
    against 0.19 px rms; their scatter is 0.17 px): 17.4 % off at −1.7 σ (JPEG: 17.3 %, −1.6 σ). That reading fits
    the top side's own points 0.26 px worse (rms 0.41 against 0.16 px): they are where it would put the top face's
    far edge, and they refute it (`MERGED_SIDE_WORSE_NOISE`). Within 2 % and 1 σ."""
    cube, mirror = _crop_cube(Path(__file__).resolve().parents[1] / "data" / name, (96, 144), 2895.401,
                              (799.5 - 770, 599.5 - 760), (0.0, 0.01196, 0.46126), 0.09716, 0.52096,
                              compressed=compressed)
    centre = np.array([0.02013, -0.07493, 0.56533])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(cube.estimate.center - centre) < 0.02 * depth
    assert abs(cube.depth - depth) < 1.0 * cube.depth_std


def test_a_white_face_as_bright_as_the_sky_beside_it_is_found_in_a_jpeg_image_by_its_blue_yellow_edges(monkeypatch):
    """The whole pipeline on a 120×210 crop, from (290, 290), of holdout 8080 all grey, scene 0, through OpenCV's
    JPEG coder at quality 90 (Mitsuba 3, 16 spp): a white cube 7.6 cm across facing the axis, its front face 17 ×
    131 px (220, 223, 227 of 255) before a sky as bright (222, 223, 217) on its left, under the strong step in
    every channel there, its bottom before the floor. Blue − red steps by 13 levels at its side; JPEG keeps it at
    half resolution. The grey search's second pass, with the edges of blue − red at `COMPRESSED_BLUE_RED_STEPS`,
    finds it: within 2 % and 1 σ (0.83 %, −0.1 σ). Without that pass nothing is found, nor refused."""
    import depth.measure as dm
    from depth.reconstruct import reconstruct

    args = (Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_8080_s0_3_jpeg.png", (120, 210), 2051.713,
            (511.5 - 290, 383.5 - 290), (0.0, 0.00948, 0.5222), 0.09096, 0.5347)
    cube, mirror = _crop_cube(*args, compressed=True)
    centre = np.array([-0.63402, -0.01767, 0.59758])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(cube.estimate.center - centre) < 0.02 * depth
    assert abs(cube.depth - depth) < 1.0 * cube.depth_std
    monkeypatch.setattr(dm, "COMPRESSED_BLUE_RED_STEPS", 0.0)  # no second search
    image, camera, mirror = _crop_setup(*args)
    rec = reconstruct(image, camera, mirror, compressed=True, workers=1)
    assert rec.cubes == [] and rec.refused == []


def test_a_merged_bottom_face_that_fits_the_edges_as_a_whole_stands_though_its_own_side_fits_worse():
    """The whole pipeline on a 280×420 crop, from (960, 40), of holdout 3030 all grey, scene 6, through OpenCV's JPEG
    coder at quality 90 (Mitsuba 3, 16 spp): a dark grey cube 6.8 cm across facing the axis, its front face
    54 × 226 px, its bottom face lit alike and merged with it in the outline. The merged reading fits the bottom
    side's points 0.08 px worse than the unmerged one, twice their scatter (0.04 px), but the edges as a whole only
    0.009 px worse (a quarter of it), and the unmerged pose, a cube 8.5 cm across, leaves 1460 of the blob's 13981
    pixels out: the silhouette chooses the merged reading (`MERGED_WORSE_NOISE`). Refused by its own side's points
    alone, the merged reading gave way to the unmerged one: 22.3 % off at +2.8 σ. Within 1 % and 1 σ."""
    cube, mirror = _crop_cube(Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_3030_s6_2_jpeg.png",
                              (280, 420), 3237.63, (1023.5 - 960, 767.5 - 40), (0.0, -0.01705, 0.76854), 0.13953,
                              0.71915, compressed=True)
    centre = np.array([0.11435, 0.15954, 0.49656])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(cube.estimate.center - centre) < 0.01 * depth
    assert abs(cube.depth - depth) < 1.0 * cube.depth_std


def test_a_merged_top_face_stands_where_the_silhouette_refutes_the_unmerged_pose_outright():
    """The whole pipeline on a 120×190 crop, from (610, 530), of the lighting bench's sky-only render of its scene 0
    (Mitsuba 3, 16 spp, a uniform sky and no sun: every face lit alike): a magenta cube 3.94 cm across, its top face
    merged with its front face in the outline. The merged reading misfits the edges beyond the unmerged one (0.80
    times their scatter of 0.048 px), and its merged side 3.8 times, but the unmerged pose leaves 444 of the blob's
    3228 pixels out (13.8 %, over `SILHOUETTE_MAX_SHARE`): no cube the blob allows, so the silhouette still chooses
    the merged reading. Refused by the edges there, the unmerged one was taken: 24.2 % off at +5.5 σ. Within 2 %
    and 1 σ."""
    cube, mirror = _crop_cube(Path(__file__).resolve().parents[1] / "data" / "mitsuba_sky_only_s0_1.png", (120, 190),
                              1810.109, (511.5 - 610, 383.5 - 530), (0.0, 0.05601, 0.6221), 0.12083, 0.5793)
    centre = np.array([0.21575, -0.10775, 0.26466])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(cube.estimate.center - centre) < 0.02 * depth
    assert abs(cube.depth - depth) < 1.0 * cube.depth_std


def test_a_merged_bottom_face_whose_own_side_fits_as_well_stands_though_the_edges_lean_the_other_way():
    """The whole pipeline on a 91×157 crop, from (818, 395), of the reconstruct bench's Mitsuba scene 1 (Mitsuba 3,
    16 spp): a magenta cube 3.53 cm across, 0.94 m from the axis, its bottom face merged with its front face
    (10 × 77 px) in the outline. The merged reading misfits the edges beyond the unmerged one by 0.52 times their
    scatter (0.077 against 0.052 px, at 0.048 px), more on the left side, but its merged bottom side no worse
    (+0.001 px): those points do not refute it (`MERGED_SIDE_WORSE_NOISE`), and the silhouette (29 pixels out
    for the unmerged pose, none for the merged) chooses it. Refused by the edges as a whole, the unmerged reading
    was taken: 23.1 % off. Within 2 % and 1 σ."""
    cube, mirror = _crop_cube(Path(__file__).resolve().parents[1] / "data" / "mitsuba_bench_m01_0.png", (91, 157),
                              2854.34, (799.5 - 818, 599.5 - 395), (0.0, -0.02404, 0.5997), 0.10035, 0.53536)
    centre = np.array([0.21621, 0.08737, 0.91376])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(cube.estimate.center - centre) < 0.02 * depth
    assert abs(cube.depth - depth) < 1.0 * cube.depth_std


def test_a_top_face_the_image_does_not_show_still_refuses_the_cube(rig):
    """The same with the top face exactly as bright as the background (0.5): then nothing tells it from
    the background, as a floor shadow read with a top face that is the floor (lighting bench, floor any-sun
    scene 7), and the pose that shows it disagrees with the blob over that face: no cube is read."""
    cube, meas, n_top = _cube_missing_its_top_face(rig, 0.35, -20.0, -0.12, 25.0, 0.5)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert not est and "no cube fits both the edges and the blob" in est.reason
    # with the image left out, the top face is not excused either
    est = estimate_face(rig.rays, dataclasses.replace(_cube_missing_its_top_face(rig, 0.35, -20.0, -0.12, 25.0,
                                                                                 0.46)[1], image=None),
                        method="exact", up=rig.mirror.axis)
    assert not est and "no cube fits both the edges and the blob" in est.reason


@pytest.mark.parametrize("azimuth, height, yaw", [(8.0, -0.04, 15.0), (20.0, -0.05, 25.0)])
def test_where_the_silhouette_overrules_the_edges_the_sigma_covers_both_readings(rig, azimuth, height, yaw):
    """The scene of `test_a_top_face_as_bright_as_the_sky_does_not_drag_the_fit_to_hide_it`, turned so
    that the edges favour the true (unmerged) reading only slightly (0.056 against 0.187 px, 0.074
    against 0.116 px rms: within a side's offset) and the silhouette, fooled by the invisible top face,
    chooses the merged one: 9.2 % and 4.5 % off. Either reading may be the cube, so the reported depth
    σ covers half their difference: the depth within 3 σ (it was 5.2 σ and 4.2 σ off)."""
    from depth.reconstruct import reconstruct
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import DirectionalLight, Scene

    cube = dataclasses.replace(rig.cube(0.35, azimuth, height=height, yaw_deg=yaw), color=(0.5, 0.5, 0.5))
    light = DirectionalLight(to_light=np.array([0.0, 1.0, 0.0]), intensity=0.8, ambient=0.25)
    top = 0.5 * (light.ambient + light.intensity)
    scene = Scene(mirror=rig.mirror, objects=(cube,), light=light, background=(top, top, top))
    rec = reconstruct(linear_to_srgb8(render(scene, rig.camera, spp=16, seed=0).image), rig.camera, rig.mirror)
    found = [c for c in rec.cubes if np.linalg.norm(c.estimate.center - cube.center) < 0.05]
    assert len(found) == 1, [r.reason for r in rec.refused]
    dist = rig.depth(cube)
    assert abs(found[0].depth - dist) < 3.0 * found[0].depth_std


def test_expected_work_counts_the_fits_exact_will_run_and_breaks_ties_by_edge_points():
    """`expected_work`: a contour side (no gap, no back edge) doubles it, each gapless top/bottom side
    adds half the base, a thin left/right gap doubles it; the other methods get the edge points."""
    def pts(n):
        return np.zeros((n, 2))

    def meas(gaps, back=(None, None), n=(100, 100, 150, 150), sharp=True):
        return FaceMeasurement(tuple(pts(k) for k in n), np.zeros((4, 2)), np.zeros((0, 2)), back_sides_px=back,
                               side_gaps_px=gaps, no_side_face_gap_px=NO_SIDE_FACE_GAP_PX_SHARP if sharp else NO_SIDE_FACE_GAP_PX)
    wide = 2.0  # px: a distinct side face
    base = meas((wide, wide, wide, wide))
    assert expected_work(base, "ddar") == expected_work(base, "dds") == 500.0
    assert expected_work(base) == pytest.approx(2.0 * 1.5)
    contour = meas((0.0, wide, wide, wide))
    assert expected_work(contour) == pytest.approx(2.0 * expected_work(base))
    # a back edge measured beside the other side: the side is hidden, not a contour
    hidden = meas((0.0, wide, wide, wide), back=(None, pts(20)))
    assert expected_work(hidden) == pytest.approx(2.0 * (1.0 + 520 / 1000.0))
    tops = [meas((wide, wide, 0.0, wide)), meas((wide, wide, 0.0, 0.0))]
    assert [expected_work(m) / expected_work(base) for m in tops] == pytest.approx([1.5, 2.0])
    # a gap between the sharp and the blurred threshold: either reading, two runs; not for blurred faces
    thin = 0.5 * (NO_SIDE_FACE_GAP_PX_SHARP + NO_SIDE_FACE_GAP_PX)
    assert expected_work(meas((thin, wide, wide, wide))) == pytest.approx(2.0 * expected_work(base))
    assert expected_work(meas((thin, wide, wide, wide), sharp=False)) == pytest.approx(
        2.0 * expected_work(meas((wide, wide, wide, wide), sharp=False)))  # there it is a contour side
    assert expected_work(meas((wide, wide, wide, wide), n=(300, 300, 150, 150))) > expected_work(base)


MITSUBA_DARK_TURNED = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_7070_s3_2.png"
"""A 94×177 crop, from (909, 559), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout
7070`, scene 3, cube 2): a dark grey cube (albedo 0.06) 2.36 cm across, turned 18.6° from facing the
mirror axis, its left side face merged with its front face (13 px wide) in the outline."""
DARK_TURNED_CROP = (MITSUBA_DARK_TURNED, (94, 177), 4202.017, (1023.5 - 909, 767.5 - 559), (0.0, -0.01612, 0.57268),
                    0.0849, 0.48976)  # `_crop_cube`'s arguments
DARK_TURNED_CENTRE = (-0.12547, 0.04315, 0.64047)  # the true cube's centre


def test_the_depth_sigma_of_a_merged_turned_face_covers_the_turns_that_fit_as_well():
    """The turn of a face whose side face merges with it shows only in the outline's kinks. This
    cube's fit settles 32 % off, and its turn profile, each turn's face placed from offsets near 0
    where the trust region starts tiny, left the turn that fits twice as well unplaced: the depth was
    reported at ±1.5 %, 21 σ off. The σ must cover the depth (within 3 σ) and stay a bound worth having
    (under half the depth). The camera is the render's, its principal point moved to the crop's."""
    found, mirror = _crop_cube(*DARK_TURNED_CROP)
    depth = float(mirror.distance_to_axis(np.array([DARK_TURNED_CENTRE]))[0])
    assert abs(found.depth - depth) < 3.0 * found.depth_std
    assert found.depth_std < 0.5 * depth


MITSUBA_GREY_NARROW = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_3030_s3_4.png"
"""A 62×134 crop, from (1246, 612), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 3030`,
scene 3, cube 4): a grey cube (albedo 0.45) 3.71 cm across, 1.27 m from the mirror axis, turned 9.7° from
facing it. Its front face is 9 px wide, and a side face 1.8 px wide, at 0.85 of the front face's brightness,
merges with it in the outline: both sides are read as the cube's outer contour."""
GREY_NARROW_CROP = (MITSUBA_GREY_NARROW, (62, 134), 3632.247, (1023.5 - 1246, 767.5 - 612), (0.0, 0.03675, 0.84419),
                    0.13559, 0.65461)  # `_crop_cube`'s arguments
GREY_NARROW_CENTRE = (0.88964, 0.00148, 0.90108)  # the true cube's centre


def test_the_turn_profile_walks_past_one_costly_turn():
    """The face above fits about as well at turns 5° to 15° from its fit's (cost 0.264–0.276 against 0.267),
    and along those turns its depth grows by 17–65 %; but at 3° either way a kink of the merged outline
    crossed the edge points and the cost rose 3.2–3.8 times for that one step. The profile
    stopped there, and the depth was reported at ±0.039 m, 29 % off at −9.5 σ. The σ must cover the depth
    (within 3 σ) and stay a bound worth having (under half the depth)."""
    found, mirror = _crop_cube(*GREY_NARROW_CROP)
    depth = float(mirror.distance_to_axis(np.array([GREY_NARROW_CENTRE]))[0])
    assert abs(found.depth - depth) < 3.0 * found.depth_std
    assert found.depth_std < 0.5 * depth


MITSUBA_GREY_NARROW_JPEG = MITSUBA_GREY_NARROW.with_name("mitsuba_grey_3030_s3_4_jpeg.png")
"""The same crop of the same render after JPEG compression (`python -m bench.holdout 3030 --jpeg`, quality 90),
decoded and stored losslessly."""


def test_the_sigma_covers_a_narrow_face_whose_top_and_bottom_ends_are_each_read_off():
    """The JPEG face above: the slopes of its 9 px top and bottom sides fix the turn, and so the depth. As
    fitted, its bottom side's right end lies 0.25 px below the truth's and its left end 0.24 px above, a tilt
    that no common offset of the side models. The σ takes each side as tilted about its middle too
    (`SIDE_TILT_SHARE`). Before, the face was read 30 % near at ±0.045 m, −8.5 σ (now ±0.27 m, −1.4 σ). The
    σ must cover the depth within 3 σ and stay under half of it."""
    found, mirror = _crop_cube(MITSUBA_GREY_NARROW_JPEG, *GREY_NARROW_CROP[1:], compressed=True)
    depth = float(mirror.distance_to_axis(np.array([GREY_NARROW_CENTRE]))[0])
    assert abs(found.depth - depth) < 3.0 * found.depth_std
    assert found.depth_std < 0.5 * depth


MITSUBA_CYAN_TOPPED = Path(__file__).resolve().parents[1] / "data" / "mitsuba_cyan_floor2_s0_0.png"
"""A 52×112 crop, from (286, 320), of a Mitsuba 3 render (16 spp; the lighting bench's floor scenes under
the second suns, `python -m bench lighting`, scene 0, cube 0): a cyan cube 4.45 cm across, 1.03 m from the
mirror axis, facing it, its front face 9 px wide under a top face 3.2 px tall merged with it in the
outline."""
CYAN_TOPPED_CROP = (MITSUBA_CYAN_TOPPED, (52, 112), 1657.587, (511.5 - 286, 383.5 - 320), (0.0, 0.03795, 0.48878),
                    0.11248, 0.54133)  # `_crop_cube`'s arguments
CYAN_TOPPED_CENTRE = (-0.81779, -0.05754, 0.62544)  # the true cube's centre


def test_the_sigma_covers_the_other_reading_of_a_top_face_that_fits_the_edges_nearly_as_well():
    """The face above read with its top face merged and read without fit the edges at 0.109 and 0.110 px
    rms, the second's centre 21 % farther. The merged reading is kept (the silhouette agrees), 16.8 % off;
    its σ alone put it at −2.7 σ. Weighted by the odds of the two fits, the σ must cover the depth within
    2 σ and stay a bound worth having (under half the depth)."""
    found, mirror = _crop_cube(*CYAN_TOPPED_CROP)
    depth = float(mirror.distance_to_axis(np.array([CYAN_TOPPED_CENTRE]))[0])
    assert abs(found.depth - depth) < 2.0 * found.depth_std
    assert found.depth_std < 0.5 * depth


def test_a_face_fitted_both_ways_gets_the_complete_sigma_of_the_reading_kept(rig):
    """A thin gap is fitted both ways and one reading kept (`estimate_face`); the σ's turn profiles run
    for that one alone (`_exact(..., defer=True)`). The estimate and its σ must be those `_exact` gives
    that reading on its own, and never under its first-order σ. (Where the profiles widen the σ, the
    Mitsuba crop of `test_the_depth_sigma_of_a_merged_turned_face_covers_the_turns_that_fit_as_well`,
    a thin gap too, fails when the first-order σ is kept.)"""
    from depth.estimate import _ddar, _exact, _prepare
    cube = rig.cube(0.5, 5.0, yaw_deg=15.0)
    merged = rig.measure(cube, merged=True)
    k = int(np.argmax(rig.measure(cube, gaps=True).side_gaps_px))
    gaps = [0.0, 0.0]
    gaps[k] = 0.4
    meas = dataclasses.replace(merged, side_gaps_px=tuple(gaps), no_side_face_gap_px=NO_SIDE_FACE_GAP_PX_SHARP)
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    contour = dataclasses.replace(meas, no_side_face_gap_px=NO_SIDE_FACE_GAP_PX)
    local, kap = _prepare(rig.rays, contour, "exact", 0)
    alone = _exact(rig.rays, contour, _ddar(local, kap, None), local, None, rig.mirror.axis)
    first, complete = _exact(rig.rays, contour, _ddar(local, kap, None), local, None, rig.mirror.axis, defer=True)
    assert np.allclose(est.center, alone.center, rtol=0, atol=1e-12)
    assert est.std == alone.std == complete().std
    assert np.allclose(first.center, est.center, rtol=0, atol=1e-12)
    assert all(first.std[key] <= est.std[key] for key in ("z", "size", "center"))


MITSUBA_JPEG_HORIZON = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_8080_s3_4_jpeg.png"
"""A 66×155 crop, from (1193, 791), of a Mitsuba 3 render (16 spp) put through the reconstruct bench's JPEG
coder (OpenCV, quality 90; the holdout `python -m bench.holdout 8080 --jpeg`, scene 3, cube 4): a dark grey
cube 5.53 cm across, upright, crossing the horizon, whose left side's edge points jump about 2 px where
the horizon crosses it."""


def _numpy_runs_avx512() -> bool:
    """Whether numpy dispatches its AVX-512 (x86-64-v4) kernels here (not switched off by
    NPY_DISABLE_CPU_FEATURES); True where it cannot tell."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:
        try:
            from numpy.core._multiarray_umath import __cpu_features__ as features
        except ImportError:
            return True
    return bool(features.get("X86_V4", features.get("AVX512_SKX", False)))


def test_the_sigma_of_a_tilt_that_still_misfits_covers_the_upright_reading():
    """No upright face explains this cube's edges (0.65 px rms: its left side's jump) and a face tilted
    38° with its top face merged fits them at 0.28 px, past the upright limit too. The tilted reading is
    59 % off and its first-order σ said ±3.4 cm in depth (17.6 σ off). Where neither reading explains the
    edges, the σ must cover the depth (within 3 σ). The camera is the render's, its principal point moved
    to the crop's.

    The tilted reading lies past a saddle: stage 2's finishing solve starts from a pose tilted about 1°
    (0.585 px) and, with numpy's AVX2 code paths, slides to the 38° tilt; with its AVX-512 ones (an AMD
    EPYC here; every other cube of the reconstruct bench's clean, noise and JPEG images within 0.01 % of
    its AVX2 result) the last digits of the same solve keep it at 0.584 px, and the cube, grey, is then
    refused as an outline no square face explains (past `SHADOW_MISFIT_PX`). Either is a reading the
    method allows: where numpy runs its AVX-512 kernels that refusal is taken, elsewhere the one cube must
    be found; a cube reported must lie within 3 σ."""
    import cv2

    from depth.reconstruct import SHADOW_MISFIT_REASON, reconstruct
    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror

    image = cv2.cvtColor(cv2.imread(str(MITSUBA_JPEG_HORIZON)), cv2.COLOR_BGR2RGB)
    pitch = 0.0021745963572879184
    rotation = [[1.0, 0.0, 0.0], [0.0, -np.sqrt(1.0 - pitch ** 2), pitch], [0.0, -pitch, -np.sqrt(1.0 - pitch ** 2)]]
    camera = PinholeCamera((66, 155), [[2360.471, 0.0, 1023.5 - 1193], [0.0, 2360.471, 767.5 - 791], [0.0, 0.0, 1.0]],
                           rotation, (0.0, 0.00103, 0.47365))
    mirror = CylinderMirror(0.1134, 0.52049, (0, 0, 0), (0, 1, 0))
    rec = reconstruct(image, camera, mirror, compressed=True, workers=1)
    if _numpy_runs_avx512() and rec.refused:
        assert not rec.cubes and len(rec.refused) == 1, (rec.cubes, rec.refused)
        assert rec.refused[0].reason.startswith(SHADOW_MISFIT_REASON), rec.refused[0].reason
        return
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    (found,) = rec.cubes
    depth = float(mirror.distance_to_axis(np.array([[0.57058, -0.05473, 0.83237]]))[0])
    assert abs(found.depth - depth) < 3.0 * found.depth_std


MITSUBA_GREY_TILTED_JPEG = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_6060_s7_1_jpeg.png"
"""A 96×176 crop, from (696, 760), of a Mitsuba 3 render (16 spp) put through the reconstruct bench's JPEG
coder (the holdout `python -m bench.holdout 6060 --jpeg`, scene 7, cube 1), on its 8×8 block grid: a grey
cube 5.15 cm across turned 11.5° from the mirror axis, upright, its front face 25 px wide."""


def test_a_tilt_kept_is_no_surer_than_the_upright_reading_it_replaced(monkeypatch):
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's.
    No upright face explains the edges (0.37 px rms) and stage 2 tilts the face 10.3°, fitting them at
    0.17 px, under the upright limit; the tilt followed a bias of the edges, not the pose (the cube is
    upright, and the upright reading is as far off). With its σ read at the misfit the tilt left, the cube
    was 13.7 % off at +7.1 σ in depth, while the upright reading's σ was 2.3 times as wide. Each σ of the
    tilted reading is at least the upright one's (that reading found by `exact` with stage 2 turned off),
    and the depth lies within 3.5 σ."""
    import depth.estimate
    from depth.reconstruct import reconstruct

    image, camera, mirror = _crop_setup(MITSUBA_GREY_TILTED_JPEG, (96, 176), 2454.543, (639.5 - 696, 479.5 - 760),
                                        (0.0, -0.02229, 0.94329), 0.1354, 0.69512)
    readings = []
    for upright_limit in (depth.estimate.UPRIGHT_MISFIT_PX, np.inf):
        monkeypatch.setattr(depth.estimate, "UPRIGHT_MISFIT_PX", upright_limit)
        rec = reconstruct(image, camera, mirror, compressed=True, workers=1)
        assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
        readings.append(rec.cubes[0])
    tilted, upright = readings
    assert abs(tilted.estimate.normal[1]) > np.sin(np.deg2rad(5.0))  # the tilt is kept
    assert upright.estimate.normal[1] == pytest.approx(0.0, abs=1e-9)
    for key in ("z", "size", "center"):
        assert tilted.estimate.std[key] >= upright.estimate.std[key] * (1 - 1e-9), key
    true_depth = float(mirror.distance_to_axis(np.array([[0.19693, -0.16089, 0.40524]]))[0])
    assert abs(tilted.depth - true_depth) < 3.5 * tilted.depth_std


@pytest.mark.parametrize("roll", [5.0, 10.0, -20.0])
def test_a_face_truly_turned_in_its_plane_keeps_the_sigma_of_its_own_fit(rig, roll):
    """A cube rolled about its front face's normal, its edges read with 0.05 px of scatter: no upright pose
    explains them (over `MAX_EDGE_MISFIT_PX`: 1.2 px at 5°), so the upright reading is no candidate, and
    the tilted reading's σ stays its own: within 1.5 times the σ of the same cube unrolled, and the centre
    within 3 σ. (Widened to the upright fit's σ, its depth σ was 36–83 times as wide.)"""
    readings = []
    for angle in (roll, 0.0):
        cube = rig.cube(0.5, 10.0, roll_deg=angle)
        est = estimate_face(rig.rays, rig.measure(cube, noise_px=0.05, seed=0, gaps=True), method="exact",
                            up=rig.mirror.axis)
        assert est, est.reason
        readings.append((cube, est))
    (cube, rolled), (_, unrolled) = readings
    assert np.linalg.norm(rolled.center - cube.center) < 3.0 * rolled.std["center"]
    for key in ("z", "size", "center"):
        assert rolled.std[key] < 1.5 * unrolled.std[key], key


MITSUBA_GREY_HORIZON = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_8080_s1_3.png"
"""An 89×155 crop, from (597, 725), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 8080`,
scene 1, cube 3): a light grey cube 2.8 cm across standing across the horizon, whose left side against
the sky is a faint step (`tests/depth/test_measure.py`)."""
GREY_HORIZON_CROP = (MITSUBA_GREY_HORIZON, (89, 155), 4019.265, (799.5 - 597, 599.5 - 725), (0.0, -0.00784, 0.81501),
                     0.11706, 0.54213)  # `_crop_cube`'s arguments
GREY_HORIZON_CENTRE = (-0.44462, -0.07036, 0.84367)  # the true cube's centre


def test_a_light_grey_cube_whose_side_against_the_sky_is_faint_is_reconstructed_within_its_sigma():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the
    crop's: the cube, missed before its faint side was traced, is found, and its depth lies within 3 σ
    (its 3 px side face merged with the front face leaves the turn loose: 34 % off at ±25 %)."""
    found, mirror = _crop_cube(*GREY_HORIZON_CROP)
    assert np.allclose(np.mean(found.corners_px, axis=0), [44.7, 77.7], atol=3.0)
    depth = float(mirror.distance_to_axis(np.array([GREY_HORIZON_CENTRE]))[0])
    assert abs(found.depth - depth) < 3.0 * found.depth_std


_TURN_FROM_CORNERS = ("open: sampled from 2 px of the corners the top and bottom sides put these cubes 32 and 34 % off; "
                      "from 1 px they came within 4.8 and 7.0 %, but the reconstruct bench lost 2 of 326 cubes and "
                      "put 84 of its `exact` estimates further off against 73 nearer (bench/README, sixty-seventh session)")


@pytest.mark.parametrize("crop, centre", [
    pytest.param(DARK_TURNED_CROP, DARK_TURNED_CENTRE, id="7070-s3-2"),
    pytest.param(GREY_HORIZON_CROP, GREY_HORIZON_CENTRE, id="8080-s1-3",
                 marks=pytest.mark.xfail(strict=True, reason=_TURN_FROM_CORNERS)),
])
def test_a_turned_face_merged_with_its_side_face_reads_its_turn_from_the_ends_of_its_top_and_bottom(crop, centre):
    """Faces 9–13 px wide, turned 19–20°, their side faces merged with them in the outline: the left and
    right sides are the cube's outer contour, and the turn shows in the top and bottom sides, whose slopes
    their ends fix best: with the exact top and bottom edges over the measured points' columns the estimates
    stay 15 and 11 % off, over the faces' whole widths within 1 %. Sampled from 2 px of the corners, the
    measured sides put these cubes 32 and 34 % off (within their σ of 28 and 38 %). A cube should come
    within 10 % of its centre and 2 σ of its depth. 7070 s3/2 does since the seventieth session: its turn
    profile, which had stopped at a single costly turn, walks on to a turn that fits better (4.0 % off)."""
    found, mirror = _crop_cube(*crop)
    centre = np.asarray(centre)
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found.estimate.center - centre) < 0.10 * depth
    assert abs(found.depth - depth) < 2.0 * found.depth_std


OURS_STRIP_CROP = (Path(__file__).resolve().parents[1] / "data" / "ours_s08_1_strip.png", (72, 96), 1603.71,
                   (511.5 - 604, 383.5 - 372), (0.0, -0.00396, 0.42689), 0.08436, 0.40131)  # `_crop_cube`'s arguments
OURS_STRIP_CENTRE = (0.47948, -0.01773, 0.56782)  # the true cube's centre


def test_a_one_pixel_strip_that_both_readings_fit_leaves_the_depth_within_its_sigma():
    """A 72 × 96 crop of the reconstruct bench's s08 (our renderer, clean): a face 7 px wide whose side face, 0.17
    px wide, darkens the column at its edge by 3 %. Read as a strip (a side face 0.91 px wide), a cube fits it
    turned to show that face, 44.6 % off; read as a pixel mixing the face and the outside, one fits 2.8 % off. The
    pixel cannot tell them apart: the strip's reading stands with a σ covering the other's (which lies beyond 2 σ of
    it), so that the depth lies within 2 σ of the truth (at 2.5 σ with the strip's own σ alone)."""
    found, mirror = _crop_cube(*OURS_STRIP_CROP)
    depth = float(mirror.distance_to_axis(np.array([OURS_STRIP_CENTRE]))[0])
    assert abs(found.depth - depth) < 2.0 * found.depth_std


MITSUBA_YELLOW_TOP_STRIP = Path(__file__).resolve().parents[1] / "data" / "mitsuba_yellow_5050_s2_1.png"
"""A 64×96 crop, from (797, 530), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 5050`,
scene 2, cube 1): a yellow cube 3.1 cm across, 0.77 m from the mirror axis, its front face 9 px wide and
52 px tall under its top face, a lighter strip 1–2 px tall, before a bright sky."""


def test_a_narrow_face_under_a_thin_top_face_is_reconstructed_within_its_sigma():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the
    crop's. The top side's edge points, read across the thin top face, leaned its line pass after pass
    until its profiles lost the edge, and the cube was refused ("top side: 1 edge points with contrast");
    its top side following the slope of its bottom side's fit, the face is outlined and the cube found
    where it is, its depth and size within 2 σ."""
    found, mirror = _crop_cube(MITSUBA_YELLOW_TOP_STRIP, (64, 96), 1610.314, (639.5 - 797, 479.5 - 530),
                               (0.0, -0.00434, 0.37382), 0.08513, 0.45909)
    assert np.allclose(np.mean(found.corners_px, axis=0), [32.3, 47.7], atol=1.0)  # the truth's, in the crop
    depth = float(mirror.distance_to_axis(np.array([[0.60255, -0.05216, 0.47486]]))[0])
    assert abs(found.depth - depth) < 2.0 * found.depth_std
    assert abs(found.estimate.size - 0.031) < 2.0 * found.estimate.std["size"]


MITSUBA_GREY_FLOOR_SIDE = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_4040_s1_4.png"
"""An 80×152 crop, from (488, 728), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 4040`,
scene 1, cube 4): a grey cube 2.52 cm across turned 21.4° from the mirror axis, its front face 11 px wide before
a bright sky, its right side face 4.5 px wide and as dark as the floor it runs into below the horizon."""


def test_a_grey_cube_whose_narrow_side_face_runs_into_the_floor_is_reconstructed_within_its_sigma():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's.
    The floor flooded the middle of the side face, a strip 1–2 px wide between its edges' bands, and the blob
    was the front face alone: read with no face beside it, `exact` turned the cube the other way, 1.35 m
    from the axis instead of 0.55 m (145 % off, at +2.2 σ). The side face is in the blob, its outer edge read
    as the cube's back vertical edge, and the cube comes out within 4 % of its centre and within 2 σ of its
    depth and size, turned within 5° of its true turn."""
    found, mirror = _crop_cube(MITSUBA_GREY_FLOOR_SIDE, (80, 152), 2995.164, (799.5 - 488, 599.5 - 728),
                               (0.0, -0.02259, 0.44299), 0.078, 0.45765)
    assert np.allclose(np.mean(found.corners_px, axis=0), [37.9, 76.6], atol=1.0)  # the truth's, in the crop
    centre = np.array([-0.43667, -0.03728, 0.33965])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found.estimate.center - centre) < 0.04 * depth
    assert abs(found.depth - depth) < 2.0 * found.depth_std
    assert abs(found.estimate.size - 0.0252) < 2.0 * found.estimate.std["size"]
    normal = np.array([-0.43022, -0.03728, 0.32882]) - centre  # the truth's front-face centre, from the centre
    normal /= np.linalg.norm(normal)
    assert np.degrees(np.arccos(np.clip(found.estimate.normal @ normal, -1.0, 1.0))) < 5.0


MITSUBA_GREY_SKY_SIDE = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_6060_s7_1.png"
"""A 96×168 crop, from (696, 764), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 6060`,
scene 7, cube 1): a grey cube 5.15 cm across turned 11.5° from the mirror axis under a blue sky, its left
side face (6.9 px wide by the cube's geometry) lit as brightly as the sky beyond it and told from it by
its colour only, so that the cube's blob leaves it out (`tests/depth/test_measure.py`)."""


def test_a_grey_cube_whose_side_face_is_lit_like_the_sky_is_reconstructed_within_its_sigma():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's.
    Read with no face beside its left side, `exact` turned the cube to hide one and then tilted it 10°:
    13.8 % off at +5.1 σ. The side face is read beyond the left side, and the cube comes out upright
    within 2 % of its centre and within 2 σ of its depth."""
    found, mirror = _crop_cube(MITSUBA_GREY_SKY_SIDE, (96, 168), 2454.543, (639.5 - 696, 479.5 - 764), (0.0, -0.02229, 0.94329), 0.1354, 0.69512)
    centre = np.array([0.19693, -0.16089, 0.40524])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found.estimate.center - centre) < 0.02 * depth
    assert abs(found.depth - depth) < 2.0 * found.depth_std
    assert abs(found.estimate.normal[1]) < np.sin(np.deg2rad(1.0))  # upright


MITSUBA_BLACK_S5 = Path(__file__).resolve().parents[1] / "data" / "mitsuba_black_1515_s5_2.png"
"""A 96×224 crop, from (512, 496), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 1515`, scene 5,
cube 2): a black cube 45.7 mm across turned 13.3° from the mirror axis, its left side face (5.4 px wide by the cube's
geometry) merged with its front face into one outline whose bottom-left corner lies 22 px below the side face's back
bottom vertex."""


def test_a_merged_outline_s_contour_reading_that_still_fits_weighs_in_the_sigma():
    """The contour reading misfits the edge points within 2 px by 0.17 px (the points past the outline's kink), the
    square-on reading (the side read as the front face's own edge, `depth.estimate._background_sides`) by 0.105 px,
    and that one stands, 20 % off. The odds of the two fits, the points taken for independent, made it sure of
    itself: −14.8 σ. Since the ninety-ninth session a contour reading that fits within `EDGE_MISFIT_WARN_PX` weighs
    at least evenly in the σ: the depth lies within 3 σ."""
    from depth.estimate import EDGE_MISFIT_WARN_PX

    found, mirror = _crop_cube(MITSUBA_BLACK_S5, (96, 224), 2130.316, (511.5 - 512, 383.5 - 496),
                               (0.0, 0.00971, 0.55132), 0.07966, 0.36132)
    centre = np.array([0.07946, -0.07678, 0.302])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert found.estimate.rms_residual < EDGE_MISFIT_WARN_PX  # reported unflagged
    assert abs(found.depth - depth) < 3.0 * found.depth_std, (found.depth, found.depth_std, depth)


def test_a_real_faint_side_face_whose_reading_fits_better_keeps_its_sigma():
    """The crop of holdout 6060 s7/1 (`MITSUBA_GREY_SKY_SIDE`): the face read without its faint side face misfits the
    edges more than the face read with it, so the σ does not cover that reading (`depth.reconstruct`,
    `faintless_reading`); covered, it would be 4 times as wide (6.8 % of the depth)."""
    found, mirror = _crop_cube(MITSUBA_GREY_SKY_SIDE, (96, 168), 2454.543, (639.5 - 696, 479.5 - 764),
                               (0.0, -0.02229, 0.94329), 0.1354, 0.69512)
    depth = float(mirror.distance_to_axis(np.array([[0.19693, -0.16089, 0.40524]]))[0])
    assert found.depth_std < 0.03 * depth


MITSUBA_GREY_FALSE_FAINT = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_1212_s0_3_jpeg.png"
"""A 56×136 crop, from (352, 360), of a Mitsuba 3 render (16 spp) put through the reconstruct bench's JPEG coder
(OpenCV, quality 90; the holdout `python -m bench.holdout 1212 --grey --jpeg`, scene 0, cube 3), on its 8×8 block
grid: a light grey cube 49.4 mm across, its front face 12 px wide, facing the mirror axis, its side faces under 0.3 px
wide, before a background shading off to its right. The look for a faint side face reads one 6.4 px wide there."""


def test_a_faint_side_face_the_edges_do_not_prefer_leaves_the_sigma_covering_the_face_without_it():
    """Read with that side face, the cube is turned to show it: 27.9 % off at −14.6 σ, misfit 0.163 px. Read without
    it, 3.7 % off, misfit 0.152 px: the edges prefer that reading, so the σ covers it as an even mixture (ninety-ninth
    session), and the depth lies within 3 σ."""
    found, mirror = _crop_cube(MITSUBA_GREY_FALSE_FAINT, (56, 136), 1933.867, (511.5 - 352, 383.5 - 360),
                               (0.0, -0.01999, 0.60408), 0.09641, 0.55635, compressed=True)
    depth = float(mirror.distance_to_axis(np.array([[-0.48463, -0.00991, 0.50914]]))[0])
    assert abs(found.depth - depth) < 3.0 * found.depth_std, (found.depth, found.depth_std, depth)


MITSUBA_GREY_JPEG_TURNED = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_6060_s1_4_jpeg.png"
"""A 96×192 crop, from (736, 784), of a Mitsuba 3 render (16 spp) put through the reconstruct bench's JPEG
coder (OpenCV, quality 90; the holdout `python -m bench.holdout 6060 --jpeg`, scene 1, cube 4), on its 8×8
block grid: a grey cube 3.38 cm across turned 16° from the mirror axis, its side face (5 px wide) lit like
its front face and merged with it in the outline."""


def test_a_jpeg_grey_cube_with_a_merged_side_face_is_read_turned():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's.
    `exact`'s starts all slid to a turn of −2°, where one left edge point 2 px below the measured corner
    lay above the placed front face and was measured against the merged face beyond the right side, 21 px
    off; the turn profile, its placements short, stopped 4° out, and the face was read upright and tilted:
    40 % off at −14.6 σ (in 3 of 5 crops of the cube; in the others the starts' basin fell the other way,
    1.77 % off). The cube comes out turned as it is (within 3°), within 3 % of its centre and within 2 σ of
    its depth."""
    found, mirror = _crop_cube(MITSUBA_GREY_JPEG_TURNED, (96, 192), 2862.498, (799.5 - 736, 599.5 - 784),
                               (0.0, -2e-05, 0.40053), 0.08022, 0.39343, compressed=True)
    centre = np.array([-0.03504, -0.08827, 0.67269])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found.estimate.center - centre) < 0.03 * depth
    assert abs(found.depth - depth) < 2.0 * found.depth_std
    normal = np.array([-0.2755585, 0.0, -0.9612843])  # the cube's front face, turned 16.0° (195.9953° about y)
    assert np.degrees(np.arccos(min(abs(found.estimate.normal @ normal), 1.0))) < 3.0


MITSUBA_BLACK_JPEG_TOP = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_6060_s6_2_jpeg.png"
"""A 224×560 crop, from (1304, 976), of a Mitsuba 3 render (16 spp) put through the reconstruct bench's JPEG
coder (the holdout `python -m bench.holdout 6060 --grey --jpeg`, scene 6, cube 2), on its 8×8 block grid: a
black cube 7.95 cm across facing the mirror axis, under a blue sky, its top face 0.037 brighter
in sRGB value than its front face across a step JPEG spread over 4–5 px."""


def test_a_jpeg_black_cube_whose_top_face_step_is_smeared_is_read_without_its_top_face():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's.
    The smeared step left no pixel steep enough to stop the front face's flat region, which ran on into
    the top face: the face read as tall as both, its top side on the top face's far edge, fitted a cube
    8.96 cm across 3 cm too far, to 0.09 px, 9.5 % off at +17.7 σ (+32.7 σ in the whole image). The cube
    comes out within 1 % of its centre, within 2 σ of its depth and within 1 % of its size."""
    found, mirror = _crop_cube(MITSUBA_BLACK_JPEG_TOP, (224, 560), 4179.281, (1023.5 - 1304, 767.5 - 976),
                               (0.0, 0.01971, 0.63587), 0.11266, 0.66899, compressed=True)
    centre = np.array([0.23276, -0.09017, 0.21879])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found.estimate.center - centre) < 0.01 * depth
    assert abs(found.depth - depth) < 2.0 * found.depth_std
    assert abs(found.estimate.size - 0.0795) < 0.01 * 0.0795


FLOOR_SHADOW_CROPS = [
    (Path(__file__).resolve().parents[1] / "data" / "mitsuba_floor_shadow_6060_s6.png", (80, 96), 4179.281,
     (1023.5 - 1070, 767.5 - 1424), (0.0, 0.01971, 0.63587), 0.11266, 0.66899),
    (Path(__file__).resolve().parents[1] / "data" / "mitsuba_floor_shadow_5050_s5.png", (32, 64), 2465.648,
     (511.5 - 598, 383.5 - 628), (0.0, 0.01266, 0.89365), 0.13304, 0.67193),
]
"""Crops of two Mitsuba 3 renders (16 spp) of unseen holdout scenes on a floor (`python -m bench.holdout 6060`,
scene 6, an 80×96 crop from (1070, 1424); `... 5050`, scene 5, a 32×64 crop from (598, 628)): the shadow a
cube casts on the grey floor, a dark quadrilateral 8–9 px wide and 23–25 px tall, seen in the mirror, with
nothing else. Each was read as a grey cube (2.8 and 6.3 mm across, edge misfit 0.41 and 0.21 px, its top
face merged into the quadrilateral)."""


@pytest.mark.parametrize("crop", FLOOR_SHADOW_CROPS, ids=["6060_s6", "5050_s5"])
def test_a_floor_shadow_read_as_a_grey_cube_with_its_top_face_merged_is_refused_as_one_flat_region(crop):
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's:
    no cube, and the quadrilateral refused because the top face its reading merges shows the front face's
    brightness (`_flat_region_reason`)."""
    from depth.reconstruct import FLAT_REGION_REASON, reconstruct

    image, camera, mirror = _crop_setup(*crop)
    rec = reconstruct(image, camera, mirror, workers=1)
    assert rec.cubes == []
    assert [r.reason.startswith(FLAT_REGION_REASON) for r in rec.refused] == [True]


MITSUBA_GREY_NOISY = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_3030_s7_4.png"
"""A 220×360 crop, from (420, 440), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 3030`,
scene 7, cube 4): a light grey cube 7.14 cm across, 0.42 m from the mirror axis, turned −15°, its front face
51 × 225 px and 0.04 of sRGB from the floor behind it, the path tracer's noise on it."""


def test_a_noisy_grey_face_whose_edges_scatter_as_far_as_it_misfits_is_not_taken_for_a_shadow():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's. The
    face's sides scatter 0.44–0.47 px from their own fits, and no square fits them better: its readings misfit by
    0.47–0.60 px and were all refused as shadows (over 0.45 px). The limit is at least 1.1 times the edges'
    scatter (`SHADOW_MISFIT_SCATTER`): the cube comes out within 5 % of its centre and within 2 σ of its depth."""
    found, mirror = _crop_cube(MITSUBA_GREY_NOISY, (220, 360), 1823.795, (639.5 - 420, 479.5 - 440),
                               (0.0, 0.04193, 0.38102), 0.0917, 0.42079)
    centre = np.array([-0.16571, -0.069, 0.38363])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found.estimate.center - centre) < 0.05 * depth
    assert abs(found.depth - depth) < 2.0 * found.depth_std


MITSUBA_GREY_NECK_CROP = (Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_9090_s3_0.png", (250, 560),
                          4277.687, (1023.5 - 880, 767.5 - 700), (0.0, 0.02081, 0.65588), 0.10052, 0.5596)
"""A 250×560 crop, from (880, 700), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 9090`,
scene 3): a white cube 2.62 cm across, 0.77 m from the mirror axis, turned −20°, its front face 12 × 95 px as
bright as the floor behind it and its side face a grey strip 4–6 px wide; above it, another white cube across the
horizon."""


def test_a_grey_side_face_found_alone_and_narrowing_to_a_neck_is_grown_across_faint_edges():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's. The
    side face is the only part of the small cube found, and the path tracer's noise leaves its strip a pixel wide
    in two of its rows: it narrows to a neck, which is taken for two touching cubes (`NECK_REASON`), and the cube was
    refused for it. Grown across faint edges as a grey detection refused for no reason is (`faint_regrowth`), its
    front face is read: 16 % off, at +1.2 σ (a top face as white as the front face merged above it)."""
    from depth.measure import NECK_REASON, detect_cubes
    from depth.reconstruct import reconstruct
    from raytrace.truth import mirror_mask

    image, camera, mirror = _crop_setup(*MITSUBA_GREY_NECK_CROP)
    assert any(d.reason == NECK_REASON and 100 < d.bbox[0] < 113 and d.bbox[1] < 458 < d.bbox[3]
               for d in detect_cubes(image / 255.0, mirror_mask(camera, mirror)))  # the side face, left of the front
    rec = reconstruct(image, camera, mirror, workers=1)
    found = [c for c in rec.cubes if c.bbox[0] < 113 < c.bbox[2] and c.bbox[1] < 458 < c.bbox[3]]
    assert len(found) == 1, [r.reason for r in rec.refused]
    centre = np.array([-0.06624, -0.1296, 0.77202])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found[0].estimate.center - centre) < 0.2 * depth
    assert abs(found[0].depth - depth) < 2.0 * found[0].depth_std


MITSUBA_GREY_TWO_PARTS_CROP = (Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_4040_s1_0.png",
                               (150, 300), 2995.164, (799.5 - 1000, 599.5 - 430), (0.0, -0.02259, 0.44299), 0.078,
                               0.45765)
"""A 150×300 crop, from (1000, 430), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 4040`, scene
1): a light grey cube 4.59 cm across, 0.31 m from the mirror axis, turned 20°, its front face 44 × 233 px before a
sky shading from cream to olive, as bright as the sky on its right; its side face a light strip 5 px wide and its
bottom face a dark one 12 px tall."""


@pytest.mark.parametrize("blue_red", [False, True])
def test_a_grey_cube_found_as_two_of_its_faces_is_grown_into_one_cube(monkeypatch, blue_red):
    """The whole pipeline on the crop. Where the grey search traces brightness edges alone (as in a JPEG image,
    `_enclosed`'s `blue_red` off), the cube is found as two blobs: its side face (9 × 42 px) and its bottom face
    (42 × 12 px). Grown across faint edges, each took in the other's blob and was refused for touching it, but
    for a reading of the side face that filled only the upper 155–170 px of the front face (4.4 px misfit): the
    cube was refused. A grown blob may now take in a grey blob within its bounds (`GROWN_PART_MARGIN_PX`), and of
    the two readings of the face one is kept (`_one_per_face`): the cube within 1 % of its centre and 2 σ of its
    depth. With the edges of blue − red as well (this uncompressed image's own reading), the search finds the
    whole cube as one blob, and a second reading of its face, grown from another blob, is refused so too."""
    from depth import measure
    from depth.reconstruct import SAME_FACE_REASON, reconstruct

    if not blue_red:
        enclosed = measure._enclosed
        monkeypatch.setattr(measure, "_enclosed", lambda *a, **k: enclosed(*a, **{**k, "blue_red": False}))
    image, camera, mirror = _crop_setup(*MITSUBA_GREY_TWO_PARTS_CROP)
    rec = reconstruct(image, camera, mirror, workers=1)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    found = rec.cubes[0]
    centre = np.array([0.24328, 0.01175, 0.19837])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(found.estimate.center - centre) < 0.01 * depth
    assert abs(found.depth - depth) < 2.0 * found.depth_std
    assert [r for r in rec.refused if r.reason.startswith(SAME_FACE_REASON)] != []


MITSUBA_WHITE_ACROSS_HORIZON_CROP = (Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_4040_s2_0.png",
                                     (120, 260), 2635.035, (639.5 - 680, 479.5 - 400), (0.0, 0.02224, 0.50541),
                                     0.08413, 0.46011)
"""A 120×260 crop, from (680, 400), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 4040 --grey`,
scene 2, cube 0): a white cube 5.85 cm across, 0.77 m from the mirror axis, its front face 20 × 142 px standing
across the horizon, 11 levels of 255 darker than the floor in every channel (under the strong step the edges are
traced at) and bluer than the cream sky above it."""


def test_a_white_face_across_the_horizon_is_enclosed_by_the_edges_of_blue_minus_red():
    """The whole pipeline on the crop: the cube is found, within 1 % of its centre and 2 σ of its depth. Without
    the edges of blue − red (`_enclosed`'s `blue_red`) the grey search found no blob there at all."""
    from depth.reconstruct import reconstruct

    image, camera, mirror = _crop_setup(*MITSUBA_WHITE_ACROSS_HORIZON_CROP)
    rec = reconstruct(image, camera, mirror, workers=1)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    centre = np.array([0.29425, -0.0463, 0.71129])
    depth = float(mirror.distance_to_axis(centre[None])[0])
    assert np.linalg.norm(rec.cubes[0].estimate.center - centre) < 0.01 * depth
    assert abs(rec.cubes[0].depth - depth) < 2.0 * rec.cubes[0].depth_std


FLOOR_SHADOW_CURVED_CROP = (Path(__file__).resolve().parents[1] / "data" / "mitsuba_floor_shadow_5050_s0.png", (48, 64),
                            1739.842, (511.5 - 350, 383.5 - 495), (0.0, 0.04837, 0.6059), 0.11666, 0.55005)
"""A 48×64 crop, from (350, 495), of a Mitsuba 3 render (16 spp) of an unseen holdout scene on a floor (`python -m
bench.holdout 5050`, scene 0): a cube's shadow on the grey floor, a dark quadrilateral 8 × 25 px whose left and right
sides bow, and part of another shadow cut by the crop's edge. Read as a grey cube 8.7 mm across (edge misfit 0.38
px), it was the one cube that run invented, in PNG and all grey."""


def test_a_floor_shadow_whose_left_and_right_sides_bow_is_refused():
    """The whole pipeline on the crop, the camera the render's with its principal point moved to the crop's: no
    cube. The shadow's left and right sides are the shadows of the cube's upright edges, lines on the floor, which
    the mirror images as curves; `exact`'s upright face misses both smoothly along their length (rms 0.38 and 0.47
    px, Durbin–Watson 0.21 and 0.10), and the region is refused for it (`_curved_sides`)."""
    from depth.reconstruct import SHADOW_MISFIT_REASON, reconstruct

    image, camera, mirror = _crop_setup(*FLOOR_SHADOW_CURVED_CROP)
    rec = reconstruct(image, camera, mirror, workers=1)
    assert rec.cubes == []
    assert [r.reason for r in rec.refused if "both its left and right sides" in r.reason
            and r.reason.startswith(SHADOW_MISFIT_REASON)] != []


@given(st.integers(min_value=3, max_value=400), st.floats(min_value=1e-3, max_value=5.0), st.booleans(),
       st.integers(min_value=0, max_value=2**31 - 1))
@settings(max_examples=40, deadline=None)
def test_side_misfit_counts_rms_and_durbin_watson(n, offset, negative, seed):
    """`_side_misfit` against what each case must give: a common offset misses smoothly (Durbin–Watson 0, the rms
    the offset); signs alternating from point to point, 4 (n − 1) / n; independent Gaussian noise over 20 000 points,
    2 within 0.1 (its expectation 2 (n − 1) / n, its σ about 2 / √n: 7 σ)."""
    from depth.estimate import _side_misfit

    count, rms, dw = _side_misfit(np.full(n, -offset if negative else offset))
    assert count == n and rms == pytest.approx(offset, rel=1e-12) and dw == pytest.approx(0.0, abs=1e-12)
    assert np.isnan(_side_misfit(np.zeros(n))[2]) and np.isnan(_side_misfit(np.ones(2))[2])
    alternating = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    assert _side_misfit(alternating)[2] == pytest.approx(4.0 * (n - 1) / n)
    noise = np.random.default_rng(seed).normal(0.0, 0.3, 20_000)  # its statistic's σ about 2 / √n = 0.014
    assert abs(_side_misfit(noise)[2] - 2.0) < 0.1


@pytest.mark.xfail(strict=True, reason="open: the turn profile's cost dips in a 2° kink, and σ reads that dip (bench/README, "
                                       "forty-ninth session)")
def test_the_sigma_of_a_face_pinned_by_its_merged_faces_kinks_covers_a_stretch_of_edge_read_off(rig):
    """An upright cube whose side faces and top face merge with its front face, seen from above, its left
    side's edge points stepping 1.5 px halfway down (as where a horizon crosses a side). The fit is 3.5 %
    off and its depth σ 0.15 mm: the turn's cost has a dip under 2° wide where the merged faces' kinks
    meet the edge points, 19 likelihood scales deep, so neither the first-order σ nor the turn profile's
    2° steps see beyond it. The σ should cover the depth (within 3 σ)."""
    from raytrace.truth import reflection_pixels
    cube = rig.cube(0.8, -30.0, height=-0.04)
    meas = rig.measure(cube, merged=True, gaps=True)
    _, corners, centre = cube.front_face(rig.mirror)
    outward = (centre - cube.center) / np.linalg.norm(centre - cube.center)
    upper = np.argsort(reflection_pixels(rig.camera, rig.mirror, corners)[0][:, 1])[:2]
    t = np.linspace(0.0, 1.0, 40)[:, None]
    top = reflection_pixels(rig.camera, rig.mirror,
                            corners[upper[0]] * (1 - t) + corners[upper[1]] * t - cube.size * outward)[0]
    left = meas.sides_px[0].copy()
    above = left[:, 1] < np.median(left[:, 1])
    left[above, 0] -= 0.75
    left[~above, 0] += 0.75
    gaps = meas.side_gaps_px
    meas = dataclasses.replace(meas, sides_px=(left, meas.sides_px[1], top, meas.sides_px[3]),
                               side_gaps_px=(gaps[0], gaps[1], 0.0, float("nan")))
    est = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert est, est.reason
    depth = float(rig.mirror.distance_to_axis(est.center[None])[0])
    assert abs(depth - rig.depth(cube)) < 3.0 * est.std["z"]


def _batches_spied(monkeypatch):
    """Spy on `_Lockstep`: the number of rows of each batched evaluation and of each call's pose sets."""
    import depth.estimate as E
    batches = []
    real = E._Lockstep.__init__

    def spying(self, evaluate):
        real(self, lambda x, w: (batches.append(len(x)), evaluate(x, w))[1])
    monkeypatch.setattr(E._Lockstep, "__init__", spying)
    return batches


def _misfit_left_side(meas):
    """The upper half of the left side read 1.5 px out: no upright square explains the edges, so
    `exact` also explores tilted faces from ten starts (its stage 2)."""
    left = meas.sides_px[0].copy()
    left[left[:, 1] < np.median(left[:, 1]), 0] -= 1.5
    return dataclasses.replace(meas, sides_px=(left,) + tuple(meas.sides_px[1:]), edge_bias_px=0.15,
                               edge_noise_px=0.02)


@pytest.mark.parametrize("case", ["merged side face", "distinct side face", "stage 2"])
def test_exact_explores_its_starts_side_by_side_to_the_same_bits_as_one_by_one(rig, monkeypatch, case):
    """`exact` runs its starting poses side by side with their evaluations batched (`_Lockstep`):
    every number of the estimate must be the same bits as with the starts run one after another, on
    noisy edges (placement first where a side face merges into the outline; with a misfit that
    also brings the tilted starts of stage 2)."""
    import pickle

    import depth.estimate as E
    if case == "merged side face":
        meas = rig.measure(rig.cube(0.5, 5.0, yaw_deg=20.0), merged=True, noise_px=0.1, seed=3)
    elif case == "distinct side face":
        meas = rig.measure(rig.cube(0.5, 12.0, yaw_deg=25.0), noise_px=0.1, seed=1)
    else:
        meas = _misfit_left_side(rig.measure(rig.cube(0.6, -20.0), gaps=True))
    batches = _batches_spied(monkeypatch)
    side_by_side = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert side_by_side
    # batched indeed: the first evaluation of each exploration takes every start's pose (7 upright turns)
    assert batches and max(batches) >= 7 * (5 if case == "merged side face" else 6)
    if case == "stage 2":
        assert max(batches) >= 10 * 8  # ten tilted starts, each pose and its 7 neighbours
    n_batched = len(batches)
    monkeypatch.setattr(E, "LOCKSTEP", False)
    one_by_one = estimate_face(rig.rays, meas, method="exact", up=rig.mirror.axis)
    assert max(batches[n_batched:]) <= 8  # with it off, a batch holds one start's poses alone
    assert pickle.dumps(side_by_side) == pickle.dumps(one_by_one)


def test_lockstep_batches_the_waiting_calls_in_order_until_each_ends():
    """Call k asks k + 1 evaluations of k + 1 poses each, at scales of its own: every batch holds, in the
    calls' order, the poses of the calls not yet ended with a row of scales each (one row for all where
    one call is left), and each call gets back its own rows."""
    from depth.estimate import _Lockstep

    batches = []

    def evaluate(x, w):
        batches.append((x[:, 0].copy(), w[:, 0].copy()))
        return x[:, :1] * 10.0 + w[:, :1]

    def call(k):
        def run(ev):
            return [ev(np.full((k + 1, 7), 100.0 * k + step), np.full(3, k / 10.0))[:, 0]
                    for step in range(k + 1)]
        return run

    results = _Lockstep(evaluate).run([call(k) for k in range(3)])
    assert [[list(g) for g in r] for r in results] == [
        [[1000.0 * k + 10.0 * step + k / 10.0] * (k + 1) for step in range(k + 1)] for k in range(3)]
    assert [(list(x), list(w)) for x, w in batches] == [
        ([0.0, 100.0, 100.0, 200.0, 200.0, 200.0], [0.0, 0.1, 0.1, 0.2, 0.2, 0.2]),
        ([101.0, 101.0, 201.0, 201.0, 201.0], [0.1, 0.1, 0.2, 0.2, 0.2]),
        ([202.0, 202.0, 202.0], [0.2])]  # one call left: its one row of scales


def test_lockstep_passes_one_row_of_scales_where_every_call_shares_it():
    from depth.estimate import _Lockstep

    shapes = []
    shared = np.arange(4.0)

    def evaluate(x, w):
        shapes.append(w.shape)
        return x[:, :4] * 0.0 + w

    out = _Lockstep(evaluate).run([lambda ev: ev(np.ones((2, 7)), shared), lambda ev: ev(np.ones((3, 7)), shared)])
    assert shapes == [(1, 4)] and all(np.array_equal(o, np.tile(shared, (len(o), 1))) for o in out)
    per_row = np.arange(8.0).reshape(2, 4)
    out = _Lockstep(evaluate).run([lambda ev: ev(np.ones((2, 7)), per_row), lambda ev: ev(np.ones((3, 7)), shared)])
    assert shapes[1:] == [(5, 4)] and np.array_equal(out[0], per_row) and np.array_equal(out[1], np.tile(shared, (3, 1)))


def test_lockstep_calls_run_in_the_callers_numpy_error_state_and_raise_their_errors():
    from depth.estimate import _Lockstep

    def divide(ev):
        return float(ev(np.ones((1, 7)), np.ones(2))[0, 0] / np.float64(0.0))

    with np.errstate(divide="raise"):
        with pytest.raises(FloatingPointError):
            _Lockstep(lambda x, w: x).run([lambda ev: 0.0, divide])
    with np.errstate(divide="ignore"):
        assert _Lockstep(lambda x, w: x).run([lambda ev: 0.0, divide]) == [0.0, np.inf]


def test_lockstep_evaluates_a_lone_pose_as_a_pair():
    """One row alone would take OpenBLAS's matrix-vector product, whose rounding differs from the
    matrix-matrix one that batches take: a lone pose is evaluated twice over and gets its one row back."""
    from depth.estimate import _Lockstep

    seen = []

    def evaluate(x, w):
        seen.append(x.copy())
        return x + np.arange(len(x))[:, None]

    _Lockstep(evaluate).run([lambda ev: ev(np.full((1, 7), 3.0), np.ones(2)),
                             lambda ev: ev(np.full((2, 7), 5.0), np.ones(2))])
    assert [s.shape for s in seen] == [(3, 7)]
    out = _Lockstep(evaluate).run([lambda ev: ev(np.full((1, 7), 3.0), np.ones(2))])
    assert [s.shape for s in seen[1:]] == [(2, 7)] and np.array_equal(seen[1], np.full((2, 7), 3.0))
    assert np.array_equal(out[0], np.full((1, 7), 3.0))


def test_every_merged_face_is_a_chain_front_back_back_front():
    """`contour` moves the middle two vertices of each merged face's chain by the shift and holds the
    ends: each side and top/bottom face must list its two front vertices (w = 0) next to each other."""
    from depth.estimate import _FACES, _TOPS, _VERTS

    for face in list(_FACES.values()) + list(_TOPS.values()):
        w = _VERTS[list(face), 2]
        assert sorted(w) == [-1.0, -1.0, 0.0, 0.0]
        front = [i for i in range(4) if w[i] == 0]
        assert (front[1] - front[0]) % 4 in (1, 3)  # adjacent around the quadrilateral


DIVERGING_FACE = Path(__file__).resolve().parents[1] / "data" / "mitsuba_colour_2020_s6_jpeg_face.npz"
"""The measurement `reconstruct` made of a floor shadow in an unseen holdout render (`python -m bench.holdout 2020
--jpeg`, scene 6: Mitsuba 3, 16 spp, through the reconstruct bench's JPEG coder): a grey hexagon 20 × 25 px at
(1047, 1498) of the 2048×1536 image. Its edge points (left, right, top, bottom, the left back edge), corners, face
pixels and scalars as measured; the image and the blob mask as a crop from `origin`, the rest of the image 0."""


def _diverging_face():
    """(rays, measurement) of `DIVERGING_FACE`, in the render's setup (camera at (0, −0.04213, 0.65663) looking at
    the mirror's centre, focal 3120.263 px; mirror radius 0.12264 m, height 0.71636 m, about y)."""
    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.truth import mirror_rays

    f = np.load(DIVERGING_FACE)
    (h, w), (r0, c0), (ch, cw) = f["shape"], f["origin"], f["blob"].shape
    image, blob = np.zeros((h, w, 3)), np.zeros((h, w), dtype=bool)
    image[r0:r0 + ch, c0:c0 + cw] = f["image"] / 255.0
    blob[r0:r0 + ch, c0:c0 + cw] = f["blob"]
    noise, bias, no_gap = (float(v) for v in f["scalars"])
    meas = FaceMeasurement(sides_px=(f["left"], f["right"], f["top"], f["bottom"]), corners_px=f["corners"],
                           face_px=f["face"], edge_noise_px=noise, back_sides_px=(f["back_left"], None),
                           edge_bias_px=bias, side_gaps_px=tuple(f["gaps"]), strip_px=tuple(f["strips"]),
                           no_side_face_gap_px=no_gap, blob_mask=blob, image=image)
    camera = PinholeCamera.from_look_at((int(w), int(h)), (3120.263, 3120.263), None, (0.0, -0.04213, 0.65663),
                                        (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    mirror = CylinderMirror(0.12264, 0.71636, (0, 0, 0), (0, 1, 0))

    def rays(px):
        r = mirror_rays(camera, mirror, px)
        return r.points, r.directions
    return rays, meas


def test_a_fit_driven_off_to_an_infinite_size_is_no_reading():
    """`exact`'s refit of this face with a merged top face ran off towards an infinite edge length (log size 1158,
    past float64), where every edge point's model coordinate is no number and `resids` counts it as 0: a cost of
    0. Building that cube raised `RaytraceError` ("size: expected a positive finite number, got inf"), and
    `catadioptric reconstruct` lost every cube of the image to it. Such a pose is no reading: the face is refused
    or read at a finite pose, and nothing raises."""
    rays, meas = _diverging_face()
    est = estimate_face(rays, meas, method="exact", up=np.array([0.0, 1.0, 0.0]))
    if est:
        assert np.isfinite(est.size) and est.size > 0 and np.all(np.isfinite(est.center))
    else:
        assert est.reason
