"""Tests of depth.measure on synthetic mirror images drawn without our renderer.

Each fake cube is a front face with straight left/right sides and quadratic top/bottom
sides through known corners, flanked by a darker side-face strip (and optionally a
brighter top strip), painted at 8× resolution in linear RGB, box-downsampled (the
anti-aliasing of a camera or renderer), sRGB-encoded and quantised to 8 bits.
"""

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from depth.errors import DepthError
from depth.measure import (
    EDGE_CHANNELS,
    FAINT_EDGE_CONTRAST,
    FAINT_EDGE_READINGS,
    FAINT_EDGE_SMOOTHING_PX,
    FAINTER_EDGE_CONTRAST,
    CubeDetection,
    FaceOutline,
    FailedMeasurement,
    _check_image,
    checked_images,
    detect_cubes,
    face_outline,
    faint_regrowth,
    same_material_faces,
    silhouette,
    silhouette_sides,
    srgb_to_linear,
)
from depth.workers import fork_map

# --------------------------------------------------------------------- synthetic images


def linear_to_srgb(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


@dataclass
class FakeCube:
    """A front face: straight left/right sides, quadratic top/bottom through its corners."""

    tl: tuple
    tr: tuple
    br: tuple
    bl: tuple
    top_sag: float = 0.0  # px; > 0 bends the middle of the top side downward
    bottom_sag: float = 0.0
    albedo: tuple = (0.8, 0.1, 0.1)
    front_shade: float = 0.7
    side_shade: float = 0.3
    top_shade: float = 0.95
    side: str | None = "left"  # a side-face strip on this side of the front face
    side_width: float = 4.0
    top_height: float = 0.0  # a top-face strip above the top side
    top_tilt: float = 0.0  # the top strip's height grows by this (px) from its left end to its right

    def corners(self):
        return np.array([self.tl, self.tr, self.br, self.bl], dtype=np.float64)

    @staticmethod
    def _line(p, q, v):
        return p[0] + (v - p[1]) * (q[0] - p[0]) / (q[1] - p[1])

    @staticmethod
    def _curve(p, q, sag, u):
        t = (u - p[0]) / (q[0] - p[0])
        return p[1] + t * (q[1] - p[1]) + sag * 4.0 * t * (1.0 - t)

    def left(self, v):
        return self._line(self.tl, self.bl, v)

    def right(self, v):
        return self._line(self.tr, self.br, v)

    def top(self, u):
        return self._curve(self.tl, self.tr, self.top_sag, u)

    def bottom(self, u):
        return self._curve(self.bl, self.br, self.bottom_sag, u)

    def face(self, u, v):
        return (u > self.left(v)) & (u < self.right(v)) & (v > self.top(u)) & (v < self.bottom(u))

    def side_strip(self, u, v):
        rows = (v > self.top(u) + 1.0) & (v < self.bottom(u) - 1.0)
        if self.side == "left":
            lu = self.left(v)
            return rows & (u > lu - self.side_width) & (u <= lu)
        if self.side == "right":
            ru = self.right(v)
            return rows & (u >= ru) & (u < ru + self.side_width)
        return np.zeros_like(rows)

    def paint(self, img, u, v):
        alb = np.asarray(self.albedo)
        img[self.side_strip(u, v)] = alb * self.side_shade
        if self.top_height > 0:
            tv = self.top(u)
            grow = self.top_tilt * (u - self.tl[0]) / (self.tr[0] - self.tl[0])
            m = (u > self.left(v)) & (u < self.right(v)) & (v > tv - self.top_height - grow) & (v <= tv)
            img[m] = alb * self.top_shade
        img[self.face(u, v)] = alb * self.front_shade


def make_image(shape, cubes, mirror=None, background="checker", noise=0.0, seed=0,
               supersample=8, decoy=True):
    """sRGB image (H, W, 3) float64 in [0, 1] and mirror mask (H, W) bool.

    mirror : (u0, v0, u1, v1); pixels whose centre lies in this rectangle see the mirror.
    decoy : paint a green patch seen directly, just outside the mirror (must be ignored).
    """
    h, w = shape
    ss = supersample
    if mirror is None:
        mirror = (w * 0.12, h * 0.05, w * 0.88, h * 0.95)
    mu0, mv0, mu1, mv1 = mirror
    u, v = np.meshgrid((np.arange(w * ss) + 0.5) / ss - 0.5, (np.arange(h * ss) + 0.5) / ss - 0.5)
    img = np.empty((h * ss, w * ss, 3))
    if background == "checker":  # rotated, so that no checker line runs along a cube side
        ca, sa, cell = np.cos(0.5), np.sin(0.5), 7.3
        k = (np.floor((ca * u + sa * v + 0.31) / cell) + np.floor((ca * v - sa * u + 0.17) / cell)) % 2
        img[:] = np.where(k[..., None] > 0, 0.45, 0.22)
    elif background == "sky":  # a sky shading ±40 % across the mirror over a floor, a wavy horizon
        sky = 0.5 * (1.0 + 0.4 * np.sin(2.0 * np.pi * u / 90.0))[..., None] * np.array([0.9, 0.95, 1.0])
        floor = v > 0.86 * h + 5.0 * np.sin(2.0 * np.pi * u / 70.0)
        img[:] = np.where(floor[..., None], np.array([0.2, 0.2, 0.24]), sky)
    elif background == "ramp":  # a sky shading gently (+30 % across the image), slightly blue
        img[:] = (0.45 * (1.0 + 0.3 * u / w))[..., None] * np.array([0.95, 0.97, 1.0])
    elif background == "warm ramp":  # the same, yellowish (a sky toward the sun, a sunlit floor)
        img[:] = (0.45 * (1.0 + 0.3 * u / w))[..., None] * np.array([1.0, 0.97, 0.9])
    elif background == "horizon":  # a bright sky over a grey floor, the horizon sloping across the mirror
        floor = v > 0.5 * h + 0.1 * (u - 0.5 * w)
        img[:] = np.where(floor[..., None], 0.3, np.array([0.85, 0.88, 0.92]))
    elif background == "blue sky":  # a clear sky, bluer than any face of a grey cube under it
        img[:] = (0.43, 0.46, 0.515)
    else:
        img[:] = 0.35
    for c in cubes:
        c.paint(img, u, v)
    outside = ~((u >= mu0) & (u <= mu1) & (v >= mv0) & (v <= mv1))
    img[outside] = 0.08
    if decoy:
        img[outside & (np.abs(u - mu0 + 6) < 4) & (np.abs(v - h / 2) < 15)] = (0.1, 0.7, 0.1)
    srgb = linear_to_srgb(img.reshape(h, ss, w, ss, 3).mean(axis=(1, 3)))
    if noise > 0:
        srgb = srgb + np.random.default_rng(seed).normal(0.0, noise, srgb.shape)
    srgb = np.round(np.clip(srgb, 0.0, 1.0) * 255.0) / 255.0  # an 8-bit PNG / 255
    pu, pv = np.meshgrid(np.arange(w), np.arange(h))
    mask = (pu >= mu0) & (pu <= mu1) & (pv >= mv0) & (pv <= mv1)
    return srgb, mask


COLOURS = {
    "red": (0.8, 0.08, 0.08),
    "green": (0.08, 0.6, 0.08),
    "blue": (0.08, 0.08, 0.8),
    "yellow": (0.75, 0.7, 0.05),
    "magenta": (0.7, 0.05, 0.7),
}


def three_cubes():
    return [
        FakeCube((50.3, 30.6), (71.8, 31.4), (72.5, 140.2), (51.1, 139.1), top_sag=1.5,
                 bottom_sag=2.2, side="left", side_width=4.5, albedo=COLOURS["red"]),
        FakeCube((100.7, 50.2), (118.2, 50.9), (118.9, 160.4), (101.2, 159.6), top_sag=-1.0,
                 bottom_sag=1.2, albedo=COLOURS["green"], side="right", side_width=3.5),
        FakeCube((150.2, 40.5), (190.6, 39.8), (191.1, 170.3), (150.9, 171.0), top_sag=2.0,
                 bottom_sag=3.0, albedo=COLOURS["blue"], side="left", side_width=5, top_height=4),
    ]


def random_cube(rng, u_centre, albedo):
    """A tall narrow face (14–32 px × 90–130 px) with random tilt, sags and side strip.

    Its footprint stays within u_centre ± 27 px."""
    width, height = rng.uniform(14, 32), rng.uniform(90, 130)
    u0, v0 = u_centre - width / 2 + rng.uniform(-0.5, 0.5), rng.uniform(25, 40)
    tilt = rng.uniform(-0.03, 0.03) * height  # left/right sides lean by this many pixels
    dv = rng.uniform(-0.04, 0.04) * width  # top/bottom slope
    return FakeCube(
        (u0, v0), (u0 + width, v0 + dv), (u0 + width + tilt, v0 + height + dv),
        (u0 + tilt + rng.uniform(-0.3, 0.3), v0 + height + rng.uniform(-0.5, 0.5)),
        top_sag=rng.uniform(-2.5, 2.5), bottom_sag=rng.uniform(-2.5, 2.5), albedo=albedo,
        front_shade=rng.uniform(0.5, 0.9), side_shade=rng.uniform(0.15, 0.35),
        side=str(rng.choice(["left", "right"])), side_width=rng.uniform(3.5, 7.0),
    )


def match(detections, cubes):
    """For each cube, the detection whose blob contains the cube's face centre."""
    out = []
    for c in cubes:
        uc, vc = c.corners().mean(axis=0)
        hits = [d for d in detections if d.mask[int(round(vc)), int(round(uc))]]
        assert len(hits) == 1, f"cube at ({uc:.0f}, {vc:.0f}) matched {len(hits)} detections"
        out.append(hits[0])
    return out


def pixel_truth(shape, cube, which):
    """Pixels of a cube's region, by pixel centre."""
    u, v = np.meshgrid(np.arange(shape[1], dtype=float), np.arange(shape[0], dtype=float))
    return cube.face(u, v) if which == "face" else cube.side_strip(u, v)


# ---------------------------------------------------------------------------- detection


def test_detects_each_cube_once_and_nothing_else():
    cubes = three_cubes()
    image, mirror = make_image((200, 240), cubes)
    detections = detect_cubes(image, mirror)
    assert len(detections) == len(cubes)  # the green decoy outside the mirror is ignored
    for d, c in zip(match(detections, cubes), cubes):
        assert isinstance(d, CubeDetection)
        assert d.reason is None and d.usable
        assert not d.cut_by_mirror_edge and not d.occluded
        # colour: the front face's sRGB colour, dominated by the albedo's strongest channel
        assert np.argmax(d.color) == np.argmax(c.albedo)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_recall_and_no_false_positives_on_random_colourful_scenes(seed):
    rng = np.random.default_rng(seed)
    names = rng.permutation(list(COLOURS))[:4]
    cubes = [random_cube(rng, 70 + 55 * i, COLOURS[n]) for i, n in enumerate(names)]
    image, mirror = make_image((190, 310), cubes, noise=2 / 255, seed=seed,
                               background=["checker", "grey"][seed % 2])
    detections = detect_cubes(image, mirror)
    assert len(detections) == len(cubes)
    for d in match(detections, cubes):
        assert d.usable, d.reason
    for d in detections:  # bbox: the mask's bounds (depth.reconstruct takes it for them)
        ys, xs = np.nonzero(d.mask)
        assert d.bbox == (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1)



@pytest.mark.parametrize("albedos", [
    [(0.8, 0.8, 0.8), (0.8, 0.8, 0.8), (0.8, 0.8, 0.8)],  # the setup file's default colour
    [(0.95, 0.95, 0.95), (0.05, 0.05, 0.05), (0.45, 0.35, 0.28)],  # white, black, a dull brown
    [(0.8, 0.8, 0.8), COLOURS["green"], (0.05, 0.05, 0.05)],  # grey and black beside a coloured one
])
def test_grey_white_and_black_cubes_are_found_on_a_uniform_background(albedos):
    """Cubes without colour (chroma under the coloured pass's threshold) on a uniform background:
    each is found once, usable, its front face separated from its side strip."""
    cubes = [dataclasses.replace(c, albedo=a) for c, a in zip(three_cubes(), albedos)]
    image, mirror = make_image((200, 240), cubes, background="grey", noise=2 / 255)
    detections = detect_cubes(image, mirror)
    assert len(detections) == len(cubes)
    for d, c in zip(match(detections, cubes), cubes):
        assert d.usable, d.reason
        face = pixel_truth(image.shape[:2], c, "face")
        iou = (d.front_face_mask & face).sum() / (d.front_face_mask | face).sum()
        assert iou > 0.9
        if np.ptp(c.albedo) == 0.0 or c.albedo == COLOURS["green"]:  # found without colour, or by it
            assert d.achromatic == (np.ptp(c.albedo) == 0.0)


def test_the_coloured_cubes_are_handed_over_before_the_grey_search_as_the_result_has_them(monkeypatch):
    # `detect_cubes(coloured_found=...)`: `depth.reconstruct` estimates the coloured cubes while the grey ones
    # are searched for; what it is handed must be what the result holds for them
    import depth.measure as dm
    cubes = [dataclasses.replace(c, albedo=a) for c, a in
             zip(three_cubes(), [(0.8, 0.8, 0.8), COLOURS["green"], (0.05, 0.05, 0.05)])]
    image, mirror = make_image((200, 240), cubes, background="grey", noise=2 / 255)
    events = []
    real = dm._achromatic_regions
    monkeypatch.setattr(dm, "_achromatic_regions", lambda *a, **k: events.append("grey search") or real(*a, **k))
    detections = detect_cubes(image, mirror, coloured_found=lambda found: events.append(found))
    assert len(events) == 2 and events[1] == "grey search"
    handed = events[0]
    assert len(detections) == 3 and [d.achromatic for d in detections].count(False) == 1
    assert len(handed) == 1 and not handed[0].achromatic
    ours = next(d for d in detections if not d.achromatic)
    assert (handed[0].bbox, handed[0].occluded, handed[0].cut_by_mirror_edge, handed[0].reason) == \
        (ours.bbox, ours.occluded, ours.cut_by_mirror_edge, ours.reason)
    np.testing.assert_array_equal(handed[0].mask, ours.mask)
    np.testing.assert_array_equal(handed[0].front_face_mask, ours.front_face_mask)
    # and without the callback, the same detections in the same order
    again = detect_cubes(image, mirror)
    assert [d.bbox for d in again] == [d.bbox for d in detections]


@pytest.mark.parametrize("albedos", [
    [(0.8, 0.8, 0.8), (0.3, 0.3, 0.3), (0.05, 0.05, 0.05)],
    [(0.95, 0.95, 0.95), (0.05, 0.05, 0.05), (0.25, 0.25, 0.25)],  # each unlike the sky behind it
])
def test_grey_white_and_black_cubes_are_found_on_a_sky_shading_over_a_floor(albedos):
    """No one background colour: a sky shading ±40 % across the mirror (a sky map reflected in a
    cylinder) over a floor. The cubes are the regions enclosed by edges; each is found once, without
    colour, its blob ending where its colour does (front face IoU > 0.9), and the horizon between sky
    and floor is no object."""
    cubes = [dataclasses.replace(c, albedo=a) for c, a in zip(three_cubes(), albedos)]
    image, mirror = make_image((200, 240), cubes, background="sky", noise=2 / 255)
    detections = detect_cubes(image, mirror)
    assert len(detections) == len(cubes)
    for d, c in zip(match(detections, cubes), cubes):
        assert d.usable and d.achromatic, d.reason
        face = pixel_truth(image.shape[:2], c, "face")
        iou = (d.front_face_mask & face).sum() / (d.front_face_mask | face).sum()
        assert iou > 0.9


def sky_over_ground(blur, shape=(200, 240), supersample=2, seed=0):
    """A black cube face in a plain sky over a checkered ground seen in perspective (its cells shrink
    to under a pixel toward the horizon, sampled 2 × 2 per pixel: aliased), blurred by `blur` px;
    sRGB with σ = 2/255 noise, and the mirror mask."""
    import cv2
    h, w = shape
    ss = supersample
    u, v = np.meshgrid((np.arange(w * ss) + 0.5) / ss - 0.5, (np.arange(h * ss) + 0.5) / ss - 0.5)
    horizon = 0.55 * h
    z = 200.0 / np.maximum(v - horizon, 1e-3)  # a camera 1 m above the ground, focal length 200 px
    cell = (np.floor((u - w / 2) * z / 200.0 / 0.3) + np.floor(z / 0.3)) % 2
    img = np.where((v > horizon)[..., None], np.where(cell > 0, 0.45, 0.15)[..., None], 0.6) * np.ones(3)
    FakeCube((50.3, 20.6), (71.8, 21.4), (72.5, 90.2), (51.1, 89.1), albedo=(0.1, 0.1, 0.1), side=None).paint(img, u, v)
    mirror = (w * 0.12 <= u) & (u <= w * 0.88) & (h * 0.05 <= v) & (v <= h * 0.95)
    img[~mirror] = 0.08
    lin = cv2.GaussianBlur(img.reshape(h, ss, w, ss, 3).mean(axis=(1, 3)), (0, 0), blur)
    srgb = linear_to_srgb(lin) + np.random.default_rng(seed).normal(0.0, 2 / 255, lin.shape)
    pu, pv = np.meshgrid(np.arange(w), np.arange(h))
    return (np.round(np.clip(srgb, 0.0, 1.0) * 255.0) / 255.0,
            (w * 0.12 <= pu) & (pu <= w * 0.88) & (h * 0.05 <= pv) & (pv <= h * 0.95))


@pytest.mark.parametrize("blur", [0.7, 1.5, 2.0])
def test_blobs_of_a_far_checkered_ground_are_no_grey_cubes(blur):
    """Toward its horizon a checkered ground's cells alias and blur into blobs of one grey, enclosed
    by edges like a cube's face, but among the edges of the other cells: only the cube in the sky is
    found (without the clutter test 1–3 blobs of the ground were found too)."""
    image, mirror = sky_over_ground(blur)
    detections = detect_cubes(image, mirror)
    assert [d.bbox[:2] for d in detections] in ([(50, 20)], [(50, 21)])
    assert detections[0].usable and detections[0].achromatic


def test_grey_cubes_are_not_looked_for_on_a_checkered_background():
    """On a textured background (the checker of a ground plane) regions of another grey than the
    background are not objects: grey cubes are not found, and nothing is invented, while a coloured
    cube among them still is."""
    cubes = [dataclasses.replace(c, albedo=a) for c, a in
             zip(three_cubes(), [(0.8, 0.8, 0.8), COLOURS["green"], (0.05, 0.05, 0.05)])]
    image, mirror = make_image((200, 240), cubes, background="checker")
    detections = detect_cubes(image, mirror)
    assert len(detections) == 1
    assert match(detections, cubes[1:2])[0].usable


def faint_white_cube(front_shade):
    """A white cube's front face (24 px × 109 px) with a dark side face 6 px wide on its right, before
    a sky shading gently ("ramp"): at `front_shade` 0.44 or 0.56 its face differs from the sky behind
    it (linear 0.49–0.51) by 0.03–0.05 in sRGB, under the weak step `_enclosed` traces edges at."""
    return FakeCube((100.3, 40.6), (124.8, 41.4), (125.5, 150.2), (101.1, 149.1), top_sag=1.5, bottom_sag=2.0,
                    albedo=(1.0, 1.0, 1.0), front_shade=front_shade, side="right", side_width=6.0, side_shade=0.25)


def found_without(image, mirror, cube, hidden, background, noise, seed):
    """What `detect_cubes` finds of `cube` in `image` where its pixels `hidden` show the background
    instead (the same background and noise): the blob that detection leaves when it misses a face,
    the input of `faint_regrowth`, whatever detection itself now finds in `image`."""
    plain, _ = make_image(image.shape[:2], [], background=background, noise=noise, seed=seed)
    (found,) = detect_cubes(np.where(hidden[..., None], plain, image), mirror)
    assert (found.mask & hidden).sum() == 0
    return found


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("front_shade", [0.44, 0.58])
def test_a_white_face_a_little_darker_or_brighter_than_a_shading_sky_is_found_whole(front_shade, seed):
    """A white cube whose front face differs from the gently shading sky behind it by 0.03–0.05 of sRGB
    in each channel. The sky's colour departs from its median by 0.05 across the mirror, over twice what
    a pixel departs from its neighbours, so the uniform background's noise band would be its shading's
    and hide the face; the regions enclosed by edges are looked for instead, and detection finds the
    whole cube: front face within IoU 0.9 of the truth, its side face beside it (before the thirty-first
    session only the side face was found, and `faint_regrowth` had to grow it)."""
    cube = faint_white_cube(front_shade)
    image, mirror = make_image((200, 240), [cube], background="ramp", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], cube, "face")
    strip = pixel_truth(image.shape[:2], cube, "strip")
    (found,) = detect_cubes(image, mirror)
    assert found.usable and found.achromatic, found.reason
    iou = (found.front_face_mask & face).sum() / (found.front_face_mask | face).sum()
    assert iou > 0.9
    assert (found.mask & strip).sum() > 0.9 * strip.sum()


def path_traced_noise(image, where, sigma, seed):
    """`image` with a path tracer's sampling noise on the pixels `where`: one Gaussian draw of σ
    `sigma` per pixel added to its three channels alike (a grey or white surface's samples differ in
    brightness, not in colour), rounded to 8 bits."""
    out = image.copy()
    n = np.random.default_rng(seed).normal(0.0, sigma, (int(where.sum()), 1))
    out[where] = np.round(np.clip(out[where] + n, 0.0, 1.0) * 255.0) / 255.0
    return out


_TOP_ROWS_LEFT_OUT = pytest.mark.xfail(strict=True, reason="open: found since the eighty-second session traces the "
                                      "edges of blue − red, but the blob leaves the face's top 6-10 rows out (IoU "
                                      "0.87-0.88)")


@pytest.mark.parametrize("seed", [pytest.param(0, marks=_TOP_ROWS_LEFT_OUT), pytest.param(1, marks=_TOP_ROWS_LEFT_OUT),
                                  2])
def test_a_white_face_lit_bluer_than_a_warm_sky_is_found_by_its_blue_yellow_edges(seed):
    """A white cube's front face lit by the blue sky before a yellowish sky or floor lit by the sun
    (holdout 9090 s4/0, 80 × 306 px, and s5/3 are missed so): each channel steps by 0.03 at most at its
    sides, under the strong step `_enclosed` traces edges at, and a path tracer's noise (σ = 0.013 of
    sRGB, the holdout faces') gives brightness edges inside it; but blue − red steps by 0.06 there, and
    that noise cancels in it (σ 0.005 against 0.016 in red on the holdout faces). Detection should find
    the face whole (IoU > 0.9)."""
    cube = FakeCube((100.3, 40.6), (124.8, 41.4), (125.5, 150.2), (101.1, 149.1), top_sag=1.5, bottom_sag=2.0,
                    albedo=(0.8375, 0.8505, 0.907), front_shade=0.56, side=None)
    image, mirror = make_image((200, 240), [cube], background="warm ramp", noise=2 / 255, seed=seed)
    plain, _ = make_image((200, 240), [], background="warm ramp")
    face = pixel_truth(image.shape[:2], cube, "face")
    steps = np.mean(image[face], axis=0) - np.mean(plain[face], axis=0)
    assert np.abs(steps).max() <= 0.035 and steps[2] - steps[0] >= 0.055  # the case: a blue-yellow step
    image = path_traced_noise(image, face, 0.013, seed)
    found = detect_cubes(image, mirror)
    assert len(found) == 1 and found[0].usable and found[0].achromatic, found
    iou = (found[0].front_face_mask & face).sum() / (found[0].front_face_mask | face).sum()
    assert iou > 0.9


