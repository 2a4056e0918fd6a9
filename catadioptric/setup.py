"""Setup files: `Setup` with `CameraConfig`, mirror configs (`CylinderConfig`) and object configs (`CubeConfig`).

The TOML format is the public contract of ../shared/SETUP_FORMAT.md. Every config is a dataclass
with `from_dict`/`to_dict`; mirrors and objects are looked up in a registry by their `type` key.
Validation raises `SetupError` with one line naming the file, the key and what was expected.

Extensions to the contract (all optional, so older files stay valid):
- `[scene]`: `background` (linear RGB), `ground` (bool: a grey checkered ground plane),
  `light_direction` (world vector the light travels along; the default comes from behind the
  camera, above and to the side, so a cube face looking at the mirror is lit and its side
  faces are not lit alike), `ambient` (0..1).
- `[camera] distortion`: the lens's distortion, OpenCV's coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]])
  as `cv2.calibrateCamera` gives them; it must be one-to-one over the image. Absent: an ideal pinhole.
- `[camera] response`: how the image's 8-bit values relate to linear light: "srgb" (the default), "linear", a
  gamma g (stored = light ** (1 / g)), or a table of the light of each of the 256 codes (one list, or 3 for R, G,
  B), as a radiometric calibration gives it (`raytrace.response`).
- `[uncertainty]`: the σ of the setup's numbers (`UncertaintyConfig`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from catadioptric.errors import SetupError

__all__ = [
    "CameraConfig", "CylinderConfig", "CubeConfig", "SceneConfig", "Setup",
    "MIRROR_TYPES", "OBJECT_TYPES", "load_setup", "save_setup", "setup_to_toml",
]


class _Where:
    """Where a value came from: the file name (or '<dict>') and the dotted key path."""

    def __init__(self, source: str, prefix: str = ""):
        self.source, self.prefix = source, prefix

    def key(self, name: str) -> str:
        return f"{self.prefix}{name}"

    def child(self, name: str) -> "_Where":
        return _Where(self.source, f"{self.prefix}{name}.")

    def error(self, name: str, expected: str, got: Any = None, show_got: bool = True) -> SetupError:
        tail = f", got {got!r}" if show_got else ""
        return SetupError(f"{self.source}: {self.key(name)}: expected {expected}{tail}")


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _number(d: dict, name: str, w: _Where, positive=False, lo=None, hi=None, default=None) -> float:
    if name not in d:
        if default is not None:
            return default
        raise w.error(name, "a number (missing key)", show_got=False)
    x = d[name]
    if not _is_number(x) or not math.isfinite(x):
        raise w.error(name, "a finite number", x)
    if positive and x <= 0:
        raise w.error(name, "a positive number", x)
    if lo is not None and x < lo or hi is not None and x > hi:
        raise w.error(name, f"a number in [{lo}, {hi}]", x)
    return float(x)


def _vector(d: dict, name: str, w: _Where, n: int, positive=False, nonzero=False, lo=None, hi=None,
            integer=False, default=None) -> tuple:
    if name not in d:
        if default is not None:
            return default
        raise w.error(name, f"a list of {n} numbers (missing key)", show_got=False)
    x = d[name]
    kind = "integers" if integer else "finite numbers"
    if not isinstance(x, list) or len(x) != n or not all(_is_number(v) for v in x):
        raise w.error(name, f"a list of {n} {kind}", x)
    if integer and not all(isinstance(v, int) for v in x):
        raise w.error(name, f"a list of {n} integers", x)
    if not all(math.isfinite(v) for v in x):
        raise w.error(name, f"a list of {n} finite numbers", x)
    if positive and not all(v > 0 for v in x):
        raise w.error(name, f"a list of {n} positive numbers", x)
    if lo is not None and not all(lo <= v <= hi for v in x):
        raise w.error(name, f"a list of {n} numbers in [{lo}, {hi}]", x)
    if nonzero and math.sqrt(sum(v * v for v in x)) == 0.0:
        raise w.error(name, "a non-zero vector", x)
    return tuple(int(v) if integer else float(v) for v in x)


def _string(d: dict, name: str, w: _Where, choices=None, default=None) -> str:
    if name not in d:
        if default is not None:
            return default
        raise w.error(name, "a string (missing key)", show_got=False)
    x = d[name]
    if not isinstance(x, str) or (choices is not None and x not in choices):
        what = "one of " + ", ".join(f'"{c}"' for c in choices) if choices else "a string"
        raise w.error(name, what, x)
    return x


def _table(d: Any, w: _Where, name: str) -> dict:
    if not isinstance(d, dict):
        raise SetupError(f"{w.source}: {name}: expected a table, got {type(d).__name__}")
    return d


def _no_unknown(d: dict, allowed: set, w: _Where) -> None:
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise SetupError(f"{w.source}: {w.key(unknown[0])}: unknown key "
                         f"(expected one of: {', '.join(sorted(allowed))})")


def _distortion(d: dict, w: _Where) -> tuple[float, ...] | None:
    """`[camera] distortion`: OpenCV's 4, 5 or 8 coefficients, or None where the key is absent."""
    if "distortion" not in d:
        return None
    x = d["distortion"]
    if not isinstance(x, list) or len(x) not in (4, 5, 8) or not all(_is_number(v) for v in x):
        raise w.error("distortion", "a list of 4, 5 or 8 numbers, OpenCV's (k1, k2, p1, p2[, k3[, k4, k5, k6]])", x)
    if not all(math.isfinite(v) for v in x):
        raise w.error("distortion", "a list of finite numbers", x)
    return tuple(float(v) for v in x)


