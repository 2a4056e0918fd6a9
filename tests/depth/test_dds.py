"""Tests of depth.dds: depth from the slope of a projected frontal line, including vertical lines."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from depth import dds
from depth.errors import DegenerateGeometryError
from depth.xslit import XSlit


def image_angle_of_line(xs: XSlit, p0, direction_xy, z):
    """Project two points of a frontal 3D line and return the image direction angle (independent of dds)."""
    a = np.array([p0[0], p0[1], z])
    b = a + np.array([direction_xy[0], direction_xy[1], 0.0])
    uv = xs.project(np.stack([a, b]))
    d = uv[1] - uv[0]
    return np.arctan2(d[1], d[0])


def slope_of(phi):
    c = np.cos(phi)
    return np.inf if abs(c) < 1e-300 else np.tan(phi)


@pytest.mark.parametrize("theta1, theta2", [(45.0, 135.0), (0.0, 90.0), (20.0, 110.0), (-30.0, 75.0)])
@pytest.mark.parametrize("obj_angle_deg", [0.0, 90.0, 17.0, -60.0, 120.0])
def test_line_slope_round_trip(theta1, theta2, obj_angle_deg):
    xs = XSlit.from_degrees(-0.045, -0.5, theta1, theta2)
    phi_o = np.deg2rad(obj_angle_deg)
    if min(abs(np.sin(phi_o - xs.theta1)), abs(np.sin(phi_o - xs.theta2))) < 1e-6:
        with pytest.raises(DegenerateGeometryError, match="parallel to a slit"):
            dds.ratio_from_angle(phi_o, xs)
        return
    for z in (0.1, 0.6, 3.0):
        phi_i = image_angle_of_line(xs, (0.02, -0.03), (np.cos(phi_o), np.sin(phi_o)), z)
        z_back = dds.depth_from_slope(slope_of(phi_i), slope_of(phi_o), xs)
        assert z_back == pytest.approx(z, rel=1e-9)
        # And the forward model gives the observed direction (angles mod π).
        phi_pred = dds.slope_angle_at_depth(z, slope_of(phi_o), xs)
        assert np.sin(phi_pred - phi_i) == pytest.approx(0.0, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(t1=st.floats(-np.pi, np.pi), dt=st.floats(0.3, np.pi - 0.3), phi=st.floats(-np.pi / 2, np.pi / 2),
       z=st.floats(0.05, 10.0), z1=st.floats(-1.0, -0.01), ratio=st.floats(1.5, 50.0))
def test_random_angles_round_trip(t1, dt, phi, z, z1, ratio):
    xs = XSlit(z1, z1 * ratio, t1, t1 + dt)
    if min(abs(np.sin(phi - xs.theta1)), abs(np.sin(phi - xs.theta2))) < 1e-3:
        return
    phi_i = image_angle_of_line(xs, (0.0, 0.0), (np.cos(phi), np.sin(phi)), z)
    z_back = dds.depth_from_slope(slope_of(phi_i), slope_of(phi), xs)
    assert z_back == pytest.approx(z, rel=1e-9)


def test_ratio_is_the_kappa_decomposition_of_the_direction():
    xs = XSlit.from_degrees(-1.0, -2.0, 45.0, 135.0)
    for phi in np.deg2rad([0.0, 30.0, 89.0, 90.0, -20.0]):
        k = xs.to_kappa([[np.cos(phi), np.sin(phi)]])[0]
        assert dds.ratio_from_angle(phi, xs) == pytest.approx(k[0] / k[1], rel=1e-12)
    # The horizontal direction at 45°/135°: (1, 0) = 0.707·v1 − 0.707·v2, so r = −1.
    assert dds.ratio_from_slope(0.0, xs) == pytest.approx(-1.0)


def test_vertical_slopes_do_not_divide_by_zero():
    xs = XSlit.from_degrees(-1.0, -2.0, 45.0, 135.0)
    assert dds.ratio_from_slope(np.inf, xs) == pytest.approx(dds.ratio_from_slope(-np.inf, xs))
    assert dds.ratio_from_slope(np.inf, xs) == pytest.approx(1.0)  # (0, 1) = 0.707·v1 + 0.707·v2


def test_depth_std_from_angle_matches_monte_carlo():
    xs = XSlit.from_degrees(-0.045, -0.5, 45.0, 135.0)
    z, phi_o = 0.4, 0.0
    phi_i = dds.slope_angle_at_depth(z, np.tan(phi_o), xs)
    sigma = 2e-4
    rng = np.random.default_rng(3)
    samples = dds.depth_from_slope(np.tan(phi_i + rng.normal(0, sigma, 20000)), 0.0, xs)
    assert np.std(samples) == pytest.approx(dds.depth_std_from_angle(phi_i, 0.0, sigma, xs), rel=0.05)