def jpeg_coded(image):
    """`image` (sRGB in [0, 1], 8-bit values) through OpenCV's JPEG coder at quality 90, 4:2:0 (the benches' JPEG
    variant), then median-filtered as `reconstruct` does before detecting cubes in a compressed image."""
    import cv2

    from depth.reconstruct import despeckled

    ok, data = cv2.imencode(".jpg", np.round(image * 255.0).astype(np.uint8)[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return despeckled(cv2.imdecode(data, cv2.IMREAD_COLOR)[..., ::-1])


def test_a_compressed_image_traces_the_edges_of_blue_minus_red_only_after_the_brightness_edges(monkeypatch):
    """The face of the test above (seed 2, found whole there) through OpenCV's JPEG coder: the grey search first
    traces brightness edges alone, under whose strong step the face lies in every channel, and then the edges of
    blue − red at `COMPRESSED_BLUE_RED_STEPS` of the steps (JPEG keeps blue − red at half resolution), which find
    it (the front face within IoU 0.85 of the truth; 0.87 here). Without that second search, or with it at the
    uncompressed steps, nothing is found; without it, nothing in the image before JPEG taken as compressed either
    (as before the eighty-sixth session, when compressed images traced no edges of blue − red)."""
    import depth.measure as dm

    cube = FakeCube((100.3, 40.6), (124.8, 41.4), (125.5, 150.2), (101.1, 149.1), top_sag=1.5, bottom_sag=2.0,
                    albedo=(0.8375, 0.8505, 0.907), front_shade=0.56, side=None)
    image, mirror = make_image((200, 240), [cube], background="warm ramp", noise=2 / 255, seed=2)
    face = pixel_truth(image.shape[:2], cube, "face")
    plain = path_traced_noise(image, face, 0.013, 2)
    assert len(detect_cubes(plain, mirror)) == 1  # precondition: found in the image taken as uncompressed
    image = jpeg_coded(plain)
    (found,) = detect_cubes(image, mirror, compressed=True)
    assert found.usable and found.achromatic, found.reason
    assert (found.front_face_mask & face).sum() / (found.front_face_mask | face).sum() > 0.85
    for steps in (0.0, 1.0):
        monkeypatch.setattr(dm, "COMPRESSED_BLUE_RED_STEPS", steps)
        assert detect_cubes(image, mirror, compressed=True) == []
        if steps == 0.0:  # the brightness edges alone: nothing, in the image uncompressed but taken as compressed too
            assert detect_cubes(plain, mirror, compressed=True) == []


def test_the_edges_of_blue_minus_red_in_a_compressed_image_change_no_region_the_brightness_edges_enclose(monkeypatch):
    """A grey cube on a warm sky, its left side face 12 px wide as bright as the sky but bluer (red down 0.04,
    blue up 0.06), through OpenCV's JPEG coder. Traced in one search with the brightness edges, the edges of
    blue − red would join the side face to the front face's region (5072 px against 3819). Traced after them
    (`blue_red_after`), they add only regions over 3 px from those found first: the grey search returns the
    regions of the brightness edges alone, to the pixel, and the detection is the same."""
    import cv2

    import depth.measure as dm
    from depth.measure import COMPRESSED_BLUE_RED_STEPS, _achromatic_regions

    cube = FakeCube((90.3, 40.6), (124.8, 41.4), (125.5, 150.2), (91.1, 149.1), top_sag=1.5, bottom_sag=2.0,
                    albedo=(0.5, 0.5, 0.5), front_shade=0.4, side="left", side_width=12.0, side_shade=0.4)
    image, mirror = make_image((200, 240), [cube], background="warm ramp")
    plain, _ = make_image((200, 240), [], background="warm ramp")
    side = pixel_truth(image.shape[:2], cube, "strip")
    image[side] = plain[side] + [-0.04, 0.0, 0.06]
    image = jpeg_coded(image)
    search = cv2.erode(mirror.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    none = np.zeros_like(search)

    def masks(regions):
        return [(off, piece.shape, np.flatnonzero(piece).tolist()) for piece, off in regions]

    alone = _achromatic_regions(image, search, none, 50)
    (front,) = alone
    (joined,) = _achromatic_regions(image, search, none, 50, blue_red=True)  # the case: one search would join them
    assert joined[0].sum() > front[0].sum() + 0.9 * side.sum()
    assert masks(_achromatic_regions(image, search, none, 50, blue_red_after=COMPRESSED_BLUE_RED_STEPS)) == masks(alone)
    (found,) = detect_cubes(image, mirror, compressed=True)
    monkeypatch.setattr(dm, "COMPRESSED_BLUE_RED_STEPS", 0.0)  # no second search
    (before,) = detect_cubes(image, mirror, compressed=True)
    assert np.array_equal(found.mask, before.mask) and np.array_equal(found.front_face_mask, before.front_face_mask)


@pytest.mark.parametrize("row", [40, 41])
@pytest.mark.parametrize("column", [84, 85, 86, 87])
def test_a_face_that_steps_in_blue_minus_red_alone_is_enclosed_after_jpeg_at_the_compressed_steps(row, column):
    """The face of `test_a_face_that_steps_in_blue_minus_red_alone_is_enclosed_only_with_those_edges` (blue − red
    up 0.065, over the strong step) through OpenCV's JPEG coder, at each phase of its 2 × 2 chroma blocks (4:2:0):
    the step spreads over about twice the pixels, and the edges of blue − red at the uncompressed steps no longer
    enclose it at any phase; at `COMPRESSED_BLUE_RED_STEPS` of them they do at every phase (the background
    leaves at least 95 % of its inside). At 0.7 of them they would not where it starts on an odd row."""
    import cv2

    from depth.measure import COMPRESSED_BLUE_RED_STEPS, _enclosed

    h, w = 160, 200
    yy, xx = np.mgrid[0:h, 0:w]
    rgb = np.stack([0.80 + 0.10 * xx / w, 0.78 + 0.10 * xx / w, 0.70 + 0.10 * xx / w], axis=-1)
    face = (yy >= row) & (yy < row + 80) & (xx >= column) & (xx < column + 30)
    rgb[face] += [-0.025, 0.0, 0.04]
    rgb = jpeg_coded(np.round(rgb * 255.0) / 255.0)
    search = np.zeros((h, w), dtype=bool)
    search[2:-2, 2:-2] = True
    inside = cv2.erode(face.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    background, _, _ = _enclosed(rgb, search, search, 0.5, blue_red=True)
    assert np.mean(background[inside]) == 1.0
    background, _, _ = _enclosed(rgb, search, search, 0.5, blue_red=True, blue_red_steps=COMPRESSED_BLUE_RED_STEPS)
    assert np.mean(background[inside]) <= 0.05


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("front_shade", [0.44, 0.56, 0.58])
def test_a_white_face_as_bright_as_the_sky_is_found_by_regrowing_its_dark_side_face(front_shade, seed):
    """Where detection finds only the dark side face of a white cube whose front face is nearly as
    bright as the sky behind it (holdout 7070 s1/4 and s3/3, 9090 s3/3 and s7/0 were missed so; here
    the front face hidden from detection), `faint_regrowth` grows that blob across the faint edges to
    the whole cube: the front face's mask within IoU 0.9 of the truth, the side face in the blob, and
    the detection usable and achromatic."""
    cube = faint_white_cube(front_shade)
    image, mirror = make_image((200, 240), [cube], background="ramp", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], cube, "face")
    strip = pixel_truth(image.shape[:2], cube, "strip")
    found = found_without(image, mirror, cube, face, "ramp", 2 / 255, seed)
    grown = faint_regrowth(image, mirror, found)
    assert grown is not None and grown.usable and grown.achromatic
    iou = (grown.front_face_mask & face).sum() / (grown.front_face_mask | face).sum()
    assert iou > 0.9
    assert (grown.mask & strip).sum() > 0.9 * strip.sum()
    assert (grown.front_face_mask & strip).sum() < 0.1 * strip.sum()


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("front_shade", [0.9, 1.0])
def test_a_grey_face_as_noisy_as_a_path_tracers_is_regrown_whole_after_a_wider_blur(front_shade, seed):
    """A grey cube (albedo 0.45) before the "ramp" sky, its pixels with a path tracer's sampling noise
    (Gaussian σ = 0.02 of sRGB value on the cube only; Mitsuba at 16 samples a pixel left a grey face
    0.017 under a sky map: holdout 9090 s3/1). Blurred over 1 px before `faint_regrowth`'s edges, that
    noise cuts the face into pieces (not grown whole); blurred over 1.5 px, the second of
    `FAINT_EDGE_SMOOTHING_PX`, the front face's mask is within IoU 0.9 of the truth."""
    cube = dataclasses.replace(faint_white_cube(0.56), albedo=(0.45, 0.45, 0.45), front_shade=front_shade)
    image, mirror = make_image((200, 240), [cube], background="ramp", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], cube, "face")
    on_cube = face | pixel_truth(image.shape[:2], cube, "strip")
    noise = np.random.default_rng(100 + seed).normal(0.0, 0.02, (int(on_cube.sum()), 3))
    image[on_cube] = np.round(np.clip(image[on_cube] + noise, 0.0, 1.0) * 255.0) / 255.0
    found = found_without(image, mirror, cube, face, "ramp", 2 / 255, seed)  # the side face alone

    def iou(grown):
        return 0.0 if grown is None else (grown.front_face_mask & face).sum() / (grown.front_face_mask | face).sum()

    assert FAINT_EDGE_SMOOTHING_PX[0] == 1.0 and iou(faint_regrowth(image, mirror, found)) < 0.9
    grown = faint_regrowth(image, mirror, found, smoothing_px=FAINT_EDGE_SMOOTHING_PX[1])
    assert grown is not None and grown.usable and iou(grown) > 0.9


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 24), st.integers(1, 24), st.floats(0.2, 0.8), st.integers(0, 2**32 - 1))
def test_holes_are_filled_as_scipy_fills_them(height, width, density, seed):
    """`_holes_filled` (OpenCV's labelling) against `scipy.ndimage.binary_fill_holes`, pixel for pixel, on
    random masks: speckle, and blobs with rings and holes touching the border or not."""
    import scipy.ndimage

    from depth.measure import _holes_filled

    rng = np.random.default_rng(seed)
    speckle = rng.random((height, width)) < density
    rings = np.zeros((height, width), dtype=bool)
    yy, xx = np.mgrid[:height, :width]
    for cy, cx, r in rng.uniform(-2, 26, (3, 3)):
        rings |= np.abs(np.hypot(yy - cy, xx - cx) - abs(r) / 2) < 0.8
    for mask in (speckle, rings, speckle & ~rings, rings | (speckle & (rng.random((height, width)) < 0.1))):
        np.testing.assert_array_equal(_holes_filled(mask), scipy.ndimage.binary_fill_holes(mask))


def _same_bits(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per element: the same float64 bits, or both NaN (a NaN's payload and sign say nothing)."""
    return (np.asarray(a).view(np.uint64) == np.asarray(b).view(np.uint64)) | (np.isnan(a) & np.isnan(b))


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 12), st.integers(1, 12), st.integers(1, 4), st.integers(1, 60), st.sampled_from([1e-3, 1.0, 1e3]),
       st.booleans(), st.integers(0, 2**32 - 1))
def test_bilinear_samples_to_the_bit_what_scipy_map_coordinates_samples(height, width, channels, n, scale, flipped,
                                                                        seed):
    """`_bilinear` (numpy, every channel at once) against `scipy.ndimage.map_coordinates(order=1,
    mode="nearest")` channel by channel, bit for bit: coordinates inside the image, beyond its edges, on
    whole pixels, on its last row and column, not finite; images of one row or column; a window of an
    image (not contiguous)."""
    import scipy.ndimage

    from depth.measure import _bilinear

    rng = np.random.default_rng(seed)
    img = rng.random((height, width, channels)) * scale
    if flipped:
        img = img[:, ::-1]
    u, v = rng.uniform(-3.0, width + 2.0, n), rng.uniform(-3.0, height + 2.0, n)
    pick = rng.integers(0, 7, n)
    u[pick == 1], v[pick == 2] = np.round(u[pick == 1]), np.round(v[pick == 2])
    u[pick == 3], v[pick == 4] = width - 1.0, height - 1.0
    u[pick == 5] = rng.choice([np.nan, np.inf, -np.inf], np.count_nonzero(pick == 5))
    v[pick == 6] = rng.choice([np.nan, np.inf, -np.inf], np.count_nonzero(pick == 6))
    want = np.stack([scipy.ndimage.map_coordinates(img[..., c], np.stack([v, u]), order=1, mode="nearest")
                     for c in range(channels)], axis=-1)
    got = _bilinear(img, u, v)
    assert got.shape == want.shape
    assert _same_bits(got, want).all()
    grid = _bilinear(img, u.reshape(-1, 1)[:1].repeat(2, axis=1), v.reshape(-1, 1)[:1].repeat(2, axis=1))
    assert grid.shape == (1, 2, channels)  # (..., C) for coordinates of any shape


@settings(max_examples=200, deadline=None)
@given(st.integers(5, 40), st.lists(st.integers(1, 3), max_size=2), st.booleans(), st.integers(0, 2**32 - 1))
def test_median5_selects_what_scipy_median_filter_selects(n, trailing, ties, seed):
    """`_median5` against `scipy.ndimage.median_filter(size=(5, 1, ...), mode="nearest")`, element for
    element, on levels with and without ties."""
    import scipy.ndimage

    from depth.measure import _median5

    rng = np.random.default_rng(seed)
    levels = rng.random((n, *trailing))
    if ties:
        levels = np.round(levels * 4.0) / 4.0
    want = scipy.ndimage.median_filter(levels, size=(5,) + (1,) * len(trailing), mode="nearest")
    np.testing.assert_array_equal(_median5(levels), want)


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 40), st.integers(1, 40), st.sampled_from([0.7, 1.0, 1.5, 2.0]), st.booleans(),
       st.integers(0, 2**32 - 1))
def test_gaussian_smoothed_is_scipy_gaussian_filter_to_the_bit(height, width, sigma, binary, seed):
    """`_gaussian_smoothed` against `scipy.ndimage.gaussian_filter`, bit for bit, on masks (as
    `_initial_model` smooths) and on random images, down to one pixel wide: narrower than the kernel,
    whose reflection beyond the edges then repeats."""
    import scipy.ndimage

    from depth.measure import _gaussian_smoothed

    rng = np.random.default_rng(seed)
    image = rng.random((height, width))
    if binary:
        image = (image < rng.random()).astype(np.float64)
    assert _same_bits(_gaussian_smoothed(image, sigma), scipy.ndimage.gaussian_filter(image, sigma)).all()


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_white_face_whose_faint_blue_step_jpeg_smears_is_regrown_at_the_fainter_steps(seed):
    """A white cube before a warm sky ("warm ramp") that its face matches in red: the face differs from
    the sky by 8 levels of 255 in blue and under 2 in red and green (holdout 9090 s7/0: 9 in blue, 0–1
    in the others), and JPEG (quality 90, chroma at half resolution) spreads that step over 4–5 px. On
    the despeckled image, as `reconstruct` detects a compressed one, detection finds the dark side face
    alone (the face hidden from it), and no reading at `FAINT_EDGE_CONTRAST` grows it to the face; the
    first at `FAINTER_EDGE_CONTRAST` does, the front face's mask within IoU 0.85 of the truth (JPEG
    moves the faint sides by up to a pixel)."""
    from depth.reconstruct import despeckled

    cube = faint_white_cube(0.51)
    image, mirror = make_image((200, 240), [cube], background="warm ramp", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], cube, "face")
    plain, _ = make_image(image.shape[:2], [], background="warm ramp", noise=2 / 255, seed=seed)
    steps = np.abs(np.mean(image[face], axis=0) - np.mean(plain[face], axis=0)) * 255.0
    assert steps[2] > 7.0 and steps[:2].max() < 2.0  # the case: a faint step in blue alone
    (found,) = detect_cubes(despeckled(jpeg(np.where(face[..., None], plain, image))), mirror, compressed=True)
    assert (found.mask & face).sum() < 0.02 * face.sum()  # the side face (JPEG's ringing reaches a pixel in)
    compressed = despeckled(jpeg(image))

    def iou(smoothing, contrast):
        grown = faint_regrowth(compressed, mirror, found, compressed=True, smoothing_px=smoothing, contrast=contrast)
        if grown is None or not grown.usable:
            return 0.0
        return (grown.front_face_mask & face).sum() / (grown.front_face_mask | face).sum()

    faint = [r for r in FAINT_EDGE_READINGS if r[1] == FAINT_EDGE_CONTRAST]
    fainter = [r for r in FAINT_EDGE_READINGS if r[1] == FAINTER_EDGE_CONTRAST]
    assert len(faint) == 2 and fainter[0][0] == 1.0
    assert all(iou(*r) < 0.5 for r in faint)
    assert iou(*fainter[0]) > 0.85


def test_readings_in_turn_that_share_their_gradients_find_what_each_finds_alone():
    """`faint_regrowth`'s readings in turn, as `reconstruct` makes them, sharing one `gradients` dict (each
    window's gradient computed once per blur): each reading finds the detection it finds alone, mask for
    mask, on the JPEG case above, whose first readings fail in both windows and whose fainter ones grow
    it. The dict is refused for another image."""
    from depth.reconstruct import despeckled

    cube = faint_white_cube(0.51)
    image, mirror = make_image((200, 240), [cube], background="warm ramp", noise=2 / 255, seed=0)
    face = pixel_truth(image.shape[:2], cube, "face")
    plain, _ = make_image(image.shape[:2], [], background="warm ramp", noise=2 / 255, seed=0)
    (found,) = detect_cubes(despeckled(jpeg(np.where(face[..., None], plain, image))), mirror, compressed=True)
    compressed = despeckled(jpeg(image))
    shared = {}
    grown_any = False
    for smoothing, contrast in FAINT_EDGE_READINGS:
        kw = {"compressed": True, "smoothing_px": smoothing, "contrast": contrast}
        alone = faint_regrowth(compressed, mirror, found, **kw)
        together = faint_regrowth(compressed, mirror, found, gradients=shared, **kw)
        assert (alone is None) == (together is None)
        if alone is not None:
            grown_any = True
            for a, b in ((alone.mask, together.mask), (alone.front_face_mask, together.front_face_mask)):
                np.testing.assert_array_equal(a, b)
    assert grown_any
    assert len(shared) > 1 + len(FAINT_EDGE_SMOOTHING_PX)  # the image, and gradients in both windows
    with pytest.raises(ValueError, match="another image"):
        faint_regrowth(compressed.copy(), mirror, found, compressed=True, gradients=shared)


@settings(max_examples=50, deadline=None)
@given(st.integers(3, 40), st.integers(3, 40), st.sampled_from([1.0, 1.5, 2.0]), st.integers(0, 2**32 - 1))
def test_the_edge_gradient_is_the_sobel_of_the_channel_with_the_largest_one(height, width, sigma, seed):
    """`_channel_gradient` against a reference written apart: scipy's Sobel (its "mirror" border is
    OpenCV's default, reflect-101) of each blurred 8-bit channel, the channel of the largest |dx| + |dy|
    taken per pixel (the first of equal ones), and with `blue_red` that of blue − red besides. The 8 bits are
    rounded from float32(value)·255 in float32, half to even, as OpenCV's `convertScaleAbs` rounds a float64
    image: rounded in float64, a value within float32's precision of a half (0.5745098102318715 · 255 =
    146.5000016) comes out a level apart."""
    import cv2
    import scipy.ndimage

    from depth.measure import _channel_gradient

    rgb = np.random.default_rng(seed).random((height, width, 3))
    rgb[:, : width // 2] *= 0.2  # a step, beside the noise
    u8 = np.round(rgb.astype(np.float32) * np.float32(255.0)).astype(np.uint8)
    u8 = cv2.GaussianBlur(u8, (0, 0), sigma).astype(np.int64)
    gx = np.stack([scipy.ndimage.sobel(u8[..., k], axis=1, mode="mirror") for k in range(3)], axis=-1)
    gy = np.stack([scipy.ndimage.sobel(u8[..., k], axis=0, mode="mirror") for k in range(3)], axis=-1)
    pick = np.argmax(np.abs(gx) + np.abs(gy), axis=-1)[..., None]
    dx, dy = _channel_gradient(rgb, sigma)
    np.testing.assert_array_equal(dx, np.take_along_axis(gx, pick, axis=-1)[..., 0])
    np.testing.assert_array_equal(dy, np.take_along_axis(gy, pick, axis=-1)[..., 0])
    # with `blue_red`: the same, and scipy's Sobel of the blurred blue − red
    dx2, dy2, bx, by = _channel_gradient(rgb, sigma, blue_red=True)
    np.testing.assert_array_equal(dx2, dx)
    np.testing.assert_array_equal(dy2, dy)
    np.testing.assert_array_equal(bx, scipy.ndimage.sobel(u8[..., 2] - u8[..., 0], axis=1, mode="mirror"))
    np.testing.assert_array_equal(by, scipy.ndimage.sobel(u8[..., 2] - u8[..., 0], axis=0, mode="mirror"))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_white_face_found_as_its_thin_top_face_alone_is_regrown_whole(seed):
    """A white cube whose front face (24 × 109 px) is as bright as the "ramp" sky, with a dark top face
    13 px tall above it and no side face: detection finds the top face alone (holdout 8080 s2/0, as its
    bottom face). The first window, 20 px about that blob, reaches 20 px into the face, which runs on
    to the window's rim and is taken for background there; the wider window holds the whole face, and
    the front face's mask comes out within IoU 0.9 of the truth, the top face beside it. Detection
    itself now finds this face whole (its sides, under the strong step, are joined to the top face's
    edge across the pixel Canny leaves at the corners: `_bridged_canny`); the top face alone, the blob
    regrowth starts from, is what it finds with the front face hidden."""
    cube = dataclasses.replace(faint_white_cube(0.56), side=None, top_height=13.0, top_shade=0.25)
    image, mirror = make_image((200, 240), [cube], background="ramp", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], cube, "face")
    (direct,) = detect_cubes(image, mirror)
    assert (direct.mask & face).sum() > 0.9 * face.sum()
    found = found_without(image, mirror, cube, face, "ramp", 2 / 255, seed)
    assert found.bbox[3] - found.bbox[1] < 20  # the top face
    grown = faint_regrowth(image, mirror, found)
    assert grown is not None and grown.usable and grown.achromatic
    iou = (grown.front_face_mask & face).sum() / (grown.front_face_mask | face).sum()
    assert iou > 0.9
    assert (grown.mask & found.mask).sum() > 0.9 * found.mask.sum()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_tall_white_face_found_as_its_sliver_of_a_top_face_alone_is_regrown_whole(seed):
    """A white cube whose front face (24 × 200 px: the XSlit stretches a near face up to 12 times its
    width) is as bright as the "ramp" sky, with a dark top face 5 px tall above it: detection finds the
    top face alone (holdout 9090 s1/3 in JPEG, as its bottom face, 39 × 6 px under a face 41 × 165 px).
    Both earlier windows, 20 and 80 px about that blob, end inside the face, which runs on to their rim
    and is taken for background there; a third window, 4 times the second, holds it. Read as
    `reconstruct` reads it (each of `FAINT_EDGE_READINGS` in turn, the first usable blob kept: here the
    strip is 5 px tall, as wide as the faint edges' band, and under noise only a wider blur or fainter
    steps leave enough of it beside the face), the front face's mask comes out within IoU 0.9 of the
    truth, the top face beside it."""
    cube = FakeCube((100.3, 45.6), (124.8, 46.4), (125.5, 245.2), (101.1, 244.1), top_sag=1.5, bottom_sag=2.0,
                    albedo=(1.0, 1.0, 1.0), front_shade=0.56, side=None, top_height=5.0, top_shade=0.25)
    image, mirror = make_image((280, 240), [cube], background="ramp", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], cube, "face")
    found = found_without(image, mirror, cube, face, "ramp", 2 / 255, seed)
    assert found.bbox[3] - found.bbox[1] <= 8  # the top face
    readings = (faint_regrowth(image, mirror, found, smoothing_px=s, contrast=c) for s, c in FAINT_EDGE_READINGS)
    grown = next((g for g in readings if g is not None and g.usable), None)
    assert grown is not None and grown.achromatic
    iou = (grown.front_face_mask & face).sum() / (grown.front_face_mask | face).sum()
    assert iou > 0.9
    assert (grown.mask & found.mask).sum() > 0.9 * found.mask.sum()


@pytest.mark.parametrize("seed", [0, 1, 4])  # (seeds 2 and 3's notched outlines read within 0.4 px of the whole ones
# since `_enclosed` tests the background's thin strips, their blobs a few corner pixels larger: no notched case)
def test_a_grey_blob_notched_by_the_background_is_read_whole_as_its_convex_hull(seed):
    """A white face (44 × 200 px) with a dark side face 6 px wide on its right, found whole, then with two
    notches 13 px deep and 10 px tall bitten out of its left side (where a faint edge breaks, the
    background reaches into the face: holdout 9090 s3/1 in JPEG). The notched blob's outline reads a
    corner over a pixel from where the whole blob's outline reads it (1.3–17 px); `convex_filled` gives
    the notched blob's convex hull, faces split again, whose front face is within IoU 0.95 of the truth
    and whose outline has every corner within 0.5 px of the whole blob's and no farther from the truth
    than the whole blob's worst corner. The whole blob, whose hull adds only its top and bottom sides'
    bend, is left as it is (None)."""
    from depth.measure import convex_filled

    cube = FakeCube((100.3, 40.6), (144.8, 38.4), (145.5, 240.2), (101.1, 242.1), top_sag=1.5, bottom_sag=2.0,
                    albedo=(1.0, 1.0, 1.0), front_shade=0.44, side="right", side_width=6.0, side_shade=0.25)
    image, mirror = make_image((280, 240), [cube], background="ramp", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], cube, "face")
    (found,) = detect_cubes(image, mirror)
    assert found.usable and found.achromatic and (found.mask & face).sum() > 0.95 * face.sum()
    assert convex_filled(image, mirror, found) is None
    notched = found.mask.copy()
    for top in (70, 170):
        notched[top:top + 10, 95:114] = False
    bitten = dataclasses.replace(found, mask=notched, front_face_mask=found.front_face_mask & notched)
    reference = face_outline(image, found.front_face_mask).corners_px
    assert np.abs(face_outline(image, bitten.front_face_mask).corners_px - reference).max() > 1.0  # the case
    whole = convex_filled(image, mirror, bitten)
    assert whole is not None and whole.usable and whole.achromatic
    iou = (whole.front_face_mask & face).sum() / (whole.front_face_mask | face).sum()
    assert iou > 0.95
    corners = face_outline(image, whole.front_face_mask).corners_px
    np.testing.assert_allclose(corners, reference, atol=0.5)
    truth = cube.corners()
    assert np.abs(corners - truth).max() <= np.abs(reference - truth).max() + 0.05


def test_regrowth_leaves_a_whole_cube_and_a_face_with_no_edge_alone():
    """Where the blob is already the whole cube (a red cube), or the front face has the sky's own
    colour (no edge at all to grow across), `faint_regrowth` gives None: nothing grows by 20 %."""
    red = dataclasses.replace(faint_white_cube(0.56), albedo=COLOURS["red"], front_shade=0.7)
    image, mirror = make_image((200, 240), [red], background="ramp", noise=2 / 255)
    (found,) = detect_cubes(image, mirror)
    assert found.usable and faint_regrowth(image, mirror, found) is None
    # the sky behind the face: linear 0.45 × (1 + 0.3 u / 240) × (0.95, 0.97, 1.0), u ≈ 113
    sky = 0.45 * (1.0 + 0.3 * 113.0 / 240.0) * np.array([0.95, 0.97, 1.0])
    hidden = dataclasses.replace(faint_white_cube(1.0), albedo=tuple(sky))
    image, mirror = make_image((200, 240), [hidden], background="ramp", noise=2 / 255)
    (found,) = detect_cubes(image, mirror)
    assert faint_regrowth(image, mirror, found) is None


def test_regrowth_that_leaks_into_a_shading_sky_is_refused():
    """A sky shading ±40 % over 90 px has ramps whose noise gives edges everywhere at the faint steps;
    the region grown there reaches the window's rim, and `faint_regrowth` gives None rather than a
    blob of sky."""
    image, mirror = make_image((200, 240), [faint_white_cube(0.56)], background="sky", noise=2 / 255)
    (found,) = detect_cubes(image, mirror)
    assert found.bbox[2] - found.bbox[0] < 10  # the side face alone
    assert faint_regrowth(image, mirror, found) is None


def test_front_face_is_separated_from_side_and_top_strips():
    cubes = three_cubes()
    image, mirror = make_image((200, 240), cubes)
    for d, c in zip(match(detect_cubes(image, mirror), cubes), cubes):
        face = pixel_truth(image.shape[:2], c, "face")
        strip = pixel_truth(image.shape[:2], c, "strip")
        iou = (d.front_face_mask & face).sum() / (d.front_face_mask | face).sum()
        assert iou > 0.9
        assert (d.front_face_mask & strip).sum() <= 0.1 * strip.sum()
        assert not (d.front_face_mask & ~d.mask).any()
        assert any((m & strip).sum() > 0.5 * strip.sum() for m in d.side_face_masks)