def _boolean(d: dict, name: str, w: _Where, meaning: str) -> bool:
    """An optional true / false key, false where absent."""
    if name not in d:
        return False
    if not isinstance(d[name], bool):
        raise w.error(name, f"true or false ({meaning})", d[name])
    return d[name]


def _response(d: dict, w: _Where):
    """`[camera] response` as a `raytrace.response.CameraResponse`, or None (sRGB) where the key is absent."""
    if "response" not in d:
        return None
    from raytrace.errors import RaytraceError
    from raytrace.response import as_response
    try:
        return as_response(d["response"], w.key("response"))
    except RaytraceError as exc:
        raise SetupError(f"{w.source}: {exc}") from None


def _mosaic(d: dict, w: _Where) -> str | None:
    """`[camera] mosaic`: the Bayer filter tile of a camera whose images are its raw frames, or None where absent.
    Such a frame's values are light (linear): no `response`; and it is demosaiced here, not `demosaiced` already."""
    if "mosaic" not in d:
        return None
    from raytrace.chroma import BAYER_PATTERNS
    expected = "a Bayer filter tile, its 2 × 2 colours row by row: " + ", ".join(f'"{p}"' for p in BAYER_PATTERNS)
    value = d["mosaic"]
    if not isinstance(value, str) or value.upper() not in BAYER_PATTERNS:
        raise w.error("mosaic", expected, value)
    for other, why in (("response", "a raw frame's values are light, linear"),
                       ("demosaiced", "a raw frame is demosaiced by reconstruct")):
        if other in d:
            raise w.error(other, f"no {other} key with camera.mosaic ({why})", d[other])
    return value.upper()


RAW_LEVEL_KEYS = ("black_level", "white_level", "white_balance")
"""`[camera]` keys of a raw Bayer frame's values (with `mosaic` alone)."""


def _raw_levels(d: dict, w: _Where) -> dict:
    """`[camera]`'s black_level, white_level and white_balance (with `mosaic` alone) as CameraConfig's fields."""
    given = [k for k in RAW_LEVEL_KEYS if k in d]
    if not given:
        return {}
    if "mosaic" not in d:
        raise w.error(given[0], "no raw frame's level or gains without camera.mosaic (the images are raw Bayer frames)",
                      d[given[0]])
    black = _number(d, "black_level", w, lo=0.0, hi=65535.0, default=0.0)
    white = _number(d, "white_level", w, lo=0.0, hi=65535.0) if "white_level" in d else None
    if white is not None and not white > black:
        raise w.error("white_level", f"a value above camera.black_level ({black:g})", d["white_level"])
    gains = _vector(d, "white_balance", w, 3, positive=True) if "white_balance" in d else None
    return {"black_level": black, "white_level": white, "white_balance": gains}


