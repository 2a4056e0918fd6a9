"""The setup's own σ carried into `exact`'s readings (`depth.setup_error`), on the rig's exact reflections of
true cube edges (no renderer): the first-order moves against whole fits with the setup moved, the moves a
translation of the whole setup must make, and the σ against setups drawn off by it."""

from dataclasses import replace

import numpy as np
import pytest

from depth.errors import DepthError
from depth.estimate import estimate_face
from depth.setup_error import SetupStd, drawn, moved, setup_effects, with_setup_std
from mirror_ray_maps import rays_of

UP = np.array([0.0, 1.0, 0.0])


def read(rig, meas, camera=None, mirror=None, slopes=False):
    """`exact`'s reading of `meas` through a setup (the rig's, where not given), upright along its mirror's axis."""
    camera, mirror = camera or rig.camera, mirror or rig.mirror
    est = estimate_face(rays_of(camera, mirror), meas, "exact", up=mirror.axis, ray_slopes=slopes)
    assert est, est.reason
    return est


def depth_of(est, mirror):
    return float(mirror.distance_to_axis(est.center[None])[0])


CASES = [("camera_position", 0, 0.002), ("camera_position", 2, 0.002), ("camera_rotation_deg", 1, 0.1),
         ("focal_px", 0, 10.0), ("focal_px", 1, 10.0), ("principal_px", 0, 2.0), ("mirror_radius", 0, 0.0005),
         ("mirror_center", 2, 0.002), ("mirror_axis_deg", 0, 0.05), ("mirror_axis_deg", 1, 0.05),
         ("distortion", 0, 0.1), ("distortion", 2, 0.002)]


def std_of(name, k, delta) -> SetupStd:
    """A `SetupStd` whose only σ is `delta` on `name` (on its k-th coefficient for the distortion's)."""
    return SetupStd(distortion=tuple(delta * (i == k) for i in range(k + 1))) if name == "distortion" else \
        SetupStd(**{name: delta})


@pytest.mark.parametrize("yaw", [0.0, 15.0])
def test_the_first_order_moves_match_whole_fits_through_the_moved_setup(rig, yaw):
    """The edges are the true setup's; a setup off by ±δ in one number reads them (a whole `exact` fit through
    its own rays, upright along its own axis). Half the difference of those two readings is what
    `setup_effects` predicts at σ = δ from the true setup's reading alone: the centre, size and depth within 3 %
    of the move (and 2 µm). A face facing the axis and one turned 15°."""
    cube = rig.cube(0.5, 20.0, yaw_deg=yaw)
    meas = rig.measure(cube, n=24)
    est = read(rig, meas, slopes=True)
    for name, k, delta in CASES:
        (predicted,) = [e for n, kk, e in setup_effects(est, rig.camera, rig.mirror, std_of(name, k, delta))
                        if kk == k]
        ends = [moved(rig.camera, rig.mirror, name, k, sgn * delta) for sgn in (1.0, -1.0)]
        fits = [read(rig, meas, *end) for end in ends]
        actual = np.r_[0.5 * (fits[0].center - fits[1].center), 0.5 * (fits[0].size - fits[1].size),
                       0.5 * (depth_of(fits[0], ends[0][1]) - depth_of(fits[1], ends[1][1]))]
        wanted = np.r_[predicted[:4], predicted[5]]
        assert np.all(np.abs(wanted - actual) <= 0.03 * np.abs(actual) + 2e-6), (name, k, wanted, actual)
        assert np.linalg.norm(actual[:3]) > 1e-5  # each of these numbers moves the cube


def test_a_whole_setup_moved_moves_the_cube_with_it_and_its_depth_and_size_not_at_all(rig):
    """Camera and mirror moved together by δ along any axis: the cube moves by δ, its size and its depth (from the
    moved axis) not at all; so the camera's move and the mirror's add up to that. Along the mirror's axis the
    mirror's own move changes no ray (an endless cylinder's lateral surface): the camera's alone moves the cube
    by δ along it."""
    cube = rig.cube(0.45, -25.0, yaw_deg=10.0)
    est = read(rig, rig.measure(cube, n=24), slopes=True)
    delta = 0.001
    effects = {(n, k): e for n, k, e in setup_effects(est, rig.camera, rig.mirror,
                                                      SetupStd(camera_position=delta, mirror_center=delta))}
    for k in range(3):
        both = effects["camera_position", k] + effects["mirror_center", k]
        assert np.allclose(both[:3], delta * np.eye(3)[k], atol=2e-7), (k, both)
        assert abs(both[3]) < 1e-8 and abs(both[5]) < 2e-7, (k, both)
        assert abs(effects["camera_position", k][5]) > 1e-5 or k == 1  # each alone moves the depth (but along the axis)
    assert np.allclose(effects["mirror_center", 1], 0.0, atol=1e-9)
    assert np.allclose(effects["camera_position", 1][:3], [0.0, delta, 0.0], atol=2e-7)