@dataclasses.dataclass
class TopShadowedCube(FakeCube):
    """A cube whose top face lies, right of `shadow_u`, in a cast shadow (a vertical step within it)."""

    shadow_u: float = 0.0

    def paint(self, img, u, v):
        super().paint(img, u, v)
        tv = self.top(u)
        m = (u > self.shadow_u) & (u < self.right(v)) & (v > tv - self.top_height) & (v <= tv)
        img[m] = np.asarray(self.albedo) * self.front_shade * 0.8


@pytest.mark.parametrize("top_height", [20.0, 28.0])
def test_a_shadow_edge_across_the_top_face_does_not_cut_the_front_face(top_height):
    """A shadow cast across a tall top face makes a vertical brightness step over the top face's
    rows only. It is no boundary between the front face and a side face (those run the face's whole
    height), so the front face is not cut there (it was: 6 of its 36 columns lost, as in the lighting
    bench's floor s4/2, which came out 11.7 % off)."""
    cube = TopShadowedCube((60.3, 50.2), (96.6, 50.9), (97.0, 210.0), (60.8, 209.5), side=None,
                           albedo=COLOURS["green"], top_height=top_height, top_shade=0.85, shadow_u=66.7)
    image, mirror = make_image((240, 200), [cube], background="grey", noise=2 / 255)
    (d,) = detect_cubes(image, mirror)
    assert d.usable, d.reason
    face = pixel_truth(image.shape[:2], cube, "face")
    assert (d.front_face_mask & face).sum() / (d.front_face_mask | face).sum() > 0.95
    assert abs(np.flatnonzero(d.front_face_mask.any(axis=0))[0] - cube.tl[0]) < 1.0


def test_a_shadow_edge_down_the_front_face_is_refused_and_said_so():
    """A cast shadow whose edge runs down the front face splits it into two face-sized parts of one
    colour, as two touching cubes would be: refused, and the reason names both readings (a Mitsuba
    render with a sun behind the mirror showed this; the reason spoke of touching cubes only)."""
    @dataclasses.dataclass
    class Shadowed(FakeCube):
        def paint(self, img, u, v):
            super().paint(img, u, v)
            img[self.face(u, v) & (u > 82.0)] = np.asarray(self.albedo) * self.front_shade * 0.6

    cube = Shadowed((60.3, 50.2), (96.6, 50.9), (97.0, 210.0), (60.8, 209.5), side="right",
                    albedo=COLOURS["green"])
    image, mirror = make_image((240, 200), [cube], background="grey", noise=2 / 255)
    (d,) = detect_cubes(image, mirror)
    assert not d.usable and "shadow" in d.reason and "touching cubes" in d.reason


@pytest.mark.parametrize("shade", [0.45, 0.85])
def test_a_face_cut_by_a_curved_shadow_edge_is_outlined_whole_with_its_part_of_the_same_colour(shade):
    """A cast shadow whose edge arcs across the front face (a neighbour's shadow) splits it by brightness
    into two parts of one colour: the detected front face is one part. `same_material_faces` gives the
    other part, and the outline of their union is the face's (corners within 0.15 px), where that of
    the front face alone follows the arc (its top corners tens of pixels off). A side face of another
    colour (a sticker-like tint) is not offered."""
    @dataclasses.dataclass
    class ArcShadowed(FakeCube):
        def paint(self, img, u, v):
            super().paint(img, u, v)
            arc = v > 120.0 + 0.05 * (u - 78.0) ** 2
            img[self.face(u, v) & arc] = np.asarray(self.albedo) * self.front_shade * shade

    cube = ArcShadowed((60.3, 50.2), (96.6, 50.9), (97.0, 210.0), (60.8, 209.5), side="right",
                       side_shade=0.5, albedo=COLOURS["green"])
    image, mirror = make_image((240, 200), [cube], background="grey", noise=2 / 255)
    (d,) = detect_cubes(image, mirror)
    assert d.usable, d.reason
    alone = face_outline(image, d.front_face_mask)
    assert not alone or np.abs(alone.corners_px - cube.corners()).max() > 5.0
    parts = same_material_faces(image, d)
    unions = [face_outline(image, d.front_face_mask | p) for p in parts]
    best = min((np.abs(o.corners_px - cube.corners()).max() for o in unions if o), default=np.inf)
    assert best < 0.15


def test_a_touching_part_of_another_colour_is_no_part_of_the_face():
    """`same_material_faces` offers only parts whose chromaticity is the front face's: a side face
    painted in another hue of the same brightness class is left out."""
    @dataclasses.dataclass
    class Tinted(FakeCube):
        def paint(self, img, u, v):
            super().paint(img, u, v)
            img[self.side_strip(u, v)] = np.array([0.3, 0.75, 0.1]) * self.side_shade

    cube = Tinted((60.3, 50.2), (96.6, 50.9), (97.0, 210.0), (60.8, 209.5), side="right", side_width=8.0,
                  side_shade=0.5, albedo=COLOURS["green"])
    image, mirror = make_image((240, 200), [cube], background="grey", noise=2 / 255)
    (d,) = detect_cubes(image, mirror)
    strip = pixel_truth(image.shape[:2], cube, "strip")
    assert any((m & strip).sum() > 0.5 * strip.sum() for m in d.side_face_masks)  # the tinted face is there
    assert not any((m & strip).sum() > 0.5 * strip.sum() for m in same_material_faces(image, d))


def test_blob_touching_the_mirror_edge_is_refused():
    inside = FakeCube((60.3, 70.2), (80.6, 70.9), (81.0, 175.0), (60.8, 174.5), side="right",
                      albedo=COLOURS["yellow"])
    # the mirror's top edge at v = 60 cuts this cube's face
    cut = FakeCube((140.2, 30.6), (160.5, 31.0), (161.0, 150.2), (140.6, 150.0), side="left",
                   albedo=COLOURS["magenta"])
    image, mirror = make_image((200, 240), [inside, cut], mirror=(25, 60, 215, 190))
    ok, refused = match(detect_cubes(image, mirror), [inside, cut])
    assert ok.usable  # `inside` is 8 px from the mirror's edges
    assert refused.cut_by_mirror_edge and not refused.occluded
    assert refused.reason is not None and "edge of the mirror" in refused.reason


def test_overlapping_cubes_of_different_colours_are_split_and_marked_occluded():
    front = FakeCube((90.2, 40.3), (112.5, 41.0), (113.1, 150.5), (90.7, 150.0), side="left",
                     albedo=COLOURS["red"])
    behind = FakeCube((108.4, 60.2), (134.9, 60.6), (135.4, 170.3), (108.9, 169.8), side="right",
                      albedo=COLOURS["blue"])
    lone = FakeCube((170.1, 50.0), (190.3, 50.4), (190.9, 160.0), (170.4, 160.2), side="left",
                    albedo=COLOURS["green"])
    image, mirror = make_image((200, 240), [behind, front, lone])  # front painted last
    detections = detect_cubes(image, mirror)
    assert len(detections) == 3
    d_behind, d_front, d_lone = match(detections, [behind, front, lone])
    for d in (d_behind, d_front):
        assert d.occluded and not d.usable
        assert "another cube" in d.reason
    assert d_lone.usable
    assert np.argmax(d_front.color) == 0 and np.argmax(d_behind.color) == 2


def test_empty_mirror_gives_no_detection():
    image, mirror = make_image((120, 160), [], noise=2 / 255)
    assert detect_cubes(image, mirror) == []


# ------------------------------------------------------------------------------ outline


def corner_errors(outline, cube):
    return np.linalg.norm(outline.corners_px - cube.corners(), axis=1)


@pytest.mark.parametrize("background", ["checker", "grey"])
def test_corners_without_noise_within_a_tenth_of_a_pixel(background):
    cubes = three_cubes()
    image, mirror = make_image((200, 240), cubes, background=background)
    for d, c in zip(match(detect_cubes(image, mirror), cubes), cubes):
        outline = face_outline(image, d.front_face_mask)
        assert isinstance(outline, FaceOutline) and outline
        assert corner_errors(outline, c).max() <= 0.1


def test_edge_points_lie_on_the_true_sides_and_are_many():
    cubes = three_cubes()
    image, mirror = make_image((200, 240), cubes)
    for d, c in zip(match(detect_cubes(image, mirror), cubes), cubes):
        o = face_outline(image, d.front_face_mask)
        left, right, top, bottom = o.sides
        height = c.bl[1] - c.tl[1]
        assert len(left) > 0.8 * height and len(right) > 0.8 * height
        assert len(top) > 0.5 * (c.tr[0] - c.tl[0] - 6)
        # horizontal distance to a near-vertical line, vertical distance to a flat curve
        dev = [left[:, 0] - c.left(left[:, 1]), right[:, 0] - c.right(right[:, 1]),
               top[:, 1] - c.top(top[:, 0]), bottom[:, 1] - c.bottom(bottom[:, 0])]
        for name, e in zip(("left", "right", "top", "bottom"), dev):
            # the 8× supersampled painting itself is a staircase of 1/8 px steps
            assert np.sqrt(np.mean(e**2)) < 0.06, name
            assert np.abs(e).max() < 0.15, name
        # corners are ordered TL, TR, BR, BL; every side point lies between its corners
        tl, tr, br, bl = o.corners_px
        assert np.all(left[:, 1] > tl[1]) and np.all(left[:, 1] < bl[1])
        assert np.all(top[:, 0] > tl[0]) and np.all(top[:, 0] < tr[0])
        assert o.edge_noise_px < 0.1


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_corners_with_noise_within_three_tenths_of_a_pixel(seed):
    cubes = three_cubes()
    image, mirror = make_image((200, 240), cubes, noise=2 / 255, seed=seed)
    for d, c in zip(match(detect_cubes(image, mirror), cubes), cubes):
        o = face_outline(image, d.front_face_mask)
        assert o, getattr(o, "reason", "")
        assert corner_errors(o, c).max() <= 0.3
        assert 0.0 < o.edge_noise_px < 0.3


@pytest.mark.parametrize("seed", [10, 11, 12])
def test_random_faces_corners_without_noise(seed):
    rng = np.random.default_rng(seed)
    cubes = [random_cube(rng, 65 + 55 * i, list(COLOURS.values())[(seed + i) % 5]) for i in range(3)]
    image, mirror = make_image((180, 240), cubes, background="checker")
    for d, c in zip(match(detect_cubes(image, mirror), cubes), cubes):
        o = face_outline(image, d.front_face_mask)
        assert o, getattr(o, "reason", "")
        assert corner_errors(o, c).max() <= 0.1


def test_outline_fails_with_a_reason_on_a_featureless_face():
    image = np.full((80, 60, 3), 0.5)
    mask = np.zeros((80, 60), dtype=bool)
    mask[10:70, 20:40] = True
    result = face_outline(image, mask)
    assert isinstance(result, FailedMeasurement) and not result
    assert "contrast" in result.reason
    tiny = np.zeros_like(mask)
    tiny[30:32, 30:32] = True
    small = face_outline(image, tiny)
    assert not small and "too small" in small.reason


def test_srgb_round_trip():
    x = np.linspace(0.0, 1.0, 101)
    assert np.allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)
    assert srgb_to_linear(np.array(0.5)) == pytest.approx(0.21404, abs=1e-5)  # IEC 61966-2-1


# ----------------------------------------------------------------------------- bad input


def test_bad_inputs_raise_depth_errors_naming_the_argument():
    image, mirror = make_image((60, 80), [])
    with pytest.raises(DepthError, match=r"image: expected float64.*uint8"):
        detect_cubes((image * 255).astype(np.uint8), mirror)
    with pytest.raises(DepthError, match=r"image: expected shape \(H, W, 3\)"):
        detect_cubes(image[..., 0], mirror)
    with pytest.raises(DepthError, match=r"image: expected values in \[0, 1\]"):
        detect_cubes(image * 255.0, mirror)
    with pytest.raises(DepthError, match=r"mirror_mask: expected shape"):
        detect_cubes(image, mirror[:-1])
    with pytest.raises(DepthError, match=r"mirror_mask: expected dtype bool"):
        detect_cubes(image, mirror.astype(np.uint8))
    with pytest.raises(DepthError, match=r"mirror_mask: no pixel"):
        detect_cubes(image, np.zeros_like(mirror))
    with pytest.raises(DepthError, match=r"face_mask: expected shape"):
        face_outline(image, mirror.T)
    with pytest.raises(DepthError, match=r"image: expected finite"):
        face_outline(np.full_like(image, np.nan), mirror)
    for bad in (np.nan, np.inf, -np.inf):  # one pixel's one channel is enough
        spoilt = image.copy()
        spoilt[37, 51, 1] = bad
        with pytest.raises(DepthError, match=r"image: expected finite"):
            detect_cubes(spoilt, mirror)
    assert issubclass(DepthError, ValueError)


def test_an_image_vouched_for_is_not_checked_again_there_and_only_there():
    # `checked_images` skips the whole-image check for the very arrays it is given, in this process and
    # in the ones `fork_map` forks from it; a copy, a slice, or the same array outside it is checked
    image, mirror = make_image((60, 80), [])
    spoilt = image * 255.0  # values out of [0, 1]: the check would refuse it
    with checked_images(spoilt):
        assert _check_image(spoilt) is spoilt
        for other in (spoilt.copy(), spoilt[1:]):
            with pytest.raises(DepthError, match=r"image: expected values in \[0, 1\]"):
                _check_image(other)
        forked = fork_map(lambda i: _check_image(spoilt) is spoilt, 2, workers=2)
        assert forked == [True, True]
        with checked_images(image):  # nested: both vouched for, the outer one still
            assert _check_image(spoilt) is spoilt and _check_image(image) is image
        assert _check_image(spoilt) is spoilt
    with pytest.raises(DepthError, match=r"image: expected values in \[0, 1\]"):
        _check_image(spoilt)
    with pytest.raises(DepthError, match=r"image: expected values in \[0, 1\]"):
        detect_cubes(spoilt, mirror)


# ------------------------------------------------------------------ against our renderer


