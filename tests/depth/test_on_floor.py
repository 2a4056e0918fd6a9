"""`exact` for cubes standing on a known floor (`depth.estimate.estimate_face_on_floor`), on the rig's exact
reflections of true cube edges (no renderer): exact recovery, the floor's own σ, and the refusals."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from depth.errors import DepthError
from depth.estimate import estimate_face, estimate_face_on_floor, floor_gap, floor_size_guess

UP = np.array([0.0, 1.0, 0.0])


def floor_of(rig):
    """The floor the rig's mirror stands on: its lower end (y = -0.245 m)."""
    return rig.mirror.center - rig.mirror.axis * rig.mirror.height / 2.0


def standing(rig, distance, azimuth, size=0.04, yaw_deg=0.0, lift=0.0):
    """A cube of `size` standing on the rig's floor (`lift` m above it), `distance` from the axis."""
    return rig.cube(distance, azimuth, height=floor_of(rig)[1] + size / 2.0 + lift, size=size, yaw_deg=yaw_deg)


def centre_error(rig, est, cube):
    return np.linalg.norm(est.center - cube.center) / rig.depth(cube)


@settings(max_examples=12, deadline=None)
@given(distance=st.floats(0.3, 1.1), azimuth=st.floats(-35.0, 35.0), size=st.floats(0.025, 0.07),
       yaw=st.floats(-25.0, 25.0))
def test_a_cube_on_the_floor_is_recovered_exactly_from_exact_edges(rig, distance, azimuth, size, yaw):
    """On a face's exact edges, standing anywhere on the floor, facing the axis or turned up to 25°: the centre
    and size to 1e-6, its bottom on the floor to a micrometre (the last step taken along the size slope is off
    by its square)."""
    cube = standing(rig, distance, azimuth, size, yaw)
    meas = rig.measure(cube, n=24)
    est = estimate_face_on_floor(rig.rays, meas, floor_of(rig), UP)
    assert est, est.reason
    assert centre_error(rig, est, cube) < 1e-6
    assert est.size == pytest.approx(size, rel=1e-6)
    assert abs(floor_gap(est, floor_of(rig), UP)) < 1e-6
    assert est.method == "exact" and est.std["size"] > 0.0


@pytest.mark.parametrize("distance, azimuth, size, yaw", [
    (0.35, -30.0, 0.04, 0.0), (0.6, 5.0, 0.03, 15.0), (0.9, 25.0, 0.03, 0.0), (1.1, -10.0, 0.025, -20.0)])
def test_the_floor_size_guess_is_near_the_size_from_two_sides_alone(rig, distance, azimuth, size, yaw):
    """The bottom side's rays meet the floor at the bottom edge and the top side's pass that high over it: the
    guess is within 1 % of the true size on exact edges, and refuses no cube standing on the floor."""
    cube = standing(rig, distance, azimuth, size, yaw)
    guess = floor_size_guess(rig.rays, rig.measure(cube, n=24), floor_of(rig), UP)
    assert guess == pytest.approx(size, rel=0.01)


def test_the_floor_reads_a_far_narrow_face_its_own_edges_cannot_scale(rig):
    """A cube 2.5 cm across 1.1 m from the axis (a face 9 px wide) with its edges read to 0.1 px: alone, `exact`
    puts its centre percents off with a depth σ of several percent; standing on the floor, within 0.1 % and
    its σ under 0.5 % of the depth, the error within 3 of it. Five draws of the noise."""
    cube = standing(rig, 1.1, 20.0, size=0.025)
    for seed in range(5):
        meas = rig.measure(cube, n=24, noise_px=0.1, seed=seed)
        alone = estimate_face(rig.rays, meas, "exact", up=UP)
        est = estimate_face_on_floor(rig.rays, meas, floor_of(rig), UP, alone=alone)
        assert alone and est
        assert alone.std["z"] / rig.depth(cube) > 0.05
        assert centre_error(rig, est, cube) < 1e-3 and est.std["z"] / rig.depth(cube) < 5e-3
        depth = float(rig.mirror.distance_to_axis(est.center[None])[0])
        assert abs(depth - rig.depth(cube)) < 3.0 * est.std["z"]


def test_the_floor_s_own_sigma_covers_a_floor_height_read_off_by_it(rig):
    """A floor height itself measured: 40 draws of it off the true one by N(0, 2 mm), each with `floor_std` 2 mm,
    on four faces' exact edges (near and far, facing the axis and turned 15°). The depth is then off by what the
    height moves it, and its σ covers that as a Gaussian would (55–85 % within 1 σ, 36 of 40 within 2 σ).
    Without the floor's σ, the σ is the edges' alone, far narrower."""
    cubes = [standing(rig, 0.35, -30.0), standing(rig, 0.6, 5.0, yaw_deg=15.0), standing(rig, 0.85, 25.0, size=0.03),
             standing(rig, 0.5, -10.0, size=0.05)]
    meas = [rig.measure(c, n=24) for c in cubes]
    alone = [estimate_face(rig.rays, m, "exact", up=UP) for m in meas]
    rng = np.random.default_rng(11)
    sd = 0.002
    z, z_edges = [], []
    for k in range(40):
        cube = cubes[k % 4]
        floor = floor_of(rig) + UP * rng.normal(0.0, sd)
        est = estimate_face_on_floor(rig.rays, meas[k % 4], floor, UP, floor_std=sd, alone=alone[k % 4])
        bare = estimate_face_on_floor(rig.rays, meas[k % 4], floor, UP, alone=alone[k % 4])
        assert est and bare
        assert np.array_equal(est.center, bare.center) and est.size == bare.size
        err = abs(float(rig.mirror.distance_to_axis(est.center[None])[0]) - rig.depth(cube))
        z.append(err / est.std["z"])
        z_edges.append(err / bare.std["z"])
    z, z_edges = np.array(z), np.array(z_edges)
    assert 0.55 <= np.mean(z <= 1.0) <= 0.85 and np.mean(z <= 2.0) >= 0.9 and z.max() < 3.5, np.sort(z)
    assert np.mean(z_edges <= 2.0) < 0.5, np.sort(z_edges)


