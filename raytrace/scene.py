"""Scene description: `Cube`, `GroundPlane`, `DirectionalLight` and the `Scene` that holds them.

Plain dataclasses in float64 world coordinates (metres); `Cube.mesh()` and `GroundPlane.mesh()`
give the triangles Embree traces, and the analytic data (face planes, checker cells) the
renderer uses to refine and shade those hits in float64.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass, field

import numpy as np

if TYPE_CHECKING:  # trimesh is imported where meshes are made: it costs 0.7 s of start-up
    import trimesh


from ._validate import as_positive, as_rotation, as_unit, as_vector
from .errors import RaytraceError

__all__ = ["Cube", "GroundPlane", "DirectionalLight", "Scene", "FACE_AXES"]

# Local face f (0..5) has outward normal sign * e_axis: +x, -x, +y, -y, +z, -z.
FACE_AXES = ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0))


def _color(value, name: str) -> np.ndarray:
    c = as_vector(value, name)
    if np.any(c < 0):
        raise RaytraceError(f"{name}: expected linear RGB values >= 0, got {c.tolist()}")
    return c


def _face_corners_local(face: int) -> np.ndarray:
    """(4, 3) corners of local face `face` of the unit cube [-1/2, 1/2]³, CCW about its outward normal,
    starting at the corner with negative coordinates along the two next (cyclic) axes."""
    k, s = FACE_AXES[face]
    i, j = (k + 1) % 3, (k + 2) % 3
    ij = [(-1, -1), (1, -1), (1, 1), (-1, 1)] if s > 0 else [(-1, -1), (-1, 1), (1, 1), (1, -1)]
    out = np.zeros((4, 3))
    out[:, k] = s * 0.5
    for n, (a, b) in enumerate(ij):
        out[n, i] = a * 0.5
        out[n, j] = b * 0.5
    return out


@dataclass(frozen=True)
class Cube:
    """An axis-free cube: local vertices (±size/2)³, rotated by `rotation`, moved to `center`.

    Attributes
    ----------
    size : float, edge length in metres
    center : (3,) float64
    rotation : (3, 3) float64, local→world rotation
    color : (3,) float64, linear RGB albedo
    """

    size: float
    center: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    color: np.ndarray = field(default_factory=lambda: np.array([0.8, 0.8, 0.8]))

    def __post_init__(self):
        object.__setattr__(self, "size", as_positive(self.size, "size"))
        object.__setattr__(self, "center", as_vector(self.center, "center"))
        object.__setattr__(self, "rotation", as_rotation(self.rotation, "rotation"))
        object.__setattr__(self, "color", _color(self.color, "color"))

    @classmethod
    def from_euler_deg(cls, size, center, rotation_deg=(0.0, 0.0, 0.0), color=(0.8, 0.8, 0.8)):
        """Cube from the setup file's `rotation_deg` (scipy ``from_euler("xyz", ..., degrees=True)``)."""
        from scipy.spatial.transform import Rotation

        angles = as_vector(rotation_deg, "rotation_deg")
        return cls(size, center, Rotation.from_euler("xyz", angles, degrees=True).as_matrix(), color)

    def vertices(self) -> np.ndarray:
        """(8, 3) float64 world vertices; vertex k has local signs of bits (x: 1, y: 2, z: 4)."""
        k = np.arange(8)
        signs = np.stack([(k & 1) > 0, (k & 2) > 0, (k & 4) > 0], axis=1) * 1.0 - 0.5
        return self.center + (signs * self.size) @ self.rotation.T

    def _slabs(self, origins, directions):
        """The slab test in the cube's frame: the rays' local directions (N, 3), the parameter t at which each
        ray enters each pair of face planes (N, 3; −inf where it runs between a pair, inf where beside it)
        and the one at which it leaves the cube (N,)."""
        o = (np.asarray(origins, dtype=np.float64) - self.center) @ self.rotation
        d = np.asarray(directions, dtype=np.float64) @ self.rotation
        half = self.size / 2.0
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (-half - o) / d, (half - o) / d
        entry = np.where(d == 0, np.where(np.abs(o) <= half, -np.inf, np.inf), np.minimum(t1, t2))
        far = np.where(d == 0, np.where(np.abs(o) <= half, np.inf, -np.inf), np.maximum(t1, t2)).min(axis=1)
        return d, entry, far

    def hits(self, origins, directions) -> np.ndarray:
        """(N,) bool: whether each ray origin + t·direction, t ≥ 0, meets the cube (slab test in the
        cube's frame; a ray parallel to a pair of faces meets it only between them)."""
        _, entry, far = self._slabs(origins, directions)
        near = entry.max(axis=1)
        return (far >= near) & (far >= 0.0)

    def entry_faces(self, origins, directions) -> np.ndarray:
        """(N,) int: the face (0..5, `FACE_AXES`) through which each ray origin + t·direction, t > 0,
        enters the cube, the one it would be seen by; −1 where the ray misses it, starts inside it or
        is not finite. The face is that of the pair of planes the ray enters last."""
        d, entry, far = self._slabs(origins, directions)
        axis = np.argmax(np.nan_to_num(entry, nan=np.inf), axis=1)
        rows = np.arange(len(d))
        near = entry[rows, axis]
        finite = np.all(np.isfinite(np.asarray(origins, dtype=np.float64)) & np.isfinite(d), axis=1)
        seen = (near > 0.0) & (far >= near) & finite
        # entering through the +half plane means moving toward −axis: the face on the + side
        face = 2 * axis + (d[rows, axis] > 0)
        return np.where(seen, face, -1)

    @property
    def face_normals(self) -> np.ndarray:
        """(6, 3) float64 outward world normals of faces 0..5 (+x, −x, +y, −y, +z, −z local)."""
        local = np.zeros((6, 3))
        for f, (k, s) in enumerate(FACE_AXES):
            local[f, k] = s
        return local @ self.rotation.T

    def face_corners(self, face: int) -> np.ndarray:
        """(4, 3) world corners of face `face`, CCW about its outward normal (see `front_face`)."""
        return self.center + (_face_corners_local(face) * self.size) @ self.rotation.T

    def mesh(self) -> "trimesh.Trimesh":
        """12 triangles; triangles 2f and 2f+1 make face f, wound outward."""
        tris = []
        for f in range(6):
            c = self.face_corners(f)
            tris += [c[[0, 1, 2]], c[[0, 2, 3]]]
        tris = np.asarray(tris)
        import trimesh  # only here: importing trimesh costs 0.7 s of every command's start-up
        return trimesh.Trimesh(tris.reshape(-1, 3), np.arange(36).reshape(12, 3), process=False)

    def front_face(self, mirror) -> tuple[int, np.ndarray, np.ndarray]:
        """The face whose outward normal points most toward the mirror axis.

        The direction is from the cube centre to its foot on the mirror axis (perpendicular
        to the axis). Corners are ordered counter-clockwise about the face's outward normal
        (i.e. as seen from the mirror), starting at the corner with negative local coordinates
        along the next two cube axes in cyclic order (x→y,z; y→z,x; z→x,y).

        Returns
        -------
        face : int, 0..5
        corners : (4, 3) float64
        center : (3,) float64
        """
        rel = self.center - mirror.center
        toward = -(rel - (rel @ mirror.axis) * mirror.axis)
        norm = np.linalg.norm(toward)
        if not norm > 0:
            raise RaytraceError("cube: its centre lies on the mirror axis, no face looks toward the mirror")
        face = int(np.argmax(self.face_normals @ (toward / norm)))
        corners = self.face_corners(face)
        return face, corners, corners.mean(axis=0)


