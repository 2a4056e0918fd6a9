"""Tests of depth.reconstruct's physical checks on an estimate, on analytic geometry (no renderer)."""

import contextlib
import functools
from dataclasses import replace

import numpy as np
import pytest

from depth.estimate import CubeEstimate, estimate_face
from depth.reconstruct import _cube_vertices, _direct_view_reason, _inside_mirror_reason
from raytrace.truth import mirror_mask


def _cube_at(centre, size=0.02, normal=(0.0, 0.0, -1.0)):
    centre = np.asarray(centre, dtype=np.float64)
    return CubeEstimate(method="exact", center=centre, size=size, z=float(np.hypot(centre[0], centre[2])),
                        front_face_center=centre, normal=np.asarray(normal, dtype=np.float64),
                        aspect_ratio=1.0, std={})


def test_cube_vertices_are_a_cube_of_the_estimated_size_about_its_centre():
    est = _cube_at((0.1, 0.02, 0.4), size=0.03, normal=(0.6, 0.0, -0.8))
    v = _cube_vertices(est, (0.0, 1.0, 0.0))
    assert np.allclose(v.mean(axis=0), est.center)
    d = np.linalg.norm(v[:, None] - v[None], axis=-1)
    # a cube's 28 vertex pairs: 12 edges, 12 face diagonals, 4 space diagonals
    assert np.allclose(np.sort(d[np.triu_indices(8, 1)]),
                       np.repeat(0.03 * np.array([1.0, np.sqrt(2.0), np.sqrt(3.0)]), [12, 12, 4]))
    # one edge direction along the normal, one along the axis
    edges = (v[:, None] - v[None])[np.isclose(d, 0.03)]
    assert np.any(np.isclose(np.abs(edges @ est.normal), 0.03))
    assert np.any(np.isclose(np.abs(edges[:, 1]), 0.03))


@pytest.fixture(scope="module")
def setup():
    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    camera = PinholeCamera.from_look_at((640, 480), (1400.0, 1400.0), None, (0.0, 0.0, 0.55), (0, 0, 0), (0, 1, 0))
    mirror = CylinderMirror(0.1, 0.49, (0, 0, 0), (0, 1, 0))
    return camera, mirror, mirror_mask(camera, mirror)


def test_a_cube_between_the_camera_and_the_mirror_showing_nowhere_is_refused(setup):
    """A cube put halfway between the camera and the mirror, on the ray through pixel (400, 300), would
    hide the mirror around that pixel: with no blob there it is refused, and the reason names the place
    (the camera's own projection of the cube's centre, within a pixel)."""
    camera, mirror, region = setup
    o, d = camera.rays(np.array([[400.0, 300.0]]))
    t, hit, _, _ = mirror.intersect(o, d)
    assert hit[0]
    est = _cube_at(o[0] + 0.5 * t[0] * d[0])
    no_blobs = np.zeros_like(region)
    reason = _direct_view_reason(camera, mirror, est, region, no_blobs, mirror.axis)
    assert reason is not None and "between the camera and the mirror" in reason
    u, v = (float(x) for x in reason.split("around (")[1].split(")")[0].split(","))
    assert np.hypot(u - 400.0, v - 300.0) < 1.0


def test_a_cube_between_the_camera_and_the_mirror_that_shows_there_is_kept(setup):
    """The same cube where the image shows a blob over its direct image: a real cube standing there."""
    camera, mirror, region = setup
    o, d = camera.rays(np.array([[400.0, 300.0]]))
    t, _, _, _ = mirror.intersect(o, d)
    est = _cube_at(o[0] + 0.5 * t[0] * d[0])
    px, _ = camera.project(_cube_vertices(est, mirror.axis))
    blobs = np.zeros_like(region)
    (u0, v0), (u1, v1) = np.floor(px.min(axis=0)).astype(int), np.ceil(px.max(axis=0)).astype(int)
    blobs[v0:v1 + 1, u0:u1 + 1] = True
    assert _direct_view_reason(camera, mirror, est, region, blobs, mirror.axis) is None


def test_a_cube_whose_direct_image_covers_its_own_measured_face_is_refused(setup):
    """The blob over the cube's direct image is the very face measured as its reflection: the camera
    would see the cube there and not its reflection behind it, so the face is a cube seen straight over
    the mirror. Refused, and the reason says so; the same cube with its face measured elsewhere (another
    blob covering the direct image) is kept."""
    camera, mirror, region = setup
    o, d = camera.rays(np.array([[400.0, 300.0]]))
    t, _, _, _ = mirror.intersect(o, d)
    est = _cube_at(o[0] + 0.5 * t[0] * d[0])
    px, _ = camera.project(_cube_vertices(est, mirror.axis))
    (u0, v0), (u1, v1) = np.floor(px.min(axis=0)).astype(int), np.ceil(px.max(axis=0)).astype(int)
    own = np.zeros_like(region)
    own[v0:v1 + 1, u0:u1 + 1] = True
    reason = _direct_view_reason(camera, mirror, est, region, own, mirror.axis, own=own)
    assert reason is not None and "hide its own reflection" in reason
    elsewhere = np.zeros_like(region)
    elsewhere[100:130, 300:310] = True
    assert region[100:130, 300:310].all()
    assert _direct_view_reason(camera, mirror, est, region, own | elsewhere, mirror.axis, own=elsewhere) is None