def test_the_setup_s_sigma_covers_setups_drawn_off_by_it(rig):
    """10 setups each drawn off the true one by N(0, σ) in every number, each reading the true setup's exact edges
    of three faces (near, far, turned): 30 readings. Each depth is off by what its setup moves it, and its σ (the
    edges' σ, tiny here: no offset of a whole side is allowed for; plus the drawn setup's share) covers that as a
    Gaussian would: 55–85 % within 1 σ, at least 90 % within 2 σ. Without the setup's share, under 75 % lie within
    2 σ of the edges' σ alone."""
    std = SetupStd(camera_position=0.001, camera_rotation_deg=0.05, focal_px=4.0, principal_px=1.0,
                   mirror_radius=0.0002, mirror_center=0.001, mirror_axis_deg=0.1)
    cubes = [rig.cube(0.35, -30.0), rig.cube(0.8, 10.0, size=0.05), rig.cube(0.5, 25.0, yaw_deg=15.0)]
    meas = [replace(rig.measure(c, n=24), edge_bias_px=0.0) for c in cubes]  # exact edges, said to be so
    rng = np.random.default_rng(7)
    z_scores, alone = [], []
    for _ in range(10):
        camera, mirror = drawn(rig.camera, rig.mirror, std, rng)
        for cube, m in zip(cubes, meas):
            est = read(rig, m, camera, mirror, slopes=True)
            error = depth_of(est, mirror) - rig.depth(cube)
            carried = with_setup_std(est, camera, mirror, std)
            z_scores.append(error / carried.std["z"])
            alone.append(error / est.std["z"])
            assert carried.std["z"] == pytest.approx(np.hypot(est.std["z"], carried.setup_std["depth"]))
    z = np.abs(z_scores)
    assert 0.55 <= np.mean(z < 1.0) <= 0.85, np.round(z, 2)
    assert np.mean(z < 2.0) >= 0.9, np.round(z, 2)
    assert np.mean(np.abs(alone) < 2.0) < 0.75, np.round(alone, 1)


def test_slopes_asked_for_leave_the_reading_as_it_was(rig):
    """The reading with its ray slopes is the reading without them, to the bit (centre, size, σ)."""
    meas = rig.measure(rig.cube(0.6, 15.0, yaw_deg=-12.0), n=24, noise_px=0.05)
    a, b = read(rig, meas), read(rig, meas, slopes=True)
    assert a.ray_slopes is None and b.ray_slopes is not None
    assert np.array_equal(a.center, b.center) and a.size == b.size and a.std == b.std
    pix, slopes, up_slopes = b.ray_slopes
    assert slopes.shape == (5, len(pix), 6) and up_slopes.shape == (5, 3)


def test_a_setup_taken_as_exact_adds_nothing_and_bad_sigmas_are_refused(rig):
    est = read(rig, rig.measure(rig.cube(0.5, 0.0), n=24), slopes=True)
    same = with_setup_std(est, rig.camera, rig.mirror, SetupStd())
    assert same.std == est.std and same.setup_std == {"depth": 0.0, "size": 0.0, "center": 0.0}
    for bad in (-1.0, float("nan"), float("inf"), True, "1"):
        with pytest.raises(DepthError, match="setup_std.focal_px: expected a σ >= 0"):
            SetupStd(focal_px=bad)
    with pytest.raises(DepthError, match="carried through method exact's fit alone"):
        setup_effects(replace(est, ray_slopes=None), rig.camera, rig.mirror, SetupStd(focal_px=1.0))
    for bad in ((-0.1,), (0.1, float("nan")), (0.0,) * 9, 0.1, (True,)):
        with pytest.raises(DepthError, match=r"setup_std.distortion: expected up to 8 σ >= 0 \(k1, k2, p1, p2"):
            SetupStd(distortion=bad)
    assert SetupStd(distortion=(0.0, 0.0)).items() == [] and SetupStd(distortion=(0.0, 0.0)).components() == []
    with pytest.raises(DepthError, match="setup_std.distortion: coefficient 0 moved by -4 folds the lens over the "
                                         "image"):
        setup_effects(est, rig.camera, rig.mirror, SetupStd(distortion=(4.0,)))