def test_corners_match_the_renderers_exact_truth():
    """Render 2 cubes in a cylinder mirror (400×300) and compare with `cube_truth`.

    The light comes from behind the mirror so that the front faces (which look toward the
    mirror axis) are lit and differ in brightness from their side faces.
    """
    render_mod = pytest.importorskip("raytrace.render")
    from raytrace.camera import PinholeCamera
    from raytrace.mirror import CylinderMirror
    from raytrace.scene import Cube, DirectionalLight, Scene
    from raytrace.truth import cube_truth, mirror_rays

    w, h = 400, 300
    camera = PinholeCamera.from_look_at((w, h), 3500.0 * w / 1600, None, [0.0, 0.0, 0.55],
                                        [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    mirror = CylinderMirror(0.1, 0.49, [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    cubes = [Cube.from_euler_deg(0.04, [0.16, 0.03, 0.35], [0.0, -155.0, 0.0], [0.8, 0.1, 0.1]),
             Cube.from_euler_deg(0.04, [-0.15, -0.02, 0.3], [0.0, 150.0, 0.0], [0.1, 0.7, 0.2])]
    scene = Scene(mirror, cubes, light=DirectionalLight([0.25, 0.45, -0.85], 0.8, 0.2))
    out = render_mod.render(scene, camera, spp=16, seed=0, workers=1)
    image = render_mod.linear_to_srgb8(out.image).astype(np.float64) / 255.0
    mirror_mask = mirror_rays(camera, mirror).hit.reshape(h, w)
    detections = detect_cubes(image, mirror_mask)
    assert len(detections) == 2
    for cube in cubes:
        truth = np.array(cube_truth(camera, mirror, cube)["front_face_corners_px"])
        uc, vc = truth.mean(axis=0)
        (d,) = [d for d in detections if d.mask[int(round(vc)), int(round(uc))]]
        assert d.usable, d.reason
        o = face_outline(image, d.front_face_mask)
        assert o, getattr(o, "reason", "")
        # truth corners are in the cube's own order: compare as sets
        dist = np.linalg.norm(o.corners_px[:, None] - truth[None], axis=2)
        assert sorted(np.argmin(dist, axis=1)) == [0, 1, 2, 3]
        assert dist.min(axis=1).max() <= 0.5


# ------------------------------------------------------------- geometric face separation


@pytest.mark.parametrize("seed", [0, 1])
def test_low_contrast_side_strip_is_split_off_by_its_edge_line(seed):
    """Front and side faces differ by only 4 % of linear brightness (0.70 vs 0.66)."""
    rng = np.random.default_rng(seed)
    cubes = [random_cube(rng, 70 + 60 * i, COLOURS[n]) for i, n in enumerate(["red", "blue"])]
    for c in cubes:
        c.front_shade, c.side_shade, c.side_width = 0.70, 0.66, rng.uniform(5.0, 8.0)
    image, mirror = make_image((180, 200), cubes, noise=1 / 255, seed=seed)
    for d, c in zip(match(detect_cubes(image, mirror), cubes), cubes):
        strip = pixel_truth(image.shape[:2], c, "strip")
        assert (d.front_face_mask & strip).sum() <= 0.15 * strip.sum()
        o = face_outline(image, d.front_face_mask)
        assert o, getattr(o, "reason", "")
        assert corner_errors(o, c).max() <= 0.5


def test_touching_cubes_of_the_same_colour_are_refused():
    a = FakeCube((80.3, 40.2), (102.6, 40.8), (103.1, 150.4), (80.8, 150.0), side=None,
                 albedo=COLOURS["green"], front_shade=0.7)
    b = FakeCube((102.6, 40.8), (125.9, 41.5), (126.4, 151.2), (103.1, 150.4), side=None,
                 albedo=COLOURS["green"], front_shade=0.55)
    image, mirror = make_image((200, 220), [a, b])
    detections = detect_cubes(image, mirror)
    assert len(detections) == 1
    assert not detections[0].usable
    assert "same colour" in detections[0].reason


@pytest.mark.parametrize("background", ["checker", "grey"])
@pytest.mark.parametrize("width", [5.0, 6.3, 7.7])
def test_narrow_faces_are_outlined_with_few_top_and_bottom_points(width, background):
    """Faces 5–8 px wide (far cubes) leave room for only a few top/bottom edge points."""
    c = FakeCube((60.3, 30.6), (60.3 + width, 31.0), (60.9 + width, 140.2), (60.8, 139.7),
                 side="left", side_width=3.0, albedo=COLOURS["blue"])
    image, mirror = make_image((170, 120), [c], background=background)
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert 3 <= len(o.sides[2]) and 3 <= len(o.sides[3])
    assert corner_errors(o, c).max() <= 0.1


def test_a_face_three_pixels_wide_is_outlined_from_two_top_and_bottom_points():
    """A face about 3 px wide (the reconstruct bench's clean s13/0, a far cube turned 6°) can leave room
    for only two top or bottom samples between the corner margins. It was refused ("top side: 2 edge
    points, need 3"); two points fix a line. (Faces 3–4.5 px wide beside a 3 px side face are often
    still refused or outlined a pixel off, with one sample or the side face in the mask: not yet.)"""
    width = 3.15
    c = FakeCube((60.3, 30.6), (60.3 + width, 31.0), (60.9 + width, 140.2), (60.8, 139.7),
                 side="left", side_width=3.0, albedo=COLOURS["blue"])
    image, mirror = make_image((170, 120), [c], background="checker")
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert len(o.sides[2]) == 2 and len(o.sides[3]) == 2
    assert corner_errors(o, c).max() <= 0.25


@pytest.mark.parametrize("v0, dv, top_height", [(30.5, -0.2, 0.3), (30.5, -0.2, 0.45), (30.55, -0.2, 0.6)])
def test_a_face_mask_a_pixel_short_of_its_top_is_stepped_out_to_the_edge(v0, dv, top_height):
    """A narrow face (10 px, seven top points) under a thin, brighter top-face strip, its mask a
    pixel short at the top (as the detection leaves it when the strip's mixed row is not the
    face's colour): the top edge lies at or just beyond the profile's reach, some points a hair
    within it. The outline steps out and measures the two-tone edge, between the strip's outer
    edge (less the overshoot of its brighter colour) and the face's own edge; the other corners
    stay exact. (These cases were refused: too few top points within reach.)"""
    c = FakeCube((60.3, v0), (70.5, v0 + dv), (70.8, v0 + 66.2), (60.6, v0 + 66.0), side=None,
                 albedo=COLOURS["red"], top_height=top_height, top_shade=0.95)
    image, _ = make_image((130, 130), [c], background="grey")
    mask = pixel_truth(image.shape[:2], c, "face")
    mask[np.flatnonzero(mask.any(axis=1))[0]] = False
    o = face_outline(image, mask)
    assert o, getattr(o, "reason", "")
    top = o.sides[2]
    below_face_edge = top[:, 1] - c.top(top[:, 0])  # > 0: inside the face
    assert below_face_edge.max() <= 0.2
    assert below_face_edge.min() >= -top_height - 0.3
    assert corner_errors(o, c)[2:].max() <= 0.05


# ------------------------------------------------------------------- thin neighbouring strips


@pytest.mark.xfail(strict=True, reason="the edge-spread pass moves a side to a strip's inner edge by one offset, "
                   "parallel to the outline of face and strip: top corners 0.20-0.27 px off (known limit)")
@pytest.mark.parametrize("tilt", [-0.6, 0.6])
def test_a_top_strip_whose_far_edge_slopes_otherwise_leaves_the_face_corners_exact(tilt):
    """A top face 1.2 px tall at the face's left end and 1.2 + tilt px at its right (its far edge
    images at another slope than the front face's top edge), of the front face's hue but brighter: the
    top side is moved to the strip's inner edge at that edge's own slope, not kept parallel to the
    outline of face and strip together (which put each top corner tilt/2 px off)."""
    c = FakeCube((60.3, 30.4), (84.6, 30.9), (85.2, 120.3), (60.9, 119.8), top_sag=0.6, side=None,
                 albedo=COLOURS["green"], top_height=1.2, top_tilt=tilt, top_shade=0.95)
    image, mirror = make_image((150, 150), [c], background="grey")
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert o.strip_px[2] == pytest.approx(1.2 + tilt / 2, abs=0.25)
    assert corner_errors(o, c).max() <= 0.1


@pytest.mark.xfail(strict=True, reason="the edge-spread pass pools a side only where 40 pixels lie beyond 2.5 px "
                   "corner margins: a 6 px face's top strip goes unseen, its top corners 1.5-1.7 px high (known limit)")
@pytest.mark.parametrize("u0", [60.3, 60.7])
def test_a_top_strip_on_a_face_six_pixels_wide_is_found(u0):
    """A face 6 px wide (its top side too short for the corners' usual margins) under a brighter top
    face 1.5 px tall: the strip is still measured, and the top corners put at the face's own edge,
    not at the strip's far edge 1.5 px above."""
    c = FakeCube((u0, 30.6), (u0 + 6.1, 30.8), (u0 + 6.4, 74.2), (u0 + 0.3, 74.0), side=None,
                 albedo=COLOURS["green"], top_height=1.5, top_shade=0.95)
    image, mirror = make_image((110, 130), [c], background="grey")
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert o.strip_px[2] == pytest.approx(1.5, abs=0.25)
    assert corner_errors(o, c)[:2].max() <= 0.15


@pytest.mark.parametrize("background", ["checker", "grey"])
@pytest.mark.parametrize("strip", [0.6, 1.0, 1.5, 2.5])
@pytest.mark.parametrize("shade", [0.35, 0.95])
def test_thin_strip_beside_a_side_does_not_move_the_face_edge(strip, background, shade, request):
    """A side face 0.6–2.5 px wide, same hue as the front face but darker or brighter, lies
    beyond the right side: the face's corners are still found within 0.1 px, and the strip is
    reported on that side (and only there)."""
    rng = np.random.default_rng(int(strip * 10) + (background == "grey"))
    u0, v0 = 70.3 + rng.uniform(-0.5, 0.5), 30.4 + rng.uniform(-0.5, 0.5)
    c = FakeCube((u0, v0), (u0 + 24.6, v0 + 0.7), (u0 + 27.1, v0 + 101.3), (u0 + 2.3, v0 + 100.8),
                 top_sag=1.2, bottom_sag=-0.8, albedo=COLOURS["red"], front_shade=0.7,
                 side_shade=shade, side="right", side_width=strip)
    if (shade, strip, background) == (0.95, 2.5, "checker"):
        request.applymarker(pytest.mark.xfail(strict=True, reason="top-right corner 0.12 px off: not yet understood"))
    image, mirror = make_image((160, 170), [c], background=background)
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert corner_errors(o, c).max() <= 0.1
    # edge points of the right side lie on the true side, not between the face and the strip
    right = o.sides[1]
    assert np.abs(np.median(right[:, 0] - c.right(right[:, 1]))) <= 0.1
    assert o.strip_px[0] == 0.0 and o.strip_px[2] == 0.0 and o.strip_px[3] == 0.0
    assert o.alternative is None  # a leaning side samples every phase: one reading
    if strip < 2.0:  # wider strips are split off by the detection's face mask
        assert o.strip_px[1] == pytest.approx(strip, abs=0.15)


@pytest.mark.parametrize("seed", range(40))
def test_a_noisy_face_before_a_noiseless_background_shows_no_strip(seed):
    """A white face 10-14 px wide, lit bluer than a warm sky of nearly its brightness (holdout 3030 s5/0's
    colours: sRGB 178, 181, 186 against 196, 197, 192), with a path tracer's noise on the face alone
    (σ 3.5 / 255, as on that face) and none on the sky: no side, top or bottom face lies beside it, so
    no strip may be read, and every corner is found within half a pixel. The noise the strip tests read
    was the pooled one, half of it the noiseless sky's: 9 of these 40 faces had a strip 1.1-2.7 px
    wide read beside a side, their corners up to 2.7 px off (3030 s5/0: its top 2.6 px low, 29 % off
    at −12.6 σ)."""
    rng = np.random.default_rng(seed)
    u0, v0, width = 60.3 + rng.uniform(-0.5, 0.5), 30.4 + rng.uniform(-0.5, 0.5), rng.uniform(10.0, 14.0)
    c = FakeCube((u0, v0), (u0 + width, v0 - 0.5), (u0 + width - 0.1, v0 + 88.9), (u0, v0 + 88.5),
                 top_sag=0.1, bottom_sag=-0.05, side=None)
    h, w, ss = 150, 140, 8
    u, v = np.meshgrid((np.arange(w * ss) + 0.5) / ss - 0.5, (np.arange(h * ss) + 0.5) / ss - 0.5)
    cover = c.face(u, v).reshape(h, ss, w, ss).mean(axis=(1, 3))[..., None]
    face, sky = srgb_to_linear(np.array([178, 181, 186]) / 255), srgb_to_linear(np.array([196, 197, 192]) / 255)
    image = np.round(linear_to_srgb(cover * face + (1.0 - cover) * sky) * 255.0) / 255.0
    image = path_traced_noise(image, cover[..., 0] > 0.02, 3.5 / 255, seed)
    o = face_outline(image, pixel_truth(image.shape[:2], c, "face"))
    assert o, getattr(o, "reason", "")
    assert np.all(np.asarray(o.strip_px) == 0.0), o.strip_px
    assert corner_errors(o, c).max() <= 0.5


def test_a_one_pixel_strip_beside_a_side_on_the_pixel_grid_gets_a_second_reading():
    """A side face exactly one pixel column wide beside a vertical left side that lies on a pixel
    boundary: every row samples the same phase, so the column could as well be a pixel mixing the
    face, a narrower strip and the outside. The outline reads the strip (the face's corners exact)
    and offers the other reading, the one-step edge inside that column, without the strip."""
    c = FakeCube((60.5, 30.6), (69.8, 30.6), (69.8, 110.4), (60.5, 110.4), side="left", side_width=1.0,
                 side_shade=0.95, albedo=(0.62, 0.62, 0.25), front_shade=0.7)
    image, mirror = make_image((140, 130), [c], background="checker")
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert o.strip_px[0] == pytest.approx(1.0, abs=0.2)
    # the checkered ground beyond the right side read as a strip there too (1.8 px, of a colour near
    # the line between the face's and the ground's); a cube shows one of its left and right faces
    assert o.strip_px[1] == 0.0
    assert np.abs(o.corners_px[[0, 3], 0] - c.corners()[[0, 3], 0]).max() <= 0.05
    alt = o.alternative
    assert alt is not None and alt.strip_px[0] == 0.0
    # > 0: the edge put out in the strip; the one-step area counts the strip, brighter than the face
    # by 0.95 / 0.7, as that much face: at most 1.36 px out
    left_shift = c.corners()[[0, 3], 0] - alt.corners_px[[0, 3], 0]
    assert np.all((left_shift > 0.3) & (left_shift < 0.95 / 0.7 + 0.05))
    # the other sides are those of the first reading
    np.testing.assert_allclose(alt.corners_px[[1, 2]], o.corners_px[[1, 2]], atol=1e-9)


@pytest.mark.parametrize("side_width", [1.0, 0.6])
def test_an_off_colour_pixel_beside_a_side_on_the_pixel_grid_has_the_strip_as_one_reading(side_width):
    """A bright side face beside a left side on a pixel boundary, against grey: every row samples
    one phase, and one sample per pixel cannot tell a strip filling the off-colour column from a pixel
    mixing face, a narrower strip and the outside. One reading is the strip filling that column, the
    face's edge at the column's inner boundary, which here is the truth; the other reads a mixed pixel.
    Brighter than the face, the column counts as face there, not as more: that edge lies inside the
    column, not beyond the pixels the cube covers (the strip's area, 0.95 / 0.7 of the face's, put it
    1.36 px out)."""
    c = FakeCube((60.5, 30.6), (69.8, 30.6), (69.8, 110.4), (60.5, 110.4), side="left", side_width=side_width,
                 side_shade=0.95, albedo=(0.62, 0.62, 0.25), front_shade=0.7)
    image, mirror = make_image((140, 130), [c], background="grey")
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert o.alternative is not None
    readings = [o, o.alternative]
    strip = [r for r in readings if r.strip_px[0] > 0]
    mixed = [r for r in readings if r.strip_px[0] == 0.0]
    assert len(strip) == 1 and len(mixed) == 1
    assert strip[0].strip_px[0] == pytest.approx(1.0, abs=0.1)
    assert np.abs(strip[0].corners_px[[0, 3], 0] - c.corners()[[0, 3], 0]).max() <= 0.1
    out = c.corners()[[0, 3], 0] - mixed[0].corners_px[[0, 3], 0]
    assert np.all((out > 0.5) & (out <= 1.0 + 0.05))  # within the column: its outer boundary is 1 px out
    np.testing.assert_allclose(o.alternative.corners_px[[1, 2]], o.corners_px[[1, 2]], atol=1e-9)


@pytest.mark.parametrize("ratio", [1.36, 2.25])
@pytest.mark.parametrize("start", [9.5, 10.0, 10.5])
def test_a_column_brighter_than_the_face_beside_a_side_on_the_pixel_grid_counts_as_face(ratio, start):
    """Linear colours, pixel centres at integers: a red face up to column 9, column 10 the face's colour
    times `ratio` (a side face lit brighter, filling that pixel), grey beyond. Every edge point of a
    vertical side is placed at the column's outer boundary, u = 10.5, from wherever its profile starts:
    the column counts as face, not as `ratio` times as much (which put the edge up to 0.9 px beyond
    every pixel the cube covers and made the refinement step out of the blob)."""
    from depth.measure import _edge_offsets

    face = np.array([0.56, 0.056, 0.056])
    img = np.full((40, 30, 3), 0.35)
    img[:, :10] = face
    img[:, 10] = face * ratio
    points = np.column_stack([np.full(20, start), np.arange(10.0, 30.0)])
    e, contrast, _ = _edge_offsets(img, points, np.tile([1.0, 0.0], (20, 1)), 1.5, 0.02)
    assert np.all(contrast > 0.02)
    np.testing.assert_allclose(start + e, 10.5, atol=1e-6)


# ------------------------------------------------------------------------------ JPEG: luma


def jpeg(srgb, quality=90):
    """Through OpenCV's JPEG codec (libjpeg: 4:2:0 chroma subsampling at this quality)."""
    import cv2
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(np.round(srgb * 255).astype(np.uint8), cv2.COLOR_RGB2BGR),
                           [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    return cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float64) / 255.0


@pytest.mark.parametrize("background", ["checker", "grey"])
def test_luma_outlines_jpeg_faces_better_than_colour(background):
    """Chroma at half resolution smears colour edges; luma keeps them where they were painted.

    The true face masks are given, so that only the outline is tested (not the detection)."""
    cubes = three_cubes()
    image, _ = make_image((200, 240), cubes, background=background)
    compressed = jpeg(image)
    errors = {}
    for channels in EDGE_CHANNELS:
        errs = []
        for c in cubes:
            outline = face_outline(compressed, pixel_truth(image.shape[:2], c, "face"), thin_strips=False,
                                   channels=channels)
            assert outline, outline
            errs.append(corner_errors(outline, c))
        errors[channels] = np.concatenate(errs)
    assert np.median(errors["luma"]) <= 0.35
    assert np.median(errors["luma"]) < 0.5 * np.median(errors["colour"])
    if background == "grey":  # no background texture: every corner
        assert errors["luma"].max() <= 0.4 and errors["luma"].max() < 0.5 * errors["colour"].max()


def _no_chroma_steps(linear, points, *args):
    """`_chroma_step_offsets` taking no point: the readings it stands before (the colour's linear area)."""
    return np.zeros(len(points), dtype=bool), np.zeros(0), np.zeros(0)


def test_luma_falls_back_to_colour_where_luma_shows_no_edge(monkeypatch):
    """A face with its background's luma: every edge point is placed on the colour profile (the left and right
    sides' on the encoded colour's area over `JPEG_CHROMA_REACH_PX`, `_chroma_step_offsets`; on this image,
    which no JPEG coder smeared, that reading and the linear one agree with each other to 0.005 px and with
    the truth to 0.03 px). Where that reading takes no point, the outline is the colour one to 1e-6 px."""
    grey = 0.35  # make_image's plain background (linear)
    y_grey = linear_to_srgb(np.array(grey))
    # a red and a blue-green sRGB colour with exactly the background's luma Y'
    red = np.array([0.75, 0.0, 0.0])
    red[1] = (y_grey - 0.299 * red[0]) / 0.587
    face = FakeCube((60.3, 40.6), (90.8, 41.2), (91.5, 150.2), (61.1, 149.1), albedo=tuple(srgb_to_linear(red)),
                    front_shade=1.0, side=None)
    image, mirror = make_image((200, 160), [face], background="grey", decoy=False)
    assert np.isclose(image[95, 75] @ [0.299, 0.587, 0.114], image[95, 20] @ [0.299, 0.587, 0.114], atol=2 / 255)
    mask = pixel_truth(image.shape[:2], face, "face")
    colour = face_outline(image, mask, channels="colour")
    assert colour and corner_errors(colour, face).max() <= 0.1
    luma = face_outline(image, mask, channels="luma")
    # the same edges: the top and bottom are read over a longer profile (`JPEG_CHROMA_REACH_PX`), the left
    # and right on the encoded colour's area, each exact on a sharp edge
    assert luma and np.abs(luma.corners_px - colour.corners_px).max() < 0.005
    assert corner_errors(luma, face).max() <= 0.03
    import depth.measure
    monkeypatch.setattr(depth.measure, "_chroma_step_offsets", _no_chroma_steps)
    fallback = face_outline(image, mask, channels="luma")
    # the top and bottom read over a longer profile move the corners by 1e-7 px
    assert fallback and np.abs(fallback.corners_px - colour.corners_px).max() < 1e-6
    with pytest.raises(DepthError, match="channels: expected one of colour, luma"):
        face_outline(image, mask, channels="rgb")


def _coloured_rectangle(face8, background8, left, right, top, bottom, shape=(96, 96), ss=16):
    """An sRGB image of an upright rectangle of colour `face8` (8-bit sRGB) before `background8`, each pixel the
    mix in linear light of the two by the share of its area the rectangle covers (ss × ss samples), and the
    mask of the pixels it covers over half."""
    h, w = shape
    xs, ys = (np.arange(w * ss) + 0.5) / ss, (np.arange(h * ss) + 0.5) / ss
    inside = ((xs >= left) & (xs < right))[None, :] & ((ys >= top) & (ys < bottom))[:, None]
    cover = inside.reshape(h, ss, w, ss).mean(axis=(1, 3))[..., None]
    face, background = srgb_to_linear(np.array(face8) / 255.0), srgb_to_linear(np.array(background8) / 255.0)
    return linear_to_srgb(cover * face + (1.0 - cover) * background), cover[..., 0] > 0.5


@pytest.mark.parametrize("face8, background8", [((200, 40, 40), (200, 200, 200)), ((40, 150, 60), (225, 225, 215)),
                                                ((128, 128, 128), (200, 200, 200))])
def test_a_coloured_jpeg_face_is_outlined_on_luma_at_its_true_width(face8, background8):
    """JPEG's luma Y' = 0.299 R' + 0.587 G' + 0.114 B' sums the channels after their sRGB encoding: across the
    edge of a coloured face it is not linear in the share of a pixel the face covers, even taken to linear
    light, and its area put each side inward: the red face before grey read 0.13 px narrower (median over five
    phases), the green one 0.05 px. Read as the coverage that mix's luma gives, the width comes back to within
    0.02 px (the phases scatter by up to 0.055 px through JPEG's blocks); a grey face, whose luma is linear, is
    the control."""
    widths = []
    for left in np.linspace(30.1, 30.9, 5):
        right = left + 23.37
        image, mask = _coloured_rectangle(face8, background8, left, right, 20.3, 75.6)
        outline = face_outline(jpeg(image, 95), mask, channels="luma", thin_strips=False)
        assert outline
        widths.append(np.median(outline.sides[1][:, 0]) - np.median(outline.sides[0][:, 0]) - (right - left))
    assert abs(np.median(widths)) <= 0.02 and np.max(np.abs(widths)) <= 0.08


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 255), min_size=3, max_size=3), st.lists(st.integers(0, 255), min_size=3, max_size=3),
       st.lists(st.floats(0.0, 1.0), min_size=1, max_size=12))
def test_luma_coverage_inverts_the_luma_of_two_colours_mixed_in_linear_light(a8, b8, shares):
    """Two colours stepping the same way in every channel (so that the luma rises with the share), their luma
    step 20 levels of 255 or more: the coverage read from the luma of each linear mix is that mix's share.
    A grey pair's coverage is the luma's linear reading itself."""
    from depth.measure import _luma_coverage
    lo, hi = np.minimum(a8, b8), np.maximum(a8, b8)
    weights = np.array([0.299, 0.587, 0.114])
    assume((linear_to_srgb(srgb_to_linear(hi / 255.0)) - linear_to_srgb(srgb_to_linear(lo / 255.0))) @ weights
           >= 20 / 255)
    c_in, c_out = srgb_to_linear(hi / 255.0), srgb_to_linear(lo / 255.0)  # the face brighter here; both ways below
    t = np.array(shares)
    for inside, outside, cover in ((c_in, c_out, t), (c_out, c_in, t)):
        mix = outside + cover[:, None] * (inside - outside)
        luma = srgb_to_linear(linear_to_srgb(mix) @ weights)[None]
        y_in, y_out = (srgb_to_linear(np.array([linear_to_srgb(c) @ weights])) for c in (inside, outside))
        got = _luma_coverage(luma, y_in, y_out, inside[None], outside[None])[0]
        assert np.allclose(got, cover, atol=1e-6)
    grey_in, grey_out = np.full(3, c_in @ weights), np.full(3, c_out @ weights)
    mix = grey_out + t[:, None] * (grey_in - grey_out)
    luma = srgb_to_linear(linear_to_srgb(mix) @ weights)[None]
    y_in, y_out = (srgb_to_linear(np.array([linear_to_srgb(c) @ weights])) for c in (grey_in, grey_out))
    got = _luma_coverage(luma, y_in, y_out, grey_in[None], grey_out[None])[0]
    assert np.allclose(got, (luma[0] - y_out) / (y_in - y_out), atol=1e-9)


def test_luma_coverage_keeps_the_linear_reading_where_the_luma_does_not_rise_with_the_coverage():
    """A yellow-green face before a grey floor (holdout 6060 s4/1): its luma steps 6 levels of 255, green up and
    blue down, and dips before it rises, so no coverage answers a luma uniquely (inverted anyway, its sides went
    0.3 and 1.0 px inward). Its samples keep the linear reading, as do those beyond either end of a step that
    is inverted (JPEG's ringing)."""
    from depth.measure import _luma_coverage
    weights = np.array([0.299, 0.587, 0.114])
    t = np.linspace(-0.2, 1.2, 29)
    for face8, floor8, inverted in (((192, 224, 94), (188, 199, 181), False), ((200, 40, 40), (200, 200, 200), True)):
        c_in, c_out = srgb_to_linear(np.array(face8) / 255.0), srgb_to_linear(np.array(floor8) / 255.0)
        luma = srgb_to_linear(linear_to_srgb(c_out + np.clip(t, 0, 1)[:, None] * (c_in - c_out)) @ weights)
        luma = luma + 0.02 * (luma[-1] - luma[0]) * np.sign(t - 0.5) * (np.abs(t - 0.5) > 0.5)  # ringing beyond
        y_in, y_out = (srgb_to_linear(np.array([linear_to_srgb(c) @ weights])) for c in (c_in, c_out))
        linear = (luma - y_out) / (y_in - y_out)
        got = _luma_coverage(luma[None], y_in, y_out, c_in[None], c_out[None])[0]
        beyond = (linear <= 0.0) | (linear >= 1.0)
        assert np.array_equal(got[beyond], linear[beyond])
        if inverted:
            assert np.allclose(got[~beyond], t[~beyond], atol=1e-6) and not np.allclose(linear[~beyond], t[~beyond],
                                                                                      atol=0.02)
        else:
            assert np.array_equal(got, linear)


@pytest.mark.parametrize("face8, background8", [((232, 235, 85), (217, 217, 217)), ((40, 200, 180), (147, 147, 147)),
                                                ((255, 150, 0), (165, 165, 165)), ((200, 100, 255), (141, 141, 141))])
def test_a_jpeg_face_stepping_in_chroma_alone_is_outlined_at_its_true_sides(face8, background8):
    """A face of its background's luma Y' (within 3 levels of 255), or whose luma steps 7 levels but dips
    before it rises across the edge (the purple face: green down, red and blue up), so that no coverage
    answers it (`_luma_invertible`): the luma does not place the left and right sides, and JPEG smears the
    chroma that shows them over about four pixels in the encoded values. Read on the colour's linear area
    (or the purple face's luma, linearly) they lay 0.2–0.5 px outward (the face 0.54–0.73 px wider in the
    median over five phases; the reconstruct bench's JPEG s16/0, a yellow face before grey, 4.2 % off in
    depth). Read on the encoded area over the chroma's reach (`_chroma_step_offsets`), each side lies
    within 0.15 px in the median and the width within 0.12 px (0.25 px at any phase)."""
    lefts, rights = [], []
    for left in np.linspace(30.1, 30.9, 5):
        right = left + 23.37
        image, mask = _coloured_rectangle(face8, background8, left, right, 20.3, 75.6)
        outline = face_outline(jpeg(image, 90), mask, channels="luma", thin_strips=False)
        assert outline, outline
        # (the rectangle's pixel i spans [i, i + 1]; the outline's pixel i is centred on i)
        lefts.append(left - 0.5 - np.median(outline.sides[0][:, 0]))
        rights.append(np.median(outline.sides[1][:, 0]) - (right - 0.5))
    widths = np.add(lefts, rights)
    assert abs(np.median(lefts)) <= 0.15 and abs(np.median(rights)) <= 0.15, (lefts, rights)
    assert abs(np.median(widths)) <= 0.12 and np.abs(widths).max() <= 0.25, widths


def test_a_chroma_step_with_another_brightness_within_reach_is_not_read_on_its_area():
    """`_chroma_step_offsets` reads a side on the encoded area only where the luma over the profile is what a
    pixel mixing its two ends makes: beside a face of its chroma but darker (a side face 2 px wide, within the
    chroma's reach), the area holds a third level and places no edge, and the side is left to the other
    readings; the other side of the same face, one step, is read. A step of too little contrast is not."""
    from depth.measure import JPEG_CHROMA_REACH_PX, _chroma_step_offsets, _edge_image
    face8, background8 = (232, 235, 85), (217, 217, 217)
    image, _ = _coloured_rectangle(face8, background8, 30.4, 53.77, 20.3, 75.6)
    darker = linear_to_srgb(0.45 * srgb_to_linear(np.array(face8) / 255.0))
    image[:, 28:30] = darker  # a side face left of the face's left side (pixel 30 mixes face and background)
    linear = _edge_image(image, "luma")
    rows = np.arange(30.0, 66.0)
    left = np.column_stack([np.full(len(rows), 30.0), rows])
    right = np.column_stack([np.full(len(rows), 53.0), rows])
    normal = np.tile([1.0, 0.0], (len(rows), 1))
    flat_left, _, _ = _chroma_step_offsets(linear, left, -normal, JPEG_CHROMA_REACH_PX, 0.02)
    flat_right, e, _ = _chroma_step_offsets(linear, right, normal, JPEG_CHROMA_REACH_PX, 0.02)
    assert not flat_left.any()
    assert flat_right.all() and np.allclose(53.0 + e, 53.77 - 0.5, atol=0.02)
    # a step under twice the contrast step (a purple face before its own side face, 11 levels of 255 darker in
    # red: the reconstruct bench's JPEG s19/2) is one step too, but its area over ±3 px gathers more noise than
    # edge: it is left to the narrower reading
    weak, _ = _coloured_rectangle((137, 55, 155), (126, 50, 144), 30.4, 53.77, 20.3, 75.6)
    taken, e, _ = _chroma_step_offsets(_edge_image(weak, "luma"), right, normal, JPEG_CHROMA_REACH_PX, 0.02)
    assert not taken.any() and e.size == 0


@pytest.mark.parametrize("left", [60.3, 63.6])
@pytest.mark.parametrize("mask_low_px", [0, 1, 2, 3])
def test_a_jpeg_face_whose_bottom_shows_no_luma_edge_is_outlined_on_its_chroma(left, mask_low_px, monkeypatch):
    """Below the face, a background of the face's luma (a dark floor tile under a purple cube: the
    reconstruct bench's JPEG s18/0 and s14/2), so only the chroma shows the bottom edge, and JPEG
    stores it at half resolution, spread over about four pixels. Read over ±1.5 px, the bottom sat
    wherever the face mask put the profile (the mask of a blob widened by the chroma's smear): the
    bottom corners 1.2–2.8 px off, or no edge at all, with the mask 2–3 px low; read over the chroma's
    reach, the bottom side lies within 0.2 px of the truth in the median whatever the mask (s14/2's bottom
    side: 1.97 → 0.02 px off in the median), its corners, which its curve's ends and the sides' last
    points over the tile fix, within 0.75 px. (Until the eighty-fourth session every pixel outside the mask
    was painted the 0.8 background, which erased the face's share of the pixels its sides cut: the top
    corners lay 0.3–1.2 px off, the sides above the tile 0.25 px out, and the bottom corners 0.3–0.65 px,
    under a bound of 0.7 px. Painted by each pixel's share, the top corners lie within 0.2 px, and the bottom
    ones 0.1–0.74 px off with the code before that session's change, 0.1–0.71 px with it, the bottom side
    0.09–0.21 px and 0.01–0.19 px off in the median. Where `_chroma_step_offsets` takes no point, the reading
    it stands before keeps that image's bottom corners within 0.7 px.)"""
    y_grey = linear_to_srgb(np.array(0.35))  # make_image's plain background (linear 0.35)
    purple = np.array([0.7, 0.0, 0.8])
    purple[1] = (y_grey - 0.299 * purple[0] - 0.114 * purple[2]) / 0.587  # sRGB, the background's luma Y'
    face = FakeCube((left, 40.6), (left + 16.5, 41.2), (left + 17.2, 150.2), (left + 0.8, 149.1),
                    albedo=tuple(srgb_to_linear(purple)), front_shade=1.0, side=None)
    image, _ = make_image((200, 140), [face], background="grey", decoy=False)
    u, v = np.meshgrid(np.arange(140.0), np.arange(200.0))
    mask = pixel_truth(image.shape[:2], face, "face")
    # luma edges elsewhere: the background 0.8 but on a tile under the bottom, each pixel the face's share of
    # it kept (painting every pixel outside the mask 0.8 erased the face's share of the pixels its sides cut,
    # and moved the sides above the tile by 0.25 px)
    tile = (v > 120) & (u > 50) & (u < 90)
    painted_over = image.copy()
    painted_over[~mask & ~tile] = linear_to_srgb(np.array(0.8))
    linear = srgb_to_linear(image)
    albedo = np.array(face.albedo)
    cover = np.clip((linear[..., 2] - 0.35) / (albedo[2] - 0.35), 0.0, 1.0)[..., None]
    image[~tile] = linear_to_srgb(cover * albedo + (1.0 - cover) * 0.8)[~tile]
    col = int(left) + 8
    assert np.isclose(image[145, col] @ [0.299, 0.587, 0.114], image[160, col] @ [0.299, 0.587, 0.114],
                      atol=2 / 255)
    compressed = jpeg(image)
    if mask_low_px:
        mask[mask_low_px:] |= mask[:-mask_low_px].copy()
    o = face_outline(compressed, mask, channels="luma", thin_strips=False)
    assert o, o
    bottom = o.sides[3]
    true_v = 149.1 + (bottom[:, 0] - (left + 0.8)) * (150.2 - 149.1) / 16.4
    assert abs(np.median(bottom[:, 1] - true_v)) <= 0.2
    errors = corner_errors(o, face)
    assert errors[:2].max() <= 0.25 and errors[2:].max() <= 0.75, errors
    import depth.measure
    monkeypatch.setattr(depth.measure, "_chroma_step_offsets", _no_chroma_steps)
    o = face_outline(jpeg(painted_over), mask, channels="luma", thin_strips=False)
    assert o, o
    assert corner_errors(o, face)[2:].max() <= 0.7


def test_despeckled_jpeg_gives_more_faces_outlined_within_half_a_pixel():
    """JPEG breaks a face into fragments of slightly different colour; detecting on the median-
    filtered image (`depth.reconstruct.despeckled`) and outlining on the image itself recovers them."""
    from depth.reconstruct import despeckled
    for background in ("checker", "grey"):
        cubes = three_cubes()
        image, mirror = make_image((200, 240), cubes, background=background)
        compressed = jpeg(image, 90)
        good = {}
        for name, det_image in (("raw", compressed), ("despeckled", despeckled(compressed))):
            n = 0
            for d in detect_cubes(det_image, mirror):
                o = face_outline(compressed, d.front_face_mask, thin_strips=False, channels="luma")
                n += bool(o) and min(corner_errors(o, c).max() for c in cubes) <= 0.5
            good[name] = n
        assert good["despeckled"] > good["raw"], (background, good)


# --------------------------------------------------------------------------- silhouette


def test_silhouette_gives_the_back_edge_beside_a_side_face_and_drops_a_ragged_border():
    cube = FakeCube((60.3, 30.6), (84.8, 31.4), (85.5, 150.2), (61.1, 149.1), side="left", side_width=4.5,
                    albedo=COLOURS["red"])
    image, _ = make_image((180, 150), [cube], background="grey", decoy=False)
    face = pixel_truth(image.shape[:2], cube, "face")
    blob = face | pixel_truth(image.shape[:2], cube, "strip")
    outline = face_outline(image, face)
    left, right = silhouette_sides(image, blob, outline)
    assert right is None  # no side face shows on the right
    assert left is not None and len(left) > 60
    # the back edge: the strip's outer boundary, 4.5 px left of the face's left side
    assert np.abs(left[:, 0] - (cube.left(left[:, 1]) - 4.5)).max() < 0.15
    gaps = silhouette(image, blob, outline).gaps_px  # beyond the left side 4.5 px, 0 elsewhere
    assert abs(gaps[0] - 4.5) < 0.15 and np.all(np.abs(gaps[1:]) < 0.1)
    # a ragged border (every other row one pixel wider, as JPEG ringing can make it) is no edge
    ragged, rag_blob = image.copy(), blob.copy()
    rows = np.flatnonzero(blob.any(axis=1))[::2]
    for r in rows:
        c = int(np.argmax(blob[r]))
        ragged[r, c - 1] = ragged[r, c]
        rag_blob[r, c - 1] = True
    assert silhouette_sides(ragged, rag_blob, outline)[0] is None
    assert silhouette_sides(ragged, rag_blob, outline, max_scatter_px=np.inf)[0] is not None


@pytest.mark.parametrize("side, background", [("left", "blue sky"), ("right", "blue sky"), ("left", "grey")])
def test_the_silhouette_of_a_face_blurred_after_its_encoding_is_read_on_the_encoded_values(side, background):
    """A blur of the stored sRGB values (image software) keeps the area under the encoded profile, so a
    boundary read on linear light moves toward its brighter side. The front face's sides were read on the
    encoded values (`face_outline(..., blur_domain="encoded")`), but the silhouette beside it in linear
    light: on the reconstruct bench's blurred turned cubes, before a background brighter than their side
    faces, the back vertical edge lay 0.26-0.48 px out, and the gaps beside sides showing no side face
    0.15-0.42 px (0.00-0.09 px in the sharp images), which leaned their depths low (36 of 44 below the
    truth). Read as the face's outline was (`FaceOutline.blur_domain`), the back edge lies within 0.08 px
    of the truth and the other gaps within 0.08 px of 0; the linear reading of the same image puts the
    back edge over 0.15 px out (the side face is darker than the background)."""
    from scipy import ndimage
    cube = FakeCube((60.3, 30.6), (84.8, 31.4), (85.5, 150.2), (61.1, 149.1), side=side, side_width=4.5,
                    albedo=COLOURS["red"])
    image, _ = make_image((180, 150), [cube], background=background, decoy=False)
    soft = np.round(np.clip(ndimage.gaussian_filter(image, sigma=(0.7, 0.7, 0)), 0.0, 1.0) * 255.0) / 255.0
    face = pixel_truth(image.shape[:2], cube, "face")
    blob = face | pixel_truth(image.shape[:2], cube, "strip")
    outline = face_outline(soft, face, blur_domain="encoded")
    assert outline.blurred and outline.blur_domain == "encoded"
    k, sign = (0, -1.0) if side == "left" else (1, 1.0)

    def back_edge_offset(sil):  # median outward offset (px) of the back-edge points from the truth
        pts = sil.sides[k]
        true_u = (cube.left(pts[:, 1]) - 4.5) if side == "left" else (cube.right(pts[:, 1]) + 4.5)
        return float(np.median(sign * (pts[:, 0] - true_u)))

    sil = silhouette(soft, blob, outline)
    assert abs(back_edge_offset(sil)) < 0.08
    assert abs(sil.gaps_px[k] - 4.5) < 0.1
    assert np.all(np.abs(np.delete(sil.gaps_px, k)) < 0.08), sil.gaps_px
    as_linear = silhouette(soft, blob, dataclasses.replace(outline, blur_domain="linear"))
    assert back_edge_offset(as_linear) > 0.15


def test_silhouette_gap_above_a_top_face_strip():
    """A top face 3 px tall above the front face: the silhouette lies 3 px above its top side."""
    cube = FakeCube((60.3, 30.6), (84.8, 31.4), (85.5, 150.2), (61.1, 149.1), side=None, top_height=3.0,
                    albedo=COLOURS["red"])
    image, _ = make_image((180, 150), [cube], background="grey", decoy=False)
    face = pixel_truth(image.shape[:2], cube, "face")
    u, v = np.meshgrid(np.arange(image.shape[1], dtype=float), np.arange(image.shape[0], dtype=float))
    blob = face | ((u > cube.left(v)) & (u < cube.right(v)) & (v > cube.top(u) - 3.0) & (v <= cube.top(u)))
    gaps = silhouette(image, blob, face_outline(image, face)).gaps_px
    assert abs(gaps[2] - 3.0) < 0.2 and np.all(np.abs(gaps[[0, 1, 3]]) < 0.1)


def banded_purple_face(side=None, side_width=0.0):
    """A purple face 16.5 px wide on horizontal bands 6 px tall, alternately a grey of the face's luma Y'
    (only the chroma shows the face's sides there) and a light grey: a purple cube on the reconstruct
    bench's checker floor (JPEG s18/0). The image, its JPEG and the face."""
    y_grey = linear_to_srgb(np.array(0.35))
    purple = np.array([0.7, 0.0, 0.8])
    purple[1] = (y_grey - 0.299 * purple[0] - 0.114 * purple[2]) / 0.587  # sRGB, the dark bands' luma Y'
    face = FakeCube((60.3, 40.6), (76.8, 41.2), (77.5, 150.2), (61.1, 149.1), albedo=tuple(srgb_to_linear(purple)),
                    front_shade=1.0, side_shade=0.4, side=side, side_width=side_width)
    image, _ = make_image((200, 140), [face], background="grey", decoy=False)
    v = np.arange(200.0)[:, None] + np.zeros(140)
    cube = pixel_truth(image.shape[:2], face, "face") | pixel_truth(image.shape[:2], face, "strip")
    image[~cube & (v // 6 % 2 == 1)] = linear_to_srgb(np.array(0.8))
    return image, jpeg(image), face


@pytest.mark.parametrize("smear_px", [0, 1, 2, 3])
def test_a_jpeg_silhouette_is_read_on_luma_not_on_the_smeared_chroma(smear_px):
    """JPEG spreads a face's chroma up to 3 px beyond it, and a blob found on colour reaches that far
    (`smear_px` on each side here). The silhouette read at the blob's boundary then fell on the smear:
    gaps of 1–2.3 px beside a face with no side face, which `depth.estimate` reads as distinct side
    faces (JPEG s18/0: 69.8 % off). Read on the luma step within the chroma's reach, dropping the
    points where only chroma shows the edge, the gaps are within 0.25 px of 0."""
    image, compressed, face = banded_purple_face()
    mask = pixel_truth(image.shape[:2], face, "face")
    outline = face_outline(compressed, mask, channels="luma", thin_strips=False)
    assert outline, outline
    blob = mask.copy()
    for k in range(1, smear_px + 1):
        blob[:, k:] |= mask[:, :-k]
        blob[:, :-k] |= mask[:, k:]
    sil = silhouette(compressed, blob, outline, channels="luma")
    assert np.all(np.abs(sil.gaps_px[:2]) <= 0.25), sil.gaps_px
    assert sil.sides == (None, None)


def test_a_jpeg_silhouette_still_finds_a_side_face_and_its_back_edge():
    """The same face with a side face 4.5 px wide on its left, darker: the luma steps twice, and the
    outermost step is the silhouette, 4.5 px out, with the back edge's points along it."""
    image, compressed, face = banded_purple_face(side="left", side_width=4.5)
    mask = pixel_truth(image.shape[:2], face, "face")
    outline = face_outline(compressed, mask, channels="luma", thin_strips=False)
    assert outline, outline
    blob = mask | pixel_truth(image.shape[:2], face, "strip")
    blob[:, :-2] |= blob[:, 2:].copy()  # the chroma's smear
    sil = silhouette(compressed, blob, outline, channels="luma")
    assert abs(sil.gaps_px[0] - 4.5) <= 0.25 and abs(sil.gaps_px[1]) <= 0.25, sil.gaps_px
    left = sil.sides[0]
    assert left is not None and len(left) >= 40
    assert np.median(np.abs(left[:, 0] - (face.left(left[:, 1]) - 4.5))) <= 0.25


def test_outline_tells_a_blurred_image_by_its_edge_width():
    from scipy import ndimage
    cubes = three_cubes()
    image, _ = make_image((200, 240), cubes, background="grey")
    soft = ndimage.gaussian_filter(image, sigma=(1.0, 1.0, 0))
    for c in cubes:
        mask = pixel_truth(image.shape[:2], c, "face")
        sharp, blurred = face_outline(image, mask), face_outline(soft, mask)
        assert sharp.edge_width_px <= 1.1 and not sharp.blurred
        assert blurred.edge_width_px > 1.5 and blurred.blurred
    jpeg_like = face_outline(image, pixel_truth(image.shape[:2], cubes[0], "face"), thin_strips=False)
    assert np.isnan(jpeg_like.edge_width_px) and not jpeg_like.blurred  # no edge-spread pass, no verdict


@pytest.mark.parametrize("lean, strip", [(2.5, 1.5), (2.5, 2.2), (0.0, 0.0), (2.5, 0.0)])
def test_a_distinct_side_strip_is_found_in_a_blurred_image(lean, strip):
    """A renderer's pixel filter (here a Gaussian of σ = 0.6 px on linear light, as Mitsuba 3's
    default) makes every edge read as blurred. A side face 1.5–2.2 px wide, darker than the front
    face beside a grey outside (a colour off the line between the two, which no blur of them makes),
    is still read as a strip: the right side lies on the front face's edge, not at the strip's outer
    edge. Without the strip, the blur's tails are not read as one. (Not yet: the same strips beside
    an upright side, whose pixels sample one phase of the edge; its one-step fit in full colour puts
    the edge beyond the profile's reach.)"""
    from scipy import ndimage
    u0, v0 = 70.3, 30.4
    c = FakeCube((u0, v0), (u0 + 14.6, v0 + 0.3), (u0 + 14.6 + lean, v0 + 92.0), (u0 + lean, v0 + 91.6),
                 albedo=COLOURS["green"], front_shade=0.7, side_shade=0.35,
                 side="right" if strip else None, side_width=strip or 1.0)
    image, _ = make_image((150, 150), [c], background="grey")
    soft = linear_to_srgb(ndimage.gaussian_filter(srgb_to_linear(image), sigma=(0.6, 0.6, 0)))
    soft = np.round(np.clip(soft, 0.0, 1.0) * 255.0) / 255.0  # an 8-bit image
    o = face_outline(soft, pixel_truth(image.shape[:2], c, "face"))
    assert o, getattr(o, "reason", "")
    assert o.blurred
    offsets = _mean_side_offsets(o, c)
    assert np.all(np.abs(offsets) < 0.25), offsets
    if strip:
        assert o.strip_px[1] == pytest.approx(strip, abs=0.4)
    assert np.all(o.strip_px[[0, 2, 3]] == 0.0) and (strip or o.strip_px[1] == 0.0)


@pytest.mark.parametrize("width", [0.0, 3.0, 4.0, 5.5])
def test_a_faint_side_face_the_blob_left_out_is_read_beyond_its_side(width):
    """A grey cube's side face lit nearly like the light outside beyond it (0.31 against 0.35 of linear
    value, under a pixel noise of 4 levels of 255 and a renderer's Gaussian pixel filter) is left out of
    the blob, and too wide (3–5.5 px) for the thin-strip pass. Holdout 8080 s5/1 was such a cube: read
    as having no face beside that side, it came out 31 % off. Pooled along the side, the profile shows
    it: its width is read (`FaceOutline.faint_side_px`), nothing on the other side, and the sides stay
    on the front face's edges. Without a side face, nothing is read."""
    from scipy import ndimage
    u0, v0 = 60.4, 25.3
    c = FakeCube((u0, v0), (u0 + 16.0, v0 + 0.2), (u0 + 16.0, v0 + 95.0), (u0, v0 + 94.6),
                 albedo=(0.5, 0.5, 0.5), front_shade=0.3, side_shade=0.62,
                 side="right" if width else None, side_width=width or 1.0)
    image, _ = make_image((150, 140), [c], background="grey")
    soft = linear_to_srgb(ndimage.gaussian_filter(srgb_to_linear(image), sigma=(0.6, 0.6, 0)))
    soft = soft + np.random.default_rng(3).normal(0.0, 4 / 255, soft.shape)
    soft = np.round(np.clip(soft, 0.0, 1.0) * 255.0) / 255.0
    o = face_outline(soft, pixel_truth(image.shape[:2], c, "face"), faint_sides=True)
    assert o, getattr(o, "reason", "")
    assert np.all(o.strip_px == 0.0), o.strip_px  # beyond the thin-strip pass's reach
    assert o.faint_side_px[0] == 0.0
    assert o.faint_side_px[1] == pytest.approx(width, abs=0.6), o.faint_side_px
    offsets = _mean_side_offsets(o, c)
    assert np.all(np.abs(offsets) < 0.25), offsets


@pytest.mark.parametrize("width", [0.0, 4.0, 6.5, 8.0])
def test_a_side_face_lit_like_the_sky_is_told_from_it_by_its_colour_and_read_beyond_its_side(width):
    """A grey cube under a blue sky whose left side face is lit as brightly as the sky beyond it: the two
    differ in colour only (the face neutral, the sky blue), and the face is left out of the blob. Read
    as no face there, a holdout's cube of this kind (6060 s7/1, its side face 6.9 px wide) came out
    13.8 % off at +5.1 σ. Its width is read beyond the left side, also where it is wider than the
    look reached before (7.5 px, and the window the look was read in, 8 px beyond the face mask, which
    stood for the outside at its rim), nothing beyond the right one, and both sides stay on the front
    face's edges. Without a side face, nothing is read."""
    from scipy import ndimage
    u0, v0 = 60.4, 25.3
    c = FakeCube((u0, v0), (u0 + 20.0, v0 + 0.2), (u0 + 20.0, v0 + 95.0), (u0, v0 + 94.6),
                 albedo=(0.5, 0.5, 0.5), front_shade=0.3, side_shade=0.936,
                 side="left" if width else None, side_width=width or 1.0)
    image, _ = make_image((150, 140), [c], background="blue sky")
    sky, side = np.array([0.43, 0.46, 0.515]), 0.5 * 0.936
    assert abs(float(np.array([0.2126, 0.7152, 0.0722]) @ sky) - side) < 0.015  # as bright (Rec. 709 luminance)
    soft = linear_to_srgb(ndimage.gaussian_filter(srgb_to_linear(image), sigma=(0.6, 0.6, 0)))
    soft = soft + np.random.default_rng(3).normal(0.0, 4 / 255, soft.shape)
    soft = np.round(np.clip(soft, 0.0, 1.0) * 255.0) / 255.0
    o = face_outline(soft, pixel_truth(image.shape[:2], c, "face"), faint_sides=True)
    assert o, getattr(o, "reason", "")
    assert np.all(o.strip_px == 0.0), o.strip_px
    assert o.faint_side_px[1] == 0.0
    assert o.faint_side_px[0] == pytest.approx(width, abs=0.6), o.faint_side_px
    assert np.all(np.abs(_mean_side_offsets(o, c)[:2]) < 0.25)


@pytest.mark.parametrize("glow, reach", [(0.2, 10.0), (0.4, 8.0), (-0.3, 12.0)])
def test_a_sky_shading_off_beyond_a_side_is_no_faint_side_face(glow, reach):
    """Beyond the right side of a grey face the background shades off over 8–12 px, from 20–40 % brighter
    (or 30 % darker) at the face to its level (as a sky near a cube did on holdouts 7070 and 8080). The
    two-step profile fits that as a strip 4.6–6.6 px wide, whose colour differs from the outside's by
    more than a faint side face's least; but its outer step holds little of that difference, and no
    face is read on either side."""
    from scipy import ndimage
    u0, v0 = 60.4, 25.3
    c = FakeCube((u0, v0), (u0 + 20.0, v0 + 0.2), (u0 + 20.0, v0 + 95.0), (u0, v0 + 94.6),
                 albedo=(0.5, 0.5, 0.5), front_shade=0.3, side=None)
    image, _ = make_image((150, 140), [c], background="grey")
    u = np.arange(image.shape[1])[None, :, None]
    shade = np.where(u > u0 + 20.5, 1.0 + glow * np.clip(1.0 - (u - u0 - 20.0) / reach, 0.0, 1.0), 1.0)
    soft = linear_to_srgb(ndimage.gaussian_filter(srgb_to_linear(image) * shade, sigma=(0.6, 0.6, 0)))
    soft = soft + np.random.default_rng(3).normal(0.0, 4 / 255, soft.shape)
    soft = np.round(np.clip(soft, 0.0, 1.0) * 255.0) / 255.0
    o = face_outline(soft, pixel_truth(image.shape[:2], c, "face"), faint_sides=True)
    assert o, getattr(o, "reason", "")
    assert np.all(o.faint_side_px == 0.0), o.faint_side_px


def _bench_crop(path):
    """A stored 8-bit RGB crop as the float64 sRGB image `depth.measure` takes."""
    import cv2
    return cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB).astype(np.float64) / 255.0


def _mean_u_offset(pts, p, q):
    """Mean signed u offset (px) of edge points `pts` (M, 2) from the true upright side through corners p, q."""
    u_true = p[0] + (pts[:, 1] - p[1]) * (q[0] - p[0]) / (q[1] - p[1])
    return float(np.mean(pts[:, 0] - u_true))


BLUR_S15_2 = Path(__file__).resolve().parents[1] / "data" / "blur_s15_2.png"
"""A 32×72 crop of the reconstruct bench's blur s15/2 image (our 16-spp render, Gaussian blur σ = 0.7 px of
the stored values): one cyan cube, its front face 5.1 px wide, a side face showing on its right."""

BLUR_S15_2_CORNERS = np.array([[19.1454, 57.8137], [14.0373, 57.7765], [14.0516, 15.7457], [19.1594, 15.5782]])
"""Its front face's corners (px, in the crop) from the exact reflection of the cube's edges (`cube_truth`)."""


def test_a_face_shows_a_strip_on_one_of_its_left_and_right_sides_only():
    """A cube shows at most one of its left and right faces (their planes are parallel, and a small
    face's rays come from nearly one viewpoint, beyond at most one of them). In this blurred crop the
    face's upright sides sample one phase of the edge, so the blur's ramp cannot be read from them,
    and the blur's tail on the left reads as a strip of its own beside the real side face on the
    right. The tail's colour lies near the line between the face's and the outside's (a side face,
    lit on its own, lies off it): the left side must stay on the face's edge (it was put 0.7 px
    inside, and the cube came out 47 % off)."""
    image = _bench_crop(BLUR_S15_2)
    dets = [d for d in detect_cubes(image, np.ones(image.shape[:2], dtype=bool)) if d.usable]
    assert len(dets) == 1
    o = face_outline(image, dets[0].front_face_mask, blur_domain="linear")
    assert o, getattr(o, "reason", "")
    assert o.strip_px[0] == 0.0 and o.strip_px[1] > 0.0, o.strip_px
    br, bl, tl, tr = BLUR_S15_2_CORNERS
    for pts, (p, q), reach in ((o.sides[0], (tl, bl), 0.25), (o.sides[1], (tr, br), 0.5)):
        assert abs(_mean_u_offset(pts, p, q)) < reach


@pytest.mark.parametrize("gap, length, joined", [(1, 20, True), (2, 20, False), (1, 3, False)])
def test_canny_chains_broken_by_one_pixel_are_joined_when_long(gap, length, joined):
    """`_bridged_canny`: a chain of pixels above the weak step, under the strong step all along, is an
    edge where a one-pixel gap separates it from a strong chain (Canny's own hysteresis drops it: it joins
    touching pixels only), not across a gap of two pixels, and not when it is a fragment of 3 px (a
    path tracer's noise inside a face)."""
    import cv2

    from depth.measure import _bridged_canny

    # Sobel images of a vertical edge along column 10: rows 5-24 past the strong step, then after `gap`
    # rows a stretch of `length` rows past the weak step only
    dx = np.zeros((60, 30), np.int16)
    dy = np.zeros((60, 30), np.int16)
    dx[5:25, 10] = 100
    start = 25 + gap
    dx[start:start + length, 10] = 30
    plain = cv2.Canny(dx, dy, 20, 40, L2gradient=True) > 0
    bridged = _bridged_canny(dx, dy, 20, 40)
    assert plain[5:25, 10].all() and not plain[start:start + length].any()
    assert bridged[5:25, 10].all()
    assert bridged[start:start + length, 10].all() == joined
    assert not bridged[start:start + length].any() or joined
    assert not (bridged & ~plain)[:, np.r_[0:10, 11:30]].any()


MITSUBA_GREY_HORIZON = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_8080_s1_3.png"
"""An 89×155 crop, from (597, 725), of a Mitsuba 3 render (16 spp; the holdout `python -m bench.holdout 8080`,
scene 1, cube 3): a light grey cube 2.8 cm across, 9 px wide, standing across the horizon, its left side
face a 3 px ramp from the sky's level (196 of 255) to the face's (about 180)."""


def test_a_light_grey_cube_whose_side_against_the_sky_is_faint_is_found():
    """The cube's left side, against the sky, steps by under the strong step of `_enclosed`'s edges, and
    Canny's chain of it broke off one pixel short both of the top side and of the horizon: the inside of
    the cube ran into the sky and no region was found. Its front face (x 40.1–49.2, y 40.2–115.4 in the
    crop, from `cube_truth`) must be found as one achromatic blob."""
    image = _bench_crop(MITSUBA_GREY_HORIZON)
    dets = [d for d in detect_cubes(image, np.ones(image.shape[:2], dtype=bool)) if d.usable]
    assert len(dets) == 1
    (det,) = dets
    assert det.achromatic
    u0, v0, u1, v1 = det.bbox
    assert u0 <= 40 and u1 >= 49 and abs(v0 - 40) <= 2 and abs(v1 - 116) <= 2, det.bbox


@pytest.mark.parametrize("neck, inside, cut", [(1, 0.72, True), (2, 0.72, True), (1, 0.64, False), (5, 0.72, False)])
def test_a_pocket_of_the_background_is_cut_off_where_its_colour_is_an_objects(neck, inside, cut):
    """`_pockets_cut`: a region of the background map that reaches the mirror's edge only through a gap of
    `neck` px in the edges around it is taken out of the background where its colour leaves the background's
    just beyond the gap by more than the step (0.025): a grey side face at 0.72 before a floor at 0.63
    flooded through its broken edge. Not where the colours are within the step (a pocket of floor), and
    not through a gap as wide as `POCKET_NECK_PX` or wider (an opening, not a neck)."""
    from depth.measure import POCKET_NECK_PX, _pockets_cut

    assert neck < POCKET_NECK_PX or not cut
    rgb = np.full((60, 80, 3), 0.63)
    rgb[20:45, 30:50] = inside
    near = np.ones((60, 80), dtype=bool)
    near[18:47, 28:52] = False  # the edge pixels around the object, 2 px thick ...
    near[20:45, 30:50] = True  # ... and its inside, which the flood reached ...
    near[45:47, 40:40 + neck] = True  # ... through a gap of `neck` px in its bottom edge
    search = np.zeros_like(near)
    search[2:-2, 2:-2] = True  # the mirror region, whose edge the background reaches
    near &= search
    out = _pockets_cut(rgb, near, search, 0.025)
    beyond = np.ones_like(near)
    beyond[18:47, 28:52] = False
    assert not (out & ~near).any() and (out == near)[beyond].all()
    assert (not out[20:45, 30:50].any()) if cut else out[20:45, 30:50].all()


MITSUBA_GREY_FLOODED = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_7070_s3_0_jpeg.png"
"""A 104×240 crop, from (1176, 904) on its 8×8 block grid, of a Mitsuba 3 render through OpenCV's JPEG coder
at quality 90 (`python -m bench.holdout 7070 --jpeg`, scene 3, cube 0): a grey cube standing across the
horizon, its front face 25 px wide at x 45.6–70.9 (`cube_truth`), its left side face 7.5 px wide at 180–190
of 255, between the sky (252) and the front face (226) above the horizon and above the floor (162) below it."""


@pytest.mark.parametrize("side, width", [("left", 1.6), ("left", 2.4), ("right", 2.0)])
@pytest.mark.parametrize("noise", [0.0, 2.0 / 255.0])
def test_a_side_face_showing_above_the_horizon_only_leaves_the_side_straight(side, width, noise):
    """A grey cube standing across the horizon: its side face, a strip 1.6–2.4 px wide, shows against the
    sky and is as bright as the floor below. The edge points follow the side face's outer edge above the
    horizon and the front face's below it (per-point readings across a strip lie inside it), and one line
    through both leans and misfits (holdout 8080 s3/4: 1.6 px out at the top, 1.1 px in at the bottom).
    The face's side is straight: both of its corners lie on the true side, and the side face is reported."""
    u0, v0 = 60.4, 20.3
    c = FakeCube((u0, v0), (u0 + 16.3, v0 - 0.2), (u0 + 16.4, v0 + 100.6), (u0 + 0.2, v0 + 100.9),
                 albedo=(0.5, 0.5, 0.5), front_shade=0.4, side_shade=0.6, side=side, side_width=width)
    image, mirror = make_image((140, 140), [c], background="horizon", noise=noise, seed=3)
    (d,) = match(detect_cubes(image, mirror), [c])
    o = face_outline(image, d.front_face_mask, faint_sides=True)
    assert o, getattr(o, "reason", "")
    k = 0 if side == "left" else 1
    true_u = c.left(o.corners_px[[0, 3], 1]) if k == 0 else c.right(o.corners_px[[1, 2], 1])
    found_u = o.corners_px[[0, 3], 0] if k == 0 else o.corners_px[[1, 2], 0]
    assert np.abs(found_u - true_u).max() <= 0.2
    assert o.strip_px[k] > 0.0 and o.strip_px[1 - k] == 0.0


MITSUBA_GREY_ACROSS_HORIZON = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_8080_s3_4.png"
"""A 72×144 crop, from (1190, 796), of a Mitsuba 3 render (`python -m bench.holdout 8080`, scene 3, cube 4): a
dark grey cube standing across the horizon, its front face 18 px wide (132 of 255), its left side face a
strip under 2 px wide (about 155) that shows against the sky (255) and not against the floor (152)."""

MITSUBA_GREY_ACROSS_HORIZON_CORNERS = np.array([[44.9709, 125.0868], [27.1204, 125.9997], [27.1392, 20.17],
                                                [44.9914, 19.8623]])
"""Its front face's corners (px, in the crop) from the exact reflection of the cube's edges (`cube_truth`)."""


def test_a_mitsuba_side_face_showing_above_the_horizon_only_leaves_the_side_straight():
    """The holdout case of the synthetic test above: one line through the left side's edge points read it
    1.6 px out at the top and 1.1 px in at the bottom, and the cube was refused as a shadow (edge misfit
    0.60 px). Both ends of the left side lie within 0.3 px of the true one (the floor's texture and the path
    tracer's noise scatter the lower part's edge points by 0.26 px rms)."""
    image = _bench_crop(MITSUBA_GREY_ACROSS_HORIZON)
    dets = [d for d in detect_cubes(image, np.ones(image.shape[:2], dtype=bool)) if d.usable]
    assert len(dets) == 1 and dets[0].achromatic
    o = face_outline(image, dets[0].front_face_mask, faint_sides=True)
    assert o, getattr(o, "reason", "")
    t = MITSUBA_GREY_ACROSS_HORIZON_CORNERS
    top, bottom = t[2], t[1]  # the truth's left side, in its own corner order
    offsets = [_mean_u_offset(o.corners_px[k][None], top, bottom) for k in (0, 3)]
    assert np.all(np.abs(offsets) <= 0.3), offsets
    assert o.strip_px[0] > 0.0 and o.strip_px[1] == 0.0


def test_a_side_face_flooded_through_a_gap_in_its_edge_stays_in_the_blob():
    """Where the side face meets the floor, JPEG spreads its step of 20 levels over 4 px, and its outer edge
    broke for more pixels than the closing bridges: the background flooded the side face, the blob was the
    front face alone, and `exact`, reading the side face's inner edge as the cube's outer contour, came out
    12 % off at +3.4 σ. The flood passes a neck of 1–2 px and keeps the side face's colour, 20 levels from
    the floor's: the side face must be in the blob."""
    from depth.reconstruct import despeckled

    image = _bench_crop(MITSUBA_GREY_FLOODED)
    dets = [d for d in detect_cubes(despeckled(image), np.ones(image.shape[:2], dtype=bool), compressed=True)
            if d.usable]
    assert len(dets) == 1 and dets[0].achromatic
    (det,) = dets
    assert det.mask[50:190, 40:44].all()  # the side face, x 38–45.6
    # not the sky or the floor beyond it (where the horizon meets the side face, at y 132–136, its pixels
    # mixing sky and floor pass for the side face's up to 3 px beyond it)
    assert not det.mask[:, :34].any() and not det.mask[np.r_[40:128, 140:195], :38].any()


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("side_width", [4.5, 5.5])
def test_a_narrow_side_face_running_into_a_floor_of_its_brightness_stays_in_the_blob(side_width, seed):
    """A grey cube before a bright sky, its bottom below the horizon, its right side face a few pixels wide
    and as dark as the floor it runs into (holdout 4040 s1/4: a side face 4.5 px wide). The side face lies in
    its edges' band but for a strip 1–4 px wide in its middle, and the floor flooded that strip through the
    side face's bottom, where no edge parts them: the blob was the front face alone, the silhouette showed no
    side face (gap 0.0 px), and `exact` turned the cube the wrong way, 145 % off. The side face's pixels
    above the horizon must be in the blob, and the silhouette must read its outer edge there, the cube's
    back vertical edge, `side_width` beyond the right side (its rows below the horizon end at the front
    face). (A side face 3.5 px wide was in the blob before, within the band's 3 px.)"""
    cube = FakeCube((100.3, 30.6), (112.1, 30.2), (111.8, 150.4), (100.1, 150.9), top_sag=0.5, bottom_sag=0.8,
                    albedo=(0.6, 0.6, 0.6), front_shade=0.8, side="right", side_width=side_width, side_shade=0.5)
    image, mirror = make_image((200, 240), [cube], background="horizon", noise=2 / 255, seed=seed)
    h, w = image.shape[:2]
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    sky = v < 0.5 * h + 0.1 * (u - 0.5 * w) - 2.0  # (the floor: linear 0.3, the side face's 0.6 × 0.5)
    side = pixel_truth(image.shape[:2], cube, "side") & sky
    side &= (u >= cube.right(v) + 0.5) & (u <= cube.right(v) + side_width - 0.5)  # pixels wholly on it
    dets = [d for d in detect_cubes(image, mirror) if d.usable]
    assert len(dets) == 1 and dets[0].achromatic
    (det,) = dets
    assert (det.mask & side).sum() >= 0.95 * side.sum()
    o = face_outline(image, det.front_face_mask)
    assert o, getattr(o, "reason", "")
    sil = silhouette(image, det.mask, o)
    assert sil.gaps_px[1] == pytest.approx(side_width, abs=0.3)
    back = sil.sides[1]
    assert back is not None and len(back) >= 30
    assert abs(np.mean(back[:, 0] - (cube.right(back[:, 1]) + side_width))) < 0.2


MITSUBA_GREEN_JPEG = Path(__file__).resolve().parents[1] / "data" / "mitsuba_green_6060_s2_2_jpeg.png"
"""A 72×144 crop at (696, 728) of a Mitsuba 3 render through OpenCV's JPEG coder at quality 90 (`python -m
bench.holdout 6060 --jpeg`, scene 2, cube 2): a green cube 4.7 cm across turned 22.8°, its front face 19 px
wide, no side face showing beside it (its back vertical edges 0.2 px out on the left, hidden on the right)."""


def test_a_jpeg_blob_boundary_scattering_beyond_the_face_here_and_there_is_no_side_face():
    """In a JPEG image the blob's boundary beside a face showing no side face scatters about the face's edge,
    a pixel or so out in some rows. Points beyond the face taken from rows here and there lie on a line as
    well as a real back edge's (the scatter of points chosen for lying beyond a limit is small): read as the
    back edge where the other rows end at the face, they put side faces on both sides, and `exact` refused
    the cube. Only one run of rows beyond the face is a side face showing over part of its height: here the
    silhouette must show none on either side."""
    from depth.reconstruct import despeckled

    image = _bench_crop(MITSUBA_GREEN_JPEG)
    dets = [d for d in detect_cubes(despeckled(image), np.ones(image.shape[:2], dtype=bool), compressed=True)
            if d.usable]
    assert len(dets) == 1 and not dets[0].achromatic
    o = face_outline(image, dets[0].front_face_mask, thin_strips=False, channels="luma")
    assert o, getattr(o, "reason", "")
    sil = silhouette(image, dets[0].mask, o, channels="luma")
    assert sil.sides[0] is None and sil.sides[1] is None
    assert np.all(sil.gaps_px[:2] < 0.75), sil.gaps_px


MITSUBA_PURPLE_JPEG = Path(__file__).resolve().parents[1] / "data" / "mitsuba_purple_4040_s4_0_jpeg.png"
"""An 80×192 crop at (856, 448), on the 8×8 block grid, of a Mitsuba 3 render through OpenCV's JPEG coder at
quality 90 (`python -m bench.holdout 4040 --jpeg`, scene 4, cube 0): a purple cube facing the mirror axis, its
front face 30 × 131 px and no side face showing."""


def test_a_jpeg_face_cut_by_ringing_between_parts_of_one_level_is_one_face():
    """JPEG ringing along a block boundary draws a line of gradient 12.5 px into the face; the blob's parts on
    either side of it, 13.5 and 17.5 px wide, differ in level by 0.010 (linear RGB), under half the weakest
    face boundary looked for. In a compressed image such a cut is no face boundary, and the two parts are one
    face: the detection is usable (refused as two face-sized parts before the seventy-ninth session)."""
    from depth.reconstruct import despeckled

    image = _bench_crop(MITSUBA_PURPLE_JPEG)
    dets = detect_cubes(despeckled(image), np.ones(image.shape[:2], dtype=bool), compressed=True)
    assert len(dets) == 1
    assert dets[0].usable, dets[0].reason
    u0, v0, u1, v1 = dets[0].bbox
    assert u1 - u0 >= 29 and v1 - v0 >= 130  # the whole face, not one part of it
    assert np.count_nonzero(dets[0].front_face_mask) > 0.9 * np.count_nonzero(dets[0].mask)


def test_touching_cubes_of_the_same_colour_are_refused_in_a_compressed_image_too():
    """`test_touching_cubes_of_the_same_colour_are_refused`, read as a compressed image: the two faces differ
    in level, so the cut between them is a face boundary, and the two face-sized parts are still refused."""
    a = FakeCube((80.3, 40.2), (102.6, 40.8), (103.1, 150.4), (80.8, 150.0), side=None,
                 albedo=COLOURS["green"], front_shade=0.7)
    b = FakeCube((102.6, 40.8), (125.9, 41.5), (126.4, 151.2), (103.1, 150.4), side=None,
                 albedo=COLOURS["green"], front_shade=0.55)
    image, mirror = make_image((200, 220), [a, b])
    detections = detect_cubes(image, mirror, compressed=True)
    assert len(detections) == 1
    assert not detections[0].usable
    assert "same colour" in detections[0].reason


MITSUBA_WHITE = Path(__file__).resolve().parents[1] / "data" / "mitsuba_white_s3_0.png"
"""A 52×138 crop of a Mitsuba 3 render (16 spp, Gaussian pixel filter; the holdout `python -m bench.holdout
8080`, scene 3, cube 0): a white cube turned 7° on a grey floor under a sky and a sun, its front face 19 px
wide, its left side face a strip 1.6 px wide brighter than the front face, its top face below the sky."""

MITSUBA_WHITE_CORNERS = np.array([[36.059, 119.8544], [16.7958, 120.9607], [16.7927, 21.9364], [36.0576, 21.3266]])
"""Its front face's corners (px, in the crop) from the exact reflection of the cube's edges (`cube_truth`)."""


def test_a_strip_brighter_than_the_face_is_read_as_one_in_a_blurred_grey_image():
    """The side face of a grey or white cube has the colour of its front face: it lies on the line
    between the face's colour and the outside's, where the test for a distinct strip in a blurred image
    (off that line, which no blur of the two reaches) saw nothing. But it lies beyond the segment
    between them, brighter than the face, which is brighter than the outside: no blur (nor a pixel
    mixing the two, on an upright side that samples one phase) makes such a value. The left side must
    lie on the front face's edge (it was put at the strip's outer edge, 1.9 px out, and the cube came
    out 21 % off)."""
    image = _bench_crop(MITSUBA_WHITE)
    dets = [d for d in detect_cubes(image, np.ones(image.shape[:2], dtype=bool)) if d.usable]
    assert len(dets) == 1
    o = face_outline(image, dets[0].front_face_mask, blur_domain="linear")
    assert o, getattr(o, "reason", "")
    assert o.blurred
    assert o.strip_px[0] == pytest.approx(1.6, abs=0.4) and np.all(o.strip_px[1:] == 0.0), o.strip_px
    br, bl, tl, tr = MITSUBA_WHITE_CORNERS
    for pts, (p, q) in ((o.sides[0], (tl, bl)), (o.sides[1], (tr, br))):
        assert abs(_mean_u_offset(pts, p, q)) < 0.25


MITSUBA_GREY = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_8080_s5_1.png"
"""A 56×128 crop of a Mitsuba 3 render (16 spp, Gaussian pixel filter; the holdout `python -m bench.holdout
8080`, scene 5, cube 1): a grey cube turned 9° before a light sky, its front face 16 px wide, its right side
face 4.0 px wide (the exact reflection of its back edge) and lit within 6–12 levels of 255 of the sky."""

MITSUBA_GREY_CORNERS = np.array([[34.0409, 111.4107], [18.0397, 110.7118], [18.4415, 17.0535], [34.4166, 16.708]])
"""Its front face's corners (px, in the crop: BR, BL, TL, TR) from the exact reflection of the cube's edges
(`cube_truth`)."""

MITSUBA_GREY_BACK_EDGE = np.array([[38.4281, 17.8586], [38.0735, 109.0836]])
"""The ends (px, in the crop: top, bottom) of its right side face's outer edge, the cube's back vertical edge,
from the exact reflection of the cube's back corners."""


def test_a_faint_side_face_left_out_of_a_mitsuba_blob_is_read_beyond_its_side():
    """The right side face of this grey cube lies beyond the thin-strip pass's reach, and its outer edge is
    too faint for the silhouette's points (it was left out of the blob before `_enclosed` tested the
    background's thin strips; it is in it now); read as no face there, `exact` came out 31 % off (+4.9 σ). Its outer edge is read from
    the profile beyond the right side (4.0 px out by the cube's geometry), nothing beyond the left, and
    both sides stay on the front face's edges. The measurement `exact` is given has that edge as the
    cube's back vertical edge, where the cube's geometry puts it, and no side face on the left."""
    from depth.reconstruct import _measurement

    image = _bench_crop(MITSUBA_GREY)
    dets = [d for d in detect_cubes(image, np.ones(image.shape[:2], dtype=bool)) if d.usable]
    assert len(dets) == 1 and dets[0].achromatic
    o = face_outline(image, dets[0].front_face_mask, blur_domain="linear", faint_sides=True)
    assert o, getattr(o, "reason", "")
    assert np.all(o.strip_px == 0.0), o.strip_px
    assert o.faint_side_px[0] == 0.0 and o.faint_side_px[1] == pytest.approx(4.0, abs=0.5), o.faint_side_px
    br, bl, tl, tr = MITSUBA_GREY_CORNERS
    for pts, (p, q) in ((o.sides[0], (tl, bl)), (o.sides[1], (tr, br))):
        assert abs(_mean_u_offset(pts, p, q)) < 0.25
    face_px = np.argwhere(dets[0].front_face_mask)[:, ::-1].astype(np.float64)
    meas = _measurement(image, dets[0].mask, o, face_px, "colour", False)
    assert meas.back_sides_px[0] is None and meas.side_gaps_px[1] == pytest.approx(4.0, abs=0.5)
    back = meas.back_sides_px[1]
    assert back is not None and len(back) >= 40
    assert abs(_mean_u_offset(back, *MITSUBA_GREY_BACK_EDGE)) < 0.3


MITSUBA_GREY_JPEG = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_8080_s5_1_jpeg.png"
"""The same cube through OpenCV's JPEG coder at quality 90 (`python -m bench.holdout 8080 --jpeg`): a 56×128
crop at (280, 448) of the decoded image, on its 8×8 block grid. Its despeckled blob (`depth.reconstruct`)
leaves out a corner of the face: the left column for the bottom 10 rows and the bottom rows' left 7 px."""

MITSUBA_GREY_JPEG_CORNERS = MITSUBA_GREY_CORNERS + [0.0, 4.0]
"""Its front face's corners in that crop (BR, BL, TL, TR)."""


def _mitsuba_grey_jpeg_detection():
    """The JPEG crop and its one usable detection, found as `depth.reconstruct` finds a JPEG image's cubes."""
    from depth.reconstruct import despeckled

    image = _bench_crop(MITSUBA_GREY_JPEG)
    dets = [d for d in detect_cubes(despeckled(image), np.ones(image.shape[:2], dtype=bool), compressed=True)
            if d.usable]
    assert len(dets) == 1 and dets[0].achromatic
    return image, dets[0]


def test_an_outline_still_moving_after_its_passes_is_measured_again_from_a_wider_first_pass():
    """A face mask with a corner missing, 2–3 px short of the face's bottom-left: the first fit of the bottom
    side leans, its left points are read at the ends of the ±1.5 px profiles, and the bottom side's fit bent
    through them pass after pass (the bottom-left corner 3.4 px high after four passes, and still moving by
    3.6 px: `exact` came out 42 % off, +4.0 σ). Measured again from the mask with a first pass over ±2.5 px,
    the outline settles on the face's corners."""
    image, det = _mitsuba_grey_jpeg_detection()
    mask = det.front_face_mask
    bottom_left = np.round(MITSUBA_GREY_JPEG_CORNERS[1]).astype(int)  # (u, v)
    assert not mask[bottom_left[1] - 4:bottom_left[1], bottom_left[0] + 1].any()  # the corner the mask lacks
    o = face_outline(image, mask, thin_strips=False, channels="luma", blur_domain="linear", faint_sides=True)
    assert o, getattr(o, "reason", "")
    br, bl, tl, tr = MITSUBA_GREY_JPEG_CORNERS
    assert np.abs(o.corners_px - [tl, tr, br, bl]).max() < 0.4
    assert o.sides[0][:, 1].max() > bl[1] - 4.0  # the left side measured down to its corner


def test_a_faint_side_face_left_out_of_a_jpeg_blob_is_read_beyond_its_side():
    """The same grey cube in the JPEG image, outlined as `depth.reconstruct` outlines a JPEG face (on luma,
    without the thin-strip pass): its right side face, 4.0 px wide by the cube's geometry, is read beyond its
    right side and none beyond its left, and the measurement `exact` is given has that face's outer edge as
    the cube's back vertical edge (read as no face there, `exact` came out 33 % off at +5.5 σ)."""
    from depth.reconstruct import _measurement

    image, d = _mitsuba_grey_jpeg_detection()
    o = face_outline(image, d.front_face_mask, thin_strips=False, channels="luma", blur_domain="linear",
                     faint_sides=True)
    assert o, getattr(o, "reason", "")
    assert o.faint_side_px[0] == 0.0 and o.faint_side_px[1] == pytest.approx(4.0, abs=0.5), o.faint_side_px
    face_px = np.argwhere(d.front_face_mask)[:, ::-1].astype(np.float64)
    meas = _measurement(image, d.mask, o, face_px, "luma", True)
    assert meas.back_sides_px[0] is None and meas.side_gaps_px[1] == pytest.approx(4.0, abs=0.5)
    back = meas.back_sides_px[1]
    assert back is not None and len(back) >= 40
    assert abs(_mean_u_offset(back, *(MITSUBA_GREY_BACK_EDGE + [0.0, 4.0]))) < 0.3


BLUR_S07_4 = Path(__file__).resolve().parents[1] / "data" / "blur_s07_4.png"
"""A 40×100 crop of the reconstruct bench's blur s07/4 image: one green cube, its front face 11.6 px
wide, with a darker side face on its right and a bottom face below."""

BLUR_S07_4_CORNERS = np.array([[23.8073, 80.9253], [12.1818, 83.0297], [12.1531, 11.2835], [23.7621, 8.7207]])
"""Its front face's corners (px, in the crop) from the exact reflection of the cube's edges (`cube_truth`)."""


def test_kinks_at_both_ends_of_a_blob_are_not_two_side_strips():
    """The blob's top and bottom outlines turn near both ends (the front face's sloping top edge,
    the bottom face's silhouette), which read as side strips at both ends and made three parts of
    about a face's width: the cube was refused as two touching cubes. A cube shows at most one of
    its left and right faces; its faces are then told by their brightness."""
    image = _bench_crop(BLUR_S07_4)
    (det,) = detect_cubes(image, np.ones(image.shape[:2], dtype=bool))
    assert det.usable and det.reason is None, det.reason
    o = face_outline(image, det.front_face_mask, blur_domain="linear")
    assert o, getattr(o, "reason", "")
    d = np.linalg.norm(o.corners_px[:, None] - BLUR_S07_4_CORNERS[None], axis=2)
    assert d.min(axis=1).max() < 0.5


def _mean_side_offsets(outline, cube):
    """Mean signed distance (px, positive outward) of each side's edge points from the true side."""
    left, right, top, bottom = outline.sides
    return np.array([np.mean(cube.left(left[:, 1]) - left[:, 0]), np.mean(right[:, 0] - cube.right(right[:, 1])),
                     np.mean(cube.top(top[:, 0]) - top[:, 1]), np.mean(bottom[:, 1] - cube.bottom(bottom[:, 0]))])


BLUR_S07_1 = Path(__file__).resolve().parents[1] / "data" / "blur_s07_1.png"
"""A 40×84 crop of the reconstruct bench's blur s07/1 image: one magenta cube turned 14°, its front face
5.5 px wide, a darker side face on its left and a darker bottom face below. The mask beside it
(`blur_s07_1_mask.png`) is the front face as `detect_cubes` found it in the whole image: 8 px wide, with a
stub 3 px wide and 3 px tall of the bottom face's pixels under it."""

BLUR_S07_1_CORNERS = np.array([[23.2993, 66.7827], [17.7497, 65.1104], [17.5213, 13.9108], [23.0665, 15.8311]])
"""Its front face's corners (px, in the crop: BR, BL, TL, TR) from the exact reflection of the cube's edges
(`cube_truth`)."""


@pytest.mark.parametrize("blur_domain", ["linear", "encoded"])
def test_a_stub_of_the_bottom_face_under_a_narrow_face_mask_does_not_tilt_its_bottom_side(blur_domain):
    """The mask's boundary along the stub joined the bottom side's first fit, which came out tilted 37°
    the wrong way (the true bottom side slopes 17°); its profiles then read 2 edge points of the 3 a
    bottom side needs, and the cube was the only one of the bench's 326 missed. The outline is now tried
    again from the mask without its end rows narrower than 0.6 of its median width. On the encoded
    values (the blur acted there) the bottom side, 4 px above the bottom face's far edge, then moved
    0.8 px down, which no choice of domain explains (it moves an edge by 0.05–0.15 px): such a side
    keeps its linear reading."""
    import cv2
    image = _bench_crop(BLUR_S07_1)
    mask = cv2.imread(str(BLUR_S07_1.with_name("blur_s07_1_mask.png")), cv2.IMREAD_GRAYSCALE) > 127
    widths = mask[mask.any(axis=1)].sum(axis=1)
    assert widths[-3:].max() <= 3 and np.median(widths) == 8  # the stub is in the mask
    o = face_outline(image, mask, blur_domain=blur_domain)
    assert o, getattr(o, "reason", "")
    br, bl = BLUR_S07_1_CORNERS[:2]
    bottom = o.sides[3]
    on_true_side = bl[1] + (bottom[:, 0] - bl[0]) * (br[1] - bl[1]) / (br[0] - bl[0])
    assert np.all(np.abs(bottom[:, 1] - on_true_side) < 0.25), bottom[:, 1] - on_true_side
    assert np.linalg.norm(o.corners_px[2] - br) < 0.3 and np.linalg.norm(o.corners_px[3] - bl) < 0.3, o.corners_px


_NOT_READ_ENCODED = "not yet: the encoded edge-spread pass finds no strip here, and the side lies 0.5-0.6 px out"


@pytest.mark.parametrize("lean, strip", [
    (2.5, 1.5), (0.0, 2.2),
    pytest.param(0.0, 1.5, marks=pytest.mark.xfail(strict=True, reason=_NOT_READ_ENCODED)),
    pytest.param(2.5, 2.2, marks=pytest.mark.xfail(strict=True, reason=_NOT_READ_ENCODED)),
])
def test_a_side_strip_is_read_on_the_encoded_values_of_an_image_blurred_there(lean, strip):
    """In an image blurred after encoding, the edge-spread pass read strips on linear values, where
    the blur's mix of the face's colour and the outside's lies off the line between them, as a strip's
    colour does; the encoded reading then measured every side again, the strip's too, whose profile,
    across the strip, put that side 0.6-0.9 px out while the outline still said the strip was there.
    The strips are now read on the encoded values and a side at a strip's inner step stays there.
    (Here 1.5 px read as 2.0 px and 2.2 px not at all on linear values; the encoded reading put the
    side 0.62 px out for both.)"""
    from scipy import ndimage
    u0, v0 = 70.3, 30.4
    c = FakeCube((u0, v0), (u0 + 14.6, v0 + 0.3), (u0 + 14.6 + lean, v0 + 92.0), (u0 + lean, v0 + 91.6),
                 albedo=COLOURS["green"], front_shade=0.7, side_shade=0.35, side="right", side_width=strip)
    image, _ = make_image((150, 150), [c], background="grey")
    soft = np.round(np.clip(ndimage.gaussian_filter(image, sigma=(0.7, 0.7, 0)), 0.0, 1.0) * 255.0) / 255.0
    o = face_outline(soft, pixel_truth(image.shape[:2], c, "face"), blur_domain="encoded")
    assert o, getattr(o, "reason", "")
    assert o.blurred
    offsets = _mean_side_offsets(o, c)
    assert abs(offsets[1]) < 0.15, offsets
    assert o.strip_px[1] == pytest.approx(strip, abs=0.4)
    assert np.all(np.abs(offsets[[0, 2, 3]]) < 0.05), offsets  # the other sides on the encoded values
    assert np.all(o.strip_px[[0, 2, 3]] == 0.0)


@pytest.mark.parametrize("background", ["grey", "checker"])
def test_blurred_edges_are_unbiased_in_the_domain_the_blur_acted_in(background):
    from scipy import ndimage
    cubes = [FakeCube(c.tl, c.tr, c.br, c.bl, c.top_sag, c.bottom_sag, albedo=c.albedo, side=None)
             for c in three_cubes()]
    image, _ = make_image((200, 240), cubes, background=background)
    q8 = lambda x: np.round(np.clip(x, 0.0, 1.0) * 255.0) / 255.0  # noqa: E731
    # a blur of the stored values (image software) and one of linear light (optics), σ = 0.7 px
    blurred = {"encoded": q8(ndimage.gaussian_filter(image, sigma=(0.7, 0.7, 0))),
               "linear": q8(linear_to_srgb(ndimage.gaussian_filter(srgb_to_linear(image), sigma=(0.7, 0.7, 0))))}
    for c in cubes:
        mask = pixel_truth(image.shape[:2], c, "face")
        for acted, img in blurred.items():
            right = face_outline(img, mask, blur_domain=acted)
            wrong = face_outline(img, mask, blur_domain="linear" if acted == "encoded" else "encoded")
            assert right.blurred and wrong.blurred
            # the right domain: each side within 0.04 px; the other is 0.05-0.16 px off toward the
            # brighter side (here the face: outward for a linear reading of an encoded blur)
            assert np.all(np.abs(_mean_side_offsets(right, c)) < 0.04), acted
            assert np.mean(np.abs(_mean_side_offsets(wrong, c))) > 0.05, acted


def test_blur_domain_is_checked():
    image, _ = make_image((200, 240), three_cubes(), background="grey")
    with pytest.raises(DepthError, match="blur_domain"):
        face_outline(image, pixel_truth(image.shape[:2], three_cubes()[0], "face"), blur_domain="gamma")


def test_blur_domain_evidence_tells_where_the_blur_acted():
    from scipy import ndimage

    from depth.measure import (
        BLUR_EVIDENCE_MARGIN,
        blur_domain_evidence,
        blur_domain_verdict,
    )
    cubes = [FakeCube(c.tl, c.tr, c.br, c.bl, c.top_sag, c.bottom_sag, albedo=c.albedo, side=None)
             for c in three_cubes()]
    image, _ = make_image((200, 240), cubes, background="grey")
    q8 = lambda x: np.round(np.clip(x, 0.0, 1.0) * 255.0) / 255.0  # noqa: E731
    blurred = {"encoded": q8(ndimage.gaussian_filter(image, sigma=(0.7, 0.7, 0))),
               "linear": q8(linear_to_srgb(ndimage.gaussian_filter(srgb_to_linear(image), sigma=(0.7, 0.7, 0))))}
    for acted, img in blurred.items():
        ev = np.array([blur_domain_evidence(img, face_outline(img, pixel_truth(image.shape[:2], c, "face"),
                                                              blur_domain="linear")) for c in cubes])
        score = ev[:, 0].sum() / ev[:, 1].sum()  # weighted mean log(SSE_encoded / SSE_linear)
        assert ev[:, 1].sum() > 0
        # clearly either side of zero, and the verdict `depth.reconstruct` acts on agrees
        assert (score < -BLUR_EVIDENCE_MARGIN) if acted == "encoded" else (score > BLUR_EVIDENCE_MARGIN)
        outlines = [face_outline(img, pixel_truth(image.shape[:2], c, "face")) for c in cubes]
        assert blur_domain_verdict(img, outlines) == acted
    assert blur_domain_verdict(image, [face_outline(image, pixel_truth(image.shape[:2], c, "face"))
                                       for c in cubes]) is None  # sharp: no blurred face, no verdict


def test_pooled_blur_domain_reads_the_pooled_evidence_with_its_margin_and_least_weight():
    from depth.measure import BLUR_EVIDENCE_MARGIN as m
    from depth.measure import BLUR_EVIDENCE_MIN_WEIGHT as w
    from depth.measure import pooled_blur_domain
    # clearly encoded, pooled over faces in any order; the same mean just inside the margin: linear
    faces = [(-2 * m * 0.6 * w, 0.6 * w), (-2 * m * 0.5 * w, 0.5 * w)]
    assert pooled_blur_domain(faces) == pooled_blur_domain(faces[::-1]) == "encoded"
    assert pooled_blur_domain([(-0.9 * m * 1.1 * w, 1.1 * w)]) == "linear"
    # strong per side, but too little weight in all
    assert pooled_blur_domain([(-5 * m * 0.9 * w, 0.9 * w)]) == "linear"
    with pytest.raises(ValueError, match="at least one blurred face"):
        pooled_blur_domain([])


MITSUBA_ORANGE_STRIP = Path(__file__).resolve().parents[1] / "data" / "mitsuba_orange_strip.png"
"""A 50×100 crop of a Mitsuba 3 render (16 spp, Gaussian pixel filter on linear light; `python -m
bench.holdout 7070`, scene 0, cube 3): an orange cube facing the axis on a grey floor, its front face
16 px wide, a brighter side face 2.3 px wide beside its right side, its top face above."""


def test_a_side_read_with_a_strip_is_no_evidence_of_where_the_blur_acted():
    """Where the blur acted is told from each side's profile fitted as one blurred step. Beside a side
    read with a strip the profile has two steps, which neither model is, and here it said "encoded",
    clearly enough (−0.054 over a weight of 0.69) to turn the pooled verdict of the whole image to
    "encoded": a Mitsuba render, blurred by its pixel filter on linear light, whose cubes then came out
    up to 15 % off instead of 2.3 %. Such sides give no evidence."""
    from depth.measure import BLUR_EVIDENCE_MARGIN, blur_domain_evidence
    image = _bench_crop(MITSUBA_ORANGE_STRIP)
    dets = [d for d in detect_cubes(image, np.ones(image.shape[:2], dtype=bool)) if d.usable]
    assert len(dets) == 1
    o = face_outline(image, dets[0].front_face_mask, blur_domain="linear")
    assert o, getattr(o, "reason", "")
    assert o.blurred and o.strip_px[1] > 0.0 and np.all(o.strip_px[[0, 2, 3]] == 0.0), o.strip_px
    total, weight = blur_domain_evidence(image, o)
    assert weight > 0.0  # the other sides still speak
    assert total >= -BLUR_EVIDENCE_MARGIN * weight  # and do not say "encoded"


MITSUBA_GREEN_NOTCH = Path(__file__).resolve().parents[1] / "data" / "mitsuba_green_notch.png"
"""A 55×147 crop of a Mitsuba 3 render (`python -m bench.holdout 7070`, scene 4, cube 2): a green cube facing
the axis on a white floor, its front face 14 px wide and 109 px tall, a thin top face above it; with
``mitsuba_green_notch_mask.png``, the front-face mask the detection gave in the whole image: the top face's
rows and the front face's, all but two pixels of the mixed row between them left out (a slit from the
right)."""

MITSUBA_GREEN_NOTCH_CORNERS = np.array([[33.5088, 129.1688], [19.8643, 128.777], [20.1399, 20.1434],
                                        [33.7699, 20.3189]])
"""Its front face's corners (px, in the crop) from the exact reflection of the cube's edges (`cube_truth`)."""


def test_a_slit_in_the_face_mask_under_its_top_does_not_pull_the_bottom_side_up():
    """The mask's boundary runs into the slit and back: along the slit's upper edge its outward normals
    point down, as the bottom side's do, and those points joined the bottom side's first fit. Its
    quadratic, through points at both ends of the face, put the bottom corners 40 px low; refined from
    there the bottom side settled 20 px inside the face and the cube came out 41 % off at −21 σ. Each side's
    points are now taken on its own side of the face's centre: the bottom corners are where the face ends."""
    import cv2
    image = _bench_crop(MITSUBA_GREEN_NOTCH)
    mask = cv2.imread(str(MITSUBA_GREEN_NOTCH.with_name("mitsuba_green_notch_mask.png")), cv2.IMREAD_GRAYSCALE) > 127
    widths = mask[mask.any(axis=1)].sum(axis=1)
    assert widths[:10].min() <= 3 < widths[10:].min()  # the slit is there, under the top rows
    o = face_outline(image, mask)
    assert o, getattr(o, "reason", "")
    br, bl, tl, tr = MITSUBA_GREEN_NOTCH_CORNERS
    assert np.linalg.norm(o.corners_px[2] - br) < 0.5 and np.linalg.norm(o.corners_px[3] - bl) < 0.5, o.corners_px
    for pts, (p, q) in ((o.sides[0], (tl, bl)), (o.sides[1], (tr, br))):
        assert abs(_mean_u_offset(pts, p, q)) < 0.25


def test_a_face_mask_cut_inside_a_uniform_face_is_grown_back_to_the_outline():
    from depth.measure import extended_to_blob
    cube = three_cubes()[1]
    image, _ = make_image((200, 240), [cube], background="grey", decoy=False)
    face = pixel_truth(image.shape[:2], cube, "face")
    u = np.arange(image.shape[1])[None, :]
    for side, cut in ((0, face & (u >= 106)), (1, face & (u <= 113))):  # 5 px cut off inside the face
        failed = face_outline(image, cut)
        assert not failed and failed.no_contrast_side == side, failed
        grown = extended_to_blob(cut, face, side)
        assert np.array_equal(grown, face)  # the row runs end at the blob's outline, no further
        outline = face_outline(image, grown)
        assert outline and corner_errors(outline, cube).max() <= 0.1
    # a side with contrast is not reported as one without
    assert face_outline(image, face).__class__ is FaceOutline


def test_extended_to_blob_stops_at_gaps_in_the_blob():
    from depth.measure import extended_to_blob
    face = np.zeros((6, 12), bool)
    face[1:5, 6:9] = True
    blob = face.copy()
    blob[1:5, 3:6] = True  # joined on the left
    blob[1:5, 0:2] = True  # a separate piece beyond a gap at column 2
    grown = extended_to_blob(face, blob, 0)
    assert grown[1:5, 3:9].all() and not grown[:, :3].any() and not grown[[0, 5]].any()
    top = extended_to_blob(face.T, blob.T, 2)  # columns: the same grown upward
    assert np.array_equal(top, grown.T)
    right = extended_to_blob(face[:, ::-1], blob[:, ::-1], 1)  # mirrored: grown rightward
    assert np.array_equal(right, grown[:, ::-1])


def test_reconstruct_tells_an_empty_mirror_only_from_the_mirror_region(rig):
    # Variation outside the mirror (the camera sees the room beside it) is no mirror content; one
    # pixel inside the mirror that differs is (it then finds no cube, rather than refusing the image).
    from depth.reconstruct import reconstruct
    from raytrace.truth import mirror_mask

    mask = mirror_mask(rig.camera, rig.mirror)
    w, h = rig.camera.resolution
    img = np.full((h, w, 3), 0.5)
    img[~mask] = np.random.default_rng(1).random((np.count_nonzero(~mask), 3))
    with pytest.raises(DepthError, match="no mirror content"):
        reconstruct(img, rig.camera, rig.mirror)
    ys, xs = np.nonzero(mask)
    img[ys[len(ys) // 2], xs[len(ys) // 2], 2] = 0.6  # the blue channel only
    assert reconstruct(img, rig.camera, rig.mirror).cubes == []


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.002, 0.5))
def test_nearest_pixel_of_a_mask_is_at_the_euclidean_distance(seed, density):
    """`_nearest` reads OpenCV's labelled distance transform, whose labels number the mask's pixels in
    raster order: the pixel it names is in the mask and lies at the nearest distance scipy's exact
    Euclidean transform gives, to within the 5 × 5 chamfer mask's approximation (under 3 % of the
    distance on 200 random masks; 4 % allowed here)."""
    from scipy import ndimage

    from depth.measure import _nearest
    rng = np.random.default_rng(seed)
    mask = rng.random((37, 53)) < density
    mask[rng.integers(37), rng.integers(53)] = True
    where = ~mask
    idx = _nearest(mask, where)
    assert mask.ravel()[idx].all()
    rows, cols = np.nonzero(where)
    got = np.hypot(idx // 53 - rows, idx % 53 - cols)
    exact = ndimage.distance_transform_edt(~mask)[where]
    assert np.all(got <= exact * 1.04 + 1e-9)


@pytest.mark.parametrize("low, high", [(0, 1), (0, 2), (1, 3), (2, 4), (100, 102), (253, 255), (254, 255)])
def test_an_8_bit_image_is_told_empty_as_its_float_values_are(rig, low, high):
    """The mirror's spread is read on an 8-bit image's own values (its extremes / 255): the same verdict as
    on the image converted to float, at spreads of one and two levels (the limit, 2/255), one pixel of
    the mirror `high` in one channel and the rest `low`."""
    from depth.reconstruct import reconstruct
    from raytrace.truth import mirror_mask

    mask = mirror_mask(rig.camera, rig.mirror)
    w, h = rig.camera.resolution
    img = np.full((h, w, 3), low, dtype=np.uint8)
    ys, xs = np.nonzero(mask)
    img[ys[len(ys) // 2], xs[len(ys) // 2], 1] = high

    def verdict(image):
        try:
            reconstruct(image, rig.camera, rig.mirror)
        except DepthError as exc:
            assert "no mirror content" in str(exc)
            return "empty"
        return "searched"
    assert verdict(img) == verdict(img.astype(np.float64) / 255.0)
    if high - low == 1:
        assert verdict(img) == "empty"


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.002, 0.5), st.integers(1, 4))
def test_nearest_means_are_the_3x3_means_at_the_nearest_pixels(seed, density, channels):
    """`_nearest_means`, which takes each distinct nearest pixel's 3 × 3 mean once, gives bit for bit the
    `_mean3x3` of every pixel's nearest mask pixel (`_nearest`) taken one by one, on random masks and images
    (the mask's pixels on the image's edge included)."""
    from depth.measure import _mean3x3, _nearest, _nearest_means
    rng = np.random.default_rng(seed)
    mask = rng.random((37, 53)) < density
    mask[rng.integers(37), rng.integers(53)] = True
    where = ~mask | (rng.random(mask.shape) < 0.1)
    img = rng.random((37, 53, channels))
    want = np.array([_mean3x3(img, [i])[0] for i in _nearest(mask, where)])
    got = _nearest_means(img, mask, where)
    assert got.shape == want.shape
    np.testing.assert_array_equal(got.view(np.uint64), want.view(np.uint64))


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(-1.0, 1.0), st.floats(20.0, 120.0), st.booleans(), st.booleans())
def test_one_phase_tells_a_side_along_the_pixel_grid_from_a_leaning_one(phase, lean, length, vertical, noisy):
    """A side whose edge keeps one sub-pixel phase along its length (its across-coordinate shifts by at
    most 0.1 px end to end) is one-phase; one whose edge leans by 0.6 px or more over its length samples
    every phase and is not, also where each point's edge is measured with 0.1 px of noise (read point by
    point, such noise alone spreads the phases: resultant 0.82, below the 0.9 required). (With 0.15 px the
    claim is false for some lengths: 48 points of that noise lean 0.13 px end to end on their own, so the
    fitted side does sample 0.23 px of phases; hypothesis drew such a case.)"""
    from depth.measure import _one_phase

    along = np.arange(0.0, length, 1.0)
    for shift, expected in ((0.1 * lean, True), ((0.6 + 0.4 * abs(lean)) * np.sign(lean or 1.0), False)):
        edge = 40.0 + phase + shift * along / along[-1]
        noise = np.random.default_rng(0).normal(0.0, 0.1, len(along)) if noisy else np.zeros(len(along))
        start = edge - 0.7  # the profiles start 0.7 px inside; each measures its edge with noise
        points = np.column_stack([start, along] if vertical else [along, start])
        normals = np.tile([1.0, 0.0] if vertical else [0.0, 1.0], (len(along), 1))
        assert _one_phase(points, normals, 0.7 + noise) is expected


MITSUBA_BLACK_MERGED = Path(__file__).resolve().parents[1] / "data" / "mitsuba_black_merged.png"
"""A 60×130 crop of a Mitsuba 3 render (`python -m bench.holdout 7070`, scene 3, cube 2): a black cube turned
18.6° on a pale floor, its left side face (4 px) as dark as its front face (12 px) and merged with it; with
``mitsuba_black_merged_mask.png`` and ``_face.png``, the blob and front-face masks the detection gave in the
whole image. Mitsuba's Gaussian pixel filter darkens the floor pixel beside the cube's left edge (200 of
207), and the blob takes it in."""

MITSUBA_BLACK_MERGED_LEFT_EDGE = np.array([[20.7157, 20.4303], [20.6672, 113.4084]])
"""The image (px, in the crop) of the cube's back left vertical edge, its silhouette there (`reflection_pixels`
of the cube's vertices)."""


@pytest.mark.xfail(strict=True, reason="open: the silhouette's window starts at the blob's boundary, a pixel out "
                   "here; re-centring it on the edge found fixes this crop but lost 3 of 326 cubes of the "
                   "reconstruct bench (twenty-first session)")
def test_the_silhouette_beside_a_blob_pixel_past_the_edge_is_located_on_the_edge():
    """The blob's boundary starts the silhouette's profile a pixel out, and its window (±1.5 px) misses
    the cube's dark level: the area puts the silhouette 0.54 px outside the cube's edge and reads a
    0.65 px side face beside the merged outline, so `exact` takes its left side for the front face's.
    The silhouette should lie on the cube's edge, and the gap say no distinct side face shows there."""
    import cv2

    from depth.estimate import NO_SIDE_FACE_GAP_PX_SHARP
    from depth.measure import silhouette
    image = _bench_crop(MITSUBA_BLACK_MERGED)
    blob, face = (cv2.imread(str(MITSUBA_BLACK_MERGED.with_name(f"mitsuba_black_merged_{k}.png")),
                             cv2.IMREAD_GRAYSCALE) > 127 for k in ("mask", "face"))
    assert image[60, 20].mean() < image[60, 10].mean() - 5 / 255  # the darkened pixel
    assert blob[60, 20] and not blob[60, 19]  # taken into the blob
    o = face_outline(image, face)
    assert o, getattr(o, "reason", "")
    sil = silhouette(image, blob, o)
    a, b = o.lines[0]
    v = np.mean([p[1] for p in o.corners_px])
    (p, q) = MITSUBA_BLACK_MERGED_LEFT_EDGE
    u_true = p[0] + (v - p[1]) * (q[0] - p[0]) / (q[1] - p[1])
    assert abs((a * v + b - sil.gaps_px[0]) - u_true) < 0.2
    assert sil.gaps_px[0] < NO_SIDE_FACE_GAP_PX_SHARP


JPEG_RINGING = Path(__file__).resolve().parents[1] / "data" / "jpeg_s15_ringing.png"
"""An 85×210 crop of the reconstruct bench's JPEG s15 (quality 90, our renderer), cube 4: a blue face 29 px
wide, turned 6°, with a 3 px darker side face on its right. JPEG ringing raises the blue a little over
three columns 6.5 px inside the face's right edge, along a block boundary, and falls back beside the side
face: a line of horizontal gradient with the same level on both sides of it."""

JPEG_RINGING_CORNERS = np.array([[24.241, 30.217], [53.046, 32.444], [53.03, 192.773], [24.218, 189.078]])
"""The front face's corners in the crop (`raytrace.truth.cube_truth`), [TL, TR, BR, BL]."""


def test_a_gradient_line_between_equal_levels_does_not_cut_the_front_face():
    """The ringing's rising edge was taken for a face boundary: the front face ended there, 6.7 px short of
    its right edge, and the cube came out 33 % off in depth. Its two sides have one level, so in a
    compressed image it is no step between faces: the front face reaches its own right edge and is
    outlined there."""
    from depth.reconstruct import despeckled
    image = _bench_crop(JPEG_RINGING)
    (d,) = detect_cubes(despeckled(image), np.ones(image.shape[:2], dtype=bool), compressed=True)  # as reconstruct does
    assert d.usable
    rows = np.arange(40, 180)
    right = np.array([np.flatnonzero(d.front_face_mask[r])[-1] for r in rows])
    edge = JPEG_RINGING_CORNERS[1, 0] + (rows - JPEG_RINGING_CORNERS[1, 1]) * (
        (JPEG_RINGING_CORNERS[2, 0] - JPEG_RINGING_CORNERS[1, 0]) / (JPEG_RINGING_CORNERS[2, 1] - JPEG_RINGING_CORNERS[1, 1]))
    assert np.all(right >= np.floor(edge) - 2) and np.all(right <= np.ceil(edge))  # not into the side face
    o = face_outline(image, d.front_face_mask, channels="luma", thin_strips=False)
    assert o, getattr(o, "reason", "")
    assert np.abs(o.corners_px - JPEG_RINGING_CORNERS).max() < 0.3
    # not told the image was compressed, the line is taken for a fold between faces lit alike
    (d,) = detect_cubes(despeckled(image), np.ones(image.shape[:2], dtype=bool))
    assert np.flatnonzero(d.front_face_mask[110])[-1] < np.floor(edge[70]) - 3


MITSUBA_CYAN_NOISE_LINE = Path(__file__).resolve().parents[1] / "data" / "mitsuba_cyan_6060_s2_3.png"
"""A 64×152 crop (x 784–848, y 56–208) of holdout 6060 scene 2 (Mitsuba 3, 16 spp, PNG), cube 3: a cyan face
22 px wide facing the mirror axis, a side face about 1 px wide on its left, its bottom face below it. One column
of the face, 4.7 px inside its left side, has its 70th percentile of horizontal gradient 0.0076 over the
columns' level, past the line detector's threshold, by the path tracer's noise alone: the three columns either
side of it have one level."""

MITSUBA_CYAN_NOISE_LINE_CORNERS = np.array([[22.552, 14.93], [44.605, 17.835], [44.839, 119.232], [22.76, 116.962]])
"""The front face's corners in the crop (`raytrace.truth.cube_truth`), [TL, TR, BR, BL]."""


def test_a_noise_line_with_one_level_either_side_does_not_cut_a_path_traced_face():
    """The face was cut at that column: its left 5 px were taken for a side face, the front face outlined
    4.7 px narrow, and the cube came out 21.7 % off at +5.5 σ. A line with one level either side is no
    boundary between faces: the front face reaches its own left side and is outlined there."""
    image = _bench_crop(MITSUBA_CYAN_NOISE_LINE)
    (d,) = detect_cubes(image, np.ones(image.shape[:2], dtype=bool))
    assert d.usable
    truth_left = MITSUBA_CYAN_NOISE_LINE_CORNERS[0, 0]
    for row in (40, 80, 110):
        assert np.flatnonzero(d.front_face_mask[row])[0] <= np.ceil(truth_left)
    o = face_outline(image, d.front_face_mask)
    assert o, getattr(o, "reason", "")
    assert np.abs(o.corners_px - MITSUBA_CYAN_NOISE_LINE_CORNERS).max() < 0.5


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_column_of_flicker_inside_a_face_is_no_face_boundary_but_a_level_step_there_is(seed):
    """A face column whose pixels alternate 10 % brighter and darker (linear), as a column of render noise
    can: its neighbours' horizontal gradient stands out of the face's, but the levels either side are one,
    and the front face is found whole. The same column as a step, the face 10 % brighter left of it (a
    side face lit a little otherwise), still splits the blob there."""
    from depth.measure import _linear_to_srgb
    c = FakeCube((60.3, 30.4), (84.6, 30.9), (85.2, 130.3), (60.9, 129.8), top_sag=0.6, side=None,
                 albedo=COLOURS["green"])
    image, mirror = make_image((160, 150), [c], background="grey", noise=2 / 255, seed=seed)
    face = pixel_truth(image.shape[:2], c, "face")
    col = 68
    rows = np.flatnonzero(face[:, col])
    flicker = srgb_to_linear(image)
    flicker[rows, col] *= 1.0 + np.where(rows % 2 == 0, 0.1, -0.1)[:, None]
    (d,) = match(detect_cubes(_linear_to_srgb(flicker), mirror), [c])
    for row in (50, 80, 110):
        assert np.flatnonzero(d.front_face_mask[row])[0] <= np.flatnonzero(face[row])[0] + 1
    step = srgb_to_linear(image)
    step[face & (np.arange(image.shape[1]) < col)] *= 1.1
    (d,) = match(detect_cubes(_linear_to_srgb(step), mirror), [c])
    for row in (50, 80, 110):
        assert col - 1 <= np.flatnonzero(d.front_face_mask[row])[0] <= col + 2


JPEG_FAINT_SIDE_FACE = Path(__file__).resolve().parents[1] / "data" / "jpeg_s17_faint_side_face.png"
"""A 100×240 crop of the reconstruct bench's JPEG s17 (quality 90, our renderer), cube 2: a magenta face
27 px wide, turned 24°, with a side face 10 px wide on its right lit 4 % darker (sRGB 204, 84, 226 against
200, 82, 222; a linear step of 0.04)."""

JPEG_FAINT_SIDE_FACE_CORNERS = np.array([[800.204, 315.999], [826.881, 304.707], [826.999, 454.761],
                                         [800.207, 462.729]]) - [768.0, 264.0]
"""The front face's corners in the crop (`raytrace.truth.cube_truth`), [TL, TR, BR, BL]."""


def test_a_faint_boundary_to_a_side_face_in_a_jpeg_image_splits_the_faces():
    """JPEG left the step between the faces in the face's levels but not in its per-pixel gradients, which
    ring in some columns of blocks and are flat in others: the front and side faces were found as one, and
    the face was outlined 10 px wide of its right side. The levels either side of the boundary column step
    by more than half the minimum face contrast: the faces are split there and the face outlined to 0.3 px,
    as `depth.reconstruct` outlines a JPEG face."""
    from depth.reconstruct import despeckled
    image = _bench_crop(JPEG_FAINT_SIDE_FACE)
    (d,) = detect_cubes(despeckled(image), np.ones(image.shape[:2], dtype=bool), compressed=True)
    assert d.usable
    right = JPEG_FAINT_SIDE_FACE_CORNERS[1, 0]
    assert all(np.flatnonzero(d.front_face_mask[r])[-1] <= np.ceil(right) for r in range(70, 180))
    assert d.side_face_masks and d.side_face_masks[0][120, int(right) + 5]
    o = face_outline(image, d.front_face_mask, channels="luma", blur_domain="linear", thin_strips=False)
    assert o, getattr(o, "reason", "")
    assert np.abs(o.corners_px - JPEG_FAINT_SIDE_FACE_CORNERS).max() < 0.4


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_faint_face_boundary_among_columns_of_ringing_and_flat_blocks_is_found_where_its_levels_step(seed):
    """`_vertical_edge_lines` on a blob in linear RGB with a step of 0.034 between columns 26 and 27 (half the
    minimum face contrast is 0.015), a ripple of ±0.02 in blue over columns 11-14 (one level either side, as
    JPEG rings), and pixel noise (σ 0.006) in every other band of 8 columns, the rest flat, as JPEG decodes a
    uniform face. Told the image is compressed, the step is a boundary, at 26.5, and the ripple none; not
    told, the columns' bimodal statistics hide the step."""
    from depth.measure import _vertical_edge_lines
    rng = np.random.default_rng(seed)
    h, w = 120, 40
    blob = np.zeros((h, w), dtype=bool)
    blob[2:-2, 1:-1] = True
    linear = np.empty((h, w, 3))
    linear[:] = (0.60, 0.09, 0.76)
    linear[:, 27:] -= (0.022, 0.003, 0.025)
    linear[:, 11:15, 2] += (0.02, 0.02, -0.02, -0.02)
    ringing = (np.arange(w) // 8) % 2 == 0
    linear += np.where(ringing[None, :, None], rng.normal(0.0, 0.006, linear.shape), 0.0)
    xs, _ = _vertical_edge_lines(linear, blob, 0.0, 0.03, compressed=True)
    assert len(xs) == 1 and abs(xs[0] - 26.5) < 0.25, xs
    assert len(_vertical_edge_lines(linear, blob, 0.0, 0.03)[0]) == 0


@pytest.mark.parametrize("bump", [0.0, 0.01])
def test_cuts_between_equal_levels_are_no_face_boundaries(bump):
    """`_stepped_span` over three parts of a blob (its cuts read by `_cuts_within_level`): a face (level A), a
    part the same within half the minimum face contrast (A + bump), and a side face 0.1 darker. The front
    face's span takes in the part of its own level, and stops at the side face."""
    from depth.measure import _cuts_within_level, _stepped_span
    h, w = 40, 30
    blob = np.zeros((h, w), dtype=bool)
    blob[2:-2, 2:-2] = True
    linear = np.zeros((h, w, 3))
    linear[:] = (0.2, 0.3, 0.6)
    linear[:, 14:21] += (0.0, 0.0, bump)
    linear[:, 21:] -= 0.1
    x = np.tile(np.arange(w, dtype=float), (h, 1))
    edges = np.array([1.0, 13.5, 20.5, 28.0])

    def span(k):
        return _stepped_span(_cuts_within_level(linear, blob, x, edges, 0.03), k)
    assert span(0) == (0, 1)
    assert span(1) == (0, 1)
    linear[:, 14:21] += (0.0, 0.0, 0.02)  # now a step of 0.02 or 0.03: a boundary
    assert span(0) == (0, 0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 40), st.integers(3, 40), st.booleans())
def test_the_3x3_mean_at_chosen_pixels_is_a_box_filter_read_there(seed, h, w, interior):
    """`_mean3x3` (the background level `_enclosed` compares a region's rim with, computed only where
    it is asked for) against scipy's box filter over the whole image, edge pixels repeated: both the
    pixels 1 px inside the image and pixels on its edge."""
    from scipy import ndimage

    from depth.measure import _mean3x3

    rng = np.random.default_rng(seed)
    img = rng.random((h, w, 3))
    yy, xx = np.mgrid[0:h, 0:w]
    pool = np.flatnonzero(((yy > 0) & (yy < h - 1) & (xx > 0) & (xx < w - 1)).ravel() if interior
                          else np.ones(h * w, dtype=bool))
    flat = rng.choice(pool, size=min(len(pool), 25), replace=False)
    if not interior:
        flat = np.r_[flat, 0, h * w - 1]  # the corners, whose neighbours lie beyond two edges
    box = ndimage.uniform_filter(img, size=(3, 3, 1), mode="nearest").reshape(-1, 3)
    np.testing.assert_allclose(_mean3x3(img, flat), box[flat], rtol=0, atol=1e-12)


MITSUBA_WHITE_FAINT = Path(__file__).resolve().parents[1] / "data" / "mitsuba_white_low_contrast.png"
"""A 72×150 crop of a Mitsuba 3 render (16 spp, Gaussian pixel filter; the holdout `python -m bench.holdout
8080 --grey`, scene 2, cube 0): a white cube facing the axis before a yellowish sky, its front face 19 px
wide and bluer than the sky by about 8 levels of 255 in blue, with a pixel noise of 4–5 levels.
``mitsuba_white_low_contrast_mask.png`` is the mask of the face and the bottom face under it, as a detection
that encloses the cube by its blue − yellow edges gives (the thirty-first and thirty-eighth sessions' trial)."""

MITSUBA_WHITE_FAINT_CORNERS = np.array([[44.7326, 121.9116], [26.0709, 122.2108], [26.1562, 22.0523],
                                        [44.801, 21.6134]])
"""Its front face's corners (px, in the crop: BR, BL, TL, TR) from the exact reflection of the cube's edges
(`cube_truth`)."""


def test_a_strip_fainter_than_the_pixel_noise_is_not_read_beside_a_low_contrast_side():
    """The left side of a face that differs from the sky beyond it by less than twice its pixel noise:
    the face's own shading and noise make its last 3 px read as a strip of a colour 0.1 of the way from
    the face's to the sky's and 0.05 off their line, less than one pixel's noise from the face. Read as
    a strip, it put the side 2.6 px inside the face (the cube 142 % off). The side must stay on the face's
    edge, with no strip."""
    import cv2
    image = _bench_crop(MITSUBA_WHITE_FAINT)
    mask = cv2.imread(str(MITSUBA_WHITE_FAINT.with_name("mitsuba_white_low_contrast_mask.png")),
                      cv2.IMREAD_GRAYSCALE) > 127
    o = face_outline(image, mask)
    assert o, getattr(o, "reason", "")
    assert o.strip_px[0] == 0.0, o.strip_px
    _, bl, tl, _ = MITSUBA_WHITE_FAINT_CORNERS
    assert abs(_mean_u_offset(o.sides[0], tl, bl)) < 0.25
    assert np.abs(o.corners_px[0, 0] - tl[0]) < 0.25  # the top-left corner on the true left side


@dataclass
class SoftTopCube(FakeCube):
    """A FakeCube whose top face meets its front face across a ramp `soft_px` tall (linear light) instead
    of a step: as JPEG's smoothing of chroma and its blocks spread a faint step."""

    soft_px: float = 0.0

    def paint(self, img, u, v):
        super().paint(img, u, v)
        alb = np.asarray(self.albedo)
        tv = self.top(u)
        t = np.clip((tv - v) / self.soft_px, 0.0, 1.0)[..., None]
        ramp = (u > self.left(v)) & (u < self.right(v)) & (v > tv - self.soft_px) & (v <= tv)
        img[ramp] = (alb * (self.front_shade + t * (self.top_shade - self.front_shade)))[ramp]


@pytest.mark.parametrize("soft_px, top_shade", [(6.0, 0.45), (8.0, 0.45), (7.0, 0.22)])
def test_a_top_face_across_a_boundary_too_soft_for_the_gradient_is_not_read_as_front_face(soft_px, top_shade):
    """A black cube's top face, 0.03–0.04 brighter (or darker) in sRGB value than its front face under a
    blue sky, meets the front face across a ramp 6–8 px tall: no pixel's gradient there exceeds the
    flat limit of `_split_by_brightness` (a quarter of the weakest face contrast per pixel), so the front
    face's flat region ran on into the top face (holdout 6060 all grey JPEG s6/2, a black cube whose top
    face JPEG smeared so: read as one face with it, the cube came out 9.5 % off at +32.7 σ). A region of
    one brightness is one face: the front face's mask holds the front face (IoU > 0.9) and under a tenth
    of the top face."""
    c = SoftTopCube((60.3, 55.6), (100.8, 54.2), (101.5, 175.2), (60.9, 176.1), albedo=(0.1, 0.1, 0.1),
                    front_shade=0.32, top_shade=top_shade, side="left", side_width=3.0, side_shade=0.45,
                    top_height=30.0, soft_px=soft_px)
    image, mirror = make_image((220, 170), [c], background="blue sky")
    u, v = np.meshgrid(np.arange(image.shape[1], dtype=float), np.arange(image.shape[0], dtype=float))
    face, tv = c.face(u, v), c.top(u)
    top = (u > c.left(v) + 1) & (u < c.right(v) - 1) & (v > tv - 30.0 + 1) & (v < tv - soft_px)
    value = image.max(axis=2)
    step = float(np.median(value[top]) - np.median(value[face]))
    assert 0.03 < abs(step) < 0.045, step  # over the weakest face contrast (0.03), as the holdout's 0.037
    assert abs(step) / soft_px < 0.0075  # the case: a boundary softer than the flat limit
    (d,) = detect_cubes(image, mirror)
    assert d.achromatic
    assert (d.front_face_mask & face).sum() / (d.front_face_mask | face).sum() > 0.9
    assert (d.front_face_mask & top).sum() < 0.1 * top.sum()


@settings(max_examples=60, deadline=None)
@given(rise=st.floats(0.0, 0.3), angle=st.floats(0.0, np.pi), noise=st.floats(0.0, 0.004),
       seed=st.integers(0, 2**16))
def test_a_face_shading_in_a_ramp_is_one_level(rise, angle, noise, seed):
    """`_one_level` keeps a flat region whose brightness ramps across it (a face lit unevenly), however
    far (up to 0.3 in sRGB value, 10 times the weakest face contrast) and in whichever direction: a ramp
    holds no two levels."""
    from depth.measure import _one_level

    h, w = 60, 40
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    along = (u - w / 2) * np.cos(angle) + (v - h / 2) * np.sin(angle)
    value = 0.4 + rise * along / np.abs(along).max()
    value = value + np.random.default_rng(seed).normal(0.0, noise, value.shape)
    core = np.ones((h, w), dtype=bool)
    core[:3, :5] = False
    np.testing.assert_array_equal(_one_level(core, value, 0.03), core)


@settings(max_examples=60, deadline=None)
@given(step=st.floats(0.035, 0.3), sign=st.sampled_from([-1.0, 1.0]), rows=st.integers(14, 30),
       noise=st.floats(0.0, 0.004), seed=st.integers(0, 2**16))
@example(step=0.03515625, sign=-1.0, rows=14, noise=0.004, seed=4301)
@example(step=0.25, sign=1.0, rows=14, noise=0.00013088267902988896, seed=0)
def test_a_flat_region_of_two_levels_is_cut_to_the_larger_one(step, sign, rows, noise, seed):
    """`_one_level` on a flat region that holds two faces, `rows` rows (14–30, over `LEVEL_SPLIT_MIN_PX`) of
    one level above 60 of another over the weakest face contrast (0.03) away, with noise up to 1 level of 255: it keeps the larger
    face, but for at most a row of its edge where the two meet. The example: a pixel of the larger face that
    the noise carried 4.4 σ toward the other level was cut out of it as a hole (CI on a fresh clone, sixty-
    second session; 35 of 2000 seeds at that step and noise). The second: levels 0.25 apart, each spread by
    0.00013, which skimage's 256-bin Otsu split inside the lower one (CI on a fresh clone, sixty-third)."""
    from depth.measure import _one_level

    h, w = 60 + rows, 40
    value = np.full((h, w), 0.4)
    value[:rows] += sign * step
    value = value + np.random.default_rng(seed).normal(0.0, noise, value.shape)
    core = np.ones((h, w), dtype=bool)
    kept = _one_level(core, value, 0.03)
    assert not kept[:rows].any()
    assert kept[rows + 1:].all()


@pytest.mark.parametrize("rows", [2, 5, 10])
def test_a_strip_of_another_level_narrower_than_a_face_stays_in_the_flat_region(rows):
    """`_one_level` on a flat region holding a strip of another level (0.1 brighter) 2–10 px tall, under
    `LEVEL_SPLIT_MIN_PX`: as the mixed pixels along a narrow face's edges, or a top face strip `exact`
    reads merged, it is left in the region."""
    from depth.measure import LEVEL_SPLIT_MIN_PX, _one_level

    assert rows < LEVEL_SPLIT_MIN_PX
    value = np.full((60 + rows, 40), 0.4)
    value[:rows] += 0.1
    core = np.ones(value.shape, dtype=bool)
    np.testing.assert_array_equal(_one_level(core, value, 0.03), core)


MITSUBA_ROW_SIDE_MASK = Path(__file__).resolve().parents[1] / "data" / "mitsuba_grey_9090_s3_row_side_mask.png"


def test_a_mask_whose_side_lies_in_one_row_has_no_clear_side_and_no_polyfit_warning():
    """``mitsuba_grey_9090_s3_row_side_mask.png``: a blob and face union `reconstruct` outlined in holdout 9090's
    grey scene 3 (a face cut by a shadow into fragments). The boundary points its first fit gives the left
    side all lie in one row, so a line u(v) through them has no direction: numpy's polyfit warned that it
    was poorly conditioned (printed to the user of `catadioptric reconstruct`) and returned a side line
    through nothing. `_initial_model` names the side it cannot fit instead, with no warning."""
    import warnings

    import cv2

    from depth.measure import _initial_model

    mask = cv2.imread(str(MITSUBA_ROW_SIDE_MASK), cv2.IMREAD_GRAYSCALE) > 127
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = _initial_model(mask)
    assert isinstance(model, FailedMeasurement)
    assert model.reason == "face mask has no clear left side"


@given(width=st.integers(8, 40), height=st.integers(8, 60), x0=st.integers(0, 6), y0=st.integers(0, 6))
def test_the_first_fit_of_a_rectangular_mask_lies_on_its_boundary(width, height, x0, y0):
    """`_initial_model` on a filled rectangle (pixels x0 … x0 + width − 1, y0 … y0 + height − 1): its sides are
    the pixel edges, u = x0 − 0.5 and x0 + width − 0.5, v = y0 − 0.5 and y0 + height − 0.5, to within a
    tenth of a pixel, and the side check leaves every rectangle its four sides."""
    from depth.measure import _initial_model

    mask = np.zeros((y0 + height + 8, x0 + width + 8), dtype=bool)
    mask[y0 + 4:y0 + 4 + height, x0 + 4:x0 + 4 + width] = True
    model = _initial_model(mask)
    assert not isinstance(model, FailedMeasurement), model
    corners = model[2]
    expected = np.array([[x0 + 3.5, y0 + 3.5], [x0 + width + 3.5, y0 + 3.5],
                         [x0 + width + 3.5, y0 + height + 3.5], [x0 + 3.5, y0 + height + 3.5]])
    np.testing.assert_allclose(corners, expected, atol=0.1)


@pytest.mark.parametrize("follower", [2, 3])
def test_a_side_that_follows_takes_the_slope_of_the_opposite_sides_new_fit(follower):
    """`_refine` with `follower`: a face 9 px wide (u 14.8 … 23.8, v 19.9 … 72.1 in pixel-centre
    coordinates, edges level), its noisy image drawn here, measured from a first model whose following
    side leans by a slope of 0.3 (2.7 px across the face, beyond the profiles' reach at its ends) and
    the opposite side the other way by 0.08. The side that follows is given the slope the opposite side
    is fitted with in the same pass (level, from that side's own edge points), not the one either came
    in with, and its edge points put it at its edge: both its corners within 0.15 px of it."""
    from depth.measure import _corners, _refine

    s = 8
    h, w = 92, 40
    v, u = (np.mgrid[0:h * s, 0:w * s] + 0.5) / s - 0.5  # pixel k covers [k − 0.5, k + 0.5)
    face = (u >= 14.8) & (u < 23.8) & (v >= 19.9) & (v < 72.1)
    hi = np.where(face[..., None], srgb_to_linear(np.array([0.72, 0.62, 0.12])),
                  srgb_to_linear(np.array([0.86, 0.87, 0.9])))
    linear = hi.reshape(h, s, w, s, 3).mean(axis=(1, 3))
    linear = np.clip(linear + np.random.default_rng(0).normal(0.0, 0.004, linear.shape), 0.0, 1.0)
    lines = np.array([[0.0, 14.8], [0.0, 23.8]])  # u = a·v + b
    k = follower - 2
    tilts = (0.3, -0.08) if k == 0 else (-0.08, 0.3)
    quads = np.array([[0.0, t, edge - t * 19.3] for t, edge in zip(tilts, (19.9, 72.1))])  # through the true middles
    model = (lines, quads, _corners(lines, quads))
    out = _refine(linear, model, 1.5, 2.0, 0.02, 5, 1.0, follower=follower)
    assert not isinstance(out, FailedMeasurement), out
    new_quads, corners = out[1], out[2]
    assert new_quads[k][0] == 0.0
    assert new_quads[k][1] == pytest.approx(2.0 * new_quads[1 - k][0] * 19.3 + new_quads[1 - k][1], abs=0.02)
    edge = (19.9, 72.1)[k]
    np.testing.assert_allclose(corners[[0, 1] if k == 0 else [2, 3], 1], edge, atol=0.15)


@given(low=st.floats(0.0, 0.5), gap=st.floats(0.01, 0.5), spread=st.floats(0.0, 0.002),
       sizes=st.tuples(st.integers(2, 300), st.integers(2, 300)), seed=st.integers(0, 2**16))
def test_otsus_threshold_of_two_separate_levels_lies_between_them(low, gap, spread, sizes, seed):
    """`_otsu_threshold` on two levels of 2–300 values, each spread uniformly by up to 0.002 (down to none
    at all) and `gap` (0.01 or more: 5 spreads) apart: the threshold lies in the gap, however narrow a
    level is (a 256-bin histogram's cannot tell a level narrower than a bin). (Otsu's criterion itself
    splits a level of 300 spread by a gap's half before a level of 2 beyond that gap.)"""
    from depth.measure import _otsu_threshold

    rng = np.random.default_rng(seed)
    a = low + spread * rng.uniform(0.0, 1.0, sizes[0])
    b = low + spread + gap + spread * rng.uniform(0.0, 1.0, sizes[1])
    t = _otsu_threshold(rng.permutation(np.r_[a, b]))
    assert a.max() < t < b.min()


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 60), st.integers(1, 60), st.integers(0, 2 ** 31 - 1), st.floats(0.3, 3.0))
def test_the_detections_smoothed_gradient_is_scipy_ndimages(h, w, seed, sigma):
    # `detect_cubes` smooths and differentiates with OpenCV (scipy's weights and "reflect" border) so that
    # it imports no scipy module; scipy.ndimage is the reference
    from scipy import ndimage

    from depth.measure import _smoothed_gradient
    rng = np.random.default_rng(seed)
    value = rng.random((h, w)) * rng.choice([0.0, 1.0]) + np.add.outer(np.arange(h) * 0.02, np.arange(w) * -0.01)
    smooth = ndimage.gaussian_filter(value, sigma)
    expected = np.hypot(ndimage.sobel(smooth, axis=0), ndimage.sobel(smooth, axis=1)) / 8.0
    np.testing.assert_allclose(_smoothed_gradient(value, sigma), expected, rtol=0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 400), st.integers(0, 2 ** 31 - 1), st.floats(0.3, 30.0))
