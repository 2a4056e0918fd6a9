"""A dark cube whose side face is lit like its front face, the two merged into one outline.

Unseen holdout 1515's scene 1 (`python -m bench.holdout 1515`), cube 2: a black cube 58.2 mm across, turned 18.5°,
under the sky, its side face as dark as its front face. `exact` reads the merged outline as the cube's outer
contour; on Mitsuba's render it lands on a cube seen square on, 41.3 mm across at 0.39 m (truth 0.68 m), 42.7 % off
at −31.5 σ, its edges fitting to 0.17 px. Rendered here by our renderer (16 samples a pixel) with light from straight
above alone, so that the front and side faces take the ambient light alike and the top face more, the same happens:
43.1 % off at −20.8 σ.

The contour model is not at fault: fitted to the measured edge points each moved onto the nearest point of the true
cube's exactly reflected edges, it recovers the pose exactly. The outline measured is: it is fitted as a quadrilateral,
whose bottom-right corner lies below the side face's back bottom vertex (the side face's bottom edge rises towards the
back), and the last points of its right and bottom sides, sampled up to that corner, lie 5.4–7.6 px off the true
outline. With them the cube seen square on fits better (0.40 px rms) than the true pose does (0.71 px).
"""

import dataclasses
import functools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube
from raytrace.truth import cube_truth, mirror_rays


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


def _rays(camera, mirror):
    def rays(px):
        r = mirror_rays(camera, mirror, px)
        return r.points, r.directions
    return rays


def test_the_merged_outline_s_contour_model_recovers_the_cube_from_its_exact_edges():
    from depth.estimate import estimate_face
    from raytrace.truth import reflection_pixels

    image, camera, mirror, cube = _scene()
    meas = _measured(image, camera, mirror)
    assert meas.side_gaps_px[1] < 0.25  # no side face told apart from the front face: one outline
    vertices = cube.vertices()
    along = np.linspace(0.0, 1.0, 400)[:, None]
    edges = np.concatenate([reflection_pixels(camera, mirror, vertices[i] + along * (vertices[j] - vertices[i]))[0]
                            for i in range(8) for j in range(i + 1, 8)
                            if np.isclose(np.linalg.norm(vertices[i] - vertices[j]), cube.size)])
    edges = edges[np.all(np.isfinite(edges), axis=1)]
    exact = tuple(edges[np.argmin(np.linalg.norm(np.asarray(sp)[:, None] - edges[None], axis=2), axis=1)]
                  for sp in meas.sides_px)
    est = estimate_face(_rays(camera, mirror), dataclasses.replace(meas, sides_px=exact), method="exact",
                        up=mirror.axis)
    truth = cube_truth(camera, mirror, cube)
    assert np.linalg.norm(est.center - truth["center"]) / truth["depth"] < 0.002
    assert est.size == pytest.approx(cube.size, rel=0.002)
    assert est.rms_residual < 0.05


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="a side face merged with the front face: the quadrilateral outline's last points run past "
                          "the side face's back bottom vertex (known limit; ninety-eighth session)")
def test_a_black_cube_s_side_face_merged_with_its_front_face_is_read_within_its_sigma():
    from depth.reconstruct import reconstruct

    image, camera, mirror, cube = _scene()
    rec = reconstruct(image, camera, mirror, workers=1)
    truth = cube_truth(camera, mirror, cube)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]
    found = rec.cubes[0]
    assert abs(found.depth - truth["depth"]) < 3.0 * found.depth_std  # (now 43 % off at −20.8 σ)
    assert np.linalg.norm(found.estimate.center - truth["center"]) / truth["depth"] < 0.03
