"""Off-screen 3D views of a setup and its reconstruction: `SceneModel`, `render_view` returning a `View`.

A `SceneModel` holds what is drawn (camera and frustum, cylinder mirror, a sparse fan of camera
rays and their reflections, each cube's two local virtual slits, reconstructed cubes as solids and
true cubes as outlines); `render_view` renders it with pyvista off-screen (no display, no GPU) from
an oblique viewpoint (`"perspective"`) or from above along the mirror axis (`"top"`, parallel
projection with rings of equal distance from the axis). The `View` keeps the world→pixel
projection of the rendered camera, so callers (and tests) can say where a world point landed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MIRROR_COLOR", "INCIDENT_COLOR", "REFLECTED_COLOR", "SLIT_COLORS", "BACKGROUND",
           "CubeSolid", "SceneModel", "View", "scene_model", "render_view", "cube_from_result",
           "cube_from_truth", "cube_palette"]

MIRROR_COLOR = (0.45, 0.72, 1.0)       # light blue: the mirror
INCIDENT_COLOR = (1.0, 0.62, 0.0)      # orange: camera → mirror
REFLECTED_COLOR = (0.95, 0.25, 0.15)   # red: mirror → scene
SLIT_COLORS = ((0.0, 0.55, 0.25), (0.55, 0.0, 0.75))  # slit 1 (along the axis) green, slit 2 purple
CAMERA_COLOR = (0.15, 0.15, 0.15)
TRUTH_COLOR = (0.0, 0.0, 0.0)
BACKGROUND = (1.0, 1.0, 1.0)


def cube_palette(n: int) -> list[tuple[float, float, float]]:
    """n distinct colours (matplotlib's tab10), the same in every picture of a report."""
    base = [(0.12, 0.47, 0.71), (1.0, 0.50, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
            (0.58, 0.40, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.50, 0.50, 0.50),
            (0.74, 0.74, 0.13), (0.09, 0.75, 0.81)]
    return [base[i % len(base)] for i in range(n)]


@dataclass(frozen=True)
class CubeSolid:
    """A cube to draw. vertices : (8, 3) float64 in VTK hexahedron order (a face, then the face behind it)."""

    vertices: np.ndarray
    color: tuple = (0.5, 0.5, 0.5)
    label: str = ""


@dataclass
class SceneModel:
    """Everything a 3D view draws, in world metres.

    incident, reflected : (N, 2, 3) float64 line segments of the ray fan
    slits : list of ((2, 3) float64 segment, slit index 0 or 1)
    cubes : reconstructed cubes (solids); truth : true cubes (outlines)
    frustum : (5, 3) float64, camera centre then the four image corners at `frustum_depth`
    """

    camera: object
    mirror: object
    frustum: np.ndarray
    incident: np.ndarray
    reflected: np.ndarray
    slits: list = field(default_factory=list)
    cubes: list = field(default_factory=list)
    truth: list = field(default_factory=list)
    rings: tuple = ()


@dataclass(frozen=True)
class View:
    """A rendered view. image : (H, W, 3) uint8 RGB; projection : (4, 4) world → clip coordinates;
    eye : (3,) the viewpoint (world)."""

    image: np.ndarray
    projection: np.ndarray
    eye: np.ndarray

    def project(self, points) -> np.ndarray:
        """Pixel positions (u, v) = (column, row) of world points : (N, 3) → (N, 2) float64."""
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        clip = np.column_stack([p, np.ones(len(p))]) @ self.projection.T
        ndc = clip[:, :2] / clip[:, 3:4]
        h, w = self.image.shape[:2]
        return np.column_stack([(ndc[:, 0] + 1) / 2 * w - 0.5, (1 - ndc[:, 1]) / 2 * h - 0.5])


def _hexahedron(corners: np.ndarray, back: np.ndarray) -> np.ndarray:
    return np.concatenate([corners, back]).astype(np.float64)


def cube_from_truth(truth_cube: dict) -> np.ndarray | None:
    """(8, 3) vertices of a true cube from `simulate`'s truth (front-face corners and centre), or None."""
    corners = np.asarray(truth_cube.get("front_face_corners", []), dtype=np.float64)
    center = np.asarray(truth_cube.get("center", []), dtype=np.float64)
    if corners.shape != (4, 3) or center.shape != (3,) or not np.all(np.isfinite(corners)):
        return None
    back = 2 * center - corners[[2, 3, 0, 1]]  # the corner behind c_i is opposite c_{i+2}
    return _hexahedron(corners, back)


def cube_from_result(cube: dict, camera, mirror) -> np.ndarray:
    """(8, 3) vertices of a reconstructed cube from its result keys.

    The face plane is given by `front_face_center` and `front_face_normal`; its in-plane turn comes
    from the reflected rays of `front_face_corners_px` met with that plane (the mirror axis when a
    corner's ray misses).
    """
    from raytrace.truth import mirror_rays
    c = np.asarray(cube["front_face_center"], dtype=np.float64)
    n = np.asarray(cube.get("front_face_normal", np.nan * np.ones(3)), dtype=np.float64)
    size = float(cube["size"])
    if not np.all(np.isfinite(n)):  # no normal in the file: the face looks at the mirror axis
        r = mirror.radial_vectors(c[None])[0]
        n = -r / np.linalg.norm(r)
    n = n / np.linalg.norm(n)
    u = np.asarray(mirror.axis, dtype=np.float64)
    px = np.asarray(cube.get("front_face_corners_px", []), dtype=np.float64)
    if px.shape == (4, 2) and np.all(np.isfinite(px)):
        rays = mirror_rays(camera, mirror, px)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((c - rays.points) @ n) / (rays.directions @ n)
        p = rays.points + t[:, None] * rays.directions
        if np.all(np.isfinite(p)) and np.all(t > 0):
            side = (p[3] - p[0] + p[2] - p[1]) / 2  # corners run TL, TR, BR, BL: left/right sides
            if np.linalg.norm(side) > 0:
                u = side
    u = u - (u @ n) * n
    if np.linalg.norm(u) < 1e-9:
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    h = size / 2
    corners = c + h * np.array([-u - w, u - w, u + w, -u + w])
    return _hexahedron(corners, corners - size * n)


def _fan_pixels(camera, mirror, rows: int, cols: int) -> np.ndarray:
    """A sparse grid of pixels that see the mirror, spread over the mirror's image : (N, 2)."""
    from raytrace.truth import mirror_rays
    w, h = camera.resolution
    gu, gv = np.meshgrid(np.linspace(0, w - 1, 64), np.linspace(0, h - 1, 48))
    px = np.column_stack([gu.ravel(), gv.ravel()])
    hit = mirror_rays(camera, mirror, px).hit
    if not hit.any():
        return np.zeros((0, 2))
    lo, hi = px[hit].min(axis=0), px[hit].max(axis=0)
    inset = (hi - lo) * 0.04
    gu, gv = np.meshgrid(np.linspace(lo[0] + inset[0], hi[0] - inset[0], cols),
                         np.linspace(lo[1] + inset[1], hi[1] - inset[1], rows))
    return np.column_stack([gu.ravel(), gv.ravel()])


def scene_model(camera, mirror, cubes=(), truth=(), slits=(), reach: float | None = None,
                fan=(4, 7), rings=None) -> SceneModel:
    """Build what a view draws.

    Parameters
    ----------
    camera : raytrace.camera.PinholeCamera
    mirror : raytrace.mirror.CylinderMirror
    cubes : list of CubeSolid (reconstructed); truth : list of (8, 3) vertex arrays (outlines)
    slits : list of ((2, 3) segment, slit index)
    reach : length of the reflected ray segments in metres (default: to the farthest cube)
    fan : (rows, columns) of the ray fan over the mirror's image
    rings : distances from the mirror axis (metres) drawn as rings in the top view
    """
    from raytrace.truth import mirror_rays
    w, h = camera.resolution
    d_axis = float(mirror.distance_to_axis(camera.position[None])[0])
    corners_px = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], dtype=np.float64)
    o, d = camera.rays(corners_px)
    zc = d @ camera.R[2]
    frustum = np.vstack([camera.position, o + d * (0.75 * d_axis / zc)[:, None]])
    px = _fan_pixels(camera, mirror, *fan)
    r = mirror_rays(camera, mirror, px)
    ok = r.hit
    pts, dirs = r.points[ok], r.directions[ok]
    if reach is None:
        far = [float(mirror.distance_to_axis(v.mean(axis=0)[None])[0]) for v in
               [c.vertices for c in cubes] + list(truth)]
        reach = 1.1 * max(far) if far else 2.0 * d_axis
    incident = np.stack([np.broadcast_to(camera.position, pts.shape), pts], axis=1)
    reflected = np.stack([pts, pts + reach * dirs], axis=1)
    if rings is None:
        far = reach + mirror.radius
        step = 0.25 if far > 0.6 else 0.1
        rings = tuple(np.arange(step, far + 1e-9, step))
    return SceneModel(camera=camera, mirror=mirror, frustum=frustum, incident=incident,
                      reflected=reflected, slits=list(slits), cubes=list(cubes), truth=list(truth),
                      rings=tuple(float(x) for x in rings))