@dataclass(frozen=True)
class ChannelConfig:
    """`[camera.red]` or `[camera.blue]`: that colour channel's own intrinsics (lateral chromatic aberration,
    `raytrace.chroma`), each key defaulting to the camera's, which are green's."""

    focal_px: tuple[float, float] | None = None
    principal_px: tuple[float, float] | None = None
    distortion: tuple[float, ...] | None = None

    KEYS: ClassVar[set] = {"focal_px", "principal_px", "distortion"}

    @classmethod
    def from_dict(cls, d: Any, w: _Where, name: str) -> "ChannelConfig":
        d = _table(d, w, w.key(name))
        w = w.child(name)
        _no_unknown(d, cls.KEYS, w)
        if not d:
            raise SetupError(f"{w.source}: {w.prefix.rstrip('.')}: expected at least one of focal_px, principal_px, "
                             "distortion (that channel's own; without the table it is the camera's)")
        return cls(focal_px=_vector(d, "focal_px", w, 2, positive=True) if "focal_px" in d else None,
                   principal_px=_vector(d, "principal_px", w, 2) if "principal_px" in d else None,
                   distortion=_distortion(d, w))

    def to_dict(self) -> dict:
        d = {}
        for key in ("focal_px", "principal_px", "distortion"):
            if getattr(self, key) is not None:
                d[key] = list(getattr(self, key))
        return d

    def build(self, camera: "CameraConfig"):
        """The `raytrace.chroma.ChannelLens` of this channel of `camera`."""
        from raytrace.chroma import ChannelLens
        fx, fy = self.focal_px if self.focal_px is not None else camera.focal_px
        cx, cy = self.principal_px if self.principal_px is not None else camera.principal
        distortion = self.distortion if self.distortion is not None else camera.distortion
        return ChannelLens(np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]), distortion)


