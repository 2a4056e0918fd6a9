"""Virtual slits of a setup and setup design: `fit_region`, `fit_tile_map`, `design_setup`, `optimize_setup`.

`fit_region` fits two virtual slits (and the GLC type) to the reflected rays of a pixel region;
`design_setup` turns the local XSlit at the image centre (and per tile) into the numbers a
researcher chooses a mirror setup by: baseline, z2/z1, the AR-vs-depth curve of a unit square,
the sensitivity ∂r_i/∂z, the maximum discernible depth for ε = 1 px and 0.1 px, and the expected
depth error of a cube over a depth range. Depths in and out are distances from the mirror axis
(as in result files); the paper's z is measured from the local virtual image plane.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from catadioptric.errors import CatadioptricError
from catadioptric.setup import Setup

__all__ = ["fit_region", "fit_tile_map", "design_setup", "optimize_setup", "Design", "centre_roi"]


def _rays(setup: Setup):
    from raytrace.truth import mirror_rays
    camera, mirror = setup.camera.build(), setup.mirror.build()

    def rays(px):
        r = mirror_rays(camera, mirror, np.asarray(px, dtype=np.float64))
        return r.points, r.directions, r.hit
    return camera, mirror, rays


def centre_roi(setup: Setup, half: int = 20) -> tuple[int, int, int, int]:
    """A (2·half)² pixel ROI centred on the image point where the mirror's centre appears."""
    camera = setup.camera.build()
    px, _ = camera.project(np.asarray(setup.mirror.center, dtype=np.float64)[None])
    w, h = setup.camera.resolution
    cu = int(np.clip(round(px[0, 0]), half, w - half))
    cv = int(np.clip(round(px[0, 1]), half, h - half))
    return (cu - half, cv - half, cu + half, cv + half)


def _check_roi(roi, setup: Setup) -> tuple[int, int, int, int]:
    w, h = setup.camera.resolution
    x0, y0, x1, y1 = (int(round(v)) for v in roi)
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise CatadioptricError(f"--roi: expected 0 <= X0 < X1 <= {w} and 0 <= Y0 < Y1 <= {h}, got {list(roi)}")
    return x0, y0, x1, y1


def fit_region(setup: Setup, roi=None) -> dict:
    """Two-slit fit and GLC type of the reflected rays of `roi` (X0, Y0, X1, Y1), or of the whole mirror.

    Returns a JSON-ready dict: slits (world point and direction), z1, z2, θ1, θ2 (degrees) of the
    XSlit frame through the rays' centroid, rms and max ray-to-slit distance (metres), glc_type,
    the condition of the linear step and the number of rays — or `ok: false` with the reason.
    """
    return _fit_frame(setup, roi)[0]


def _fit_frame(setup: Setup, roi=None):
    """(JSON-ready fit dict, XSlitFrame or None) of the reflected rays of `roi`."""
    from xslit_fit.fit import fit_two_slits
    from xslit_fit.frame import XSlitFrame
    from xslit_fit.glc import glc_type
    _, _, rays = _rays(setup)
    w, h = setup.camera.resolution
    x0, y0, x1, y1 = _check_roi(roi, setup) if roi is not None else (0, 0, w, h)
    step = max(1, int(np.sqrt((x1 - x0) * (y1 - y0) / 200_000)))  # at most ~200k rays
    gu, gv = np.meshgrid(np.arange(x0, x1, step, dtype=np.float64), np.arange(y0, y1, step, dtype=np.float64))
    points, dirs, hit = rays(np.column_stack([gu.ravel(), gv.ravel()]))
    out = {"roi": [x0, y0, x1, y1], "n_rays": int(hit.sum())}
    if hit.sum() < 8:
        raise CatadioptricError(f"--roi {[x0, y0, x1, y1]}: expected a region that sees the mirror, "
                                f"got {int(hit.sum())} mirror pixels")
    points, dirs = points[hit], dirs[hit]
    fit = fit_two_slits(points, dirs)
    out["glc_type"] = glc_type(points, dirs)
    if not fit:
        out.update(ok=False, reason=fit.reason, detail=fit.detail)
        return out, None
    frame = XSlitFrame.from_fit(fit)
    out.update(ok=True,
               slits=[{"point": s.point.tolist(), "direction": s.direction.tolist()} for s in frame.slits],
               z1=float(frame.z1), z2=float(frame.z2),
               theta1_deg=float(np.rad2deg(frame.theta1)), theta2_deg=float(np.rad2deg(frame.theta2)),
               baseline=float(abs(frame.z2 - frame.z1)), ratio=float(frame.z2 / frame.z1),
               rms_ray_distance=float(fit.rms_distance), max_ray_distance=float(fit.max_distance),
               condition=float(fit.condition), plane_origin=frame.origin.tolist(), plane_normal=frame.e_z.tolist())
    return out, frame


