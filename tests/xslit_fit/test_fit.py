"""Tests of xslit_fit.fit: exact XSlits, the cylinder mirror's virtual slits, and failures by reason."""

import numpy as np
import pytest
from xslit_rays import cylinder_rays, glc_bundle, random_rotation, unit, xslit_rays

from xslit_fit import REASONS, FailedFit, FitError, SlitFit, fit_two_slits


def random_slits(rng):
    """Two skew slits at random positions and directions (at least 0.3 rad apart)."""
    while True:
        u1, u2 = unit(rng.normal(size=3)), unit(rng.normal(size=3))
        if np.linalg.norm(np.cross(u1, u2)) > 0.3:
            return (rng.normal(size=3), u1), (2 * rng.normal(size=3), u2)


def line_error(line, true):
    """(direction error, distance of the fitted point from the true line)."""
    q, u = true
    return (np.linalg.norm(np.cross(line.direction, u)),
            np.linalg.norm(np.cross(line.point - q, u)))


@pytest.mark.parametrize("seed", range(8))
def test_exact_xslit_slits_are_recovered_to_1e9(seed):
    rng = np.random.default_rng(seed)
    s1, s2 = random_slits(rng)
    p, d = xslit_rays(s1, s2, 300, rng)
    fit = fit_two_slits(p, d)
    assert isinstance(fit, SlitFit) and fit
    scale = 1 + max(np.abs(s1[0]).max(), np.abs(s2[0]).max())
    # Slit order per CONVENTIONS: slit 1 is nearer the plane through the ray centroid
    # that is parallel to both slits (computed here from the true slits).
    normal = unit(np.cross(s1[1], s2[1]))
    c = p.mean(axis=0)
    near, far = sorted([s1, s2], key=lambda s: abs((s[0] - c) @ normal))
    for line, true in zip(fit.slits, (near, far)):
        ang, dist = line_error(line, true)
        assert ang < 1e-9 and dist < 1e-9 * scale
    assert fit.rms_distance < 1e-9 * scale and fit.max_distance < 1e-9 * scale
    assert fit.n_rays == 300 and np.isfinite(fit.condition)


def test_linear_step_alone_is_exact_on_exact_rays():
    rng = np.random.default_rng(11)
    s1, s2 = random_slits(rng)
    p, d = xslit_rays(s1, s2, 100, rng)
    fit = fit_two_slits(p, d, refine=False)
    assert fit and not fit.refined
    assert max(min(line_error(ln, s)[1] for s in (s1, s2)) for ln in fit.slits) < 1e-9


def test_zero_weights_ignore_outliers():
    rng = np.random.default_rng(12)
    s1, s2 = random_slits(rng)
    p, d = xslit_rays(s1, s2, 200, rng)
    p_out, d_out = rng.normal(size=(20, 3)), unit(rng.normal(size=(20, 3)))
    w = np.r_[np.ones(200), np.zeros(20)]
    fit = fit_two_slits(np.r_[p, p_out], np.r_[d, d_out], weights=w)
    assert fit and fit.n_rays == 200
    assert max(min(line_error(ln, s)[1] for s in (s1, s2)) for ln in fit.slits) < 1e-9
    unweighted = fit_two_slits(np.r_[p, p_out], np.r_[d, d_out])
    assert not unweighted or unweighted.rms_distance > 1e3 * fit.rms_distance


def test_noisy_xslit_residual_is_the_noise_level():
    rng = np.random.default_rng(13)
    s1, s2 = random_slits(rng)
    p, d = xslit_rays(s1, s2, 2000, rng)
    sigma = 1e-4
    fit = fit_two_slits(p + rng.normal(scale=sigma, size=p.shape), d)
    # A point displaced by isotropic noise σ moves its ray by ~σ·sqrt(2/3) across each slit.
    assert 0.3 * sigma < fit.rms_distance < 1.5 * sigma
    assert max(min(line_error(ln, s)[0] for s in (s1, s2)) for ln in fit.slits) < 1e-2


