"""The setup's own uncertainty, carried into each cube's σ.

A setup file's numbers are measured: the camera's place and turn, its focal lengths, principal point and lens
distortion, the mirror's radius, place and axis. `exact`'s σ counts the edges' noise alone, as if the setup were
exact. A setup off by a millimetre moves every edge point's reflected ray, and with them the fitted cube.

`exact`, asked for them (`estimate_face(..., ray_slopes=True)`), gives how its reading moves per unit of each
edge point's ray (`CubeEstimate.ray_slopes`: the pose re-solved to first order, as `size_slope` re-solves it as
the size moves). Each setup parameter moved by ±1 σ moves the points' rays, traced again through the camera and
the mirror so moved; the reading's move is their sum through those slopes, half the difference between +σ and
−σ: one σ of that parameter's effect. The parameters are taken as independent of each other; their effects add
in quadrature. The depth is the distance from the mirror's axis, so a parameter that moves the axis moves it
also through the axis: a camera and mirror moved together move the cube with them and its depth not at all.
`exact` fits a face upright along the mirror's axis (the scene's vertical) unless its edges say otherwise, so a
turn of the axis also turns the frame such a face turns in (`ray_slopes`' second part).

The setup's errors are common to every cube of an image: their shares of the cubes' σ are not independent
from cube to cube, unlike the edges' noise.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from depth.errors import DepthError
from depth.estimate import CubeEstimate


@dataclass(frozen=True)
class SetupStd:
    """The σ of each of a setup's measured numbers (0: taken as exact).

    camera_position : metres, each coordinate of the camera's centre, its turn held (its look_at moved with it)
    camera_rotation_deg : degrees, the camera's turn about each of its own axes (x right, y down, z forward)
    focal_px : pixels, each of fx and fy
    principal_px : pixels, each of cx and cy
    mirror_radius : metres
    mirror_center : metres, each coordinate of the mirror's centre
    mirror_axis_deg : degrees, the axis's tilt about each of two directions square to it
    distortion : the σ of each of the lens's distortion coefficients in OpenCV's order (k1, k2, p1, p2, k3, k4, k5,
        k6; `raytrace.lens`), up to 8 (those left out 0); about a lens without distortion, the ideal one's
    """

    camera_position: float = 0.0
    camera_rotation_deg: float = 0.0
    focal_px: float = 0.0
    principal_px: float = 0.0
    mirror_radius: float = 0.0
    mirror_center: float = 0.0
    mirror_axis_deg: float = 0.0
    distortion: tuple = ()

    def __post_init__(self):
        d = self.distortion
        if not isinstance(d, (tuple, list, np.ndarray)) or len(d) > 8 or not all(
                not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating)) and np.isfinite(v)
                and v >= 0 for v in d):
            raise DepthError(f"setup_std.distortion: expected up to 8 σ >= 0 (k1, k2, p1, p2, k3, k4, k5, k6), "
                             f"got {d!r}")
        object.__setattr__(self, "distortion", tuple(float(v) for v in d))
        for f in fields(self):
            if f.name == "distortion":
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not (
                    np.isfinite(value) and value >= 0):
                raise DepthError(f"setup_std.{f.name}: expected a σ >= 0, got {value!r}")
            object.__setattr__(self, f.name, float(value))

    def items(self) -> list:
        """(name, σ) of the parameters whose σ is not 0 (the distortion's, a list of its coefficients' σ)."""
        def has(name):
            return any(self.distortion) if name == "distortion" else getattr(self, name) > 0
        return [(f.name, list(self.distortion) if f.name == "distortion" else getattr(self, f.name))
                for f in fields(self) if has(f.name)]

    def components(self) -> list:
        """(name, k, σ) of each component with a σ, each moved on its own by `moved`: a number's σ for each of its
        components (`_COMPONENTS`), the distortion's own for each coefficient."""
        out = []
        for name, sigma in self.items():
            if name == "distortion":
                out += [(name, k, s) for k, s in enumerate(sigma) if s > 0]
            else:
                out += [(name, k, sigma) for k in range(_COMPONENTS[name])]
        return out


def moved(camera, mirror, name: str, k: int, delta: float):
    """(camera, mirror) with parameter `name`'s k-th component moved by delta (its unit)."""
    from scipy.spatial.transform import Rotation  # (not at import: the command's start-up does without scipy)

    if name == "camera_position":
        return replace(camera, position=camera.position + delta * np.eye(3)[k]), mirror
    if name == "camera_rotation_deg":
        turn = Rotation.from_rotvec(np.deg2rad(delta) * camera.R[k]).as_matrix()  # about the camera's own axis k
        return replace(camera, R=camera.R @ turn.T), mirror
    if name in ("focal_px", "principal_px"):
        K = camera.K.copy()
        K[k, k if name == "focal_px" else 2] += delta
        return replace(camera, K=K), mirror
    if name == "distortion":
        from raytrace.errors import RaytraceError
        coeffs = np.zeros(8) if camera.distortion is None else camera.distortion.copy()
        coeffs[k] += delta
        try:
            return replace(camera, distortion=coeffs), mirror
        except RaytraceError as exc:
            raise DepthError(f"setup_std.distortion: coefficient {k} moved by {delta:+g} folds the lens over the "
                             f"image ({exc})") from None
    if name == "mirror_radius":
        return camera, replace(mirror, radius=mirror.radius + delta)
    if name == "mirror_center":
        return camera, replace(mirror, center=mirror.center + delta * np.eye(3)[k])
    # mirror_axis_deg: about the frame's k-th direction square to the axis
    turn = Rotation.from_rotvec(np.deg2rad(delta) * mirror.frame[k]).as_matrix()
    return camera, replace(mirror, axis=turn @ mirror.axis)


