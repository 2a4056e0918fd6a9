"""A colour camera's channels made the image `reconstruct` reads: lateral chromatic aberration undone, and raw
Bayer frames demosaiced.

A camera whose red or blue channel has a lens of its own (`raytrace.chroma`, `[camera.red]` / `[camera.blue]`)
images an edge in that channel tenths of a pixel to pixels away from where green images it, more so toward the
image's corners. Read as it is, a face's sides come out fringed: its colour steps in two places, the edges read
between them. `aligned_to_green` resamples red and blue onto green's geometry, so that every later step reads the
image a camera without the aberration would have taken (up to the resampling's own blur).

A camera's raw Bayer frame (`[camera] mosaic`) holds one channel's sample of light per pixel. `from_raw_frame` makes
it an sRGB image by one of `DEMOSAICS` (`raw_light` its values as light).
"""

from __future__ import annotations

import numpy as np

from .errors import DepthError

__all__ = ["INTERPOLATION", "INTERPOLATIONS", "aligned_to_green", "DEMOSAIC", "DEMOSAICS", "raw_light",
           "from_raw_frame"]

INTERPOLATION = "cubic-clamped"
"""How a channel is sampled between its pixels: OpenCV's bicubic (`cv2.INTER_CUBIC`), each sample clipped to the
range of the 2 × 2 pixels around it; see `bench_chromatic`."""
INTERPOLATIONS = ("linear", "cubic", "cubic-clamped", "lanczos")


def _to_light(values: np.ndarray, response, k: int) -> np.ndarray:
    """Channel k's light (float32) of stored values (uint8 codes through a table of the 256, or floats)."""
    from raytrace.response import srgb_to_linear
    if values.dtype == np.uint8:
        codes = np.arange(256, dtype=np.uint8)
        table = response.to_linear(codes, channel=k) if response is not None else srgb_to_linear(codes / 255.0)
        return table.astype(np.float32)[values[..., k]]
    if response is not None:
        return response.to_linear(values[..., k], channel=k).astype(np.float32)
    return srgb_to_linear(values[..., k]).astype(np.float32)


def _stored(light: np.ndarray, response, k: int, as_uint8: bool) -> np.ndarray:
    """Channel k's light (clipped to [0, 1]) stored again as the camera stores it: rounded codes, or floats."""
    from raytrace.response import linear_to_srgb
    light = np.clip(light.astype(np.float64), 0.0, 1.0)
    if as_uint8:
        if response is not None:
            return response.encode8(light, channel=k)
        from raytrace.render import linear_to_srgb8
        return linear_to_srgb8(light)
    return linear_to_srgb(light) if response is None else response.stored(light, channel=k)


def _within_neighbours(moved: np.ndarray, light: np.ndarray, at: np.ndarray) -> np.ndarray:
    """`moved` (sampled at `at`) clipped to the range of the 2 × 2 pixels around each sample: the kernel's
    overshoot beside a sharp edge (a ringing of 10–15 codes of 255 beside a one-pixel step) taken away."""
    import cv2
    box = np.ones((2, 2), np.uint8)
    low = cv2.erode(light, box, anchor=(0, 0), borderType=cv2.BORDER_REPLICATE)  # min over (x..x+1, y..y+1)
    high = cv2.dilate(light, box, anchor=(0, 0), borderType=cv2.BORDER_REPLICATE)
    below = np.floor(at)
    h, w = light.shape
    x = np.clip(below[..., 0], 0, w - 1).astype(np.intp)
    y = np.clip(below[..., 1], 0, h - 1).astype(np.intp)
    return np.clip(moved, low[y, x], high[y, x])


