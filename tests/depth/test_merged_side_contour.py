"""A known limit: a dark cube whose side face is lit like its front face, the two merged into one outline.

Unseen holdout 1515's scene 1 (`python -m bench.holdout 1515`), cube 2: a black cube 58.2 mm across, turned 18.5°,
under the sky, its side face as dark as its front face. `exact` reads the merged outline as the cube's outer
contour; on Mitsuba's render it lands on a cube seen square on, 41.3 mm across at 0.39 m (truth 0.68 m), 42.7 % off
at −31.5 σ, the edges fitting to 0.17 px. Rendered here by our renderer with light from straight above alone (the
front and side faces take the ambient light alike, the top face more), the same outline is read at the right pose,
0.7 % off, but its edges miss that pose by 0.52 px rms (the bottom side by 1.05 px), and the blob is refused as a
shadow: at the true pose the contour model does not explain the merged outline to the pixel's noise.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube
from raytrace.truth import cube_truth


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="a side face merged with the front face: the contour model misses the merged outline by "
                          "0.5 px at the true pose (known limit; ninety-eighth session)")
def test_a_black_cube_s_side_face_merged_with_its_front_face_is_read_at_the_outline_s_noise():
    from raytrace.render import linear_to_srgb8, render
    from raytrace.scene import DirectionalLight, Scene

    from depth.reconstruct import reconstruct

    camera = PinholeCamera.from_look_at((1600, 1200), (2562.993, 2562.993), None, (0.0, -0.02861, 0.54424), (0, 0, 0),
                                        (0, 1, 0))
    mirror = CylinderMirror(0.122, 0.69298, (0, 0, 0), (0, 1, 0))
    cube = Cube(0.0582, (-0.2031, -0.14715, 0.64954), Rotation.from_euler("y", 181.1611, degrees=True).as_matrix(),
                [0.06, 0.06, 0.06])
    light = DirectionalLight((0.0, 1.0, 0.0), 0.6, 0.5)  # the upright faces lit alike, the top face more
    shot = render(Scene(mirror, [cube], light=light, background=[0.75, 0.77, 0.8]), camera, spp=4, workers=1)
    noisy = linear_to_srgb8(shot.image) + np.random.default_rng(1).normal(0.0, 2.0, shot.image.shape)
    image = np.clip(np.round(noisy), 0, 255).astype(np.uint8)
    rec = reconstruct(image, camera, mirror, workers=1)
    truth = cube_truth(camera, mirror, cube)
    assert len(rec.cubes) == 1, [r.reason for r in rec.refused]  # (refused now: "its outline is no square face's")
    found = rec.cubes[0]
    assert np.linalg.norm(found.estimate.center - truth["center"]) / truth["depth"] < 0.02
    assert found.estimate.rms_residual < 0.3