@pytest.mark.parametrize("centre", [
    (0.0, 0.0, 0.8),     # behind the camera
    (0.3, 0.0, 0.3),     # beside the mirror, out of the camera's view (the usual place of a cube)
    (0.0, 0.0, -0.3),    # behind the mirror, hidden by it
    (0.114, 0.0, 0.0),   # in view, beside the mirror's image, not in front of it
])
def test_cubes_not_standing_before_the_mirror_are_not_refused(setup, centre):
    camera, mirror, region = setup
    est = _cube_at(centre, size=0.01)
    if centre == (0.114, 0.0, 0.0):  # the case is what it says: in the image, off the mirror
        px, _ = camera.project(_cube_vertices(est, mirror.axis))
        assert np.all((px > 0) & (px < [640, 480]))
        assert not region[np.round(px[:, 1]).astype(int), np.round(px[:, 0]).astype(int)].any()
    assert _direct_view_reason(camera, mirror, est, region, np.zeros_like(region), mirror.axis) is None


def test_a_cube_whose_centre_lies_inside_the_mirror_is_refused():
    """Two floor shadows of holdout 7070 scene 2 came out as these estimates (centre, normal, size as
    `exact` gave them): squares nearly edge-on to their rays, the cubes behind them reaching back into
    a mirror of radius 141.3 mm, their centres 127.3 and 131.4 mm from its axis. Both are refused, and
    the reason gives that distance; cubes just outside the radius, or inside it but above the mirror's
    top, are kept."""
    from raytrace.mirror import CylinderMirror
    mirror = CylinderMirror(0.1413, 0.8103, (0, 0, 0), (0, 1, 0))
    for centre, normal, size, r_mm in [((0.0403, -0.0795, 0.1207), (-0.907, 0.329, 0.263), 0.00332, "127.3"),
                                       ((0.0512, -0.0810, 0.1210), (-0.825, 0.375, 0.424), 0.00353, "131.4")]:
        reason = _inside_mirror_reason(mirror, _cube_at(centre, size=size, normal=normal))
        assert reason is not None and "inside the mirror" in reason and f"{r_mm} mm from the axis" in reason
    outward = np.array([0.6, 0.0, 0.8])
    for centre in [outward * 0.1414, outward * 0.1413 + [0.0, 0.4052, 0.0]]:
        assert _inside_mirror_reason(mirror, _cube_at(centre, size=0.0002, normal=-outward)) is None


def test_a_mirror_without_contains_is_not_checked():
    class Surface:  # only what reconstruct needs to trace rays; no notion of inside
        radius = 1.0
    assert _inside_mirror_reason(Surface(), _cube_at((0.0, 0.0, 0.0))) is None


def _rendered_blob():
    """A cube seen in the mirror, turned 140.8° about the axis (the sky-lit scene of test_estimate),
    and its blob as our ray tracer's Embree render sees it: the pixels whose one sample per pixel
    hit it via the mirror."""
    from scipy.spatial.transform import Rotation

    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.render import render
    from raytrace.scene import Cube, Scene
    camera = PinholeCamera.from_look_at((1024, 768), (1810.109, 1810.109), None, (0.0, 0.05601, 0.6221), (0, 0, 0),
                                        (0, 1, 0))
    mirror = CylinderMirror(0.12083, 0.5793, (0, 0, 0), (0, 1, 0))
    cube = Cube(0.0394, np.array([0.21575, -0.10775, 0.26466]),
                Rotation.from_euler("y", -140.81, degrees=True).as_matrix(), color=(0.8, 0.8, 0.8))
    r = render(Scene(mirror=mirror, objects=(cube,)), camera, spp=1, seed=0)
    return camera, mirror, cube, (r.object_id == 0) & r.via_mirror