@pytest.mark.parametrize("lift", [0.1, 0.25])
def test_a_cube_off_the_floor_is_refused(rig, lift):
    """A cube 10 or 25 cm above the floor, its face read to 0.05 px: the size that would stand it on the floor is
    several times its edges' own, far beyond their σ: refused, not read at that size."""
    cube = standing(rig, 0.45, 15.0, lift=lift)
    est = estimate_face_on_floor(rig.rays, rig.measure(cube, n=24, noise_px=0.05, seed=2), floor_of(rig), UP)
    assert not est and "it does not stand on that floor" in est.reason, est


def test_a_reading_whose_gap_jumps_across_the_floor_settles_at_the_jump_with_both_readings_in_its_sigma(
        rig, monkeypatch):
    """Where `exact`'s reading changes with the size (its fit at a known size above 39.9 mm put 1.5 mm lower here),
    the bottom's height over the floor jumps across it: no size stands the cube on the floor, and Newton's steps
    cycle either side of the jump (refused after 8 fits without a safeguard). The steps are bracketed and halved:
    the size lands within 0.2 % of the jump, and the centre's σ covers the other side's reading too."""
    import depth.estimate as de
    cube = standing(rig, 0.6, 10.0, size=0.04)
    meas = rig.measure(cube, n=24)
    jump, real = 0.0399, de.estimate_face

    def reading(*args, **kwargs):
        est = real(*args, **kwargs)
        if est and kwargs.get("cube_size") is not None and kwargs["cube_size"] > jump:
            est = replace(est, center=est.center - 0.0015 * UP)
        return est
    plain = estimate_face_on_floor(rig.rays, meas, floor_of(rig), UP)
    monkeypatch.setattr(de, "estimate_face", reading)
    est = estimate_face_on_floor(rig.rays, meas, floor_of(rig), UP)
    assert est, est.reason
    assert est.size == pytest.approx(jump, rel=2e-3)
    # the other side's reading lies 1.5 mm lower: an even mixture of the two adds half of that to the centre's σ
    assert est.std["center"] == pytest.approx(np.hypot(plain.std["center"], 0.00075), rel=0.1)


def test_a_floor_the_camera_looks_along_fixes_no_size(rig):
    """The rig's camera is at the height of y = 0: a cube standing on the floor y = 0 has its bottom at the
    camera's height whatever its size (a pinhole's rays scale about the camera), so the floor fixes no size."""
    cube = rig.cube(0.5, 10.0, height=0.02, size=0.04)
    est = estimate_face_on_floor(rig.rays, rig.measure(cube, n=24), np.zeros(3), UP)
    assert not est and "the floor fixes no size" in est.reason, est


def test_a_floor_std_that_is_no_sigma_is_refused(rig):
    meas = rig.measure(standing(rig, 0.5, 0.0), n=24)
    for bad in (-0.001, float("nan")):
        with pytest.raises(DepthError, match="floor_std: expected the σ of the floor's height in metres"):
            estimate_face_on_floor(rig.rays, meas, floor_of(rig), UP, floor_std=bad)


def test_the_floor_s_sigma_is_the_scalar_propagation_of_its_three_sources():
    """`_on_floor_std` against the same σ worked by hand for a fit whose centre's height, its z and the floor's
    height are independent: the size moves by −(δ height − δ floor) / rate, and z by its own noise plus its slope
    times that; the turn profile's widening (the fit's σ beyond its first order) adds in quadrature."""
    from depth.estimate import CubeEstimate, _on_floor_std
    cy, cz, zz, sh, k, m = 2e-4, 5e-3, 4e-3, 1e-3, -2.5, 0.8  # σ of the centre's height, its depth, z; floor σ; slopes
    rate = k - 0.5
    cov = np.diag([1e-4 ** 2, cy ** 2, cz ** 2, 0.0, zz ** 2])
    at = CubeEstimate(method="exact", center=np.array([0.1, -0.2, 0.6]), size=0.04, z=0.5,
                      front_face_center=np.array([0.1, -0.2, 0.58]), normal=np.array([0.0, 0.0, -1.0]),
                      aspect_ratio=5.0, std={"z": 1.5 * zz, "size": 0.0, "center": 0.01},
                      size_slope={"center": np.array([0.0, k, 3.0]), "z": m}, first_order_cov=cov)
    est = _on_floor_std(at, UP, rate, sh)
    ds2 = (cy ** 2 + sh ** 2) / rate ** 2  # the size's variance
    assert est.std["size"] == pytest.approx(np.sqrt(ds2), rel=1e-12)
    assert est.std["z"] == pytest.approx(np.sqrt(zz ** 2 + m ** 2 * ds2 + (1.5 ** 2 - 1.0) * zz ** 2), rel=1e-12)
    # the centre: x its own; y (1 + k (−1/rate)) δy + k δh / rate; z_c its own + 3 δs
    var_c = 1e-4 ** 2 + (1 - k / rate) ** 2 * cy ** 2 + (k / rate) ** 2 * sh ** 2 + cz ** 2 + 9.0 * ds2
    assert est.std["center"] ** 2 == pytest.approx(var_c + max(0.01 ** 2 - (1e-4 ** 2 + cy ** 2 + cz ** 2), 0.0),
                                                   rel=1e-12)
    assert np.array_equal(est.center, at.center) and est.size == at.size