def test_each_number_moves_what_its_name_says(rig):
    """`moved`: the camera's place along a world axis, its turn held; a turn about the camera's own axis k leaving
    that axis where it was and turning the others by the angle; fx, fy, cx, cy; the radius; the mirror's centre;
    its axis tilted by the angle, square to it."""
    from raytrace.camera import PinholeCamera
    cam, mir = PinholeCamera.from_look_at((800, 600), (1750.0, 1700.0), None, (0.1, 0.2, 0.55), (0.0, 0.05, 0.0),
                                          (0.1, 1.0, 0.0)), rig.mirror  # turned about every axis
    c, m = moved(cam, mir, "camera_position", 2, 0.003)
    assert np.allclose(c.position - cam.position, [0, 0, 0.003]) and np.array_equal(c.R, cam.R) and m is mir
    for k in range(3):
        c, _ = moved(cam, mir, "camera_rotation_deg", k, 2.0)
        assert np.allclose(c.R[k], cam.R[k])
        for j in {0, 1, 2} - {k}:
            assert np.degrees(np.arccos(np.clip(c.R[j] @ cam.R[j], -1, 1))) == pytest.approx(2.0)
    for name, k, cell in (("focal_px", 0, (0, 0)), ("focal_px", 1, (1, 1)), ("principal_px", 0, (0, 2)),
                          ("principal_px", 1, (1, 2))):
        c, _ = moved(cam, mir, name, k, 1.5)
        expected = np.zeros((3, 3))
        expected[cell] = 1.5
        assert np.allclose(c.K - cam.K, expected)
    _, m = moved(cam, mir, "mirror_radius", 0, 0.001)
    assert m.radius == pytest.approx(mir.radius + 0.001)
    _, m = moved(cam, mir, "mirror_center", 0, -0.002)
    assert np.allclose(m.center - mir.center, [-0.002, 0, 0])
    for k in range(2):
        _, m = moved(cam, mir, "mirror_axis_deg", k, 0.5)
        assert np.degrees(np.arccos(m.axis @ mir.axis)) == pytest.approx(0.5)
        assert abs((m.axis - mir.axis) @ mir.frame[k]) < 1e-12  # tilted about frame[k], so not toward it
    c, _ = moved(cam, mir, "distortion", 1, 0.02)  # from an ideal lens
    assert np.array_equal(c.distortion, [0, 0.02, 0, 0, 0, 0, 0, 0]) and np.array_equal(c.K, cam.K)
    bent = replace(cam, distortion=[-0.1, 0.03, 1e-3, 0.0, 0.01])
    c, _ = moved(bent, mir, "distortion", 4, -0.005)
    assert np.allclose(c.distortion - bent.distortion, [0, 0, 0, 0, -0.005, 0, 0, 0], atol=1e-15)
    assert np.array_equal(bent.distortion, [-0.1, 0.03, 1e-3, 0.0, 0.01, 0, 0, 0])  # the camera moved from, kept


def test_reconstruct_refuses_a_setup_sigma_it_cannot_carry(rig):
    """`reconstruct(setup_std=)`: carried through method exact's fit alone, and only a `SetupStd`: one-line errors
    before any work."""
    from depth.reconstruct import reconstruct
    image = np.zeros((600, 800, 3), np.uint8)
    std = SetupStd(focal_px=1.0)
    for kwargs, message in ((dict(method="ddar"), "not ddar's"), (dict(method="shape_prior"), "not shape_prior's")):
        with pytest.raises(DepthError, match=f"setup_std: the setup's σ is carried through method exact's fit alone "
                                             f"\\(exact, exact_shape_prior\\), {message}"):
            reconstruct(image, rig.camera, rig.mirror, setup_std=std, **kwargs)
    with pytest.raises(DepthError, match="setup_std: expected a depth.setup_error.SetupStd, got dict"):
        reconstruct(image, rig.camera, rig.mirror, setup_std={"focal_px": 1.0})