@dataclass(frozen=True)
class GroundPlane:
    """A finite checkered square plane.

    Attributes
    ----------
    point : (3,) float64, centre of the square
    normal : (3,) float64, unit (the lit side)
    extent : float, side length of the square, metres
    checker : float, side length of one checker cell, metres
    colors : ((3,), (3,)) linear RGB of the two cell colours
    """

    point: np.ndarray = field(default_factory=lambda: np.array([0.0, -0.25, 0.0]))
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    extent: float = 10.0
    checker: float = 0.05
    colors: tuple = ((0.75, 0.75, 0.75), (0.25, 0.25, 0.25))

    def __post_init__(self):
        object.__setattr__(self, "point", as_vector(self.point, "point"))
        object.__setattr__(self, "normal", as_unit(self.normal, "normal"))
        object.__setattr__(self, "extent", as_positive(self.extent, "extent"))
        object.__setattr__(self, "checker", as_positive(self.checker, "checker"))
        if len(self.colors) != 2:
            raise RaytraceError("colors: expected two RGB colours")
        object.__setattr__(self, "colors", (_color(self.colors[0], "colors[0]"), _color(self.colors[1], "colors[1]")))

    @property
    def basis(self) -> np.ndarray:
        """(2, 3) float64 in-plane unit axes (e1, e2)."""
        n = self.normal
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        e1 = np.cross(helper, n)
        e1 /= np.linalg.norm(e1)
        return np.stack([e1, np.cross(n, e1)])

    def plane_coords(self, points) -> np.ndarray:
        """(N, 2) in-plane coordinates of world points (N, 3)."""
        return (np.asarray(points, dtype=np.float64) - self.point) @ self.basis.T

    def cell_parity(self, points) -> np.ndarray:
        """(N,) int 0/1 checker cell of points (N, 3)."""
        ij = np.floor(self.plane_coords(points) / self.checker).astype(np.int64)
        return (ij[:, 0] + ij[:, 1]) & 1

    def mesh(self) -> "trimesh.Trimesh":
        """Two triangles covering the square, wound toward `normal`."""
        e1, e2 = self.basis * (self.extent / 2)
        p = self.point
        v = np.array([p - e1 - e2, p + e1 - e2, p + e1 + e2, p - e1 + e2])
        import trimesh
        return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