@dataclass(frozen=True)
class CameraConfig:
    """The pinhole camera of `[camera]` (OpenCV conventions)."""

    resolution: tuple[int, int]
    focal_px: tuple[float, float]
    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float]
    principal_px: tuple[float, float] | None = None
    distortion: tuple[float, ...] | None = None  # OpenCV's (k1, k2, p1, p2[, k3[, k4, k5, k6]]); None: none
    response: Any = None  # a raytrace.response.CameraResponse; None: sRGB
    red: ChannelConfig | None = None  # that channel's own intrinsics (lateral chromatic aberration); None: green's
    blue: ChannelConfig | None = None
    demosaiced: bool = False  # its images are demosaiced from an RGGB Bayer mosaic
    mosaic: str | None = None  # its images are raw Bayer frames of this filter tile ("RGGB", ...); None: RGB images
    black_level: float = 0.0  # a raw frame's value of no light
    white_level: float | None = None  # its value of full scale; None: its type's maximum (255, 65535)
    white_balance: tuple[float, float, float] | None = None  # its red, green and blue gains; None: 1, 1, 1

    KEYS: ClassVar[set] = {"resolution", "focal_px", "principal_px", "position", "look_at", "up", "distortion",
                           "response", "red", "blue", "demosaiced", "mosaic", "black_level", "white_level",
                           "white_balance"}

    @classmethod
    def from_dict(cls, d: dict, source: str = "<dict>", prefix: str = "camera.") -> "CameraConfig":
        w = _Where(source, prefix)
        d = _table(d, w, prefix.rstrip("."))
        _no_unknown(d, cls.KEYS, w)
        res = _vector(d, "resolution", w, 2, positive=True, integer=True)
        cam = cls(resolution=res,
                  focal_px=_vector(d, "focal_px", w, 2, positive=True),
                  position=_vector(d, "position", w, 3),
                  look_at=_vector(d, "look_at", w, 3),
                  up=_vector(d, "up", w, 3, nonzero=True),
                  principal_px=_vector(d, "principal_px", w, 2) if "principal_px" in d else None,
                  distortion=_distortion(d, w),
                  response=_response(d, w),
                  red=ChannelConfig.from_dict(d["red"], w, "red") if "red" in d else None,
                  blue=ChannelConfig.from_dict(d["blue"], w, "blue") if "blue" in d else None,
                  demosaiced=_boolean(d, "demosaiced", w, "true where the camera's images are demosaiced from an "
                                      "RGGB Bayer mosaic"),
                  mosaic=_mosaic(d, w), **_raw_levels(d, w))
        view = np.subtract(cam.look_at, cam.position)
        if np.linalg.norm(view) == 0:
            raise w.error("look_at", "a point different from camera.position", list(cam.look_at))
        cosang = abs(np.dot(view, cam.up)) / (np.linalg.norm(view) * np.linalg.norm(cam.up))
        if cosang > 1 - 1e-9:
            raise w.error("up", "a direction not parallel to the viewing direction (look_at - position)",
                          list(cam.up))
        if cam.distortion is not None:
            from raytrace.camera import distortion_fold
            from raytrace.lens import as_distortion
            ideal = replace(cam, distortion=None).build()  # (the lens's check, named by this file and key)
            fold = distortion_fold(ideal.resolution, ideal.K, as_distortion(cam.distortion))
            if fold is not None:
                raise w.error("distortion", "coefficients whose distortion is one-to-one over the image (these fold "
                              f"near pixel ({fold[0]:.0f}, {fold[1]:.0f}))", list(cam.distortion))
        for name in ("red", "blue"):
            channel = getattr(cam, name)
            if channel is not None and channel.distortion is not None:
                from raytrace.camera import distortion_fold
                lens = channel.build(cam)
                fold = distortion_fold(cam.resolution, lens.K, lens.distortion)
                if fold is not None:
                    raise w.child(name).error("distortion", "coefficients whose distortion is one-to-one over the "
                                              f"image (these fold near pixel ({fold[0]:.0f}, {fold[1]:.0f}))",
                                              list(channel.distortion))
        return cam

    @property
    def principal(self) -> tuple[float, float]:
        """(cx, cy): `principal_px`, or the image centre ((W-1)/2, (H-1)/2)."""
        if self.principal_px is not None:
            return self.principal_px
        return ((self.resolution[0] - 1) / 2.0, (self.resolution[1] - 1) / 2.0)

    def to_dict(self) -> dict:
        d = {"resolution": list(self.resolution), "focal_px": list(self.focal_px)}
        if self.principal_px is not None:
            d["principal_px"] = list(self.principal_px)
        d.update(position=list(self.position), look_at=list(self.look_at), up=list(self.up))
        if self.distortion is not None:
            d["distortion"] = list(self.distortion)
        if self.response is not None:
            d["response"] = self.response.to_value()
        for name in ("red", "blue"):
            if getattr(self, name) is not None:
                d[name] = getattr(self, name).to_dict()
        if self.demosaiced:
            d["demosaiced"] = True
        if self.mosaic is not None:
            d["mosaic"] = self.mosaic
        if self.black_level:
            d["black_level"] = self.black_level
        if self.white_level is not None:
            d["white_level"] = self.white_level
        if self.white_balance is not None:
            d["white_balance"] = list(self.white_balance)
        return d

    def build(self):
        """The `raytrace.camera.PinholeCamera` of this config."""
        from raytrace.camera import PinholeCamera
        return PinholeCamera.from_look_at(self.resolution, self.focal_px, self.principal,
                                          self.position, self.look_at, self.up, self.distortion, self.response,
                                          red=self.red.build(self) if self.red is not None else None,
                                          blue=self.blue.build(self) if self.blue is not None else None)


@dataclass(frozen=True)
class CylinderConfig:
    """`[mirror]` with type = "cylinder": the open lateral surface of a circular cylinder."""

    radius: float
    height: float
    center: tuple[float, float, float]
    axis: tuple[float, float, float]
    type: str = "cylinder"

    KEYS: ClassVar[set] = {"type", "radius", "height", "center", "axis"}

    @classmethod
    def from_dict(cls, d: dict, source: str = "<dict>", prefix: str = "mirror.") -> "CylinderConfig":
        w = _Where(source, prefix)
        _no_unknown(d, cls.KEYS, w)
        return cls(radius=_number(d, "radius", w, positive=True),
                   height=_number(d, "height", w, positive=True),
                   center=_vector(d, "center", w, 3),
                   axis=_vector(d, "axis", w, 3, nonzero=True))

    def to_dict(self) -> dict:
        return {"type": self.type, "radius": self.radius, "height": self.height,
                "center": list(self.center), "axis": list(self.axis)}

    def build(self):
        """The `raytrace.mirror.CylinderMirror` of this config."""
        from raytrace.mirror import CylinderMirror
        return CylinderMirror(self.radius, self.height, self.center, self.axis)

    def distance_to_axis(self, point) -> float:
        """Distance from a world point to the mirror's axis (metres)."""
        a = np.asarray(self.axis, float) / np.linalg.norm(self.axis)
        p = np.asarray(point, float) - np.asarray(self.center, float)
        return float(np.linalg.norm(p - np.dot(p, a) * a))


