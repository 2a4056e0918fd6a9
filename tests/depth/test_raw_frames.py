"""`depth.chroma.from_raw_frame`: a camera's raw Bayer frame (each pixel its filter's sample of linear light) made
into the sRGB image `reconstruct` reads, by each of its demosaics."""

import numpy as np
import pytest

from depth.chroma import DEMOSAIC, DEMOSAICS, from_raw_frame
from depth.errors import DepthError


def _srgb(light):
    """IEC 61966-2-1's encoding, written out here."""
    light = np.asarray(light, dtype=np.float64)
    return np.where(light <= 0.0031308, 12.92 * light, 1.055 * light ** (1 / 2.4) - 0.055)


def _flat_frame(light_rgb, pattern, shape=(24, 32), dtype=np.uint16):
    """A frame of one colour of light: each pixel its filter's channel, at the type's full scale."""
    full = np.iinfo(dtype).max
    tile = np.array([light_rgb["RGB".index(c)] for c in pattern]).reshape(2, 2)
    return np.round(np.tile(tile, (shape[0] // 2, shape[1] // 2)) * full).astype(dtype)


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
@pytest.mark.parametrize("demosaic", DEMOSAICS)
def test_a_flat_colour_of_light_comes_back_as_its_srgb_encoding(pattern, demosaic):
    light = (0.5, 0.2, 0.05)
    got = from_raw_frame(_flat_frame(light, pattern), pattern, demosaic)[4:-4, 4:-4]
    want = _srgb(np.round(np.array(light) * 65535) / 65535)
    if demosaic == "VNG":  # (its codes: the light stored as 8-bit sRGB, then demosaiced)
        assert got.dtype == np.uint8
        np.testing.assert_array_equal(got, np.broadcast_to(np.round(want * 255).astype(np.uint8), got.shape))
    else:  # (two-colour's passes work in float32)
        assert got.dtype == np.float64
        atol = 1e-7 if demosaic == "two-colour" else 1e-12
        np.testing.assert_allclose(got, np.broadcast_to(want, got.shape), rtol=0, atol=atol)


@pytest.mark.parametrize("demosaic", DEMOSAICS)
def test_an_8_bit_frame_s_full_scale_is_255(demosaic):
    frame = _flat_frame((1.0, 0.5, 0.0), "RGGB", dtype=np.uint8)  # 255, 128, 0
    got = np.asarray(from_raw_frame(frame, "RGGB", demosaic)[4:-4, 4:-4], dtype=np.float64)
    got = got / 255.0 if demosaic == "VNG" else got
    atol = 0.5 / 255 if demosaic == "VNG" else 1e-7  # (VNG's 8-bit codes; two-colour's float32)
    np.testing.assert_allclose(got[..., 1], _srgb(128 / 255), rtol=0, atol=atol)
    np.testing.assert_allclose(got[..., 0], 1.0, rtol=0, atol=atol)


@pytest.mark.parametrize("demosaic, code", [("bilinear", "COLOR_BayerGRBG2RGB"),
                                           ("edge-aware", "COLOR_BayerGRBG2RGB_EA")])
def test_opencv_s_demosaics_run_on_the_frame_s_linear_values(demosaic, code):
    """"bilinear" and "edge-aware" are OpenCV's on the 16-bit values, then encoded as sRGB (here written out)."""
    import cv2
    frame = np.random.default_rng(4).integers(0, 65536, (24, 32), dtype=np.uint16)
    want = _srgb(cv2.cvtColor(frame, getattr(cv2, code)) / 65535.0)
    np.testing.assert_allclose(from_raw_frame(frame, "GRBG", demosaic), want, rtol=0, atol=1e-12)


def _three_colours():
    """A face (16 × 16 px), its top face 2 px tall below it and the background: light (H, W, 3) and its RGGB frame."""
    from raytrace.chroma import bayer_mosaic
    light = np.empty((32, 32, 3))
    light[:] = (0.6, 0.6, 0.6)
    light[4:20, 8:24] = (0.7, 0.25, 0.55)
    light[20:22, 8:24] = (0.35, 0.12, 0.28)
    return light, np.round(bayer_mosaic(light, "RGGB") * 65535).astype(np.uint16)


def test_two_colour_takes_vng_s_colour_where_three_colours_meet(monkeypatch):
    """Where a window's colours lie off any one line (over `TWO_COLOUR_OFF_LINE`'s second share of their variance),
    the pixel is VNG's; where they lie on one (under the first), the passes'. On a face with a 2 px top face below it,
    the passes alone leave the worst pixel further off (their line through two of the three colours)."""
    import depth.chroma as chroma
    from raytrace.response import srgb_to_linear
    light, frame = _three_colours()
    got = srgb_to_linear(from_raw_frame(frame, "RGGB", "two-colour"))
    passes = np.moveaxis(chroma._two_colour_passes((frame / 65535.0).astype(np.float32), chroma._tile("RGGB")), 0, -1)
    share = chroma._off_line_share(np.moveaxis(passes, -1, 0))
    vng = srgb_to_linear(from_raw_frame(frame, "RGGB", "VNG") / 255.0)
    lo, hi = chroma.TWO_COLOUR_OFF_LINE
    assert (share >= hi).sum() > 50 and (share <= lo).sum() > 500
    np.testing.assert_allclose(got[share >= hi], vng[share >= hi], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[share <= lo], passes[share <= lo], rtol=0, atol=1e-6)
    between = (share > lo) & (share < hi)  # (a mix, the passes' share falling evenly from lo to hi)
    weight = ((hi - share[between]) / (hi - lo))[:, None]
    assert between.sum() > 10
    np.testing.assert_allclose(got[between], weight * passes[between] + (1 - weight) * vng[between], rtol=0, atol=1e-6)
    blended = np.abs(got - light).max()
    monkeypatch.setattr(chroma, "TWO_COLOUR_OFF_LINE", (2.0, 3.0))  # (no share reaches it: the passes alone)
    alone = np.abs(srgb_to_linear(from_raw_frame(frame, "RGGB", "two-colour")) - light).max()
    assert blended < 0.85 * alone, (blended, alone)


def _step_placed(demosaic, edge, a=(0.6, 0.3, 0.1), b=(0.1, 0.4, 0.5), pattern="RGGB"):
    """Where each channel of a demosaiced frame puts a vertical step of light between colours a (left) and b, the
    pixels area-sampled with the step at x = `edge`: per channel, the mean over rows of the area under each row's
    share of the step, read back in light."""
    h, w = 16, 32
    a, b = np.array(a), np.array(b)
    share = np.clip(edge - np.arange(w), 0.0, 1.0)  # the share of each pixel left of the edge
    light = np.broadcast_to(b + share[None, :, None] * (a - b), (h, w, 3))
    from raytrace.chroma import bayer_mosaic
    frame = np.round(bayer_mosaic(light, pattern) * 65535).astype(np.uint16)
    got = np.asarray(from_raw_frame(frame, pattern, demosaic), dtype=np.float64)
    got = (got / 255.0 if got.dtype == np.float64 and demosaic == "VNG" else got)[4:-4, 2:-2]
    from raytrace.response import srgb_to_linear
    with np.errstate(divide="ignore", invalid="ignore"):  # (a channel that does not step: NaN)
        shares = (srgb_to_linear(got) - b) / (a - b)
        return (shares.sum(axis=1) + 2.0).mean(axis=0)  # (from x = 0)


EDGES = np.arange(14.0, 16.0, 0.1)


def test_two_colour_places_a_step_in_every_channel_where_the_light_steps():
    for pattern in ("RGGB", "GBRG"):
        off = np.array([_step_placed("two-colour", e, pattern=pattern) - e for e in EDGES])
        assert np.abs(off).max() < 0.03, (pattern, np.abs(off).max(axis=0))
    # a step darker in every channel, and one in green alone
    for a, b in (((0.5, 0.5, 0.5), (0.05, 0.1, 0.02)), ((0.2, 0.6, 0.2), (0.2, 0.1, 0.2))):
        off = np.array([_step_placed("two-colour", e, a, b) - e for e in EDGES])
        assert np.abs(off[:, 1]).max() < 0.03
        if a[0] != b[0]:
            assert np.abs(off).max() < 0.03


def test_bilinear_places_green_s_step_and_red_and_blue_s_within_half_a_pixel():
    """The other demosaics' bounds, which `two-colour` betters: bilinear's green (a quincunx, whose two rows' samples
    interleave) keeps a step's place; its red and blue, sampled every second column, alias by up to half a pixel."""
    off = np.array([_step_placed("bilinear", e) - e for e in EDGES])
    assert np.abs(off[:, 1]).max() < 0.005
    assert 0.3 < np.abs(off[:, [0, 2]]).max() <= 0.5 + 1e-3


def test_a_frame_s_light_runs_from_its_black_level_to_its_white_level_times_each_channel_s_gain():
    from depth.chroma import raw_light
    frame = np.array([[64, 2080], [4095, 5000]], np.uint16)  # R G / G B of an RGGB tile
    got = raw_light(frame, "RGGB", black=64, white=4095, gains=(2.0, 1.0, 0.5))
    want = np.empty((2, 2))
    want[0, 0] = 0.0  # red at black, whatever its gain
    want[0, 1] = (2080 - 64) / (4095 - 64) * 1.0  # green, half scale
    want[1, 0] = 1.0  # green at white
    want[1, 1] = min((5000 - 64) / (4095 - 64) * 0.5, 1.0)  # blue above white: its gain, then clipped
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    np.testing.assert_allclose(raw_light(np.array([[32]], np.uint16), "RGGB", black=64), 0.0)  # below black: none
    red = raw_light(np.array([[1000]], np.uint16), "RGGB", white=4000.0, gains=(3.0, 1.0, 1.0))
    np.testing.assert_allclose(red, 0.75, rtol=0, atol=1e-15)
    flat = _flat_frame((0.25, 0.5, 0.125), "GBRG")
    image = from_raw_frame(flat, "GBRG", "bilinear", gains=(2.0, 1.0, 4.0))[4:-4, 4:-4]
    np.testing.assert_allclose(image, np.broadcast_to(_srgb([0.5, 0.5, 0.5]), image.shape), rtol=0, atol=2e-5)
    with pytest.raises(DepthError, match=r"^black, white: expected 0 <= black < white <= 255 \(the frame's type's "
                                         r"most\), got 4096.0, 255.0$"):
        raw_light(np.zeros((2, 2), np.uint8), "RGGB", black=4096.0)
    with pytest.raises(DepthError, match=r"^black, white: expected .* got 0.0, 70000.0$"):
        raw_light(np.zeros((2, 2), np.uint16), "RGGB", white=70000.0)
    with pytest.raises(DepthError, match=r"^gains: expected 3 positive numbers \(red, green, blue\), got \[1.0, 0.0, "
                                         r"1.0\]$"):
        raw_light(np.zeros((2, 2), np.uint16), "RGGB", gains=(1.0, 0.0, 1.0))


def _rectangles(shape, seed, straddling=()):
    """Light (H, W, 3): rectangles of colour (30 × 25 px, edges at fractions of a pixel) on grey, 12 about the frame's
    left part and one at each top-left of `straddling`; a flat band from column 128 on."""
    rng = np.random.default_rng(seed)
    h, w = shape
    light = np.full((h, w, 3), 0.3)
    rows, cols = np.arange(h)[:, None] + 0.5, np.arange(w)[None, :] + 0.5
    corners = [(rng.uniform(0, h - 40), rng.uniform(0, 95)) for _ in range(12)] + list(straddling)
    for y, x in corners:
        cover = np.clip(np.minimum(rows - y, y + 30 - rows) + 0.5, 0, 1) * np.clip(np.minimum(cols - x, x + 25 - cols)
                                                                                 + 0.5, 0, 1)
        light = light + cover[..., None] * (rng.uniform(0.05, 0.9, 3) - light)
    light[:, 128:] = 0.3
    return light


def _two_colour_of_the_whole_frame(frame, pattern):
    """`two-colour`'s image written out as its parts computed on the whole frame at once (no blocks, no jobs):
    the passes, their off-line share and VNG's colour blended by it, encoded as sRGB."""
    import depth.chroma as chroma
    from raytrace.response import srgb_to_linear
    passes = chroma._two_colour_passes((frame / 65535.0).astype(np.float32), chroma._tile(pattern))
    lo, hi = chroma.TWO_COLOUR_OFF_LINE
    weight = np.clip((hi - chroma._off_line_share(passes)) / (hi - lo), 0.0, 1.0)[..., None]
    vng = srgb_to_linear(from_raw_frame(frame, pattern, "VNG") / 255.0)
    return _srgb(weight * np.moveaxis(passes, 0, -1) + (1.0 - weight) * vng)


WHOLE_FRAME_ATOL = 1e-6
"""The two-colour image against its passes over the whole frame: alike but for the float32 box sums' last bits (a
job's read 2 px short of its reach moves pixels by up to 1e-3)."""


def test_two_colour_in_jobs_on_any_number_of_cores_is_its_passes_over_the_whole_frame(monkeypatch):
    """Its passes run on the blocks about what is not flat, in bands of rows, each computed from as far beyond it as
    its pixels read (the bilinear start's 1 px, 3 px a pass, 3 px of the last window): the image its passes give
    over the whole frame, the same on 1 core and on 3. Beyond their reach of any edge, the frame's light."""
    import depth.chroma as chroma
    import depth.workers
    from raytrace.chroma import bayer_mosaic
    light = _rectangles((512, 200), 7, straddling=[(370.3, 40.6), (378.0, 90.2)])  # (across the bands' cut, 384)
    frame = np.round(bayer_mosaic(light, "GRBG") * 65535).astype(np.uint16)
    jobs = chroma._busy_boxes(chroma._bilinear((frame / 65535.0).astype(np.float32), chroma._tile("GRBG")))
    assert len(jobs) == 2 and jobs[0][0][1] == jobs[1][0][0] == 384
    assert chroma._two_colour_reach() == 1 + 10 * 3 + 3  # (34: even, as a tile needs)
    got = {}
    for cores in (1, 3):
        monkeypatch.setattr(depth.workers, "available_cores", lambda c=cores: c)
        got[cores] = from_raw_frame(frame, "GRBG", "two-colour")
    np.testing.assert_array_equal(got[1], got[3])
    np.testing.assert_allclose(got[1], _two_colour_of_the_whole_frame(frame, "GRBG"), rtol=0, atol=WHOLE_FRAME_ATOL)
    # beyond the passes' reach of the band's edge, the light as it is
    np.testing.assert_allclose(got[1][:, 160:], _srgb(np.round(0.3 * 65535) / 65535), rtol=0, atol=1e-7)


def test_two_colour_runs_its_passes_on_the_blocks_about_what_is_not_flat_alone():
    import depth.chroma as chroma
    from raytrace.chroma import bayer_mosaic
    light = np.full((768, 384, 3), 0.4)
    light[10:50, 12:40] = (0.8, 0.3, 0.1)  # one face, within the first block
    light[500:540, 300:330] = (0.1, 0.3, 0.8)  # another, in the second band of rows (384 on)
    frame = np.round(bayer_mosaic(light, "RGGB") * 65535).astype(np.uint16)
    start = chroma._bilinear((frame / 65535.0).astype(np.float32), chroma._tile("RGGB"))
    reach = chroma._two_colour_reach()
    # each face's blocks and the blocks about them, a job each, read from as far beyond it as its pixels read
    assert chroma._busy_boxes(start) == [((0, 128, 0, 128), (0, 128 + reach, 0, 128 + reach)),
                                         ((384, 640, 192, 384), (384 - reach, 640 + reach, 192 - reach, 384))]
    got = from_raw_frame(frame, "RGGB", "two-colour")
    np.testing.assert_allclose(got, _two_colour_of_the_whole_frame(frame, "RGGB"), rtol=0, atol=WHOLE_FRAME_ATOL)
    np.testing.assert_allclose(got[128:384], _srgb(np.round(0.4 * 65535) / 65535), rtol=0, atol=1e-7)
    # two runs of blocks in one band closer than their reaches (one block apart, 64 < 2 × 34 px): one job
    near = light.copy()
    near[500:540, 300:330] = 0.4
    near[200:240, 300:330] = (0.1, 0.3, 0.8)
    near_start = chroma._bilinear((np.round(bayer_mosaic(near, "RGGB") * 65535) / 65535).astype(np.float32),
                                  chroma._tile("RGGB"))
    assert chroma._busy_boxes(near_start) == [((0, 320, 0, 384), (0, 320 + reach, 0, 384))]
    # only where it will be read (here about the first face): the second face's edges are bilinear's
    where = np.zeros(frame.shape, bool)
    where[20:40, 20:30] = True
    assert chroma._busy_boxes(start, where) == chroma._busy_boxes(start)[:1]
    only = from_raw_frame(frame, "RGGB", "two-colour", where=where)
    np.testing.assert_array_equal(only[:384], got[:384])
    bilinear = _srgb(np.moveaxis(start, 0, -1).astype(np.float64))
    np.testing.assert_allclose(only[384:], bilinear[384:], rtol=0, atol=1e-7)
    assert np.abs(only[384:] - got[384:]).max() > 0.01


def test_two_colour_gives_the_pixels_it_will_read_the_colours_it_gives_them_in_the_whole_frame():
    """`where`: the pixels that will be read (a mirror region); those within the reach of its edge read what lies
    beyond it as they do without it."""
    from raytrace.chroma import bayer_mosaic
    light = _rectangles((512, 200), 11, straddling=[(190.0, 60.5)])
    frame = np.round(bayer_mosaic(light, "BGGR") * 65535).astype(np.uint16)
    rows, cols = np.mgrid[:512, :200]
    where = (rows - 120) ** 2 / 80 ** 2 + (cols - 60) ** 2 / 45 ** 2 < 1.0  # (an ellipse cutting rectangles)
    whole = from_raw_frame(frame, "BGGR", "two-colour")
    got = from_raw_frame(frame, "BGGR", "two-colour", where=where)
    np.testing.assert_allclose(got[where], whole[where], rtol=0, atol=WHOLE_FRAME_ATOL)
    assert np.abs(got[~where] - whole[~where]).max() > 0.01  # (beyond it, not all of them)


def test_frames_and_arguments_it_cannot_read_are_refused():
    frame = np.zeros((8, 8), np.uint16)
    with pytest.raises(DepthError, match=r"^frame: expected an \(H, W\) uint8 or uint16 raw Bayer frame, got uint16 "
                                         r"\(8, 8, 3\)$"):
        from_raw_frame(np.zeros((8, 8, 3), np.uint16), "RGGB")
    with pytest.raises(DepthError, match=r"^frame: expected .* got float32 \(8, 8\)$"):
        from_raw_frame(np.zeros((8, 8), np.float32), "RGGB")
    with pytest.raises(DepthError, match=r"^pattern: expected one of RGGB, BGGR, GRBG, GBRG, got 'rggb'$"):
        from_raw_frame(frame, "rggb")
    with pytest.raises(DepthError, match=r"^demosaic: expected one of VNG, bilinear, edge-aware, two-colour, "
                                         r"got 'AHD'$"):
        from_raw_frame(frame, "RGGB", "AHD")
    with pytest.raises(DepthError, match=r"^where: expected a mask of the frame's \(8, 8\), got \(8, 6\)$"):
        from_raw_frame(frame, "RGGB", where=np.ones((8, 6), bool))
    assert DEMOSAIC in DEMOSAICS