@pytest.mark.parametrize("patch_px, refused", [(0, False), (4, False), (12, True)])
def test_a_grey_blob_reaching_past_the_cube_read_from_it_is_refused(patch_px, refused):
    """`_shadow_reason` on a grey cube's blob rendered by our ray tracer, the estimate being the true
    cube: its own blob is kept. With a square of `patch_px` px added beside it, touching it (a piece of
    a larger object that the cube does not explain), (patch_px − 2)² of the blob's pixels lie outside
    the cube more than a pixel deep: 4 (under `BLOB_OUTSIDE_SHARE` of the blob) are kept, 100 are
    refused, and the reason gives the count."""
    from depth.estimate import FaceMeasurement
    from depth.reconstruct import BLOB_OUTSIDE_SHARE, _shadow_reason
    from raytrace.truth import mirror_rays
    camera, mirror, cube, blob = _rendered_blob()
    ys, xs = np.nonzero(blob)
    n_own = len(ys)
    if patch_px:  # to the right of the blob's rightmost column, at its middle row
        row = int(np.median(ys[xs == xs.max()]))
        blob = blob.copy()
        blob[row - patch_px // 2: row - patch_px // 2 + patch_px, xs.max() + 1: xs.max() + 1 + patch_px] = True
    n_blob = int(blob.sum())
    assert n_blob == n_own + patch_px ** 2
    assert ((patch_px - 2) ** 2 > BLOB_OUTSIDE_SHARE * n_blob) == refused  # the case is what it says
    est = CubeEstimate(method="exact", center=cube.center, size=cube.size, z=0.0, front_face_center=cube.center,
                       normal=cube.rotation[:, 2], aspect_ratio=1.0, std={}, rms_residual=0.05)
    meas = FaceMeasurement(sides_px=(), corners_px=np.zeros((4, 2)), face_px=np.zeros((0, 2)), blob_mask=blob)

    def rays(px):
        m = mirror_rays(camera, mirror, px)
        return m.points, m.directions
    reason = _shadow_reason(rays, meas, est, None, mirror.axis)
    if refused:
        assert reason is not None and f"{(patch_px - 2) ** 2} of its {n_blob} pixels lie outside the cube" in reason
    else:
        assert reason is None


def test_check_image_takes_8_bit_as_it_is_and_refuses_float_values_outside_0_1():
    from depth.errors import DepthError
    from depth.reconstruct import check_image
    u8 = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3) * 4  # 0 .. 236
    u8[0, 0, 0], u8[-1, -1, -1] = 0, 255
    out = check_image(u8, (5, 4))
    assert out.dtype == np.float64 and np.array_equal(out * 255.0, u8.astype(np.float64))
    assert out.min() == 0.0 and out.max() == 1.0
    # into a given array (`reconstruct`'s, shared with its helper), 8-bit or float, the same values
    for given in (u8, out.copy()):
        buffer = np.full((4, 5, 3), -1.0)
        assert check_image(given, (5, 4), out=buffer) is buffer and np.array_equal(buffer, out)
    for bad in (np.nan, np.inf, -np.inf, 1.0 + 1e-9, -1e-9):  # one channel of one pixel
        img = out.copy()
        img[2, 3, 1] = bad
        with pytest.raises(DepthError, match=r"image: expected values in \[0, 1\]"):
            check_image(img, (5, 4))


def test_detections_packed_to_cross_a_pipe_come_back_as_they_were():
    # `reconstruct` sends its detections to the helper process that outlines the faces cut to their boxes
    import pickle

    from depth.measure import CubeDetection
    from depth.reconstruct import _packed, _unpacked
    rng = np.random.default_rng(3)
    shape = (60, 80)
    dets = []
    for k in range(3):
        blob = np.zeros(shape, dtype=bool)
        blob[10 + k:30 + 2 * k, 5 + 20 * k:18 + 20 * k] = rng.random((20 + k, 13)) < 0.8
        rows, cols = np.flatnonzero(blob.any(axis=1)), np.flatnonzero(blob.any(axis=0))
        bbox = (int(cols[0]), int(rows[0]), int(cols[-1] + 1), int(rows[-1] + 1))
        front = blob & (rng.random(shape) < 0.6)
        side = blob & ~front
        if k == 2:  # a side mask with a pixel beyond the blob's box goes whole
            side = side.copy()
            side[0, 0] = True
        dets.append(CubeDetection(mask=blob, front_face_mask=front, side_face_masks=[side, np.zeros(shape, bool)],
                                  bbox=bbox, color=rng.random(3), achromatic=bool(k % 2), reason=None if k else "x"))
    packed = _packed(dets)
    assert len(pickle.dumps(packed)) < len(pickle.dumps(dets)) / 2
    back = _unpacked(pickle.loads(pickle.dumps(packed)), shape)
    for a, b in zip(dets, back):
        for ma, mb in zip([a.mask, a.front_face_mask] + a.side_face_masks, [b.mask, b.front_face_mask] + b.side_face_masks):
            assert mb.dtype == bool and mb.shape == shape
            np.testing.assert_array_equal(ma, mb)
        assert (a.bbox, a.achromatic, a.reason, a.cut_by_mirror_edge, a.occluded) == \
               (b.bbox, b.achromatic, b.reason, b.cut_by_mirror_edge, b.occluded)
        np.testing.assert_array_equal(a.color, b.color)