def fit_tile_map(setup: Setup, tiles: int, progress=None):
    """`xslit_fit.tiles.fit_tiles` over the setup's whole ray map with tiles × tiles tiles."""
    from xslit_fit.tiles import fit_tiles
    if tiles < 1 or tiles > 128:
        raise CatadioptricError(f"--tiles: expected an integer from 1 to 128, got {tiles}")
    camera, _, rays = _rays(setup)
    w, h = setup.camera.resolution
    points, dirs, hit = rays(camera.pixel_grid())
    return fit_tiles(points.reshape(h, w, 3), dirs.reshape(h, w, 3), hit.reshape(h, w), tiles=(tiles, tiles),
                     progress=progress)


def tile_map_dict(tm) -> dict:
    def arr(a):
        return [[None if not np.isfinite(v) else float(v) for v in row] for row in a]
    return {"z1": arr(tm.z1), "z2": arr(tm.z2), "baseline": arr(tm.baseline), "ratio": arr(tm.ratio),
            "rms_ray_distance": arr(tm.rms), "valid": tm.valid.tolist(), "bounds": tm.bounds.tolist(),
            "reasons": [[str(r) for r in row] for row in tm.reasons]}


@dataclass(frozen=True)
class Design:
    """Design numbers at the image centre. Arrays are over `depths` (distance from the mirror axis)."""

    fit: dict
    plane_distance: float          # distance from the mirror axis to the local virtual image plane
    depths: np.ndarray
    aspect_ratio: np.ndarray       # r_i of a unit square (r_o = 1)
    sensitivity: np.ndarray        # ∂r_i/∂z, per metre
    expected_error: np.ndarray     # σ of depth for the cube size and 1 px corner-extent noise, metres
    cube_size: float
    max_depth_1px: float
    max_depth_01px: float
    pixels_per_kappa: tuple
    floor_error: np.ndarray | None = None  # σ of depth of a cube standing on the floor, 1 px bottom edge (NaN: unseen)
    setup_error: dict | None = None  # σ of depth from the setup's own σ, per number and 'total' (`setup_depth_error`)

    def to_dict(self) -> dict:
        curve = [{"depth": float(d), "aspect_ratio": float(r), "sensitivity": float(s),
                  "expected_depth_error": float(e)}
                 for d, r, s, e in zip(self.depths, self.aspect_ratio, self.sensitivity, self.expected_error)]
        if self.floor_error is not None:  # (null where the floor there is not in the image)
            for point, f in zip(curve, self.floor_error):
                point["expected_depth_error_on_floor"] = float(f) if np.isfinite(f) else None
        if self.setup_error is not None:  # (null where the cube is not wholly in the image)
            for i, point in enumerate(curve):
                point["expected_depth_error_from_setup"] = {
                    name: float(v[i]) if np.isfinite(v[i]) else None for name, v in self.setup_error.items()}
        return {"centre_fit": self.fit, "plane_distance_from_axis": self.plane_distance,
                "cube_size": self.cube_size,
                "max_discernible_depth": {"eps_1px": self.max_depth_1px, "eps_0.1px": self.max_depth_01px},
                "curve": curve}


