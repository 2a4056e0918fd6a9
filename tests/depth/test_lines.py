"""Tests of depth.lines: pixel ↔ plane sampling, segment ratios of projected lines, AR-range grouping, LSD."""

import cv2
import numpy as np
import pytest

from depth import ddar, dds
from depth.lines import XSlitSampling, detect_segments, group_by_ratio, segment_depths, segment_ratios
from depth.xslit import XSlit

XS = XSlit.from_degrees(-3.6, -717.9, 45.0, 135.0)


def test_sampling_round_trip_and_isotropic_case():
    rng = np.random.default_rng(0)
    s = XSlitSampling(XS, (0.3, 0.002), (100.0, 50.0))
    px = rng.uniform(0, 200, (50, 2))
    np.testing.assert_allclose(s.to_pixels(s.to_plane(px)), px, atol=1e-9)
    iso = XSlitSampling(XS, 0.01, (100.0, 50.0))
    np.testing.assert_allclose(iso.to_plane(px), (px - (100.0, 50.0)) * 0.01, atol=1e-12)
    # pitch p_k scales κ_k only
    k = s.kappa(px)
    np.testing.assert_allclose(k / (0.3, 0.002), XS.to_kappa(px - (100.0, 50.0)), atol=1e-9)
    with pytest.raises(ValueError, match="pitch"):
        XSlitSampling(XS, (0.1, -1.0), (0, 0))


@pytest.mark.parametrize("direction, r_o", [((1.0, 0.0), -1.0), ((0.0, 1.0), 1.0), ((1.0, 0.5), None)])
def test_segment_ratio_of_projected_frontal_lines(direction, r_o):
    """r_i of the image of a frontal 3D line equals Eqn. ardef; its DDS depth is the line's depth."""
    if r_o is None:
        r_o = float(dds.ratio_from_angle(np.arctan2(direction[1], direction[0]), XS))
    s = XSlitSampling(XS, (0.05, 0.0004), (320.0, 240.0))
    z = np.array([300.0, 800.0, 2500.0])
    a = np.column_stack([np.full(3, 40.0), np.full(3, -20.0), z])
    b = a + np.column_stack([np.full(3, 90 * direction[0]), np.full(3, 90 * direction[1]), np.zeros(3)])
    seg = np.hstack([s.to_pixels(XS.project(a)), s.to_pixels(XS.project(b))])
    r_i = segment_ratios(seg, s)
    np.testing.assert_allclose(r_i, ddar.aspect_ratio(z, XS.z1, XS.z2, r_o), rtol=1e-9)
    np.testing.assert_allclose(segment_depths(r_i, r_o, XS), z, rtol=1e-7)


def test_group_by_ratio_ranges():
    ro = np.array([-1.0, 1.0])  # 3D horizontal and vertical for θ1 = 45°, θ2 = 135°
    r_inf = XS.z2 / XS.z1
    r_i = np.array([-5.0, 5.0, -r_inf * 0.99, r_inf * 0.999, 0.5, -0.2, r_inf * 1.5, np.nan])
    np.testing.assert_array_equal(group_by_ratio(r_i, XS, ro), [0, 1, 0, 1, -1, -1, -1, -1])
    # the range ends are Eqn. ratiorange: r_o at z → z_near = 0 and (z2/z1)·r_o at z → ∞
    lo, hi = ddar.aspect_ratio_limits(XS.z1, XS.z2, 1.0)
    assert (lo, hi) == pytest.approx((1.0, r_inf))


def test_lsd_finds_drawn_lines_with_their_angles():
    img = np.zeros((120, 160), np.uint8)
    ends = [((20.0, 20.0), (140.0, 50.0)), ((30.0, 100.0), (60.0, 10.0))]
    for p, q in ends:
        cv2.line(img, tuple(int(round(c * 16)) for c in p), tuple(int(round(c * 16)) for c in q), 255, 3,
                 cv2.LINE_AA, shift=4)
    seg = detect_segments(img, min_length=20)
    ang = np.degrees(np.arctan2(seg[:, 3] - seg[:, 1], seg[:, 2] - seg[:, 0])) % 180
    for p, q in ends:
        want = np.degrees(np.arctan2(q[1] - p[1], q[0] - p[0])) % 180
        assert np.min(np.abs((ang - want + 90) % 180 - 90)) < 0.5
    with pytest.raises(ValueError, match="gray"):
        detect_segments(np.zeros(5))