@functools.cache
def _grey_cube(height, turn_deg, azimuth_deg=10.0, size=0.05):
    """A grey cube `size` across 0.3 m from the axis, `azimuth_deg` round it from the camera's side and
    `height` from the camera's, facing the mirror axis turned by `turn_deg`, rendered by our ray tracer under
    a light from above (a top face, seen in the mirror by rays going down, is lit brighter than the front
    face): the image (sRGB values in [0, 1]), the blob, the face each pixel shows (`FACE_AXES` of the cube's
    own frame, y up; −1 off the cube; from the render's hit points: the local axis at ±size/2), the cube's
    `CubeEstimate`, the rays, the mirror axis and the camera's up."""
    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import Cube, DirectionalLight, Scene
    from raytrace.truth import mirror_rays

    camera = PinholeCamera.from_look_at((800, 600), (1750.0, 1750.0), None, (0.0, 0.0, 0.55), (0, 0, 0), (0, 1, 0))
    mirror = CylinderMirror(0.1, 0.49, (0, 0, 0), (0, 1, 0))
    azimuth = np.deg2rad(azimuth_deg)
    centre = np.array([0.3 * np.sin(azimuth), height, 0.3 * np.cos(azimuth)])
    turn = np.arctan2(-centre[0], -centre[2]) + np.deg2rad(turn_deg)
    rotation = np.array([[np.cos(turn), 0.0, np.sin(turn)], [0.0, 1.0, 0.0], [-np.sin(turn), 0.0, np.cos(turn)]])
    cube = Cube(size, centre, rotation, [0.5, 0.5, 0.5])
    scene = Scene(mirror, [cube], light=DirectionalLight([0.3, 0.9, 0.4], 0.8, 0.25), background=[0.6, 0.6, 0.65])
    shot = render(scene, camera, spp=4, workers=1)
    blob = shot.object_id == 0
    to_mirror = np.linalg.norm(shot.mirror_point - camera.position, axis=-1)
    seen = shot.mirror_point + (shot.ray_distance - to_mirror)[..., None] * shot.reflected_dir
    local = (seen[blob] - centre) @ rotation
    axis = np.argmax(np.abs(local), axis=1)
    faces = np.full(blob.shape, -1)
    faces[blob] = 2 * axis + (local[np.arange(len(axis)), axis] < 0)

    def rays(px):
        r = mirror_rays(camera, mirror, px)
        return r.points, r.directions

    est = _cube_at(centre, size=size, normal=rotation[:, 2])
    return linear_to_srgb8(shot.image) / 255.0, blob, faces, est, rays, mirror.axis, -camera.R[1]


def _painted(image, faces, colours, seed):
    """`image` with each face in `colours` ({face: grey level}) painted that grey under noise of 2 levels."""
    rng = np.random.default_rng(seed)
    out = image.copy()
    for f, level in colours.items():
        m = faces == f
        out[m] = level + rng.normal(0.0, 2.0 / 255.0, (m.sum(), 3))
    return out


def test_a_grey_cube_whose_faces_show_their_own_brightness_is_not_taken_for_a_flat_region():
    from depth.reconstruct import _flat_region_reason

    image, blob, faces, est, rays, up, sky = _grey_cube(-0.12, 0.0)
    assert np.count_nonzero(faces == 2) > 300 and np.count_nonzero(faces == 4) > 800  # top (local +y), front
    assert image[faces == 2].mean() > image[faces == 4].mean() + 0.2
    assert _flat_region_reason(image, rays, est, blob, up, sky) is None
    # a top face only 0.02 brighter (5 levels of 8 bits) than the front face, under noise of 2 levels, is told
    # from it: the test is a step measured against the noise, not a share of the brightness
    assert _flat_region_reason(_painted(image, faces, {2: 0.41, 4: 0.39}, 1), rays, est, blob, up, sky) is None


def test_a_region_of_one_brightness_read_as_a_cube_with_its_top_face_is_a_flat_region():
    """The cube's pixels painted one grey under noise (a shadow of its outline on a floor): refused, naming
    the top face. Painted white as far as the 8 bits go (a white cube in the sun, every face clipped), not:
    equal brightness there says nothing of the light."""
    from depth.reconstruct import FLAT_REGION_REASON, _flat_region_reason

    image, blob, faces, est, rays, up, sky = _grey_cube(-0.12, 0.0)
    flat = _painted(image, faces, {2: 0.39, 4: 0.39}, 2)
    reason = _flat_region_reason(flat, rays, est, blob, up, sky)
    assert reason is not None and reason.startswith(FLAT_REGION_REASON) and "top face" in reason
    assert _flat_region_reason(flat, rays, est, blob, -up, sky) == reason  # the axis's sign says nothing
    clipped = image.copy()
    clipped[blob] = 1.0
    assert _flat_region_reason(clipped, rays, est, blob, up, sky) is None


def test_a_cube_turned_to_show_a_side_face_is_a_flat_region_only_where_no_face_shows_a_step():
    """Turned 35°, the cube shows a side face beside its top and front faces. Where the top face takes the
    front face's brightness but the side face does not, the faces still tell a cube: kept. Where the side
    face alone takes it, kept: two upright faces turned from the light take the same sky light. All three
    alike: refused."""
    from depth.reconstruct import FLAT_REGION_REASON, _flat_region_reason

    image, blob, faces, est, rays, up, sky = _grey_cube(-0.12, 35.0)
    side = 0 if np.count_nonzero(faces == 0) > np.count_nonzero(faces == 1) else 1
    assert np.count_nonzero(faces == side) > 200 and np.count_nonzero(faces == 2) > 200
    stepped_side = _painted(image, faces, {2: 0.39, side: 0.6, 4: 0.39}, 3)
    assert _flat_region_reason(stepped_side, rays, est, blob, up, sky) is None
    stepped_top = _painted(image, faces, {2: 0.7, side: 0.39, 4: 0.39}, 4)
    assert _flat_region_reason(stepped_top, rays, est, blob, up, sky) is None
    flat = _painted(image, faces, {2: 0.39, side: 0.39, 4: 0.39}, 5)
    reason = _flat_region_reason(flat, rays, est, blob, up, sky)
    assert reason is not None and reason.startswith(FLAT_REGION_REASON)


