"""A dark cube whose side face is lit like its front face, the two merged into one outline.

Unseen holdout 1515's scene 1 (`python -m bench.holdout 1515`), cube 2: a black cube 58.2 mm across, turned 18.5°,
under the sky, its side face as dark as its front face. `exact` reads the merged outline as the cube's outer
contour. The contour model is exact: fitted to the measured edge points each moved onto the nearest point of the true
cube's exactly reflected edges, it recovers the pose exactly. The outline measured is not: it is fitted as a
quadrilateral, whose bottom-right corner lies below the side face's back bottom vertex (the side face's bottom edge
rises towards the back), and the last points of its right and bottom sides, sampled up to that corner, lie 2.7–7.6 px
off the true outline. Those few points raised the contour reading's misfit (Mitsuba's render: 0.105 → 0.47 px rms at
the true pose) past that of the reading with the side read as the front face's own edge, a cube seen square on
(`depth.estimate._background_sides`), which stood: 41.3 mm across at 0.39 m (truth 0.68 m), 42.7 % off at −31.5 σ.
Since the ninety-eighth session the two readings are compared by their misfits over the edge points within
`GROSS_MISFIT_PX` of each (`CubeEstimate.inlier_rms`: 0.174 px for the contour reading, 0.167 px for the other, which
then stands only under 0.8 times the first): 4.5 % off on Mitsuba's render. Rendered here by our renderer
(16 samples a pixel) with light from straight above alone, so that the front and side faces take the ambient light
alike and the top face more, the same outline was read 43.1 % off at −20.8 σ; now its contour reading, 5.9 % off,
misfits the edges by 0.62 px and the blob is refused as a shadow (0.45 px): the cube is still not read.
"""

import dataclasses
import functools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mirror_ray_maps import rays_of
from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube
from raytrace.truth import cube_truth


@functools.cache
def _scene():
    """(image, camera, mirror, cube): the black cube, our renderer, light from above, noise of 2 levels."""
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import DirectionalLight, Scene

    camera = PinholeCamera.from_look_at((1600, 1200), (2562.993, 2562.993), None, (0.0, -0.02861, 0.54424), (0, 0, 0),
                                        (0, 1, 0))
    mirror = CylinderMirror(0.122, 0.69298, (0, 0, 0), (0, 1, 0))
    cube = Cube(0.0582, (-0.2031, -0.14715, 0.64954), Rotation.from_euler("y", 181.1611, degrees=True).as_matrix(),
                [0.06, 0.06, 0.06])
    light = DirectionalLight((0.0, 1.0, 0.0), 0.6, 0.5)  # the upright faces lit alike, the top face more
    shot = render(Scene(mirror, [cube], light=light, background=[0.75, 0.77, 0.8]), camera, spp=16, workers=1)
    noisy = linear_to_srgb8(shot.image) + np.random.default_rng(1).normal(0.0, 2.0, shot.image.shape)
    return np.clip(np.round(noisy), 0, 255).astype(np.uint8), camera, mirror, cube


def _measured(image, camera, mirror):
    """The detection's one face, outlined and measured as `reconstruct` does (an uncompressed image)."""
    from depth.measure import detect_cubes, face_outline
    from depth.reconstruct import _measurement, _pixels
    from raytrace.truth import mirror_mask

    img = image / 255.0
    (det,) = detect_cubes(img, mirror_mask(camera, mirror))
    outline = face_outline(img, det.front_face_mask, channels="colour", blur_domain="linear",
                           faint_sides=det.achromatic)
    return _measurement(img, det.mask, outline, _pixels(det.front_face_mask), "colour", False)


def _on_the_true_edges(meas, camera, mirror, cube):
    """The measurement's edge points, side by side, each moved onto the nearest point of the images of the cube's
    12 edges (400 points each, reflected by the exact law: `raytrace.truth.reflection_pixels`)."""
    from raytrace.truth import reflection_pixels

    vertices = cube.vertices()
    along = np.linspace(0.0, 1.0, 400)[:, None]
    edges = np.concatenate([reflection_pixels(camera, mirror, vertices[i] + along * (vertices[j] - vertices[i]))[0]
                            for i in range(8) for j in range(i + 1, 8)
                            if np.isclose(np.linalg.norm(vertices[i] - vertices[j]), cube.size)])
    edges = edges[np.all(np.isfinite(edges), axis=1)]
    return tuple(edges[np.argmin(np.linalg.norm(np.asarray(sp)[:, None] - edges[None], axis=2), axis=1)]
                 for sp in meas.sides_px)