def design_setup(setup: Setup, depth_range=None, cube_size: float = 0.04, n: int = 25, setup_std=None,
                 progress=None) -> Design:
    """Design numbers of a setup at the image centre (see the module docstring). With `setup_std` (a
    `depth.setup_error.SetupStd`), also the depth error the setup's own σ gives (`setup_depth_error`; `progress`
    is called as each depth is done)."""
    from depth import ddar
    roi = centre_roi(setup)
    fit, frame = _fit_frame(setup, roi)
    if not fit.get("ok"):
        raise CatadioptricError(f"the centre of the mirror image has no XSlit fit: {fit.get('reason')}")
    mirror = setup.mirror
    origin = np.asarray(fit["plane_origin"])
    plane_distance = mirror.distance_to_axis(origin)
    z1, z2 = fit["z1"], fit["z2"]
    if depth_range is None:
        depth_range = (plane_distance + 2 * mirror.radius, plane_distance + 10 * mirror.radius)
    a, b = map(float, depth_range)
    if not (np.isfinite(a) and np.isfinite(b) and plane_distance < a < b):
        raise CatadioptricError(f"--depth-range: expected {plane_distance:.3f} < A < B (metres from the mirror axis), "
                                f"got {a} {b}")
    depths = np.linspace(a, b, n)
    z = depths - plane_distance
    r = ddar.aspect_ratio(z, z1, z2)
    sens = ddar.sensitivity(z, z1, z2)
    # Pixels per κ unit at the centre: the image size of a κ step, by finite differences of the ray map.
    _, _, rays = _rays(setup)
    x0, y0, x1, y1 = roi
    cu, cv = (x0 + x1) / 2, (y0 + y1) / 2
    pts, dirs, _ = rays(np.array([[cu, cv], [cu + 1, cv], [cu, cv + 1]]))
    k = frame.kappa(frame.rays_to_plane(pts, dirs))
    jac = np.column_stack([k[1] - k[0], k[2] - k[0]])  # κ per pixel (2×2)
    px_per_kappa = 1.0 / np.abs(jac).max(axis=1)
    # Expected depth error: a cube of `cube_size` spans s_u·size, s_v·size in κ; ±1 px noise on each extent.
    su, sv = -z2 / (z - z2), -z1 / (z - z1)
    ext_u_px = su * cube_size * px_per_kappa[0]
    ext_v_px = sv * cube_size * px_per_kappa[1]
    sigma_r = r * np.hypot(1.0 / ext_u_px, 1.0 / ext_v_px)
    err = ddar.depth_std_from_aspect_ratio(r, sigma_r, z1, z2)
    L = max(setup.camera.resolution)
    return Design(fit=fit, plane_distance=float(plane_distance), depths=depths, aspect_ratio=r, sensitivity=sens,
                  expected_error=err, cube_size=cube_size, floor_error=floor_depth_error(setup, depths),
                  setup_error=None if setup_std is None else setup_depth_error(setup, depths, setup_std, cube_size,
                                                                               progress),
                  max_depth_1px=float(plane_distance + ddar.max_discernible_depth(z1, z2, eps=1.0 / L)),
                  max_depth_01px=float(plane_distance + ddar.max_discernible_depth(z1, z2, eps=0.1 / L)),
                  pixels_per_kappa=tuple(float(x) for x in px_per_kappa))


def floor_depth_error(setup: Setup, depths, px: float = 1.0) -> np.ndarray:
    """σ (m) of the depth of a cube standing on the floor the mirror stands on (its lower end; `catadioptric
    reconstruct --on-floor`), at each of `depths` (from the mirror axis) along the azimuth the reflected ray of the
    mirror centre's image point takes, from its bottom edge's place in the image off by `px` pixels vertically.
    The floor then fixes each depth by the bottom edge's rays alone: each depth's floor point is imaged
    (`reflection_pixels`), the pixels `px` above and below it are traced back to the floor, and half the span of
    their distances from the axis is the σ. It falls as the camera stands higher over the floor, and does not
    depend on the cube's size. NaN where the floor point is not seen in the image, or the rays `px` from it do not
    meet the floor ahead."""
    from raytrace.truth import reflection_pixels
    camera, mirror, rays = _rays(setup)
    depths = np.asarray(depths, dtype=np.float64)
    out = np.full(depths.shape, np.nan)
    found = _centre_heading(setup, rays)
    if found is None:
        return out
    heading, up = found
    floor = np.asarray(mirror.center, dtype=np.float64) - up * mirror.height / 2.0
    pix, seen = reflection_pixels(camera, mirror, floor + depths[:, None] * heading)
    w, h = camera.resolution
    seen &= np.all(np.isfinite(pix), axis=1) & (pix[:, 0] >= 0) & (pix[:, 0] <= w - 1) & (pix[:, 1] >= 0) & \
        (pix[:, 1] <= h - 1)
    reach = []
    for step in (-px, px):
        p, e, ok = rays(pix[seen] + [0.0, step])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((floor - p) @ up) / (e @ up)
        q = p + t[:, None] * e
        reach.append(np.where(ok & (t > 0), mirror.distance_to_axis(q), np.nan))
    out[seen] = np.abs(reach[1] - reach[0]) / 2.0
    return out