def test_a_top_face_too_thin_to_judge_refuses_nothing():
    """A cube 1.5 cm across 6 cm below the camera's height: its top face shows 2–3 px tall, fewer than
    `FLAT_FACE_MIN_PX` pixels of it more than a pixel in from its edges, and a cube painted one grey is not
    refused (too few pixels to tell a step by)."""
    from depth.reconstruct import FLAT_FACE_MIN_PX, _cube, _face_colours, _flat_region_reason

    image, blob, faces, est, rays, up, sky = _grey_cube(-0.06, 0.0, azimuth_deg=40.0, size=0.015)
    ys, xs = np.nonzero(blob)
    inner = [n for n, _, _ in _face_colours(image, rays, _cube(est, up), (ys.min() - 2, ys.max() + 3, xs.min() - 2,
                                                                       xs.max() + 3))]
    assert 0 < inner[0] < FLAT_FACE_MIN_PX and inner[4] > 100  # the top face (x: the axis), the front face
    flat = _painted(image, faces, {f: 0.39 for f in range(6)}, 6)
    assert _flat_region_reason(flat, rays, est, blob, up, sky) is None


def test_a_cube_level_with_the_camera_is_judged_by_no_side_face_alone():
    """Level with the camera (and 50° round the axis from it, out of its direct view), the rays that see the
    cube run nearly level: no top face shows, a side face does. A cube painted one grey is not refused: two
    upright faces turned from the light take the same sky light."""
    from depth.reconstruct import _flat_region_reason

    image, blob, faces, est, rays, up, sky = _grey_cube(0.0, 35.0, azimuth_deg=50.0)
    assert np.count_nonzero((faces == 2) | (faces == 3)) == 0  # the top and bottom faces (local y)
    assert np.count_nonzero(faces == 0) + np.count_nonzero(faces == 1) > 500
    flat = _painted(image, faces, {0: 0.39, 1: 0.39, 4: 0.39}, 7)
    assert _flat_region_reason(flat, rays, est, blob, up, sky) is None


def test_a_bottom_face_lit_like_the_front_face_is_no_flat_region():
    """Above the camera's height, the cube is seen by rays going up: its bottom face shows, lit by the
    ambient light alone, as its front face is in our render (within 1 %). A bottom face is lit by the
    ground, which can light it as an upright face in shade is: the cube is kept."""
    from depth.reconstruct import _flat_region_reason

    image, blob, faces, est, rays, up, sky = _grey_cube(0.12, 0.0)
    assert np.count_nonzero(faces == 3) > 300 and np.count_nonzero(faces == 2) == 0  # the bottom face (local −y)
    assert abs(image[faces == 3].mean() - image[faces == 4].mean()) < 0.01
    assert _flat_region_reason(image, rays, est, blob, up, sky) is None
    assert _flat_region_reason(image, rays, est, blob, -up, sky) is None


@pytest.mark.parametrize("later_fits_better", [False, True])
def test_of_two_readings_of_one_face_the_one_with_the_lower_misfit_is_kept(later_fits_better):
    """`_one_per_face` on three readings: two of one face (the second's outline shifted 3 px, each centre
    inside the other's outline) and one elsewhere. The one with the lower edge misfit is kept, whichever
    came first, and the other refused naming the kept one's centre; the third and a refused reading pass."""
    from types import SimpleNamespace

    from depth.reconstruct import SAME_FACE_REASON, _one_per_face

    def reading(x0, misfit, reason=None):
        corners = np.array([[x0, 10.0], [x0 + 20.0, 10.0], [x0 + 20.0, 90.0], [x0, 90.0]])
        return (replace(_cube_at((0.1, 0.0, 0.4)), rms_residual=misfit), SimpleNamespace(corners_px=corners),
                reason, (int(x0), 10, int(x0) + 20, 90))

    first, second = reading(100.0, 0.3), reading(103.0, 0.2 if later_fits_better else 0.4)
    apart, refused = reading(300.0, 0.5), reading(101.0, 0.1, "face outline: too few edge points")
    out = _one_per_face([first, second, apart, refused])
    kept, other = (second, first) if later_fits_better else (first, second)
    passed = [r[0] for r in out if r[2] is None]
    assert len(passed) == 2 and passed[0] is kept[0] and passed[1] is apart[0]
    same = [r for r in out if r[2] and r[2].startswith(SAME_FACE_REASON)]
    assert len(same) == 1 and same[0][0] is other[0]
    centre = np.mean(kept[1].corners_px, axis=0)
    assert f"({centre[0]:.0f}, {centre[1]:.0f}) px" in same[0][2]
    assert [r[2] for r in out if r[0] is refused[0]] == [refused[2]]


def _identical_cubes_image(rig, placements, size=0.04):
    """Our renderer's image (16 spp) of coloured cubes of one size at (distance, azimuth°, turn°) each, and the
    cubes."""
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import DirectionalLight, Scene
    colours = [(0.8, 0.2, 0.2), (0.2, 0.7, 0.2), (0.2, 0.3, 0.8)]
    cubes = [replace(rig.cube(d, az, size=size, yaw_deg=yaw), color=c) for (d, az, yaw), c in zip(placements, colours)]
    light = DirectionalLight(to_light=np.array([0.3, 1.0, 0.5]), intensity=0.8, ambient=0.3)
    scene = Scene(mirror=rig.mirror, objects=tuple(cubes), light=light, background=(0.6, 0.6, 0.6))
    return linear_to_srgb8(render(scene, rig.camera, spp=16, seed=0).image), cubes