def test_the_hue_histograms_circular_smoothing_is_scipy_ndimages(n, seed, sigma):
    from scipy import ndimage

    from depth.measure import _circular_smooth
    hist = np.random.default_rng(seed).random(n) * 100
    np.testing.assert_allclose(_circular_smooth(hist, sigma), ndimage.gaussian_filter1d(hist, sigma, mode="wrap"),
                               rtol=0, atol=1e-9)


def test_detecting_cubes_imports_no_scipy_module():
    # a fresh `catadioptric reconstruct` imports scipy's modules in the process that outlines the faces
    # while it detects the cubes (`depth.reconstruct`, `depth.workers.fork_helper`): the detection needs none
    import subprocess
    import sys
    code = """
import sys
import numpy as np
from raytrace.scene import Scene, Cube
from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.render import render, linear_to_srgb8
from raytrace.truth import mirror_mask
from depth.measure import detect_cubes
camera = PinholeCamera.from_look_at((320, 240), (700.0, 700.0), None, (0, 0, 0.55), (0, 0, 0), (0, 1, 0))
mirror = CylinderMirror(0.1, 0.49, (0, 0, 0), (0, 1, 0))
cubes = [Cube(0.05, (0.15, 0.0, 0.35), color=(0.8, 0.1, 0.1)), Cube(0.05, (-0.2, 0.02, 0.4), color=(0.5, 0.5, 0.5))]
img = linear_to_srgb8(render(Scene(mirror, cubes), camera, spp=4, seed=0).image) / 255.0
before = {m for m in sys.modules if m.startswith("scipy.")}
dets = detect_cubes(img, mirror_mask(camera, mirror))
print(len(dets), sorted({m for m in sys.modules if m.startswith("scipy.")} - before))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    found, imported = done.stdout.split(" ", 1)
    assert int(found) >= 1 and imported.strip() == "[]"


# ------------------------------------------------------- objects across a horizon (`_bays_continued`)


def across_the_horizon(lower, upper=None, noise=2 / 255, seed=0, shape=(320, 300), face=(135.3, 165.6, 60.4, 262.7),
                       supersample=4, horizon=160.0):
    """A bright sky over a grey floor (linear 0.3), the horizon at row `horizon` + 0.1 (u − 150), and an upright
    face (u0, u1, v0, v1 px) standing across it, of linear colour `lower` below the horizon and `upper` (default
    `lower`) above it; sRGB with Gaussian noise, rounded to 8 bits. Returns (image, mirror mask, face mask by
    pixel centre)."""
    h, w = shape
    ss = supersample
    u, v = np.meshgrid((np.arange(w * ss) + 0.5) / ss - 0.5, (np.arange(h * ss) + 0.5) / ss - 0.5)
    floor = v > horizon + 0.1 * (u - 150.0)
    img = np.where(floor[..., None], 0.3, np.array([0.85, 0.88, 0.92]) * (1.0 + 0.1 * u / w)[..., None])
    u0, u1, v0, v1 = face
    inside = (u > u0) & (u < u1) & (v > v0) & (v < v1)
    img[inside & floor] = lower
    img[inside & ~floor] = lower if upper is None else upper
    srgb = linear_to_srgb(img.reshape(h, ss, w, ss, 3).mean(axis=(1, 3)))
    srgb = srgb + np.random.default_rng(seed).normal(0.0, noise, srgb.shape)
    pu, pv = np.meshgrid(np.arange(w), np.arange(h))
    mirror = (pu >= 8) & (pu < w - 8) & (pv >= 8) & (pv < h - 8)
    return (np.round(np.clip(srgb, 0.0, 1.0) * 255.0) / 255.0, mirror,
            (pu > u0) & (pu < u1) & (pv > v0) & (pv < v1))


@pytest.mark.parametrize("lower", [0.27, 0.335])  # 5–6 of 255 darker, and brighter, than the floor
@pytest.mark.parametrize("seed", [0, 1])
def test_a_face_of_the_floors_colour_standing_across_the_horizon_is_found_whole(lower, seed):
    """Before the sky the face is outlined by edges on three sides; before the floor, whose colour it has
    within 5–6 of 255 (holdout 8080 s7/0), it shows no edge, and the floor flooded it: nothing was found.
    Now its part before the sky is a bay of the floor, and the face runs on below it between its sides for
    as long as its colour leaves the floor's beside it: it is found once, whole (IoU > 0.9 with the true
    face, its bottom within 2 px)."""
    image, mirror, face = across_the_horizon(lower, seed=seed)
    (found,) = detect_cubes(image, mirror)
    assert found.usable and found.achromatic, found.reason
    iou = (found.mask & face).sum() / (found.mask | face).sum()
    assert iou > 0.9
    assert abs(found.bbox[3] - 263) <= 2 and abs(found.bbox[1] - 60) <= 2


@pytest.mark.parametrize("seed", [0, 1])
def test_a_face_too_wide_for_the_first_opening_standing_across_the_horizon_is_found_whole(seed):
    """A face 76 px wide, 5 of 255 darker than the floor (holdout 7070 all grey JPEG s6/4: 74 × 350 px): the
    disc of the first opening (`BAY_RADII_PX`, 30 px) fits inside its part before the sky, which is no bay of
    that opening, and the floor flooded it: nothing was found. The second opening's bay, it is found whole."""
    from depth.measure import BAY_RADII_PX

    assert 2 * BAY_RADII_PX[0] < 76 < 2 * BAY_RADII_PX[-1]
    image, mirror, face = across_the_horizon(0.27, seed=seed, shape=(440, 300), face=(112.3, 188.6, 40.4, 352.7),
                                             horizon=250.0)
    (found,) = detect_cubes(image, mirror)
    assert found.usable and found.achromatic, found.reason
    assert (found.mask & face).sum() / (found.mask | face).sum() > 0.9
    assert abs(found.bbox[3] - 353) <= 2 and abs(found.bbox[1] - 40) <= 2