def aligned_to_green(image, camera, interpolation: str = INTERPOLATION) -> np.ndarray:
    """`image` (H, W, 3) as `camera` stores it (uint8 codes, or float64 in [0, 1]) with its red and blue channels
    each sampled, in light, where that channel images the ray of each pixel of green's (`raytrace.chroma.
    channel_pixels`), then stored again as the camera stores light (its `response`, sRGB if None); green and any
    channel without a lens of its own are returned as they are. Beyond the image's border a channel's edge pixels
    are repeated."""
    import cv2

    from raytrace.chroma import channel_pixels
    modes = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC, "cubic-clamped": cv2.INTER_CUBIC,
             "lanczos": cv2.INTER_LANCZOS4}
    if interpolation not in modes:
        raise DepthError(f"interpolation: expected one of {', '.join(INTERPOLATIONS)}, got {interpolation!r}")
    img = np.asarray(image)
    lensed = [(k, name) for k, name in ((0, "red"), (2, "blue")) if getattr(camera, name, None) is not None]
    if not lensed:
        return img
    response = getattr(camera, "response", None)
    out = img.copy()
    for k, name in lensed:
        at = channel_pixels(camera, name).astype(np.float32)  # (OpenCV's maps are float32: 1e-4 px at 2048 px)
        light = _to_light(img, response, k)
        moved = cv2.remap(light, at[..., 0], at[..., 1], modes[interpolation], borderMode=cv2.BORDER_REPLICATE)
        if interpolation == "cubic-clamped":
            moved = _within_neighbours(moved, light, at)
        out[..., k] = _stored(moved, response, k, img.dtype == np.uint8)
    return out


DEMOSAIC = "two-colour"
"""How `from_raw_frame` fills each pixel's two channels its filter did not record (see `DEMOSAICS`). On `bench_bayer`'s
raw frames it finds as many cubes as VNG or more (Mitsuba's 57 of 61 each, ours 23 of 23 against 20; the demo scene
5 of 5 against 3 and one invented), its centre error median 0.81 % on Mitsuba's (VNG 1.14 %; cube by cube a draw, 29
better and 27 worse), for 0.22 s per megapixel more (`python -m bench bayer`)."""
DEMOSAICS = ("VNG", "bilinear", "edge-aware", "two-colour")
"""`from_raw_frame`'s demosaics: "VNG", OpenCV's variable number of gradients on the frame's light stored as sRGB codes
(its VNG takes 8 bits alone); "bilinear" and "edge-aware", OpenCV's on the frame's own (linear) values; "two-colour"
(`_two_colour`), each pixel's missing channels as the local line of colours through its own sample, VNG's where the
colours about it lie on no line."""

TWO_COLOUR_WINDOW = 7
"""Side (px) of the window whose colours `_two_colour` fits a line to."""
TWO_COLOUR_STEPS = 10
TWO_COLOUR_RELAXATION = 1.5
"""`_two_colour`'s passes, each moving the missing channels this many times the way to the window's line (over-
relaxed: on a step of light between two colours each channel's edge within 0.02 px after 10, 0.06 px after 10 plain
passes, 0.24 px after 2; `tests/depth/test_raw_frames.py`)."""
TWO_COLOUR_OFF_LINE = (0.01, 0.05)
"""Share of a window's colour variance off its main axis over which `_two_colour`'s pixel gives way to VNG's (from
all of it at the first to none at the second): three colours meet there (a face, its thin top face and the
background), where no line holds."""

TWO_COLOUR_FLAT = 1e-5
"""Total colour variance of a window (light², summed over the channels) under which it is taken as flat and keeps its
`_two_colour` pixel: its share off the main axis is then its rounding's, and VNG's colours are 8-bit codes."""

_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def _tile(pattern: str) -> list:
    """The channel (0, 1, 2) of each pixel of a pattern's 2 × 2 tile, [row][column] (`bayer_channels`'s)."""
    from raytrace.chroma import bayer_channels
    return bayer_channels(pattern, (2, 2)).tolist()


def _box(a: np.ndarray, dst: np.ndarray | None = None) -> np.ndarray:
    import cv2
    return cv2.boxFilter(a, -1, (TWO_COLOUR_WINDOW, TWO_COLOUR_WINDOW), dst=dst, normalize=True,
                         borderType=cv2.BORDER_REFLECT_101)