@pytest.mark.parametrize("compressed", [False, True])
def test_reconstruct_reads_no_pixel_beyond_its_reading_region(rig, compressed):
    """`reading_region`: the mirror region and `READING_MARGIN_PX` about it, all of the image a reading reads (a raw
    frame's demosaic need not work beyond it). The pixels beyond it, replaced by noise, change no cube and no
    refusal."""
    from depth.reconstruct import READING_MARGIN_PX, reading_region, reconstruct
    image, _ = _identical_cubes_image(rig, [(0.4, -45.0, 0.0), (0.45, 40.0, 10.0), (1.0, 15.0, 0.0)])
    region = reading_region(rig.camera, rig.mirror)
    mirror = mirror_mask(rig.camera, rig.mirror)
    assert np.all(region[mirror]) and np.mean(~region) > 0.1
    cols = np.flatnonzero(~region[300])  # (a row across the mirror: the margin on either side of it)
    assert np.flatnonzero(mirror[300])[[0, -1]].tolist() == [cols[cols < 400][-1] + 1 + READING_MARGIN_PX,
                                                            cols[cols > 400][0] - 1 - READING_MARGIN_PX]
    noisy = image.copy()
    noisy[~region] = np.random.default_rng(3).integers(0, 256, (int(np.sum(~region)), 3), dtype=np.uint8)
    read = [reconstruct(im, rig.camera, rig.mirror, compressed=compressed) for im in (image, noisy)]
    assert len(read[0].cubes) == 3
    assert [c.to_dict() for c in read[1].cubes] == [c.to_dict() for c in read[0].cubes]
    assert [r.to_dict() for r in read[1].refused] == [r.to_dict() for r in read[0].refused]



@pytest.mark.parametrize("stage", ["outline", "estimate", "helper"])
def test_a_face_whose_reading_raises_is_refused_and_the_other_cubes_are_read_as_before(rig, monkeypatch, stage):
    """`_guarded`: an exception no check expects, raised while one face is outlined or estimated (put there for the
    cube leftmost in the image), refuses that face with the exception named, and the image's other cubes come out
    as they do without it (the whole image raised before). A `DepthError`, the caller's input, is raised as it is.
    "helper": read by a helper process forked once the fault is in place (`start_helper`), which estimates the
    coloured faces as their outlines come (`fork_chain`)."""
    import depth.measure
    import depth.reconstruct as rec_module
    import depth.workers
    from depth.errors import DepthError

    image, _ = _identical_cubes_image(rig, [(0.4, -45.0, 0.0), (0.45, 40.0, 10.0), (1.0, 15.0, 0.0)])
    plain = rec_module.reconstruct(image, rig.camera, rig.mirror, workers=1)
    assert len(plain.cubes) == 3 and plain.refused == []
    left = min(plain.cubes, key=lambda c: c.bbox[0])
    module, name = (depth.measure, "face_outline") if stage == "outline" else (rec_module, "estimate_face")
    helped = contextlib.nullcontext
    if stage == "helper":  # (forked once a process, where the estimators' modules are not imported yet: here, now)
        monkeypatch.setattr(rec_module, "_HELPER_FORKED", False)
        monkeypatch.setattr(depth.workers, "will_fork_helper", lambda modules: depth.workers._can_fork())
        helped = rec_module.helper_started
    real = getattr(module, name)

    def failing(error):
        def call(*args, **kwargs):
            face_x = np.mean(np.nonzero(args[1])[1]) if stage == "outline" else np.mean(args[1].corners_px[:, 0])
            if face_x < left.bbox[2]:  # (bbox: x0, y0, x1, y1)
                raise error
            return real(*args, **kwargs)
        return call

    monkeypatch.setattr(module, name, failing(FloatingPointError("put here by the test")))
    with helped():
        got = rec_module.reconstruct(image, rig.camera, rig.mirror, workers=1)
    assert [c.to_dict() for c in got.cubes] == [c.to_dict() for c in plain.cubes if c is not left]
    assert [r.reason for r in got.refused] == [
        f"{rec_module.INTERNAL_ERROR_REASON} (FloatingPointError: put here by the test): please report it"]
    assert got.refused[0].bbox == left.bbox
    monkeypatch.setattr(module, name, failing(DepthError("cube_size: put here by the test")))
    with pytest.raises(DepthError, match="put here by the test"), helped():
        rec_module.reconstruct(image, rig.camera, rig.mirror, workers=1)


