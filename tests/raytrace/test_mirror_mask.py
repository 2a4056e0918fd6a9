"""mirror_mask (block-refined) against the per-pixel hit mask of mirror_rays."""

import numpy as np
import pytest

from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.truth import mirror_mask, mirror_rays


@pytest.mark.parametrize("resolution, focal, position, look_at, axis, block", [
    ((320, 240), 350.0, (0.0, 0.0, 0.55), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 8),
    ((333, 251), 500.0, (0.1, 0.2, 0.6), (0.0, 0.05, 0.0), (0.0, 1.0, 0.0), 8),
    ((200, 300), 300.0, (0.0, 0.0, 0.5), (0.02, 0.0, 0.0), (0.2, 1.0, 0.1), 16),
    ((160, 120), 900.0, (0.0, 0.0, 0.55), (0.0, 0.24, 0.0), (0.0, 1.0, 0.0), 4),  # the rim in view
])
def test_mask_matches_every_pixel_ray(resolution, focal, position, look_at, axis, block):
    cam = PinholeCamera.from_look_at(resolution, (focal, focal), None, position, look_at, (0.0, 1.0, 0.0))
    mirror = CylinderMirror(0.1, 0.49, (0.0, 0.0, 0.0), axis)
    w, h = resolution
    expected = mirror_rays(cam, mirror).hit.reshape(h, w)
    assert 0 < expected.sum() < expected.size or expected.all()
    np.testing.assert_array_equal(mirror_mask(cam, mirror, block=block), expected)


def test_a_mirror_without_a_hit_test_of_its_own_is_masked_by_its_intersect():
    """`mirror_mask` asks a mirror's `hits` where it has one (`CylinderMirror`), else its `intersect`: a
    mirror offering only `intersect` gets the same mask."""
    cam = PinholeCamera.from_look_at((160, 120), (150.0, 150.0), None, (0.0, 0.0, 0.55), (0.0, 0.0, 0.0),
                                     (0.0, 1.0, 0.0))
    mirror = CylinderMirror(0.1, 0.49, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))

    class IntersectOnly:
        def intersect(self, origins, directions):
            return mirror.intersect(origins, directions)

    mask = mirror_mask(cam, mirror)
    assert 0 < mask.sum() < mask.size
    np.testing.assert_array_equal(mirror_mask(cam, IntersectOnly()), mask)