_COMPONENTS = {"camera_position": 3, "camera_rotation_deg": 3, "focal_px": 2, "principal_px": 2, "mirror_radius": 1,
               "mirror_center": 3, "mirror_axis_deg": 2}
"""How many components each number of `SetupStd` has (each moved on its own by `moved`)."""


def drawn(camera, mirror, std: SetupStd, rng):
    """(camera, mirror) with each component of each number of `std` drawn off by N(0, its σ) (`rng`, a numpy
    Generator): a setup as it might have been measured."""
    for name, k, sigma in std.components():
        camera, mirror = moved(camera, mirror, name, k, rng.normal(0.0, sigma))
    return camera, mirror


def _along_size(est: CubeEstimate, d_size: float) -> np.ndarray:
    """The move (5,) of `est`'s centre (3), size and z as its size moves by `d_size`, its pose along `size_slope`."""
    slope = est.size_slope
    return np.r_[d_size * np.asarray(slope["center"]), d_size, d_size * slope["z"]]


def setup_effects(est: CubeEstimate, camera, mirror, std: SetupStd) -> list:
    """Per setup parameter component with a σ: (name, k, the move of the centre (3), size, z and depth (6,) at one
    σ of it, half the difference between +σ and −σ). `est` must carry its `ray_slopes`."""
    from raytrace.truth import mirror_rays

    if est.ray_slopes is None:
        raise DepthError(f"setup_std: carried through method exact's fit alone, not {est.method}'s")
    if not all(hasattr(mirror, key) for key in ("radius", "center", "axis")):
        raise DepthError("setup_std: carried through a cylindrical mirror's radius, centre and axis; this mirror "
                         "has none")

    def traced(cam, mir, pix):
        r = mirror_rays(cam, mir, pix)
        return np.concatenate([r.points, r.directions], axis=1)

    # each reading whose rays move it: this one's, and those of the sizes a common size was fused from
    readings = [est.ray_slopes] + [rs for rs, _ in est.common_size_from or ()]
    held = [~np.all(np.isfinite(traced(camera, mirror, pix)), axis=1) for pix, _, _ in readings]

    def reading_move(j, name, k, sigma, plus, minus):
        """The move (5,) at one σ of reading j (of `readings`), its pose re-solved."""
        pix, slopes, up_slopes = readings[j]
        # a point whose ray leaves the mirror either way is held where it was
        delta = np.nan_to_num(0.5 * (traced(*plus, pix) - traced(*minus, pix)), nan=0.0, posinf=0.0, neginf=0.0)
        delta[held[j]] = 0.0
        move = np.einsum("fnc,nc->f", slopes, delta)
        if name == "mirror_axis_deg":  # the scene's vertical, the axis, turns too: an upright face with it
            move += up_slopes @ (np.deg2rad(sigma) * mirror.frame[k])
        return move

    out = []
    for name, k, sigma in std.components():
        plus, minus = moved(camera, mirror, name, k, sigma), moved(camera, mirror, name, k, -sigma)
        move = reading_move(0, name, k, sigma, plus, minus)
        if est.common_size_from is not None:  # the common size moves as the sizes it was fused from
            move += _along_size(est, sum(w * reading_move(j, name, k, sigma, plus, minus)[3]
                                         for j, (_, w) in enumerate(est.common_size_from, start=1)))
        if est.on_floor is not None:
            move += _floor_move(est, mirror, plus[1], minus[1], move)
        depths = [m.distance_to_axis((est.center + sgn * move[:3])[None])[0]
                  for sgn, (_, m) in ((1.0, plus), (-1.0, minus))]
        out.append((name, k, np.r_[move, 0.5 * (depths[0] - depths[1])]))
    return out


def _floor_move(est: CubeEstimate, mirror, plus, minus, move) -> np.ndarray:
    """A cube read standing on the floor (`estimate_face_on_floor`): the further move of its centre (3), size and z
    (5,) as a setup number moves the reading at its size by `move` (5+) and the mirror from `mirror` to `plus` and
    `minus` (±1 σ). The floor stays where it is along the mirror's axis from the mirror's centre (as `reconstruct`'s
    `floor_height` places it) and square to the axis, so it moves and turns with the mirror; the size moves until
    the cube's bottom is on it again: by −(the bottom's height over the floor's move) / (its rate per metre of
    size), and the pose with it (`size_slope`)."""
    point, up, rate = est.on_floor
    sign = 1.0 if up @ mirror.axis >= 0 else -1.0
    height = (point - mirror.center) @ mirror.axis
    ends = [(m.center + height * m.axis, sign * m.axis) for m in (plus, minus)]
    d_point, d_up = 0.5 * (ends[0][0] - ends[1][0]), 0.5 * (ends[0][1] - ends[1][1])
    d_gap = up @ move[:3] + (est.center - point) @ d_up - up @ d_point  # at the reading's size
    return _along_size(est, -d_gap / rate)


def with_setup_std(est: CubeEstimate, camera, mirror, std: SetupStd) -> CubeEstimate:
    """`est` with the setup's σ carried into its own: each σ ('z' is the depth's, 'size', 'center') in quadrature
    with the setup's share (`setup_effects`), which `CubeEstimate.setup_std` keeps apart ('depth', 'size',
    'center')."""
    effects = setup_effects(est, camera, mirror, std)
    var = np.sum([e ** 2 for _, _, e in effects], axis=0) if effects else np.zeros(6)
    share = {"depth": float(np.sqrt(var[5])), "size": float(np.sqrt(var[3])), "center": float(np.sqrt(var[:3].sum()))}
    return replace(est, std={**est.std, "z": float(np.hypot(est.std["z"], share["depth"])),
                             "size": float(np.hypot(est.std["size"], share["size"])),
                             "center": float(np.hypot(est.std["center"], share["center"]))}, setup_std=share)
