"""Tests of depth.xslit: Eqn. pinproj against an independent two-slit ray construction."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from depth.errors import DegenerateGeometryError, DepthError
from depth.xslit import XSlit


def ray_through_two_lines(p, a1, d1, a2, d2):
    """Independent construction: the line through p meeting lines (a1, d1) and (a2, d2).

    It lies in the plane spanned by p and line 1, and in the plane spanned by p and line 2;
    its direction is the cross product of the two planes' normals.
    """
    n1 = np.cross(d1, a1 - p)
    n2 = np.cross(d2, a2 - p)
    return np.cross(n1, n2)


def image_by_construction(xs: XSlit, p):
    d1 = np.array([np.cos(xs.theta1), np.sin(xs.theta1), 0.0])
    d2 = np.array([np.cos(xs.theta2), np.sin(xs.theta2), 0.0])
    d = ray_through_two_lines(p, np.array([0, 0, xs.z1]), d1, np.array([0, 0, xs.z2]), d2)
    t = -p[2] / d[2]
    return (p + t * d)[:2]


slit_depth = st.floats(-5.0, -0.01) | st.floats(0.01, 5.0)
angle = st.floats(-np.pi, np.pi)


@settings(max_examples=200, deadline=None)
@given(z1=slit_depth, z2=slit_depth, t1=angle, dt=st.floats(0.2, np.pi - 0.2),
       x=st.floats(-3, 3), y=st.floats(-3, 3), z=st.floats(6.0, 50.0))
def test_projection_matches_two_slit_construction(z1, z2, t1, dt, x, y, z):
    if abs(z1 - z2) < 1e-3:
        return
    xs = XSlit(z1, z2, t1, t1 + dt)
    p = np.array([x, y, z])
    expected = image_by_construction(xs, p)
    np.testing.assert_allclose(xs.project(p)[0], expected, rtol=1e-9, atol=1e-9 * (1 + abs(x) + abs(y)))


@settings(max_examples=100, deadline=None)
@given(z1=slit_depth, z2=slit_depth, t1=angle, dt=st.floats(0.2, np.pi - 0.2),
       u=st.floats(-2, 2), v=st.floats(-2, 2), z=st.floats(6.0, 50.0))
def test_back_projection_inverts_projection_and_ray_meets_both_slits(z1, z2, t1, dt, u, v, z):
    if abs(z1 - z2) < 1e-3:
        return
    xs = XSlit(z1, z2, t1, t1 + dt)
    p = xs.back_project([[u, v]], z)
    np.testing.assert_allclose(xs.project(p)[0], [u, v], atol=1e-9)
    o, d = xs.ray([[u, v]])
    for zi, th in ((xs.z1, xs.theta1), (xs.z2, xs.theta2)):
        # distance between the ray and slit i: |(o - a)·(d × s)| / |d × s|
        s = np.array([np.cos(th), np.sin(th), 0.0])
        c = np.cross(d[0], s)
        dist = abs(np.dot(o[0] - np.array([0, 0, zi]), c)) / np.linalg.norm(c)
        assert dist < 1e-9 * (1 + abs(zi))


def test_kappa_round_trip_and_basis():
    xs = XSlit.from_degrees(-1.0, -3.0, 30.0, 100.0)
    rng = np.random.default_rng(1)
    xy = rng.normal(size=(20, 2))
    k = xs.to_kappa(xy)
    np.testing.assert_allclose(k[:, 0:1] * [np.cos(xs.theta1), np.sin(xs.theta1)]
                               + k[:, 1:2] * [np.cos(xs.theta2), np.sin(xs.theta2)], xy, atol=1e-12)
    np.testing.assert_allclose(xs.from_kappa(k), xy, atol=1e-12)


@pytest.mark.parametrize("args, match", [
    ((1.0, 1.0), "pinhole"),
    ((0.0, 1.0), "image plane"),
    ((1.0, 2.0, 0.3, 0.3 + np.pi), "parallel slits"),
    ((np.nan, 2.0), "finite"),
])
def test_degenerate_xslits_are_refused(args, match):
    with pytest.raises(DepthError, match=match):
        XSlit(*args)


def test_pinhole_error_is_a_degenerate_geometry_error():
    with pytest.raises(DegenerateGeometryError):
        XSlit(2.0, 2.0)


def test_bad_points_name_the_argument():
    xs = XSlit(-1.0, -2.0)
    with pytest.raises(DepthError, match="points: expected an \\(N, 3\\) array"):
        xs.project([[1.0, 2.0]])
    with pytest.raises(DepthError, match="slit's depth"):
        xs.project([[1.0, 2.0, -1.0]])
