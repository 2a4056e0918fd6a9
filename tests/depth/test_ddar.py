"""Tests of depth.ddar: round trips through XSlit projection, finite differences, the arch scene."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from depth import ddar
from depth.errors import DegenerateGeometryError, DepthError
from depth.xslit import XSlit


def measured_aspect_ratio(xs: XSlit, center, kx, ky):
    """Project a frontal rectangle with sides kx·v1, ky·v2 and measure its AR from the image corners."""
    basis = xs.basis
    corners_k = np.array([[0, 0], [kx, 0], [kx, ky], [0, ky]], dtype=float)
    xy = corners_k @ basis.T + center[:2]
    pts = np.column_stack([xy, np.full(4, center[2])])
    k_img = xs.to_kappa(xs.project(pts))
    return (k_img[1, 0] - k_img[0, 0]) / (k_img[3, 1] - k_img[0, 1])


virtual_slits = st.tuples(st.floats(-2.0, -0.01), st.floats(-2.0, -0.01)).filter(
    lambda t: abs(t[0] - t[1]) > 1e-2 * max(abs(t[0]), abs(t[1])))


@settings(max_examples=300, deadline=None)
@given(slits=virtual_slits, t1=st.floats(-np.pi, np.pi), dt=st.floats(0.3, np.pi - 0.3),
       cx=st.floats(-1, 1), cy=st.floats(-1, 1), z=st.floats(0.05, 20.0),
       kx=st.floats(0.01, 2.0), ky=st.floats(0.01, 2.0))
def test_frontal_rectangle_round_trip_is_exact(slits, t1, dt, cx, cy, z, kx, ky):
    z1, z2 = slits
    xs = XSlit(z1, z2, t1, t1 + dt)
    r_i = measured_aspect_ratio(xs, np.array([cx, cy, z]), kx, ky)
    np.testing.assert_allclose(r_i, ddar.aspect_ratio(z, z1, z2, kx / ky), rtol=1e-9)
    z_back = ddar.depth_from_aspect_ratio(r_i, z1, z2, kx / ky)
    assert abs(z_back - z) <= 1e-9 * z + 1e-12 * abs(z2)


def test_arch_scene_round_trip_is_exact():
    # The paper's PO-XSlit: z1 = -3.2 cm, z2 = -346.7 cm; circles (r_o = 1) at 900 and 2300 cm.
    xs = XSlit(-3.2, -346.7)
    for z in (900.0, 2300.0):
        r_i = measured_aspect_ratio(xs, np.array([12.0, -40.0, z]), 150.0, 150.0)
        assert ddar.depth_from_aspect_ratio(r_i, -3.2, -346.7) == pytest.approx(z, rel=1e-12)


@pytest.mark.parametrize("z1, z2", [(-3.2, -346.7), (-0.045, -0.5), (0.5, 2.0), (-1.0, 3.0)])
def test_sensitivity_and_depth_derivative_match_finite_differences(z1, z2):
    zn = ddar.near_depth(z1, z2)
    for z in zn + np.array([0.5, 3.0, 40.0, 900.0]) * max(abs(z1), abs(z2)):
        h = 1e-6 * z
        fd = (ddar.aspect_ratio(z + h, z1, z2, 1.3) - ddar.aspect_ratio(z - h, z1, z2, 1.3)) / (2 * h)
        assert ddar.sensitivity(z, z1, z2, 1.3) == pytest.approx(fd, rel=1e-6)
        r = ddar.aspect_ratio(z, z1, z2, 1.3)
        hr = 1e-7 * abs(r)
        fdz = (ddar.depth_from_aspect_ratio(r + hr, z1, z2, 1.3, strict=False)
               - ddar.depth_from_aspect_ratio(r - hr, z1, z2, 1.3, strict=False)) / (2 * hr)
        assert ddar.depth_derivative(r, z1, z2, 1.3) == pytest.approx(fdz, rel=1e-5)


@pytest.mark.parametrize("z1, z2", [(-3.2, -346.7), (-0.045, -0.5), (0.5, 2.0)])
@pytest.mark.parametrize("eps", [1e-3, 1e-4, 0.05])
def test_max_discernible_depth_is_where_ar_is_eps_from_its_limit(z1, z2, eps):
    z_max = ddar.max_discernible_depth(z1, z2, r_o=1.0, eps=eps)
    r_inf = z2 / z1
    assert abs(ddar.aspect_ratio(z_max, z1, z2) - r_inf) == pytest.approx(eps, rel=1e-9)
    # Deeper than z_max, the AR is closer than eps to its limit: indiscernible.
    assert abs(ddar.aspect_ratio(1.01 * z_max, z1, z2) - r_inf) < eps


def test_max_discernible_depth_defaults_to_one_over_image_size():
    assert ddar.max_discernible_depth(-3.2, -346.7, image_size=800) == \
        ddar.max_discernible_depth(-3.2, -346.7, eps=1 / 800)
    with pytest.raises(DepthError, match="eps"):
        ddar.max_discernible_depth(-3.2, -346.7)


def test_ar_limits_bracket_every_reachable_ar():
    for z1, z2 in [(-3.2, -346.7), (0.5, 2.0), (-1.0, 3.0)]:
        lo, hi = ddar.aspect_ratio_limits(z1, z2, 1.0)
        zn = ddar.near_depth(z1, z2)
        r = ddar.aspect_ratio(zn + np.geomspace(1e-3, 1e6, 50), z1, z2)
        assert np.all((r > lo) & (r < hi))


def test_unreachable_ar_and_pinhole_are_refused():
    with pytest.raises(DepthError, match="outside the reachable aspect-ratio range"):
        ddar.depth_from_aspect_ratio(200.0, -3.2, -346.7)
    assert np.isnan(ddar.depth_from_aspect_ratio(200.0, -3.2, -346.7, strict=False))
    with pytest.raises(DegenerateGeometryError, match="pinhole"):
        ddar.depth_from_aspect_ratio(2.0, -1.0, -1.0)


def test_depth_std_matches_monte_carlo():
    rng = np.random.default_rng(7)
    z1, z2, z = -0.045, -0.5, 0.35
    r = ddar.aspect_ratio(z, z1, z2)
    sigma = 1e-3 * r
    samples = ddar.depth_from_aspect_ratio(r + rng.normal(0, sigma, 20000), z1, z2)
    predicted = ddar.depth_std_from_aspect_ratio(r, sigma, z1, z2)
    assert np.std(samples) == pytest.approx(predicted, rel=0.05)