@dataclass(frozen=True)
class CubeConfig:
    """`[[objects]]` with type = "cube": edge `size`, `center`, `rotation_deg` (scipy "xyz"), `color`."""

    size: float
    center: tuple[float, float, float]
    rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    color: tuple[float, float, float] = (0.8, 0.8, 0.8)
    type: str = "cube"

    KEYS: ClassVar[set] = {"type", "size", "center", "rotation_deg", "color"}

    @classmethod
    def from_dict(cls, d: dict, source: str = "<dict>", prefix: str = "objects[0].") -> "CubeConfig":
        w = _Where(source, prefix)
        _no_unknown(d, cls.KEYS, w)
        return cls(size=_number(d, "size", w, positive=True),
                   center=_vector(d, "center", w, 3),
                   rotation_deg=_vector(d, "rotation_deg", w, 3, default=(0.0, 0.0, 0.0)),
                   color=_vector(d, "color", w, 3, lo=0.0, hi=1.0, default=(0.8, 0.8, 0.8)))

    def to_dict(self) -> dict:
        return {"type": self.type, "size": self.size, "center": list(self.center),
                "rotation_deg": list(self.rotation_deg), "color": list(self.color)}

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) float64 rotation matrix equal to scipy's Rotation.from_euler("xyz", rotation_deg,
        degrees=True) (extrinsic x, then y, then z: Rz·Ry·Rx), written out because importing
        scipy.spatial costs 0.3 s of every command's start-up."""
        return euler_xyz_matrix(self.rotation_deg)

    def build(self):
        """The `raytrace.scene.Cube` of this config."""
        from raytrace.scene import Cube
        return Cube(self.size, self.center, self.rotation, self.color)


@dataclass(frozen=True)
class SceneConfig:
    """Optional `[scene]` (an extension of the contract): background, ground plane and lighting."""

    background: tuple[float, float, float] = (0.85, 0.85, 0.85)
    ground: bool = False
    light_direction: tuple[float, float, float] = (-0.25, -0.45, 0.85)
    ambient: float = 0.35

    KEYS: ClassVar[set] = {"background", "ground", "light_direction", "ambient"}

    @classmethod
    def from_dict(cls, d: dict, source: str = "<dict>", prefix: str = "scene.") -> "SceneConfig":
        w = _Where(source, prefix)
        d = _table(d, w, prefix.rstrip("."))
        _no_unknown(d, cls.KEYS, w)
        ground = d.get("ground", cls.ground)
        if not isinstance(ground, bool):
            raise w.error("ground", "true or false", ground)
        return cls(background=_vector(d, "background", w, 3, lo=0.0, hi=1.0, default=cls.background),
                   ground=ground,
                   light_direction=_vector(d, "light_direction", w, 3, nonzero=True,
                                           default=cls.light_direction),
                   ambient=_number(d, "ambient", w, lo=0.0, hi=1.0, default=cls.ambient))

    def to_dict(self) -> dict:
        return {"background": list(self.background), "ground": self.ground,
                "light_direction": list(self.light_direction), "ambient": self.ambient}