@pytest.mark.parametrize("radius, distance", [(0.1, 0.6), (0.05, 0.4), (0.15, 1.0), (0.1, 0.3)])
def test_cylinder_mirror_central_roi_slits(radius, distance):
    """Camera on the perpendicular through the axis; 40×40 px ROI at the image centre."""
    p, d, valid = cylinder_rays(radius, distance, roi=(300, 220, 340, 260))
    assert valid.all()
    fit = fit_two_slits(p.reshape(-1, 3), d.reshape(-1, 3))
    assert fit
    do = distance - radius                                  # camera-to-surface distance
    behind_axis_slit = radius * do / (2 * do + radius)      # convex-mirror image in the section
    s1, s2 = fit.slits
    assert abs(s1.direction[1]) > 0.9999                    # slit 1 ∥ mirror axis (world y)
    assert abs(s2.direction[0]) > 0.9999                    # slit 2 ⟂ axis, horizontal
    on1 = s1.point - s1.point[1] / s1.direction[1] * s1.direction      # where y = 0
    on2 = s2.point - s2.point[0] / s2.direction[0] * s2.direction      # where x = 0
    assert radius - on1[2] == pytest.approx(behind_axis_slit, rel=0.01)
    assert abs(on1[0]) < 0.01 * behind_axis_slit
    assert radius - on2[2] == pytest.approx(do, rel=0.01)
    assert abs(on2[1]) < 0.01 * do                          # at the camera's height (y = 0)


def test_parallel_rays_fail():
    rng = np.random.default_rng(20)
    p = rng.normal(size=(50, 3))
    fit = fit_two_slits(p, np.tile([0.3, -0.2, 1.0], (50, 1)))
    assert isinstance(fit, FailedFit) and not fit and bool(fit) is False
    assert fit.reason == "parallel rays"


def test_pinhole_bundle_fails_as_a_pencil_without_slits():
    rng = np.random.default_rng(21)
    centre = np.array([0.3, -1.0, 2.0])
    d = unit(rng.normal(size=(200, 3)) * [0.3, 0.3, 1.0] + [0, 0, 1])
    p = centre + rng.uniform(0.5, 2.0, (200, 1)) * d
    fit = fit_two_slits(p, d)
    assert not fit and fit.reason == "pencil (single centre of projection)"
    assert not hasattr(fit, "slits")


def test_noisy_pinhole_is_still_a_pencil():
    rng = np.random.default_rng(22)
    d = unit(rng.normal(size=(500, 3)) * [0.3, 0.3, 1.0] + [0, 0, 1])
    p = rng.uniform(0.5, 2.0, (500, 1)) * d + rng.normal(scale=1e-7, size=(500, 3))
    fit = fit_two_slits(p, d)
    assert not fit and fit.reason in ("pencil (single centre of projection)", "ill-conditioned")


@pytest.mark.parametrize("n", [0, 1, 3])
def test_too_few_rays(n):
    rng = np.random.default_rng(23)
    fit = fit_two_slits(rng.normal(size=(n, 3)), unit(rng.normal(size=(n, 3))))
    assert not fit and fit.reason == "too few rays"


def test_zero_weights_leave_too_few_rays():
    rng = np.random.default_rng(24)
    s1, s2 = random_slits(rng)
    p, d = xslit_rays(s1, s2, 10, rng)
    fit = fit_two_slits(p, d, weights=[1, 1, 1] + [0] * 7)
    assert not fit and fit.reason == "too few rays"


@pytest.mark.parametrize("kind, reason", [
    ("pinhole", "pencil (single centre of projection)"),
    ("pencil", "double root (one slit)"),
    ("pushbroom", "slit at infinity (pushbroom)"),
    ("orthographic", "parallel rays"),
    ("twisted_orthographic", "double root at infinity (twisted orthographic)"),
    ("bilinear", "complex roots"),
])
def test_degenerate_glc_bundles_fail_with_their_reason(kind, reason):
    p, d = glc_bundle(kind, np.random.default_rng(30), c=(0.2, -0.1))
    fit = fit_two_slits(p, d)
    assert not fit and fit.reason == reason and reason in REASONS


def test_coplanar_rays_fail():
    rng = np.random.default_rng(31)
    rot = random_rotation(rng)
    p = np.c_[rng.normal(size=(40, 2)), np.zeros(40)] @ rot.T
    d = unit(np.c_[rng.normal(size=(40, 2)), np.zeros(40)]) @ rot.T
    fit = fit_two_slits(p, d)
    assert not fit and fit.reason == "coplanar rays"


def test_validation():
    with pytest.raises(FitError, match="points: expected shape \\(N, 3\\)"):
        fit_two_slits(np.zeros((5, 2)), np.ones((5, 2)))
    with pytest.raises(FitError, match="weights: expected shape \\(5,\\)"):
        fit_two_slits(np.zeros((5, 3)), np.ones((5, 3)), weights=np.ones(4))
    with pytest.raises(FitError, match="weights: expected finite non-negative"):
        fit_two_slits(np.zeros((5, 3)), np.ones((5, 3)), weights=-np.ones(5))
    with pytest.raises(FitError, match="points: expected finite numbers"):
        fit_two_slits(np.full((5, 3), np.nan), np.ones((5, 3)))