@pytest.mark.parametrize("yaw", [0.0, 15.0])
def test_a_cube_on_the_floor_moves_with_the_setup_and_the_floor_with_the_mirror(rig, yaw):
    """`estimate_face_on_floor`'s reading: the floor lies at the mirror's lower end (as `--on-floor` places it),
    square to its axis, so it moves and turns with the mirror. A setup off by ±δ in one number reads the true
    setup's exact edges (a whole on-floor fit: Newton on the size through the moved setup's rays and floor); half
    the difference of the two readings is what `setup_effects` predicts from the true setup's reading: centre,
    size and depth within 3 % of the move (and 2 µm). The size moves now: the floor fixes it."""
    from depth.estimate import estimate_face_on_floor
    floor_at = -rig.mirror.height / 2.0
    cube = rig.cube(0.55, 15.0, height=floor_at + 0.02, yaw_deg=yaw)
    meas = rig.measure(cube, n=24)

    def on_floor(camera, mirror, slopes=False):
        est = estimate_face_on_floor(rays_of(camera, mirror), meas, mirror.center + floor_at * mirror.axis,
                                     mirror.axis, ray_slopes=slopes)
        assert est, est.reason
        return est
    est = on_floor(rig.camera, rig.mirror, slopes=True)
    assert abs(depth_of(est, rig.mirror) - rig.depth(cube)) < 1e-6 and est.on_floor is not None
    for name, k, delta in CASES + [("mirror_center", 1, 0.002)]:  # (the mirror, and the floor, up its axis)
        (predicted,) = [e for n, kk, e in setup_effects(est, rig.camera, rig.mirror, std_of(name, k, delta))
                        if kk == k]
        ends = [moved(rig.camera, rig.mirror, name, k, sgn * delta) for sgn in (1.0, -1.0)]
        fits = [on_floor(*end) for end in ends]
        actual = np.r_[0.5 * (fits[0].center - fits[1].center), 0.5 * (fits[0].size - fits[1].size),
                       0.5 * (depth_of(fits[0], ends[0][1]) - depth_of(fits[1], ends[1][1]))]
        wanted = np.r_[predicted[:4], predicted[5]]
        assert np.all(np.abs(wanted - actual) <= 0.03 * np.abs(actual) + 2e-6), (name, k, wanted, actual)


def test_cubes_of_one_size_move_with_the_common_size_the_setup_moves(rig):
    """`estimate_faces_exact_shape_prior`: three 4 cm cubes (0.35–0.8 m, one turned 15°); the common size is the
    inverse-variance mean of their own sizes, so a setup number moves it as it moves those. Whole joint readings
    through the setup moved by ±δ (each face alone, the common size, each face again at it) move each cube by what
    `setup_effects` predicts from the true setup's readings: the centre's move within 3 % of its length, size and
    depth within 3 % (and 2 µm). The edges carry 0.05 px of noise, so that the sizes' σ, and their weights, differ."""
    from depth.estimate import estimate_faces_exact_shape_prior
    cubes = [rig.cube(0.35, -30.0), rig.cube(0.55, 10.0, yaw_deg=15.0), rig.cube(0.8, 25.0)]
    meas = [rig.measure(c, n=24, noise_px=0.05, seed=i) for i, c in enumerate(cubes)]

    def joint(camera, mirror, slopes=False):
        out = estimate_faces_exact_shape_prior(rays_of(camera, mirror), meas, up=mirror.axis, ray_slopes=slopes)
        assert all(out), [e.reason for e in out if not e]
        return out
    ests = joint(rig.camera, rig.mirror, slopes=True)
    assert all(e.common_size_from is not None and len(e.common_size_from) == 3 for e in ests)
    for name, k, delta in [("camera_position", 0, 0.002), ("focal_px", 1, 10.0), ("mirror_radius", 0, 0.0005),
                           ("mirror_axis_deg", 0, 0.05)]:
        ends = [moved(rig.camera, rig.mirror, name, k, sgn * delta) for sgn in (1.0, -1.0)]
        fits = [joint(*end) for end in ends]
        for i, est in enumerate(ests):
            (predicted,) = [e for n, kk, e in setup_effects(est, rig.camera, rig.mirror, std_of(name, k, delta))
                            if kk == k]
            actual = np.r_[0.5 * (fits[0][i].center - fits[1][i].center), 0.5 * (fits[0][i].size - fits[1][i].size),
                           0.5 * (depth_of(fits[0][i], ends[0][1]) - depth_of(fits[1][i], ends[1][1]))]
            wanted = np.r_[predicted[:4], predicted[5]]
            # the centre as a vector (the edges' noise leaves residuals, and a small component of a 5 mm move may
            # be off by a few per cent of itself), the size and the depth each
            assert np.linalg.norm(wanted[:3] - actual[:3]) <= 0.03 * np.linalg.norm(actual[:3]) + 2e-6, (name, k, i)
            assert np.all(np.abs(wanted[3:] - actual[3:]) <= 0.03 * np.abs(actual[3:]) + 2e-6), (name, k, i, wanted,
                                                                                                   actual)