def test_exact_shape_prior_reads_a_far_cube_at_the_scale_of_two_near_ones_in_a_rendered_image(rig):
    """Three cubes 4 cm across, two near (fronts 17–19 px wide), one 1 m from the axis (7.5 px wide), whose
    own edges hardly fix its scale: its depth σ alone is about as large as its depth. `exact_shape_prior` reads
    all three at one size, within 1 % of the truth; each centre within 1 % and each depth within 3 σ, the far
    cube's σ a fraction of what `exact` alone gives it."""
    from depth.priors import common_size
    from depth.reconstruct import reconstruct
    image, cubes = _identical_cubes_image(rig, [(0.4, -45.0, 0.0), (0.45, 40.0, 10.0), (1.0, 15.0, 0.0)])
    alone = reconstruct(image, rig.camera, rig.mirror, method="exact")
    rec = reconstruct(image, rig.camera, rig.mirror, method="exact_shape_prior")
    assert rec.method == "exact_shape_prior" and not rec.refused and len(rec.cubes) == len(alone.cubes) == 3
    sizes = {c.estimate.size for c in rec.cubes}
    assert len(sizes) == 1 and abs(next(iter(sizes)) / 0.04 - 1.0) < 0.01
    # the size is that of the three `exact` readings, weighed by their σ
    fused = common_size([c.estimate.size for c in alone.cubes], [c.estimate.std["size"] for c in alone.cubes])
    assert sizes == {fused.size} and rec.cubes[0].estimate.std["size"] == fused.std
    for found, ref in zip(rec.cubes, alone.cubes):
        cube = min(cubes, key=lambda q: np.linalg.norm(found.estimate.center - q.center))
        assert np.linalg.norm(found.estimate.center - cube.center) < 0.01 * rig.depth(cube)
        assert abs(found.depth - rig.depth(cube)) < 3.0 * found.depth_std
        d = found.to_dict()
        assert d["method"] == "exact_shape_prior" and d["uncertainty_scale"] >= 1.0 and d["edge_misfit_px"] < 0.3
        if cube is cubes[2]:
            assert found.depth_std < 0.2 * ref.depth_std
    # The common size's σ carried through each fit: at that size known, `exact` reads the same depths with σ from
    # the edges alone; the rest is the scale's. At a fixed image a cube's distance from the (virtual) viewpoint
    # scales with its size, and that distance lies between its depth less the mirror's radius and its depth plus
    # the camera's distance from the axis (0.55 m): so does the share of the σ the size adds, per unit σ_S / S.
    size, size_std = rec.cubes[0].estimate.size, rec.cubes[0].estimate.std["size"]
    known = reconstruct(image, rig.camera, rig.mirror, method="exact", cube_size=size)
    for found, at in zip(rec.cubes, known.cubes):
        assert found.depth == pytest.approx(at.depth, rel=1e-9)
        scale_share = np.sqrt(found.depth_std ** 2 - at.depth_std ** 2) / (size_std / size)
        assert found.depth - rig.mirror.radius < scale_share < found.depth + 0.55


@pytest.mark.parametrize("placements", [[(0.4, -45.0, 0.0), (0.45, 40.0, 10.0)], [(0.4, -45.0, 0.0)]])
def test_exact_shape_prior_counts_its_fits_at_the_common_size_in_the_progress(rig, placements):
    # outlines, estimates, then the fits at the common size: three steps a blob, counted up to the total (which
    # a lone cube, fitted at no common size, reaches as well)
    from depth.reconstruct import reconstruct
    image, _ = _identical_cubes_image(rig, placements)
    for method, steps in (("exact", 2), ("exact_shape_prior", 3)):
        calls = []
        reconstruct(image, rig.camera, rig.mirror, method=method, progress=lambda d, t: calls.append((d, t)))
        blobs = len(placements)
        assert {t for _, t in calls} == {steps * blobs}
        done = [d for d, _ in calls]
        assert done == sorted(done) and done[-1] == steps * blobs and done[0] <= blobs


def test_exact_shape_prior_sets_aside_a_cube_of_another_size_and_says_so(rig):
    """Three 4 cm cubes and one 4.6 cm across, 0.6 m from the axis: `exact` reads its size 4.77 ± 0.2 cm, over 3 σ
    from the others', so it is left out of their common size (within 1 % of 4 cm). It is still read at that size,
    which puts it nearer than it is (at 0.47 m), but its σ covers its own reading too, and its result says its size
    was set aside; the others' do not. (Larger, at 5 cm, no 4 cm cube fits its edges there: refused.)"""
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import DirectionalLight, Scene
    from depth.reconstruct import reconstruct
    _, cubes = _identical_cubes_image(rig, [(0.4, -45.0, 0.0), (0.45, 40.0, 10.0), (1.0, 15.0, 0.0)])
    big = replace(rig.cube(0.6, -25.0, size=0.046), color=(0.8, 0.7, 0.1))
    light = DirectionalLight(to_light=np.array([0.3, 1.0, 0.5]), intensity=0.8, ambient=0.3)
    scene = Scene(mirror=rig.mirror, objects=tuple(cubes) + (big,), light=light, background=(0.6, 0.6, 0.6))
    image = linear_to_srgb8(render(scene, rig.camera, spp=16, seed=0).image)
    rec = reconstruct(image, rig.camera, rig.mirror, method="exact_shape_prior")
    assert len(rec.cubes) == 4 and not rec.refused, [r.reason for r in rec.refused]
    aside = [c for c in rec.cubes if c.to_dict()["size_set_aside"]]
    assert len(aside) == 1
    found = aside[0]
    x, _, z = found.estimate.center
    assert np.degrees(np.arctan2(x, z)) == pytest.approx(-25.0, abs=2.0)  # the 4.6 cm cube's direction
    assert found.depth < rig.depth(big) - 0.05 and abs(found.depth - rig.depth(big)) < 3.0 * found.depth_std
    for found in rec.cubes:
        assert abs(found.estimate.size / 0.04 - 1.0) < 0.01
        if found is not aside[0]:
            cube = min(cubes, key=lambda q: np.linalg.norm(found.estimate.center - q.center))
            assert abs(found.depth - rig.depth(cube)) < 3.0 * found.depth_std