def test_the_merged_outline_s_contour_model_recovers_the_cube_from_its_exact_edges():
    from depth.estimate import estimate_face

    image, camera, mirror, cube = _scene()
    meas = _measured(image, camera, mirror)
    assert meas.side_gaps_px[1] < 0.25  # no side face told apart from the front face: one outline
    exact = _on_the_true_edges(meas, camera, mirror, cube)
    est = estimate_face(rays_of(camera, mirror), dataclasses.replace(meas, sides_px=exact), method="exact",
                        up=mirror.axis)
    truth = cube_truth(camera, mirror, cube)
    assert np.linalg.norm(est.center - truth["center"]) / truth["depth"] < 0.002
    assert est.size == pytest.approx(cube.size, rel=0.002)
    assert est.rms_residual < 0.05


def test_a_few_points_measured_off_the_outline_are_left_out_of_the_inlier_misfit():
    from depth.estimate import GROSS_MISFIT_PX, estimate_face

    image, camera, mirror, cube = _scene()
    meas = _measured(image, camera, mirror)
    exact = _on_the_true_edges(meas, camera, mirror, cube)
    rays = rays_of(camera, mirror)
    on = estimate_face(rays, dataclasses.replace(meas, sides_px=exact), method="exact", up=mirror.axis)
    assert on.inlier_rms == on.rms_residual < 1e-6  # every point within GROSS_MISFIT_PX: one misfit
    bottom = exact[3].copy()
    bottom[-4:, 1] += np.array([10.0, 12.0, 14.0, 16.0])  # the last 4 of 31 points far below the outline
    off = estimate_face(rays, dataclasses.replace(meas, sides_px=exact[:3] + (bottom,)), method="exact",
                        up=mirror.axis)
    assert GROSS_MISFIT_PX == 2.0
    assert off.rms_residual > 0.3  # the four count in the misfit...
    assert off.inlier_rms < 0.1  # ...not in the misfit over the points within 2 px (the fit, pulled by them, 0.05)
    bottom = exact[3].copy()
    bottom[-4:, 1] += 1.8  # 1.8 px below it: misfit, not gross
    near = estimate_face(rays, dataclasses.replace(meas, sides_px=exact[:3] + (bottom,)), method="exact",
                         up=mirror.axis)
    assert near.inlier_rms == near.rms_residual > 0.05


@functools.cache
def _reconstructed():
    """`reconstruct` of `_scene`'s image, once for the tests that read it."""
    from depth.reconstruct import reconstruct

    image, camera, mirror, _ = _scene()
    return reconstruct(image, camera, mirror, workers=1)


def test_the_merged_outline_is_no_longer_read_as_a_cube_seen_square_on():
    _, camera, mirror, cube = _scene()
    rec = _reconstructed()
    truth = cube_truth(camera, mirror, cube)
    for found in rec.cubes:  # (read 43.1 % off at −20.8 σ before; now refused as a shadow, its misfit 0.62 px)
        assert abs(found.depth - truth["depth"]) < 3.0 * found.depth_std


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="a side face merged with the front face: its contour reading misfits the edges by 0.62 px "
                          "and is refused as a shadow (known limit; ninety-eighth session)")
def test_a_black_cube_s_side_face_merged_with_its_front_face_is_read_within_its_sigma():
    _, camera, mirror, cube = _scene()
    rec = _reconstructed()
    truth = cube_truth(camera, mirror, cube)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    found = rec.cubes[0]
    assert abs(found.depth - truth["depth"]) < 3.0 * found.depth_std
    assert np.linalg.norm(found.estimate.center - truth["center"]) / truth["depth"] < 0.03