def test_a_white_face_of_the_skys_colour_standing_across_the_horizon_is_found_whole():
    """The other way round (holdout 7070 grey s6/0): a white face of the sky's colour, outlined before the
    floor on three sides, is a bay of the sky, and runs on above it, 10 of 255 brighter than the sky."""
    sky = np.array([0.85, 0.88, 0.92]) * (1.0 + 0.1 * 150.0 / 300.0)
    image, mirror, face = across_the_horizon(0.93 * sky, upper=0.93 * sky, face=(135.3, 165.6, 30.4, 232.7))
    (found,) = detect_cubes(image, mirror)
    assert found.usable and found.achromatic, found.reason
    assert (found.mask & face).sum() / (found.mask | face).sum() > 0.9


@pytest.mark.parametrize("lower", [0.3, (0.318, 0.3, 0.282)])
def test_a_bay_whose_object_does_not_run_on_beyond_it_stays_background(lower):
    """A face of the floor's colour before the sky, whose part before the floor has the floor's colour
    exactly (an object seen before the sky alone) or leaves it in hue alone (R up, B down, its brightness the floor's:
    holdout 9090 grey s2/3, outlined 13 px off at its bottom, came out 135 % off), no run is taken beyond
    the bay, and nothing is found there: no cube is read from the bay alone."""
    image, mirror, face = across_the_horizon(lower, upper=0.3)
    assert not any(d.mask[face].any() for d in detect_cubes(image, mirror))


