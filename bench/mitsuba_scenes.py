"""Mitsuba 3 renders of benchmark scenes: `mitsuba_render(setup)` returns an sRGB (H, W, 3) uint8 image, or None without Mitsuba.

The camera follows the mapping measured in GEOMETRY_NOTES.md (perspective sensor, fov_axis="x",
fov = 2·atan(W/(2·fx)), no principal-point offset), the mirror is Mitsuba's analytic open
`cylinder` with a perfect `conductor` (material="none"), cubes are `cube` shapes scaled, rotated
and moved. The lighting deliberately differs from our renderer's: a path tracer with a constant
environment plus a directional light from another direction (so shading, soft inter-reflections
and sampling noise are Mitsuba's own).
"""

from __future__ import annotations

import numpy as np

__all__ = ["mitsuba_available", "mitsuba_render", "scene_dict", "SPP", "LIGHT_TRAVEL", "ENV_RADIANCE"]

SPP = 16
LIGHT_TRAVEL = (0.3, -1.0, -0.5)
"""Direction the directional light travels (world): from above, behind the camera's shoulder."""
ENV_RADIANCE = 0.45
SUN_IRRADIANCE = 2.2


def mitsuba_available() -> bool:
    try:
        import mitsuba  # noqa: F401
    except ImportError:
        return False
    return True


def scene_dict(camera, mirror, cubes, spp: int, sun_travel, sun_irradiance: float, sky_radiance: float,
               rfilter: str | None = None, max_depth: int = 5, sky_map: np.ndarray | None = None,
               floor_albedo: float | None = None) -> dict:
    """A Mitsuba 3 scene dict of our camera (PinholeCamera), CylinderMirror and Cubes, with a
    directional sun and a constant sky.

    `sky_map` ((H, W, 3) linear radiance, equirectangular, Mitsuba's +y up) replaces the constant sky
    (`sky_radiance` is then unused); `floor_albedo` adds a diffuse grey floor 10 m across, square to
    the mirror's axis at its lower end (the mirror stands on it; cubes cast shadows on it)."""
    import mitsuba as mi
    w, h = camera.resolution
    cx, cy = camera.K[0, 2], camera.K[1, 2]
    if abs(cx - (w - 1) / 2) > 1e-9 or abs(cy - (h - 1) / 2) > 1e-9:
        raise ValueError("mitsuba scene: expected the default principal point (no offset)")
    half = mirror.height / 2 * mirror.axis
    film = {"type": "hdrfilm", "width": int(w), "height": int(h)}
    if rfilter:
        film["rfilter"] = {"type": rfilter}
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth},
        "sensor": {
            "type": "perspective",
            "fov_axis": "x",
            "fov": float(np.degrees(2 * np.arctan(w / (2 * camera.K[0, 0])))),
            "to_world": mi.ScalarTransform4f().look_at(origin=camera.position.tolist(),
                                                       target=(camera.position + camera.R[2]).tolist(),
                                                       up=(-camera.R[1]).tolist()),
            "film": film,
            "sampler": {"type": "stratified", "sample_count": spp},
        },
        "mirror": {"type": "cylinder", "p0": (mirror.center - half).tolist(), "p1": (mirror.center + half).tolist(),
                   "radius": float(mirror.radius), "bsdf": {"type": "conductor", "material": "none"}},
        "sun": {"type": "directional", "direction": [float(x) for x in sun_travel],
                "irradiance": {"type": "rgb", "value": sun_irradiance}},
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": sky_radiance}},
    }
    if sky_map is not None:
        d["sky"] = {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(sky_map, dtype=np.float32))}
    if floor_albedo is not None:
        # Mitsuba's rectangle spans [-1, 1]² of its local xy plane, normal +z: map z to the axis
        e1 = np.cross(mirror.axis, [1.0, 0.0, 0.0] if abs(mirror.axis[0]) < 0.9 else [0.0, 0.0, 1.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(mirror.axis, e1)
        m4 = np.eye(4)
        m4[:3, :3] = np.stack([5.0 * e1, 5.0 * e2, mirror.axis], axis=1)
        m4[:3, 3] = mirror.center - half
        d["floor"] = {"type": "rectangle", "to_world": mi.ScalarTransform4f(m4.tolist()),
                      "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(floor_albedo)] * 3}}}
    for k, c in enumerate(cubes):
        m4 = np.eye(4)
        m4[:3, :3] = c.rotation * (c.size / 2)
        m4[:3, 3] = c.center
        d[f"cube{k}"] = {"type": "cube", "to_world": mi.ScalarTransform4f(m4.tolist()),
                         "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(x) for x in c.color]}}}
    return d


def _dict(setup) -> dict:
    scene = setup.build_scene()
    return scene_dict(setup.camera.build(), scene.mirror, scene.objects, SPP, LIGHT_TRAVEL, SUN_IRRADIANCE,
                      ENV_RADIANCE, rfilter="gaussian")


def mitsuba_render(setup, seed: int = 0) -> np.ndarray | None:
    """Render a `catadioptric.setup.Setup` with Mitsuba 3 (`scalar_rgb`) : (H, W, 3) uint8 sRGB, or None."""
    if not mitsuba_available():
        return None
    import mitsuba as mi
    from raytrace.render import linear_to_srgb8
    mi.set_variant("scalar_rgb")
    img = np.asarray(mi.render(mi.load_dict(_dict(setup)), seed=seed), dtype=np.float64)[:, :, :3]
    return linear_to_srgb8(img)
