"""Lateral chromatic aberration undone: each colour channel sampled where it images green's rays.

A camera whose red or blue channel has a lens of its own (`raytrace.chroma`, `[camera.red]` / `[camera.blue]`)
images an edge in that channel tenths of a pixel to pixels away from where green images it, more so toward the
image's corners. Read as it is, a face's sides come out fringed: its colour steps in two places, the edges read
between them. `aligned_to_green` resamples red and blue onto green's geometry, so that every later step reads the
image a camera without the aberration would have taken (up to the resampling's own blur).
"""

from __future__ import annotations

import numpy as np

from .errors import DepthError

__all__ = ["INTERPOLATION", "INTERPOLATIONS", "aligned_to_green"]

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