@given(st.integers(12, 160), st.floats(0.0, 1.0), st.integers(0, 2 ** 32 - 1),
       st.lists(st.floats(-0.05, 0.05), min_size=3, max_size=3))
@settings(max_examples=80, deadline=None, derandomize=True)
def test_a_runs_end_is_its_step_where_the_step_is_clear(n, where, seed, level):
    """`_run_end` on a step (its level for `end` rows, zero after): without noise, its end and level
    exactly; with noise of σ = 0.004 a row where the step adds up to 12 σ or more, its end within 2 rows
    plus 8 / δ² (δ: the step's level over σ, per row; the change point's spread grows as 1 / δ²) and a sum
    of at least `RUN_SIGMAS`."""
    from depth.measure import RUN_SIGMAS, _run_end

    level, sigma = np.asarray(level), 0.004
    end = 1 + int(where * (n - 6))
    steps = np.where((np.arange(n) < end)[:, None], level, 0.0)
    if np.linalg.norm(level) > 0:
        found, got, sigmas = _run_end(steps)
        assert found == end and np.allclose(got, level) and sigmas == np.inf
    if np.linalg.norm(level) * np.sqrt(end) >= 12 * sigma:
        found, got, sigmas = _run_end(steps + sigma * np.random.default_rng(seed).standard_normal((n, 3)))
        assert abs(found - end) <= 2 + 8 * (sigma / np.linalg.norm(level)) ** 2
        assert sigmas >= RUN_SIGMAS


