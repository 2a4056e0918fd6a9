"""Tests of xslit_fit.tiles: per-tile two-slit fits of a cylinder ray map."""

import numpy as np
import pytest
from xslit_rays import cylinder_rays

from xslit_fit import FitError, fit_tiles


def test_tile_map_of_a_cylinder():
    radius, distance = 0.1, 0.6
    p, d, valid = cylinder_rays(radius, distance, width=320, height=240, focal=1500.0)
    calls = []
    tm = fit_tiles(p, d, valid, tiles=(3, 5), max_rays_per_tile=600,
                   progress=lambda done, total: calls.append((done, total)))
    assert tm.shape == (3, 5) and calls[-1] == (15, 15) and len(calls) == 15
    # Bounds tile the image exactly.
    assert tm.bounds[0, 0].tolist() == [0, 0, 64, 80]
    assert tm.bounds[-1, -1].tolist() == [256, 160, 320, 240]
    covered = np.zeros(valid.shape, int)
    for x0, y0, x1, y1 in tm.bounds.reshape(-1, 4):
        covered[y0:y1, x0:x1] += 1
    assert (covered == 1).all()
    # The centre tile (64 x 80 px, centred on the camera's perpendicular to the axis):
    # slits R·do/(2·do + R) and do behind the surface, 1 %. The plane of the tile's frame is
    # through its mirror points, within (R − sqrt(R² − (40 px · do / f)²)) ≈ 2e-4 m of the
    # surface point on the perpendicular: that is inside the 1 %.
    do = distance - radius
    assert tm.valid[1, 2]
    assert -tm.z1[1, 2] == pytest.approx(radius * do / (2 * do + radius), rel=0.01)
    assert -tm.z2[1, 2] == pytest.approx(do, rel=0.01)
    # Mirror symmetry of the set-up: left/right and top/bottom tiles agree.
    ok = tm.valid & tm.valid[:, ::-1] & tm.valid[::-1, :]
    assert ok.sum() >= 9
    assert np.allclose(tm.z1[ok], tm.z1[:, ::-1][ok], rtol=0.02)
    assert np.allclose(tm.z1[ok], tm.z1[::-1, :][ok], rtol=0.02)
    assert np.allclose(tm.baseline[ok], np.abs(tm.z2 - tm.z1)[ok])
    assert np.allclose(tm.ratio[ok], (tm.z2 / tm.z1)[ok])
    # Tiles without enough mirror pixels carry a reason and no invented numbers.
    bad = ~tm.valid
    assert np.isnan(tm.z1[bad]).all() and all(r for r in tm.reasons[bad])
    assert (tm.n_rays <= 600).all()


def test_max_rms_invalidates_poor_tiles():
    p, d, valid = cylinder_rays(0.1, 0.6, width=160, height=120, focal=375.0)
    tm = fit_tiles(p, d, valid, tiles=(1, 1), max_rms=1e-6)
    assert not tm.valid[0, 0] and tm.reasons[0, 0] == "rms above max_rms" and tm.rms[0, 0] > 1e-6


def test_validation():
    p, d, valid = cylinder_rays(0.1, 0.6, width=16, height=12, focal=40.0)
    with pytest.raises(FitError, match="tiles: expected 1 <= ny <= 12"):
        fit_tiles(p, d, valid, tiles=(13, 2))
    with pytest.raises(FitError, match="valid: expected shape \\(12, 16\\)"):
        fit_tiles(p, d, valid[:5], tiles=(2, 2))
    with pytest.raises(FitError, match="ray_dirs: expected the shape of ray_points"):
        fit_tiles(p, d[:, :3], valid, tiles=(2, 2))


def test_background_tiles_are_invalid_with_a_reason():
    # At f = 375 px the mirror's silhouette is at tan = R/sqrt(D² − R²), 63.4 px either side
    # of the centre column 79.5, so the outermost 16 px columns see no mirror.
    p, d, valid = cylinder_rays(0.1, 0.6, width=160, height=120, focal=375.0)
    assert not valid[:, :16].any() and not valid[:, -16:].any()
    tm = fit_tiles(p, d, valid, tiles=(2, 10), max_rays_per_tile=300)
    assert not tm.valid[:, [0, -1]].any()
    assert set(tm.reasons[:, [0, -1]].ravel()) == {"too few rays"}
    assert np.isnan(tm.z1[:, [0, -1]]).all() and (tm.n_rays[:, [0, -1]] == 0).all()
    assert tm.valid[:, 4:6].all()
