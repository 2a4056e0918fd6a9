"""Tests of xslit_fit.plucker: Plücker coordinates, reciprocal product, distances, four-line transversals."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from xslit_rays import glc_bundle, unit

from xslit_fit import FitError, Line, lines_through_four, plucker, ray_line_distance, reciprocal_product

vec = st.lists(st.floats(-10, 10, allow_nan=False), min_size=3, max_size=3).map(np.array)


@settings(max_examples=50, deadline=None)
@given(vec, vec, st.floats(-5, 5))
def test_moment_does_not_depend_on_the_point_on_the_ray(p, d, t):
    if np.linalg.norm(d) < 1e-3:
        return
    a = plucker(p, d)
    b = plucker(p + t * d, 3.0 * d)
    assert np.allclose(a, b, atol=1e-9 * (1 + np.abs(p).max()))


@settings(max_examples=50, deadline=None)
@given(vec, vec, vec, vec)
def test_reciprocal_product_is_signed_distance_times_sine(p1, d1, p2, d2):
    if min(np.linalg.norm(d1), np.linalg.norm(d2)) < 1e-2:
        return
    d1, d2 = unit(d1), unit(d2)
    # Independent closed form: |(p2 − p1)·(d1 × d2)|, the distance times |sin(angle)|.
    expected = abs((p2 - p1) @ np.cross(d1, d2))
    got = abs(reciprocal_product(plucker(p1, d1)[0], plucker(p2, d2)[0]))
    assert got == pytest.approx(expected, abs=1e-9)


def test_reciprocal_product_vanishes_for_meeting_lines():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(10, 3))                              # common points
    a = plucker(x + 2 * (da := unit(rng.normal(size=(10, 3)))), da)
    b = plucker(x - 3 * (db := unit(rng.normal(size=(10, 3)))), db)
    assert np.max(np.abs(reciprocal_product(a, b))) < 1e-12


def test_ray_line_distance_matches_closest_points_by_least_squares():
    rng = np.random.default_rng(2)
    p, d = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    q, ell = rng.normal(size=3), rng.normal(size=3)
    got = ray_line_distance(p, d, q, ell)
    for i in range(50):  # independent: minimise |p + s d − q − t ell| over (s, t)
        st_ = np.linalg.lstsq(np.stack([d[i], -ell], 1), q - p[i], rcond=None)[0]
        assert got[i] == pytest.approx(np.linalg.norm(p[i] + st_[0] * d[i] - q - st_[1] * ell))


def test_ray_line_distance_of_parallel_lines_is_their_separation():
    d = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, -1.0]])
    p = np.array([[3.0, 4.0, 7.0], [1.0, 0.0, 0.0]])
    assert np.allclose(ray_line_distance(p, d, [0, 0, 0], [0, 0, 1]), [5.0, 1.0])


def test_lines_through_four_recovers_the_two_lines_they_meet():
    rng = np.random.default_rng(3)
    for _ in range(5):
        s1 = (rng.normal(size=3), unit(rng.normal(size=3)))
        s2 = (rng.normal(size=3), unit(rng.normal(size=3)))
        a = s1[0] + rng.normal(size=(4, 1)) * s1[1]
        b = s2[0] + rng.normal(size=(4, 1)) * s2[1]
        found = lines_through_four(plucker(a, b - a))
        assert len(found) == 2
        for s in (s1, s2):
            true = Line(*s).plucker()
            # same line up to sign: compare normalised 6-vectors
            assert min(min(np.linalg.norm(f - true), np.linalg.norm(f + true)) for f in found) < 1e-9


def test_lines_through_four_of_a_bilinear_congruence_is_empty():
    p, d = glc_bundle("bilinear", np.random.default_rng(4), n=2)
    assert lines_through_four(plucker(p, d)) == []


def test_lines_through_four_rejects_bad_input():
    with pytest.raises(FitError, match="lines: expected a finite \\(4, 6\\)"):
        lines_through_four(np.zeros((3, 6)))
    with pytest.raises(FitError, match="not on the Klein quadric"):
        lines_through_four(np.ones((4, 6)))
    rays = plucker(np.zeros((4, 3)), np.eye(3)[[0, 1, 2, 0]])   # a repeated line
    with pytest.raises(FitError, match="linearly dependent"):
        lines_through_four(rays)


def test_validation_names_the_argument():
    with pytest.raises(FitError, match="directions: expected the shape of points"):
        plucker(np.zeros((3, 3)), np.ones((2, 3)))
    with pytest.raises(FitError, match="directions: expected non-zero"):
        plucker(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(FitError, match="line_direction: expected a non-zero direction"):
        ray_line_distance(np.zeros((1, 3)), np.ones((1, 3)), [0, 0, 0], [0, 0, 0])
