"""A camera's response: how the 8-bit values it stores relate to the linear light that reached the sensor.

sRGB (IEC 61966-2-1) is what a renderer writes and what the whole pipeline assumes by default. A camera, or
another renderer's view transform (a gamma, a tone curve), may store something else; a pixel that mixes two
colours, at an edge, is their mix in linear light, so a sub-pixel edge read through the wrong curve lands off
(`catadioptric`'s `[camera] response`). `CameraResponse` is one of:

- "linear": the stored value is the light itself;
- a gamma g: stored = light ** (1 / g);
- a table: the light of each of the 256 codes, one curve for all channels or one per channel (R, G, B), as a
  radiometric calibration gives it (e.g. `cv2.createCalibrateDebevec`, whose channels are in B, G, R order);
  it is scaled so that code 255 is 1.

`to_linear` reads stored values as light; `as_srgb` re-encodes them as the sRGB values a camera of that light
would have stored (what `depth` reads); `encode8` stores light as this camera would (what `simulate` writes).
`calibrate_response` measures a camera's response from one scene taken at several exposure times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import check_same_rgb8
from .errors import RaytraceError

__all__ = ["CameraResponse", "as_response", "calibrate_response", "srgb_to_linear", "linear_to_srgb"]


def srgb_to_linear(srgb) -> np.ndarray:
    """Invert the sRGB transfer function: (...) float64 in [0, 1] → (...) float64 linear values in [0, 1]."""
    srgb = np.asarray(srgb, dtype=np.float64)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(lin) -> np.ndarray:
    """The sRGB transfer function (inverse of `srgb_to_linear`), values clipped to [0, 1] first."""
    lin = np.clip(lin, 0.0, 1.0)
    return np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1.0 / 2.4) - 0.055)


CODES = np.arange(256) / 255.0
"""The 256 stored values of an 8-bit image, in [0, 1]."""


@dataclass(frozen=True, eq=False)
class CameraResponse:
    """A response other than sRGB (which is None wherever a camera's response is asked for).

    Attributes
    ----------
    kind : "linear", "gamma" or "table"
    gamma : float, for "gamma" (stored = light ** (1 / gamma))
    table : (256, 3) float64, for "table": the light of each code per channel, non-decreasing, code 255 at 1
    """

    kind: str
    gamma: float | None = None
    table: np.ndarray | None = None

    def __eq__(self, other) -> bool:
        if not isinstance(other, CameraResponse):
            return NotImplemented
        return (self.kind, self.gamma) == (other.kind, other.gamma) and (
            self.table is other.table or (self.table is not None and other.table is not None
                                          and np.array_equal(self.table, other.table)))

    def __hash__(self) -> int:
        return hash((self.kind, self.gamma, None if self.table is None else self.table.tobytes()))

    def to_linear(self, values, channel: int | None = None) -> np.ndarray:
        """The light of stored values: (..., 3) uint8 codes, or float64 stored values in [0, 1] (a table's
        curve then interpolated between codes) → (..., 3) float64 in [0, 1]. With `channel` (0, 1 or 2), `values`
        are that channel's alone, (...) → (...)."""
        values = np.asarray(values)
        if self.kind == "table":
            if values.dtype == np.uint8:
                return self.table[values, np.arange(3)] if channel is None else self.table[values, channel]
            x = np.clip(values.astype(np.float64), 0.0, 1.0)
            if channel is not None:
                return np.interp(x, CODES, self.table[:, channel])
            return np.stack([np.interp(x[..., k], CODES, self.table[:, k]) for k in range(3)], axis=-1)
        x = values / 255.0 if values.dtype == np.uint8 else np.clip(values.astype(np.float64), 0.0, 1.0)
        return x if self.kind == "linear" else x ** self.gamma

    def as_srgb(self, values) -> np.ndarray:
        """Stored values re-encoded as sRGB: (..., 3) float64 in [0, 1], what a camera that stores sRGB would
        have stored of the same light (unrounded). 8-bit codes are looked up, each code's value made once."""
        values = np.asarray(values)
        if values.dtype == np.uint8:
            lut = linear_to_srgb(self.to_linear(np.repeat(np.arange(256, dtype=np.uint8)[:, None], 3, axis=1)))
            return lut[values, np.arange(3)]
        return linear_to_srgb(self.to_linear(values))

    def encode8(self, linear, channel: int | None = None) -> np.ndarray:
        """Light (..., 3) in [0, 1] (clipped) → the (..., 3) uint8 codes this camera stores: its curve's inverse
        rounded to the nearest code, as a camera rounds what its curve makes of the light (a table's curve is
        piecewise linear between codes; on a flat run, the run's first code). With `channel` (0, 1 or 2), `linear`
        is that channel's alone, (...) → (...)."""
        x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
        if self.kind != "table":
            return np.round(self.stored(x) * 255.0).astype(np.uint8)

        def codes(light, t):
            code = np.round(np.interp(light, t, np.arange(256.0))).astype(np.intp)
            return np.searchsorted(t, t[code], side="left").astype(np.uint8)

        if channel is not None:
            return codes(x, self.table[:, channel])
        out = np.empty(x.shape, dtype=np.uint8)
        for k in range(3):
            out[..., k] = codes(x[..., k], self.table[:, k])
        return out

    def stored(self, linear, channel: int | None = None) -> np.ndarray:
        """Light (..., 3) in [0, 1] (clipped) → the stored values in [0, 1] whose light it is, unrounded: the curve's
        inverse (a table's taken as piecewise linear between codes). With `channel`, that channel's light alone."""
        x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
        if self.kind == "linear":
            return x
        if self.kind == "gamma":
            return x ** (1.0 / self.gamma)
        if channel is not None:
            return np.interp(x, self.table[:, channel], CODES)
        return np.stack([np.interp(x[..., k], self.table[:, k], CODES) for k in range(3)], axis=-1)

    def to_value(self):
        """The setup file's value of this response: "linear", the gamma, or the table (256 numbers, or 3 lists
        of 256 where the channels differ)."""
        if self.kind == "linear":
            return "linear"
        if self.kind == "gamma":
            return self.gamma
        if np.array_equal(self.table[:, 0], self.table[:, 1]) and np.array_equal(self.table[:, 0], self.table[:, 2]):
            return self.table[:, 0].tolist()
        return self.table.T.tolist()


def as_response(value, name: str = "response") -> CameraResponse | None:
    """A camera's response from its setup value: None or "srgb" (→ None: sRGB), "linear" (either in any case), a
    gamma (a number in (0, 10]), or a table of 256 numbers (the light of each code) or of 3 such lists (R, G, B). Raises
    `RaytraceError` naming `name` and what was expected."""
    if value is None or (isinstance(value, str) and value.lower() == "srgb"):
        return None
    if isinstance(value, CameraResponse):
        return value
    if isinstance(value, str):
        if value.lower() == "linear":
            return CameraResponse("linear")
        raise RaytraceError(f'{name}: expected "srgb", "linear", a gamma or a table of 256 values, got {value!r}')
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        g = float(value)
        if not (np.isfinite(g) and 0.0 < g <= 10.0):
            raise RaytraceError(f"{name}: expected a gamma in (0, 10] (stored = light ** (1 / gamma)), got {value!r}")
        return CameraResponse("gamma", gamma=g)
    try:
        table = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        table = None
    if table is None or table.shape not in ((256,), (3, 256)):
        raise RaytraceError(f'{name}: expected "srgb", "linear", a gamma, or a table of 256 numbers (the light of '
                            f"each code) or 3 lists of 256 (R, G, B), got {_shape_of(value, table)}")
    table = np.broadcast_to(table, (3, 256)).T
    if not np.all(np.isfinite(table)) or np.any(table < 0):
        raise RaytraceError(f"{name}: expected finite light values >= 0 in its table")
    if np.any(np.diff(table, axis=0) < 0) or np.any(table[-1] <= table[0]):
        channel = int(np.flatnonzero(np.any(np.diff(table, axis=0) < 0, axis=0) | (table[-1] <= table[0]))[0])
        raise RaytraceError(f"{name}: expected a table rising with the code (never falling, code 255 above code 0); "
                            f"channel {channel} {'falls' if np.any(np.diff(table[:, channel]) < 0) else 'is flat'}")
    return CameraResponse("table", table=np.ascontiguousarray(table / table[-1]))


def _shape_of(value, table) -> str:
    """How `as_response` describes a value it cannot take."""
    if table is None or table.ndim == 0:
        return repr(value)[:60]
    return f"an array of shape {table.shape}"


WELL_EXPOSED = (32, 240)
"""Codes `calibrate_response` compares exposures on: away from the dark noise and from saturation."""


def calibrate_response(images, times, samples: int = 200, smoothness: float = 10.0):
    """A camera's response from one scene taken at several exposure times (Debevec and Malik 1997, OpenCV's
    `cv2.createCalibrateDebevec`), kept rising with the code (a running maximum) and scaled so that code 255 is 1.

    images : sequence of (H, W, 3) uint8 RGB images of one still scene, the camera's other settings unchanged
    times : their exposure times (s, or any unit), > 0
    samples : pixels the calibration solves on (a grid); smoothness : its curve's smoothness weight (λ)

    Returns (response, agreement): agreement is how far the exposures, read through it, disagree on each pixel's
    light (per unit time) where each pair of successive exposures has it well exposed in every channel
    (`WELL_EXPOSED`): {"median": .., "p90": .., "values": n (pixel channels compared)}, relative (0.01 is 1 %), or
    None where no pixel is.
    Raises `RaytraceError` naming the argument on bad input.
    """
    import cv2
    times = np.asarray(times, dtype=np.float64).ravel()
    imgs = [np.asarray(im) for im in images]
    if len(imgs) < 2 or len(times) != len(imgs):
        raise RaytraceError(f"times: expected one exposure time per image (at least 2 images), got {len(times)} "
                            f"time(s) for {len(imgs)} image(s)")
    if not np.all(np.isfinite(times)) or np.any(times <= 0):
        raise RaytraceError(f"times: expected positive exposure times, got {times.tolist()}")
    if len(np.unique(times)) < 2:
        raise RaytraceError("times: expected at least two different exposure times")
    check_same_rgb8(imgs)
    calibrate = cv2.createCalibrateDebevec(int(samples), float(smoothness), False)
    curve = calibrate.process([np.ascontiguousarray(im[:, :, ::-1]) for im in imgs], times.astype(np.float32))
    curve = np.maximum.accumulate(np.asarray(curve, dtype=np.float64).reshape(256, 3)[:, ::-1], axis=0)  # RGB
    response = as_response(curve.T.tolist(), "the calibrated response")
    return response, _agreement(response, imgs, times)


def _agreement(response: CameraResponse, imgs: list, times: np.ndarray) -> dict | None:
    """`calibrate_response`'s agreement: |log| of the ratio of two successive exposures' light per unit time,
    over the pixels both have well exposed in every channel."""
    lo, hi = WELL_EXPOSED
    order = np.argsort(times)
    ratios = []
    for a, b in zip(order[:-1], order[1:]):
        ia, ib = imgs[a], imgs[b]
        ok = np.all((ia >= lo) & (ia <= hi) & (ib >= lo) & (ib <= hi), axis=-1)
        if ok.any():
            la, lb = response.to_linear(ia[ok]) / times[a], response.to_linear(ib[ok]) / times[b]
            ratios.append(np.abs(np.log(lb / la)).ravel())
    if not ratios:
        return None
    r = np.concatenate(ratios)
    return {"median": float(np.expm1(np.median(r))), "p90": float(np.expm1(np.percentile(r, 90))), "values": len(r)}