@dataclass(frozen=True)
class DirectionalLight:
    """A light at infinity plus ambient light (Lambertian shading, no shadows).

    radiance = albedo · (ambient + intensity · max(0, n·to_light))

    Attributes
    ----------
    to_light : (3,) float64, unit direction from surfaces toward the light
    intensity : float >= 0
    ambient : float >= 0
    """

    to_light: np.ndarray = field(default_factory=lambda: np.array([0.4, 0.8, 0.6]))
    intensity: float = 0.8
    ambient: float = 0.25

    def __post_init__(self):
        object.__setattr__(self, "to_light", as_unit(self.to_light, "to_light"))
        for name in ("intensity", "ambient"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v >= 0):
                raise RaytraceError(f"{name}: expected a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, v)


@dataclass(frozen=True)
class Scene:
    """A mirror, the objects it reflects, an optional ground plane, a light and a background.

    Attributes
    ----------
    mirror : CylinderMirror | MeshMirror | None
    objects : tuple of Cube; `object_id` in renders indexes this tuple
    ground : GroundPlane | None
    light : DirectionalLight
    background : (3,) float64 linear RGB seen by rays that hit nothing
    """

    mirror: object
    objects: tuple = ()
    ground: GroundPlane | None = None
    light: DirectionalLight = field(default_factory=DirectionalLight)
    background: np.ndarray = field(default_factory=lambda: np.array([0.05, 0.05, 0.08]))

    def __post_init__(self):
        objs = tuple(self.objects)
        for i, o in enumerate(objs):
            if not isinstance(o, Cube):
                raise RaytraceError(f"objects[{i}]: expected a Cube, got {type(o).__name__}")
        object.__setattr__(self, "objects", objs)
        if self.ground is not None and not isinstance(self.ground, GroundPlane):
            raise RaytraceError("ground: expected a GroundPlane or None")
        if not isinstance(self.light, DirectionalLight):
            raise RaytraceError("light: expected a DirectionalLight")
        object.__setattr__(self, "background", _color(self.background, "background"))