def _centre_heading(setup: Setup, rays):
    """The unit horizontal direction (square to the mirror's axis) of the reflected ray of the mirror centre's
    image point, and the axis: (heading, up), or None where that ray misses the mirror or runs along the axis."""
    x0, y0, x1, y1 = centre_roi(setup)
    _, d, hit = rays(np.array([[(x0 + x1) / 2.0, (y0 + y1) / 2.0]]))
    if not hit[0]:
        return None
    up = np.asarray(setup.mirror.build().axis, dtype=np.float64)
    heading = d[0] - (d[0] @ up) * up
    if np.linalg.norm(heading) < 1e-9:
        return None
    return heading / np.linalg.norm(heading), up


def _exact_edges(camera, mirror, cube, n: int = 24):
    """A `depth.estimate.FaceMeasurement` of `cube`'s front face from its true edges, each side's `n` points imaged
    by the exact reflection (`reflection_pixels`), or None where any of them is not seen in the image. The cube
    stands upright along the mirror's axis."""
    from matplotlib.path import Path as Polygon
    from depth.estimate import FaceMeasurement
    from raytrace.truth import reflection_pixels
    _, corners, _ = cube.front_face(mirror)
    t = np.linspace(0.08, 0.92, n)[:, None]
    sides, vertical = [], []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        px, ok = reflection_pixels(camera, mirror, a * (1 - t) + b * t)
        w, h = camera.resolution
        if not (ok.all() and np.all(np.isfinite(px)) and np.all((px >= 0) & (px <= [w - 1, h - 1]))):
            return None
        sides.append(px)
        vertical.append(abs((b - a) @ mirror.axis) > 0.5 * cube.size)
    (il, ir), (it, ib) = ([k for k in range(4) if vertical[k] == v] for v in (True, False))
    il, ir = sorted((il, ir), key=lambda k: sides[k][:, 0].mean())
    it, ib = sorted((it, ib), key=lambda k: sides[k][:, 1].mean())
    cpx = reflection_pixels(camera, mirror, corners)[0]
    order = [int(np.argmin(cpx @ [1.0, 1.0])), int(np.argmin(cpx @ [-1.0, 1.0])), int(np.argmax(cpx @ [1.0, 1.0])),
             int(np.argmax(cpx @ [-1.0, 1.0]))]  # top-left, top-right, bottom-right, bottom-left
    outline = np.concatenate(sides)
    lo, hi = np.floor(outline.min(0)), np.ceil(outline.max(0))
    gu, gv = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    grid = np.column_stack([gu.ravel(), gv.ravel()])
    return FaceMeasurement((sides[il], sides[ir], sides[it], sides[ib]), cpx[order],
                           grid[Polygon(outline).contains_points(grid)], 0.0)


def setup_depth_error(setup: Setup, depths, std, cube_size: float = 0.04, progress=None) -> dict:
    """σ (m) of the depth `reconstruct` reads for a cube of `cube_size` facing the mirror's axis at each of `depths`
    (from the axis) along the azimuth the reflected ray of the mirror centre's image point takes, at the height of
    the mirror's centre, from the setup's own σ `std` (a `depth.setup_error.SetupStd`, what an `[uncertainty]`
    table gives): per number of `std` (its components in quadrature) and in total ('total'). The cube's exact edges
    are read by `exact` through the setup, and each number's move of that reading is `depth.setup_error`'s (the
    image's own noise left out). NaN where the face is not wholly in the image or `exact` reads none."""
    from depth.estimate import estimate_face
    from depth.setup_error import setup_effects
    from raytrace.scene import Cube
    camera, mirror, rays = _rays(setup)
    depths = np.asarray(depths, dtype=np.float64)
    out = {name: np.full(depths.shape, np.nan) for name, _ in std.items()}
    out["total"] = np.full(depths.shape, np.nan)
    found = _centre_heading(setup, rays)
    if found is None:
        return out
    heading, up = found
    rotation = np.column_stack([np.cross(up, -heading), up, -heading])  # local +z toward the axis, +y up
    for i, depth in enumerate(depths):
        cube = Cube(cube_size, np.asarray(mirror.center, dtype=np.float64) + depth * heading, rotation)
        meas = _exact_edges(camera, mirror, cube)
        est = None if meas is None else estimate_face(lambda px: rays(px)[:2], meas, "exact", up=up, ray_slopes=True)
        if est:
            effects = setup_effects(est, camera, mirror, std)
            total = 0.0
            for name, _ in std.items():
                var = sum(e[5] ** 2 for n, _, e in effects if n == name)
                out[name][i] = np.sqrt(var)
                total += var
            out["total"][i] = np.sqrt(total)
        if progress is not None:
            progress(i + 1, len(depths))
    return out