def test_noise_alone_seldom_makes_a_run():
    """Over 400 draws of pure noise (no object beyond a bay), `_run_end` adds up to `RUN_SIGMAS` in under
    5 % of them: the change point chosen as the best of up to L − 5 rows inflates the sum, but 5 σ holds."""
    from depth.measure import RUN_SIGMAS, _run_end

    rng = np.random.default_rng(7)
    runs = [_run_end(0.004 * rng.standard_normal((int(n), 3)))[2] >= RUN_SIGMAS for n in rng.integers(12, 400, 400)]
    assert np.mean(runs) < 0.05


@pytest.mark.parametrize("blue_red", [False, True])
def test_a_face_that_steps_in_blue_minus_red_alone_is_enclosed_only_with_those_edges(blue_red):
    """`_enclosed` on a warm sky shading across the mirror, with a face 30 × 80 px whose red falls by 0.025 and
    blue rises by 0.04 (a white face lit by the blue sky): in every channel it steps by under the strong step,
    so that Canny's hysteresis drops its weak edges and the background floods it; in blue − red it steps by
    0.065, over the strong step, and with `blue_red` those edges enclose it (the background leaves its inside)."""
    import cv2

    from depth.measure import _enclosed

    h, w = 160, 200
    yy, xx = np.mgrid[0:h, 0:w]
    rgb = np.stack([0.80 + 0.10 * xx / w, 0.78 + 0.10 * xx / w, 0.70 + 0.10 * xx / w], axis=-1)
    face = (yy >= 40) & (yy < 120) & (xx >= 85) & (xx < 115)
    rgb[face] += [-0.025, 0.0, 0.04]
    search = np.zeros((h, w), dtype=bool)
    search[2:-2, 2:-2] = True
    background, _, _ = _enclosed(rgb, search, search, 0.5, blue_red=blue_red)
    inside = cv2.erode(face.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    assert np.mean(background[inside]) == (0.0 if blue_red else 1.0)
