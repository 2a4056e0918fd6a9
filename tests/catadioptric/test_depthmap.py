"""Tests of `catadioptric depthmap`: dense metric depth of a small XSlit image, and refusals that write nothing."""

import re

import cv2
import numpy as np
import pytest
import tomli_w

from catadioptric.cli import main
from depth import ddar
from depth.lines import XSlitSampling
from depth.xslit import XSlit

Z1, Z2, TH1, TH2 = -1.0, -10.0, 45.0, 135.0
NEAR, FAR = 8.0, 20.0            # depths of the left (x < 0) and right (x >= 0) frontal planes
W, H = 200, 150


def sampling():
    xs = XSlit.from_degrees(Z1, Z2, TH1, TH2)
    p2 = 0.004
    # pitch ratio = r_i at z = 12, so 3D-horizontal and -vertical lines image near the pixel diagonals
    return XSlitSampling(xs, (p2 * float(ddar.aspect_ratio(12.0, Z1, Z2, 1.0)), p2), ((W - 1) / 2, (H - 1) / 2))


def grid_shade(p, period, width=None):
    """Gray value of a light plane ruled with dark 3D-horizontal and -vertical lines, at points (N, 3)."""
    width = 0.09 * period if width is None else width
    fx = np.abs(((p[:, 0] / period) % 1) - 0.5) * period
    fy = np.abs(((p[:, 1] / period) % 1) - 0.5) * period
    return np.where((fx > period / 2 - width / 2) | (fy > period / 2 - width / 2), 0.15, 0.85)


def two_planes(smp, n=4):
    """Analytic render (n×n box-filtered samples) of the two ruled planes through the ideal XSlit.

    Returns image (H, W) in [0, 1] and the true depth z (H, W) at pixel centres (NaN on background).
    The grid period grows with depth so both planes show lines some 30 px apart."""
    vv, uu = np.mgrid[0:H, 0:W]
    pix = np.column_stack([uu.ravel(), vv.ravel()]).astype(np.float64)

    def trace(px):
        o, d = smp.rays(px)
        pa = o + (NEAR / d[:, 2])[:, None] * d
        pb = o + (FAR / d[:, 2])[:, None] * d
        left, right = pa[:, 0] < 0, pb[:, 0] >= 0
        val = np.where(left, grid_shade(pa, 0.7), np.where(right, grid_shade(pb, 0.7 * FAR / NEAR), 0.5))
        z = np.where(left, NEAR, np.where(right, FAR, np.nan))
        return val, z

    img = np.zeros(len(pix))
    for a in range(n):
        for b in range(n):
            img += trace(pix + [(a + 0.5) / n - 0.5, (b + 0.5) / n - 0.5])[0]
    return (img / n ** 2).reshape(H, W), trace(pix)[1].reshape(H, W)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    smp = sampling()
    img, truth = two_planes(smp)
    d = tmp_path_factory.mktemp("depthmap")
    path = d / "xslit.png"
    cv2.imwrite(str(path), np.rint(img * 255).astype(np.uint8))
    setup = d / "xslit.toml"
    setup.write_text(tomli_w.dumps({"xslit": {"z1": Z1, "z2": Z2, "theta1_deg": TH1, "theta2_deg": TH2,
                                              "pitch": list(smp.pitch)}}))
    return path, setup, truth


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("method", ["graphcut", "quadratic"])
def test_depthmap_recovers_the_two_planes_metric_depths(capsys, tmp_path, scene, method):
    image, setup, truth = scene
    out = tmp_path / "sub" / "depth.png"
    code, text, err = run(capsys, "depthmap", image, "--setup", setup, "-o", out, "--method", method)
    assert code == 0, err
    assert out.is_file() and out.with_suffix(".npy").is_file()
    assert str(out) in text and str(out.with_suffix(".npy")) in text
    colour = cv2.imread(str(out), cv2.IMREAD_COLOR)
    depth = np.load(out.with_suffix(".npy"))
    assert colour.shape == (H, W, 3) and depth.shape == (H, W) and depth.dtype == np.float64
    # Tolerance (stated): each plane's median depth within 5 % of the truth (DDS on LSD segments,
    # 8-bit image); three quarters of the pixels within 15 %.
    for z in (NEAR, FAR):
        on = truth == z
        assert np.nanmedian(depth[on]) == pytest.approx(z, rel=0.05)
    ok = np.isfinite(truth) & np.isfinite(depth)
    assert ok.mean() > 0.9
    rel = np.abs(depth[ok] - truth[ok]) / truth[ok]
    assert np.percentile(rel, 75) < 0.15


def test_depthmap_options_instead_of_a_setup_file(capsys, tmp_path, scene):
    image, _, _ = scene
    p1, p2 = sampling().pitch
    out = tmp_path / "d.png"
    code, _, err = run(capsys, "depthmap", image, "--xslit", Z1, Z2, TH1, TH2, "--pitch", p1, p2, "-o", out,
                       "--method", "quadratic")
    assert code == 0, err
    assert np.nanmedian(np.load(tmp_path / "d.npy")) > 0


def _bad_cases(tmp_path, image, setup):
    gray = tmp_path / "gray.png"
    cv2.imwrite(str(gray), np.full((60, 80), 128, np.uint8))
    no_z2 = tmp_path / "noz2.toml"
    no_z2.write_text("[xslit]\nz1 = -1.0\npitch = 0.01\n")
    return [
        ((tmp_path / "missing.png", "--setup", setup), "missing.png: no such image file"),
        ((image, "--setup", tmp_path / "missing.toml"), "cannot read"),
        ((image, "--setup", no_z2), r"\[xslit\]\.z2: missing"),
        ((image,), "give --setup"),
        ((gray, "--setup", setup), "no line segment carries a depth"),
        ((image, "--xslit", -1.0, -1.0, 45.0, 135.0, "--pitch", 0.01, 0.01), "pinhole"),
    ]


def test_depthmap_bad_input_exits_1_with_one_line_and_writes_nothing(capsys, tmp_path, scene):
    image, setup, _ = scene
    cases = _bad_cases(tmp_path, image, setup)
    before = sorted(p.name for p in tmp_path.iterdir())
    for args, message in cases:
        out = tmp_path / "out" / "depth.png"
        code, text, err = run(capsys, "depthmap", *args, "-o", out)
        assert code == 1, (args, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("catadioptric: error:"), err
        assert re.search(message, lines[0]), (message, lines[0])
        assert text == ""
        assert sorted(p.name for p in tmp_path.iterdir()) == before, args
    code, _, err = run(capsys, "depthmap", image, "--setup", setup, "-o", tmp_path / "depth.jpg")
    assert code == 1 and "ending in .png" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