@dataclass(frozen=True)
class UncertaintyConfig:
    """Optional `[uncertainty]` (an extension of the contract): the σ of the setup's own measured numbers, which
    `reconstruct` carries into each cube's σ (`depth.setup_error`). Each key is optional, ≥ 0, and 0 by default
    (that number taken as exact)."""

    camera_position: float = 0.0  # metres, each coordinate, the camera's turn held (look_at moved with it)
    camera_rotation_deg: float = 0.0  # about each of the camera's own axes
    focal_px: float = 0.0  # fx and fy each
    principal_px: float = 0.0  # cx and cy each
    mirror_radius: float = 0.0  # metres
    mirror_center: float = 0.0  # metres, each coordinate
    mirror_axis_deg: float = 0.0  # the axis's tilt about each of two directions square to it
    distortion: tuple = ()  # each of [camera] distortion's coefficients (k1, k2, p1, p2, k3, k4, k5, k6), up to 8

    KEYS: ClassVar[tuple] = ("camera_position", "camera_rotation_deg", "focal_px", "principal_px", "mirror_radius",
                             "mirror_center", "mirror_axis_deg")

    @classmethod
    def from_dict(cls, d: dict, source: str = "<dict>", prefix: str = "uncertainty.") -> "UncertaintyConfig":
        w = _Where(source, prefix)
        d = _table(d, w, prefix.rstrip("."))
        _no_unknown(d, {*cls.KEYS, "distortion"}, w)
        values = {key: _number(d, key, w, default=0.0) for key in cls.KEYS}
        for key, value in values.items():
            if value < 0:
                raise w.error(key, "a σ >= 0", value)
        if "distortion" in d:
            x = d["distortion"]
            if not isinstance(x, list) or not 1 <= len(x) <= 8 or not all(_is_number(v) and math.isfinite(v) and v >= 0
                                                                          for v in x):
                raise w.error("distortion", "a list of 1 to 8 σ >= 0, one per coefficient of camera.distortion "
                              "(k1, k2, p1, p2, k3, k4, k5, k6)", x)
            values["distortion"] = tuple(float(v) for v in x)
        return cls(**values)

    def to_dict(self) -> dict:
        d = {key: getattr(self, key) for key in self.KEYS if getattr(self, key) != 0.0}
        if self.distortion:
            d["distortion"] = list(self.distortion)
        return d

    def build(self):
        """The `depth.setup_error.SetupStd` of this table."""
        from depth.setup_error import SetupStd
        return SetupStd(**{key: getattr(self, key) for key in self.KEYS}, distortion=self.distortion)


def euler_xyz_matrix(angles_deg) -> np.ndarray:
    """Rz(γ)·Ry(β)·Rx(α) for extrinsic "xyz" angles (α, β, γ) in degrees : (3, 3) float64."""
    a, b, g = np.deg2rad(np.asarray(angles_deg, dtype=np.float64))
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
    ry = np.array([[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]])
    rz = np.array([[cg, -sg, 0.0], [sg, cg, 0.0], [0.0, 0.0, 1.0]])
    return rz @ ry @ rx


MIRROR_TYPES: dict[str, type] = {"cylinder": CylinderConfig}
OBJECT_TYPES: dict[str, type] = {"cube": CubeConfig}
TOP_KEYS = {"units", "camera", "mirror", "objects", "scene", "uncertainty"}