def _quiet_vtk() -> None:
    """VTK warns on stderr when it falls back from X to off-screen rendering; the CLI prints one line."""
    from vtkmodules.vtkCommonCore import vtkLogger, vtkObject  # vtk comes with pyvista
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    vtkObject.GlobalWarningDisplayOff()


def _segments(pv, seg: np.ndarray):
    """pyvista PolyData of line segments (N, 2, 3)."""
    seg = np.asarray(seg, dtype=np.float64).reshape(-1, 2, 3)
    n = len(seg)
    lines = np.column_stack([np.full(n, 2), 2 * np.arange(n), 2 * np.arange(n) + 1]).ravel()
    return pv.PolyData(seg.reshape(-1, 3), lines=lines)


def _hex_grid(pv, vertices: np.ndarray):
    import vtk
    cells = np.concatenate([[8], np.arange(8)])
    return pv.UnstructuredGrid(cells, np.array([vtk.VTK_HEXAHEDRON]), np.asarray(vertices, dtype=np.float64))


def _ring(mirror, radius: float, n: int = 180) -> np.ndarray:
    e1, e2, a = mirror.frame
    phi = np.linspace(0, 2 * np.pi, n + 1)
    top = mirror.center + a * 0.0
    pts = top + radius * (np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2))
    return np.stack([pts[:-1], pts[1:]], axis=1)


