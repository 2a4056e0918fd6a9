"""The ray map the estimators take, bound to a camera and a mirror (a helper module of the tests beside it, not a
test module: imported by name, as pytest puts this directory on the path)."""

import numpy as np

from raytrace.truth import mirror_rays


def rays_of(camera, mirror):
    """The function from pixels (N, 2) to their reflected rays' (points (N, 3), directions (N, 3)) of `camera`
    looking at `mirror` (`raytrace.truth.mirror_rays`), as `depth.reconstruct` hands it to the estimators."""
    def rays(px):
        r = mirror_rays(camera, mirror, np.asarray(px, dtype=np.float64))
        return r.points, r.directions
    return rays