def optimize_setup(setup: Setup, depth_range, cube_size: float = 0.04, distance_bounds=None, radius_bounds=None,
                   grid: int = 7, progress=None) -> tuple[Setup, float, list]:
    """Grid search over camera distance and mirror radius minimising the mean relative depth error.

    The camera moves along its line to the mirror centre; the focal length scales with the
    distance so the mirror keeps its size in the image. Returns (best setup, its score, all rows).
    """
    cam, m = setup.camera, setup.mirror
    c = np.asarray(m.center, float)
    pos = np.asarray(cam.position, float)
    d0 = float(np.linalg.norm(pos - c))
    distance_bounds = distance_bounds or (0.6 * d0, 1.6 * d0)
    radius_bounds = radius_bounds or (0.5 * m.radius, 1.5 * m.radius)
    rows, best = [], (np.inf, setup)
    ds = np.linspace(*distance_bounds, grid)
    rs = np.linspace(*radius_bounds, grid)
    total, done = len(ds) * len(rs), 0
    for d in ds:
        for rad in rs:
            done += 1
            if d <= 1.5 * rad:
                continue
            new_pos = c + (pos - c) * d / d0
            f = tuple(v * d / d0 for v in cam.focal_px)
            s = replace(setup, camera=replace(cam, position=tuple(new_pos), focal_px=f),
                        mirror=replace(m, radius=float(rad)))
            try:
                des = design_setup(s, depth_range, cube_size)
            except CatadioptricError:
                continue
            score = float(np.mean(des.expected_error / des.depths))
            rows.append({"distance": float(d), "radius": float(rad), "mean_relative_error": score})
            if score < best[0]:
                best = (score, s)
            if progress is not None:
                progress(done, total)
    if not np.isfinite(best[0]):
        raise CatadioptricError("--optimize: no setup in the bounds gives a usable XSlit at the image centre")
    return best[1], best[0], rows


def plot_design(design: Design, path_or_buffer) -> None:
    """Three panels: AR of a unit square vs depth, sensitivity, and expected depth error."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.6), constrained_layout=True)
    ax[0].plot(design.depths, design.aspect_ratio, color="tab:blue")
    ax[0].set(xlabel="depth from mirror axis (m)", ylabel="aspect ratio r_i (r_o = 1)", title="DDAR curve")
    ax[1].plot(design.depths, np.abs(design.sensitivity), color="tab:orange")
    ax[1].set(xlabel="depth (m)", ylabel="|∂r_i/∂z| (1/m)", title="sensitivity", yscale="log")
    ax[2].plot(design.depths, 100 * design.expected_error / design.depths, color="tab:red",
               label=f"{100 * design.cube_size:.0f} cm cube, ±1 px extents")
    if design.floor_error is not None and np.isfinite(design.floor_error).any():
        ax[2].plot(design.depths, 100 * design.floor_error / design.depths, color="tab:green",
                   label="standing on the floor (--on-floor), bottom edge ±1 px")
    if design.setup_error is not None and np.isfinite(design.setup_error["total"]).any():
        ax[2].plot(design.depths, 100 * design.setup_error["total"] / design.depths, color="tab:purple",
                   label="from the setup's [uncertainty], exact edges")
    ax[2].set(xlabel="depth (m)", ylabel="expected depth error (%)", title="expected depth error", yscale="log")
    ax[2].legend(fontsize=7)
    fig.suptitle(f"z1 = {design.fit['z1']:.4f} m, z2 = {design.fit['z2']:.4f} m, "
                 f"z2/z1 = {design.fit['ratio']:.2f}")
    fig.savefig(path_or_buffer, format="png", dpi=100)
    plt.close(fig)
