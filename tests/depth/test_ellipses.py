"""Tests of depth.ellipses: the direct ellipse fit, contour AR of rendered ellipses, rectangle moments."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from depth import ddar
from depth.ellipses import closed_contours, ellipse_ratio, fit_ellipse, rectangle_extents
from depth.lines import XSlitSampling
from depth.xslit import XSlit


def ellipse_points(c, a, b, phi, n=200, t0=0.0, t1=2 * np.pi):
    t = np.linspace(t0, t1, n, endpoint=False)
    r = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    return np.asarray(c) + (np.column_stack([a * np.cos(t), b * np.sin(t)]) @ r.T)


@settings(max_examples=30, deadline=None)
@given(st.floats(-50, 50), st.floats(-50, 50), st.floats(1, 100), st.floats(0.05, 1.0), st.floats(0, np.pi))
def test_fit_recovers_exact_ellipse(cx, cy, a, ecc, phi):
    b = a * ecc
    fit = fit_ellipse(ellipse_points((cx, cy), a, b, phi))
    assert fit
    np.testing.assert_allclose(fit.center, (cx, cy), atol=1e-6 * a)
    np.testing.assert_allclose(fit.semi_axes, sorted([a, b], reverse=True), rtol=1e-6)
    # half extent along x of a rotated ellipse: sqrt(a² cos² φ + b² sin² φ)
    assert fit.half_extent((1, 0)) == pytest.approx(np.hypot(a * np.cos(phi), b * np.sin(phi)), rel=1e-6)


def test_fit_on_an_arc_and_agreement_with_opencv():
    rng = np.random.default_rng(3)
    p = ellipse_points((10, -4), 40, 25, 0.3, n=400)
    p += rng.normal(0, 0.05, p.shape)
    fit = fit_ellipse(p)
    (cx, cy), (w, h), ang = cv2.fitEllipse(p.astype(np.float32))
    np.testing.assert_allclose(fit.center, (cx, cy), atol=0.02)
    np.testing.assert_allclose(fit.semi_axes, sorted([w / 2, h / 2], reverse=True), rtol=2e-3)
    half = fit_ellipse(ellipse_points((0, 0), 30, 10, 0.0, n=100, t1=np.pi))  # a half ellipse (an arch)
    np.testing.assert_allclose(half.semi_axes, (30, 10), rtol=1e-6)


def test_failed_fits_are_falsy_with_reason():
    assert not fit_ellipse([[0, 0], [1, 1], [2, 0]])
    assert "points" in fit_ellipse([[0, 0], [1, 1], [2, 0]]).reason
    line = np.column_stack([np.arange(20.0), 2 * np.arange(20.0)])
    bad = fit_ellipse(line)
    assert not bad and bad.reason


def coverage_image(inside, shape, n=8):
    """Box-filtered coverage of a region by n×n sub-pixel samples (independent of the package)."""
    h, w = shape
    v, u = np.mgrid[0:h, 0:w].astype(float)
    acc = np.zeros(shape)
    for ox in (np.arange(n) + 0.5) / n - 0.5:
        for oy in (np.arange(n) + 0.5) / n - 0.5:
            acc += inside(u + ox, v + oy)
    return acc / n ** 2


@pytest.mark.parametrize("theta1_deg", [0.0, 45.0])
def test_ellipse_ratio_of_a_projected_circle(theta1_deg):
    xs = XSlit.from_degrees(-3.2, -346.7, theta1_deg, theta1_deg + 90)
    z, radius = 1500.0, 300.0
    s_u, s_v = xs.kappa_scales(z)
    sampling = XSlitSampling(xs, (radius * s_u / 40, radius * s_v / 30), (59.5, 59.5))
    # pixel → κ in plane, inside the imaged circle: (κ_u/s_u)² + (κ_v/s_v)² <= R²
    def inside(u, v):
        k = sampling.kappa(np.column_stack([u.ravel(), v.ravel()]))
        return ((k[:, 0] / s_u) ** 2 + (k[:, 1] / s_v) ** 2 <= radius ** 2).reshape(u.shape)
    img = coverage_image(inside, (120, 120))
    (contour,) = closed_contours(img, 0.5)
    r_i, fit = ellipse_ratio(contour, sampling)
    assert fit
    assert r_i == pytest.approx(float(ddar.aspect_ratio(z, xs.z1, xs.z2, 1.0)), rel=2e-3)


def test_rectangle_extents_from_exact_coverage():
    xs = XSlit.from_degrees(6.0, 12.0, 0.0, 90.0)
    sampling = XSlitSampling(xs, (0.02, 0.03), (0.0, 0.0))
    u0, u1, v0, v1 = 10.3, 47.85, 5.6, 21.1
    u = np.arange(60.0)
    v = np.arange(30.0)
    cu = np.clip(np.minimum(u + 0.5, u1) - np.maximum(u - 0.5, u0), 0, 1)  # exact pixel overlaps
    cv = np.clip(np.minimum(v + 0.5, v1) - np.maximum(v - 0.5, v0), 0, 1)
    ext = rectangle_extents(np.outer(cv, cu), sampling)
    # Moments of the sampled (not continuous) box-filtered profile: a sampling-phase error of
    # a few thousandths of a pixel remains; 0.01 px bounds it.
    np.testing.assert_allclose(ext / (0.02, 0.03), [u1 - u0, v1 - v0], atol=0.01)
    ext_shifted = rectangle_extents(np.outer(cv, cu) * 0 + np.outer(cv, np.roll(cu, 3)), sampling)
    np.testing.assert_allclose(ext_shifted, ext, rtol=1e-12)  # a whole-pixel shift changes nothing


def test_rectangle_extents_rejects_empty():
    xs = XSlit.from_degrees(6.0, 12.0)
    with pytest.raises(ValueError, match="covers no pixel"):
        rectangle_extents(np.zeros((5, 5)), XSlitSampling(xs, 0.1, (0, 0)))