def render_view(model: SceneModel, kind: str = "perspective", window_size=(1200, 800)) -> View:
    """Render the model off-screen; kind is "perspective" (oblique) or "top" (along the mirror axis)."""
    import pyvista as pv
    from catadioptric.errors import CatadioptricError
    if kind not in ("perspective", "top"):
        raise CatadioptricError(f"kind: expected 'perspective' or 'top', got {kind!r}")
    _quiet_vtk()
    m, cam = model.mirror, model.camera
    axis = np.asarray(m.axis, dtype=np.float64)
    up = axis if np.dot(axis, cam.R[1]) <= 0 else -axis  # image "up" is −y of the camera
    p = pv.Plotter(off_screen=True, window_size=tuple(int(x) for x in window_size))
    try:
        p.set_background(BACKGROUND)
        # The mirror is an open surface; from above, its footprint is drawn as a filled disc.
        p.add_mesh(pv.Cylinder(center=m.center, direction=axis, radius=m.radius, height=m.height,
                               capping=kind == "top", resolution=180),
                   color=MIRROR_COLOR, smooth_shading=True, specular=0.2, ambient=0.35, diffuse=0.65,
                   opacity=0.45 if kind == "perspective" else 1.0)
        if len(model.incident):
            p.add_mesh(_segments(pv, model.incident), color=INCIDENT_COLOR, line_width=2)
            p.add_mesh(_segments(pv, model.reflected), color=REFLECTED_COLOR, line_width=1.5, opacity=0.6)
        f = model.frustum
        p.add_mesh(_segments(pv, np.array([[f[0], f[i]] for i in range(1, 5)] +
                                          [[f[i], f[1 + i % 4]] for i in range(1, 5)])),
                   color=CAMERA_COLOR, line_width=2)
        p.add_mesh(pv.Sphere(radius=0.012, center=cam.position), color=CAMERA_COLOR)
        for seg, k in model.slits:  # tubes, so that they show through the half-transparent mirror
            a, b = np.asarray(seg, dtype=np.float64)
            p.add_mesh(pv.Tube(pointa=a, pointb=b, radius=0.005, resolution=1, n_sides=12),
                       color=SLIT_COLORS[k], ambient=0.4)
        for c in model.cubes:
            p.add_mesh(_hex_grid(pv, c.vertices), color=c.color, ambient=0.3, diffuse=0.7)
        for v in model.truth:
            p.add_mesh(_hex_grid(pv, v).extract_all_edges(), color=TRUTH_COLOR, line_width=2)
        labelled = [c for c in model.cubes if c.label]
        if labelled:
            p.add_point_labels(np.array([c.vertices.mean(axis=0) for c in labelled]) + 0.03 * up,
                               [c.label for c in labelled], font_size=14 if kind == "top" else 12,
                               shape_opacity=0.6, show_points=False, always_visible=True)
        # Frame the camera, the mirror and the cubes (rays may leave the picture).
        e1, e2, _ = m.frame
        rim = m.center + m.radius * np.array([e1, -e1, e2, -e2])
        allp = np.vstack([f, rim + axis * m.height / 2, rim - axis * m.height / 2]
                         + [c.vertices for c in model.cubes] + list(model.truth))
        if kind == "top":
            ring_pts = []
            for r in model.rings:
                p.add_mesh(_segments(pv, _ring(m, r)), color=(0.6, 0.6, 0.6), line_width=1)
                ring_pts.append(m.center + r * _label_dir(m, cam))
            if model.rings:
                p.add_point_labels(np.array(ring_pts), [f"{r:.2f} m" for r in model.rings], font_size=12,
                                   shape_opacity=0.0, show_points=False, text_color=(0.35, 0.35, 0.35),
                                   always_visible=True)
            toward_cam = m.radial_vectors(cam.position[None])[0]
            toward_cam /= np.linalg.norm(toward_cam)
            p.camera.position = tuple(m.center + 5.0 * up)
            p.camera.focal_point = tuple(m.center)
            p.camera.up = tuple(-toward_cam)
            p.enable_parallel_projection()
            p.reset_camera(bounds=_bounds(np.vstack([allp, m.center + max(model.rings or (0.5,)) *
                                                     np.array([e1, -e1, e2, -e2])])))
            p.camera.zoom(1.3)
        else:
            toward_cam = cam.position - m.center
            toward_cam -= (toward_cam @ axis) * axis
            toward_cam /= np.linalg.norm(toward_cam)
            side = np.cross(axis, toward_cam)
            focal = allp.mean(axis=0)
            eye = focal + 1.6 * toward_cam + 1.2 * side + 1.1 * up
            p.camera.position = tuple(eye)
            p.camera.focal_point = tuple(focal)
            p.camera.up = tuple(up)
            p.reset_camera(bounds=_bounds(allp))
            p.camera.zoom(1.4)
        img = np.asarray(p.screenshot(return_img=True))[:, :, :3].copy()
        vc = p.renderer.GetActiveCamera()
        mat = vc.GetCompositeProjectionTransformMatrix(p.renderer.GetTiledAspectRatio(), -1, 1)
        proj = np.array([[mat.GetElement(i, j) for j in range(4)] for i in range(4)])
        eye = np.array(vc.GetPosition(), dtype=np.float64)
    finally:
        p.close()
    return View(image=img, projection=proj, eye=eye)


def _label_dir(mirror, camera) -> np.ndarray:
    """In-plane direction (perpendicular to the axis and to the camera's side) for ring labels."""
    r = mirror.radial_vectors(camera.position[None])[0]
    s = np.cross(mirror.axis, r)
    return s / np.linalg.norm(s)


def _bounds(points: np.ndarray) -> tuple:
    lo, hi = points.min(axis=0), points.max(axis=0)
    return (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])