@dataclass(frozen=True)
class Setup:
    """A whole setup file: camera, mirror, objects (used by `simulate` only) and optional scene."""

    camera: CameraConfig
    mirror: CylinderConfig | None
    objects: tuple = ()
    scene: SceneConfig = field(default_factory=SceneConfig)
    units: str = "m"
    uncertainty: UncertaintyConfig | None = None

    @classmethod
    def from_dict(cls, d: dict, source: str = "<dict>", require_mirror: bool = True,
                  check_geometry: bool = True) -> "Setup":
        """Validate a parsed setup dictionary. `source` names the file in error messages."""
        w = _Where(source)
        _no_unknown(d, TOP_KEYS, w)
        units = _string(d, "units", w, choices=("m",), default="m")
        if "camera" not in d:
            raise SetupError(f"{source}: camera: missing table [camera]")
        camera = CameraConfig.from_dict(d["camera"], source)
        mirror = None
        if "mirror" in d:
            md = _table(d["mirror"], w, "mirror")
            mtype = _string(md, "type", w.child("mirror"), choices=tuple(MIRROR_TYPES))
            mirror = MIRROR_TYPES[mtype].from_dict(md, source)
        elif require_mirror:
            raise SetupError(f"{source}: mirror: missing table [mirror] (expected a mirror, e.g. type = \"cylinder\")")
        objects = []
        raw = d.get("objects", [])
        if not isinstance(raw, list):
            raise SetupError(f"{source}: objects: expected an array of tables [[objects]]")
        for i, od in enumerate(raw):
            prefix = f"objects[{i}]."
            od = _table(od, w, prefix.rstrip("."))
            otype = _string(od, "type", w.child(f"objects[{i}]"), choices=tuple(OBJECT_TYPES))
            objects.append(OBJECT_TYPES[otype].from_dict(od, source, prefix))
        scene = SceneConfig.from_dict(d["scene"], source) if "scene" in d else SceneConfig()
        uncertainty = UncertaintyConfig.from_dict(d["uncertainty"], source) if "uncertainty" in d else None
        setup = cls(camera=camera, mirror=mirror, objects=tuple(objects), scene=scene, units=units,
                    uncertainty=uncertainty)
        if check_geometry and mirror is not None:
            setup._check_geometry(source)
        return setup

    def to_dict(self) -> dict:
        d: dict = {"units": self.units, "camera": self.camera.to_dict()}
        if self.mirror is not None:
            d["mirror"] = self.mirror.to_dict()
        if self.scene != SceneConfig():
            d["scene"] = self.scene.to_dict()
        if self.uncertainty is not None:
            d["uncertainty"] = self.uncertainty.to_dict()
        if self.objects:
            d["objects"] = [o.to_dict() for o in self.objects]
        return d

    def _check_geometry(self, source: str) -> None:
        """A camera inside the mirror, or a mirror the camera does not see, is an error."""
        m = self.mirror
        if m.distance_to_axis(self.camera.position) <= m.radius:
            raise SetupError(f"{source}: camera.position: expected a point outside the mirror "
                             f"(distance to the axis > mirror.radius = {m.radius}), got {list(self.camera.position)}")
        camera, mirror = self.camera.build(), m.build()
        w, h = self.camera.resolution
        gu, gv = np.meshgrid(np.linspace(0, w - 1, 48), np.linspace(0, h - 1, 36))
        origins, dirs = camera.rays(np.column_stack([gu.ravel(), gv.ravel()]))
        hit = mirror.intersect(origins, dirs)[1]
        if not np.any(hit):
            raise SetupError(f"{source}: camera.look_at: expected the camera to look at the mirror "
                             f"(no pixel of the image sees it)")

    def build_scene(self):
        """The `raytrace.scene.Scene` of this setup (mirror, cubes, background, ground, light)."""
        from raytrace import scene as rs
        m = self.mirror
        ground = None
        if self.scene.ground:
            axis = np.asarray(m.axis, float) / np.linalg.norm(m.axis)
            up = axis if np.dot(axis, self.camera.up) >= 0 else -axis
            ground = rs.GroundPlane(point=np.asarray(m.center, float) - up * m.height / 2.0, normal=up,
                                    checker=0.1)
        light = rs.DirectionalLight(to_light=-np.asarray(self.scene.light_direction, float),
                                    ambient=self.scene.ambient)
        return rs.Scene(mirror=m.build(), objects=tuple(o.build() for o in self.objects),
                        ground=ground, light=light, background=self.scene.background)


def load_setup(path, require_mirror: bool = True) -> Setup:
    """Read and validate a setup TOML file; any problem is a one-line `SetupError` naming the file."""
    path = Path(path)
    name = str(path)
    if not path.exists():
        raise SetupError(f"{name}: no such setup file")
    if path.is_dir():
        raise SetupError(f"{name}: expected a setup file (TOML), got a directory")
    try:
        with path.open("rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise SetupError(f"{name}: invalid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SetupError(f"{name}: cannot read setup file: {exc}") from None
    return Setup.from_dict(data, source=name, require_mirror=require_mirror)


def setup_to_toml(setup: Setup) -> str:
    """The TOML text of a setup (round-trips through `load_setup`)."""
    import tomli_w
    return tomli_w.dumps(setup.to_dict())


def save_setup(setup: Setup, path) -> None:
    """Write a setup as TOML."""
    Path(path).write_text(setup_to_toml(setup))