def _bilinear(light: np.ndarray, tile: list) -> np.ndarray:
    """(3, H, W) float32: each channel's samples kept, the rest the weighted mean of its samples about them (1 2 1)."""
    import cv2
    kernel = np.outer([1.0, 2.0, 1.0], [1.0, 2.0, 1.0]).astype(np.float32)
    out = np.empty((3,) + light.shape, np.float32)
    for c in range(3):
        own = np.zeros(light.shape, np.float32)
        for i in range(2):
            for j in range(2):
                own[i::2, j::2] = tile[i][j] == c
        summed = cv2.filter2D(light * own, -1, kernel, borderType=cv2.BORDER_REFLECT_101)
        weight = cv2.filter2D(own, -1, kernel, borderType=cv2.BORDER_REFLECT_101)
        out[c] = np.where(own > 0, light, summed / weight)
    return out


def _window_moments(x: np.ndarray, into: tuple | None = None):
    """Each pixel's window means of the channels (3 of (H, W)) and of their products (`_PAIRS`: dict); written into
    `into` (`_moment_buffers`'s) where given, which a pass over a large image pays for once, not at every pass (each new
    image-sized array's pages are faulted in afresh)."""
    mean, prod, product = into if into is not None else _moment_buffers(x)
    for c in range(3):
        _box(x[c], mean[c])
    for p in _PAIRS:
        np.multiply(x[p[0]], x[p[1]], out=product)
        _box(product, prod[p])
    return mean, prod


def _moment_buffers(x: np.ndarray) -> tuple:
    """Arrays for `_window_moments` of `x` (3, H, W): 3 means, 6 products' means (`_PAIRS`) and one product."""
    def new():
        return np.empty(x.shape[1:], x.dtype)
    return [new() for _ in range(3)], {p: new() for p in _PAIRS}, new()


TWO_COLOUR_BLOCK = 64
"""Side (px, even) of the blocks `_two_colour` runs its passes on: those holding a window that is not flat
(`TWO_COLOUR_FLAT`), with the blocks around them; elsewhere the bilinear start is kept, which is exact where the light
is flat. Most of a mirror image is: on the command timing's five 2048 × 1536 frames, 0.5–28 % of the pixels have a
window that is not."""
TWO_COLOUR_BAND = 6
"""Height (blocks) of the bands of rows `_busy_boxes` cuts the busy blocks into: within a band, each run of them
along its columns is one job, computed from as far beyond it as the passes reach (`_two_colour_reach`)."""


def _two_colour_reach() -> int:
    """How far (px, even) a pixel of `_two_colour` reads the frame: the bilinear start's 1 px, 3 px a pass (half its
    window), and the off-line share's window's half again (34 px)."""
    half = TWO_COLOUR_WINDOW // 2
    reach = 1 + TWO_COLOUR_STEPS * half + half
    return reach + reach % 2  # (an even reach keeps a box's tile)


def _window_variance(x: np.ndarray) -> np.ndarray:
    """(H, W): each window's colour variance, summed over the channels (`x`: (3, H, W))."""
    return sum(_box(x[c] * x[c]) - _box(x[c]) ** 2 for c in range(3))