def test_exact_shape_prior_refuses_a_lone_cube_and_a_given_size(rig):
    from depth.errors import DepthError
    from depth.reconstruct import reconstruct
    image, _ = _identical_cubes_image(rig, [(0.4, -45.0, 0.0)])
    rec = reconstruct(image, rig.camera, rig.mirror, method="exact_shape_prior")
    assert rec.cubes == [] and len(rec.refused) == 1
    assert "exact_shape_prior: the shape prior needs at least 2 cubes read with a size σ; 1 was" in rec.refused[0].reason
    assert len(reconstruct(image, rig.camera, rig.mirror, method="exact").cubes) == 1
    with pytest.raises(DepthError, match="cube_size: exact_shape_prior estimates the cubes' common size"):
        reconstruct(image, rig.camera, rig.mirror, method="exact_shape_prior", cube_size=0.04)


@pytest.mark.parametrize("kwargs, match", [
    (dict(cube_size_std=0.0004), "cube_size_std: the σ of a known cube_size, carried through method exact's fit: "
                                 "give cube_size and method exact$"),
    (dict(cube_size=0.04, cube_size_std=0.0004, method="ddar"), "give cube_size and method exact, not ddar"),
    (dict(cube_size=0.04, cube_size_std=-0.0004), "cube_size_std: expected a σ of the edge length in metres, >= 0, "
                                                   "got -0.0004"),
    (dict(cube_size=0.04, cube_size_std=float("inf")), "cube_size_std: expected a σ of the edge length"),
])
def test_a_known_size_s_sigma_is_refused_without_the_size_or_the_exact_estimator(rig, kwargs, match):
    from depth.errors import DepthError
    from depth.reconstruct import reconstruct
    image = np.zeros((rig.camera.resolution[1], rig.camera.resolution[0], 3), np.uint8)
    with pytest.raises(DepthError, match=match):
        reconstruct(image, rig.camera, rig.mirror, **kwargs)


@pytest.mark.parametrize("kwargs, match", [
    (dict(floor_std=0.001), "floor_std: the σ of a floor's height: give floor_height too"),
    (dict(floor_height=float("nan")), "floor_height: expected a height in metres along the mirror's axis, got nan"),
    (dict(floor_height=-0.245, method="ddar"), "floor_height: cubes standing on a floor are fitted by method exact, "
                                               "not ddar"),
    (dict(floor_height=-0.245, method="exact_shape_prior"), "fitted by method exact, not exact_shape_prior"),
    (dict(floor_height=-0.245, cube_size=0.04), "floor_height: the floor fixes each cube's size; give it or "
                                                "cube_size, not both"),
    (dict(floor_height=-0.245, floor_std=-0.001), "floor_std: expected the σ of the floor's height in metres, >= 0"),
])
def test_a_floor_the_arguments_cannot_have_is_refused(rig, kwargs, match):
    from depth.errors import DepthError
    from depth.reconstruct import reconstruct
    image = np.zeros((rig.camera.resolution[1], rig.camera.resolution[0], 3), np.uint8)
    with pytest.raises(DepthError, match=match):
        reconstruct(image, rig.camera, rig.mirror, **kwargs)


@pytest.mark.parametrize("yaw, roll, merged", [(0.0, 0.0, False), (20.0, 0.0, True), (10.0, 12.0, False)])
def test_the_front_face_corners_reported_are_where_the_fitted_pose_puts_them(rig, yaw, roll, merged):
    """`exact`'s pose gives its front face's corners (`CubeEstimate.front_face_corners`); reflected by the exact
    law, they are the true face's to 0.01 px on the rig's exact edges: a face facing the axis, one turned 20° whose
    side face merged with it (the outline its contour), one turned in its own plane by 12°. Reported in the order of
    the measured outline's corners, even where that outline is the silhouette's, pixels beyond the front face (here
    its left corners 6 px further left); another estimator's reading, without such corners, keeps the measured ones."""
    from depth.reconstruct import _front_face_px
    from raytrace.truth import cube_truth
    cube = rig.cube(0.5, 15.0, yaw_deg=yaw, roll_deg=roll)
    meas = rig.measure(cube, n=30, merged=merged)
    est = estimate_face(rig.rays, meas, "exact", up=rig.mirror.axis)
    assert est, est.reason
    truth = np.asarray(cube_truth(rig.camera, rig.mirror, cube)["front_face_corners_px"])
    order = np.argsort(np.arctan2(*(truth - truth.mean(axis=0)).T[::-1]))  # any order the outline may have
    silhouette = truth[order] + np.where(truth[order][:, :1] < truth[:, 0].mean(), [-6.0, 0.0], [0.0, 0.0])
    got = _front_face_px(est, rig.camera, rig.mirror, silhouette)
    np.testing.assert_allclose(got, truth[order], atol=0.01)
    ddar = estimate_face(rig.rays, meas, "ddar")
    assert ddar.front_face_corners is None
    assert _front_face_px(ddar, rig.camera, rig.mirror, silhouette) is silhouette