def _busy_boxes(x: np.ndarray, where: np.ndarray | None = None) -> list:
    """((top, bottom, left, right), (first, last, cfirst, clast)) of the jobs `_two_colour` runs its passes in: the
    `TWO_COLOUR_BLOCK` blocks holding a window that is not flat (in `where`, (H, W) bool, or within reach of it, where
    given) and those about them, cut in bands of `TWO_COLOUR_BAND` rows of blocks, within a band each run of them
    along its columns (runs closer than their reaches merged); each to be computed from the frame's rows first:last
    and columns cfirst:clast, which reach as far beyond it as its pixels read (`_two_colour_reach`). Tops and lefts
    are even (the frame's tile kept), and the jobs depend on the frame alone, not on the cores they run on."""
    import cv2
    b, reach = TWO_COLOUR_BLOCK, _two_colour_reach()
    busy = _window_variance(x) >= TWO_COLOUR_FLAT
    if where is not None:  # (and what lies within the reach of it, which its pixels read)
        where = np.ascontiguousarray(where, dtype=bool).view(np.uint8)
        busy &= cv2.dilate(where, np.ones((2 * reach + 1,) * 2, np.uint8)).view(bool)
    h, w = busy.shape
    rows, cols = -(-h // b), -(-w // b)
    padded = np.zeros((rows * b, cols * b), bool)
    padded[:h, :w] = busy
    blocks = padded.reshape(rows, b, cols, b).any(axis=(1, 3)).astype(np.uint8)
    grown = cv2.dilate(blocks, np.ones((3, 3), np.uint8)).astype(bool)
    gap = -(-2 * reach // b)  # (blocks: runs closer than this share most of their reach)
    jobs = []
    for r0 in range(0, rows, TWO_COLOUR_BAND):
        band = grown[r0:r0 + TWO_COLOUR_BAND]
        on = np.flatnonzero(band.any(axis=0))
        if not len(on):
            continue
        breaks = np.flatnonzero(np.diff(on) > gap)
        for c0, c1 in zip(on[np.r_[0, breaks + 1]], on[np.r_[breaks, len(on) - 1]] + 1):
            ys = np.flatnonzero(band[:, c0:c1].any(axis=1))
            top, bottom = (r0 + int(ys[0])) * b, min((r0 + int(ys[-1]) + 1) * b, h)
            left, right = int(c0) * b, min(int(c1) * b, w)
            jobs.append(((top, bottom, left, right),
                         (max(top - reach, 0), min(bottom + reach, h), max(left - reach, 0), min(right + reach, w))))
    return jobs


def _two_colour_passes(light: np.ndarray, tile: list) -> np.ndarray:
    """(3, H, W) float32: a frame's light (H, W) demosaiced as mixes of two colours. Where a window holds two colours,
    a pixel's colour is a + t (b − a) for its share t of one, and every channel is a line in its own channel's sample
    over the window; each pass sets a pixel's missing channels on the line (least squares) the window's present
    estimate gives through its sample, starting from `_bilinear`. On a straight step between two colours it places
    every channel's edge where the light's is (the red and blue samples of one row are 2 px apart: no interpolation of
    those alone places it better than ±0.5 px)."""
    x = _bilinear(light, tile)
    buffers = _moment_buffers(x)
    phases = []
    for i in range(2):
        for j in range(2):
            at = (slice(i, None, 2), slice(j, None, 2))
            phases.append((tile[i][j], at) + tuple(np.empty(light[at].shape, np.float32) for _ in range(2)))
    for _ in range(TWO_COLOUR_STEPS):
        mean, prod = _window_moments(x, buffers)
        for c, at, slope_over, step in phases:  # (in place, in this order: (sample − mean) / (variance + 1e-7), the
            mc = mean[c][at]  # line's value at the sample, a pixel's channels moved that way; all float32)
            np.subtract(light[at], mc, out=slope_over)
            np.multiply(mc, mc, out=step)
            np.subtract(prod[c, c][at], step, out=step)
            step += 1e-7
            slope_over /= step
            for k in sorted({0, 1, 2} - {c}):
                xs = x[k][at]
                np.multiply(mean[k][at], mc, out=step)
                np.subtract(prod[min(k, c), max(k, c)][at], step, out=step)
                step *= slope_over
                np.add(mean[k][at], step, out=step)
                step -= xs
                step *= TWO_COLOUR_RELAXATION
                xs += step
    return np.clip(x, 0.0, 1.0, out=x)


def _off_line_share(x: np.ndarray, region: tuple = (slice(None), slice(None))) -> np.ndarray:
    """(H, W): the share of each window's colour variance (`x`: (3, H, W)) off its main axis, 1 − λ₁ / trace of its
    3 × 3 covariance (λ₁ its largest eigenvalue, in closed form: Smith, "Eigenvalues of a symmetric 3 × 3 matrix",
    Comm. ACM 4, 1961); 0 where the window is flat (`TWO_COLOUR_FLAT`). Of the pixels of `region` (rows, columns)
    alone, their windows read from the whole of `x`; computed where they are not flat alone."""
    mean, prod = _window_moments(x)
    total = sum((prod[c, c][region] - mean[c][region] * mean[c][region]).astype(np.float64) for c in range(3))
    share = np.zeros(total.shape, np.float64)
    busy = total >= TWO_COLOUR_FLAT
    if not busy.any():
        return share
    c = {p: (prod[p][region][busy] - mean[p[0]][region][busy] * mean[p[1]][region][busy]).astype(np.float64)
         for p in _PAIRS}
    total = c[0, 0] + c[1, 1] + c[2, 2]
    q = total / 3.0
    d0, d1, d2 = c[0, 0] - q, c[1, 1] - q, c[2, 2] - q
    off = c[0, 1] ** 2 + c[0, 2] ** 2 + c[1, 2] ** 2
    p = np.sqrt(np.maximum((d0 ** 2 + d1 ** 2 + d2 ** 2 + 2.0 * off) / 6.0, 1e-60))  # (p³ stays > 0)
    det = (d0 * (d1 * d2 - c[1, 2] ** 2) - c[0, 1] * (c[0, 1] * d2 - c[1, 2] * c[0, 2])
           + c[0, 2] * (c[0, 1] * c[1, 2] - d1 * c[0, 2]))
    largest = q + 2.0 * p * np.cos(np.arccos(np.clip(det / (2.0 * p ** 3), -1.0, 1.0)) / 3.0)
    share[busy] = np.clip(1.0 - largest / np.maximum(total, 1e-12), 0.0, 1.0)
    return share


def _two_colour(light: np.ndarray, pattern: str, where: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 3) float64 sRGB in [0, 1]: `_two_colour_passes` where the frame is not flat (`_busy_boxes`: in `where` or
    within reach of it, where given; its bilinear start elsewhere), VNG's colour where the window's colours lie on no
    line (`TWO_COLOUR_OFF_LINE`). Written to touch few image-sized arrays: a fresh process pays for each one's pages
    (0.7 s of a 2048 × 1536 frame's 1.2 s, before)."""
    from raytrace.chroma import demosaiced_mosaic
    from raytrace.render import linear_to_srgb8
    from raytrace.response import srgb_to_linear
    tile = _tile(pattern)
    light32 = light.astype(np.float32)
    x = _bilinear(light32, tile)
    jobs = _busy_boxes(x, where)
    out = np.empty(light.shape + (3,), np.float64)
    for c in range(3):
        out[..., c] = x[c]
    if not jobs:
        return _encoded_in_place(out)
    vng = demosaiced_mosaic(linear_to_srgb8(light), pattern)
    table = srgb_to_linear(np.arange(256) / 255.0)
    lo, hi = TWO_COLOUR_OFF_LINE

    def run(job):  # a box, computed from as far beyond it as its pixels read
        (top, bottom, left, right), (first, last, cfirst, clast) = job
        part = _two_colour_passes(light32[first:last, cfirst:clast], tile)
        inner = (slice(top - first, bottom - first), slice(left - cfirst, right - cfirst))
        weight = np.clip((hi - _off_line_share(part, inner)) / (hi - lo), 0.0, 1.0)[..., None]
        region = (slice(top, bottom), slice(left, right))
        out[region] = weight * np.moveaxis(part, 0, -1)[inner] + (1.0 - weight) * table[vng[region]]

    from concurrent.futures import ThreadPoolExecutor

    from depth.workers import available_cores
    # (threads: numpy's and OpenCV's loops let go of the GIL)
    with ThreadPoolExecutor(min(available_cores(), len(jobs))) as pool:
        list(pool.map(run, jobs))
    return _encoded_in_place(out)


def _encoded_in_place(lin: np.ndarray) -> np.ndarray:
    """`raytrace.response.linear_to_srgb` of `lin` (float64), computed in its own memory."""
    np.clip(lin, 0.0, 1.0, out=lin)
    dark = lin <= 0.0031308
    low = lin[dark] * 12.92
    np.power(lin, 1.0 / 2.4, out=lin)
    lin *= 1.055
    lin -= 0.055
    lin[dark] = low
    return lin


def raw_light(frame, pattern: str, black: float = 0.0, white: float | None = None, gains=None) -> np.ndarray:
    """(H, W) float64 in [0, 1]: a raw Bayer frame's light, (value − `black`) / (`white` − `black`), each pixel times
    its filter's channel's gain (`gains`: red, green, blue; a camera's white balance), clipped. `white` defaults to the
    frame type's maximum (255, 65535)."""
    from raytrace.chroma import BAYER_PATTERNS, bayer_channels
    raw = np.asarray(frame)
    if raw.ndim != 2 or raw.dtype not in (np.uint8, np.uint16):
        raise DepthError(f"frame: expected an (H, W) uint8 or uint16 raw Bayer frame, got {raw.dtype} {raw.shape}")
    if pattern not in BAYER_PATTERNS:
        raise DepthError(f"pattern: expected one of {', '.join(BAYER_PATTERNS)}, got {pattern!r}")
    most = float(np.iinfo(raw.dtype).max)
    white = most if white is None else float(white)
    if not (0.0 <= black < white <= most):
        raise DepthError(f"black, white: expected 0 <= black < white <= {most:.0f} (the frame's type's most), got "
                         f"{black}, {white}")
    light = (raw - float(black)) / (white - float(black))
    if gains is not None:
        gains = np.asarray(gains, dtype=np.float64)
        if gains.shape != (3,) or not np.all(np.isfinite(gains) & (gains > 0)):
            raise DepthError(f"gains: expected 3 positive numbers (red, green, blue), got {gains.tolist()}")
        light *= gains[bayer_channels(pattern, raw.shape)]
    return np.clip(light, 0.0, 1.0)


def from_raw_frame(frame, pattern: str, demosaic: str = DEMOSAIC, black: float = 0.0, white: float | None = None,
                   gains=None, where: np.ndarray | None = None) -> np.ndarray:
    """The sRGB image (H, W, 3) a raw Bayer `frame` makes: (H, W) uint8 or uint16, each pixel its colour filter's
    sample of light (`pattern`: `raytrace.chroma.BAYER_PATTERNS`), linear: `raw_light` (0 none at `black`, full scale
    at `white`, each channel times its gain). `demosaic` (`DEMOSAICS`): "VNG" gives uint8 codes, the others float64 in
    [0, 1]. Either is read as a demosaiced camera's image (`reconstruct`'s `compressed`: red and blue interpolated over
    three pixels of four, as a JPEG image's chroma is). `where` ((H, W) bool): the pixels that will be read
    (`depth.reconstruct.reading_region`); "two-colour" then runs its passes about these alone, and gives them the
    colours it gives them without it; beyond their reach, bilinear's colour."""
    import cv2

    from raytrace.chroma import demosaiced_mosaic
    from raytrace.render import linear_to_srgb8
    from raytrace.response import linear_to_srgb
    if demosaic not in DEMOSAICS:
        raise DepthError(f"demosaic: expected one of {', '.join(DEMOSAICS)}, got {demosaic!r}")
    light = raw_light(frame, pattern, black, white, gains)
    if where is not None and np.shape(where) != light.shape:
        raise DepthError(f"where: expected a mask of the frame's {light.shape}, got {np.shape(where)}")
    if demosaic == "VNG":
        return demosaiced_mosaic(linear_to_srgb8(light), pattern)
    if demosaic == "two-colour":
        return _two_colour(light, pattern, where)
    code = getattr(cv2, f"COLOR_Bayer{pattern}2RGB" + ("_EA" if demosaic == "edge-aware" else ""))
    values = np.round(light * 65535.0).astype(np.uint16)  # (OpenCV's take integers; a 16-bit frame's own, unscaled)
    return linear_to_srgb(np.clip(cv2.cvtColor(np.ascontiguousarray(values), code) / 65535.0, 0.0, 1.0))
