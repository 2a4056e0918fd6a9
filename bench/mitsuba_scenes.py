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

__all__ = ["mitsuba_available", "mitsuba_render", "SPP", "LIGHT_TRAVEL", "ENV_RADIANCE"]

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


def _dict(setup) -> dict:
    import mitsuba as mi
    cam = setup.camera.build()
    w, h = setup.camera.resolution
    if setup.camera.principal_px is not None:
        cx, cy = setup.camera.principal_px
        if abs(cx - (w - 1) / 2) > 1e-9 or abs(cy - (h - 1) / 2) > 1e-9:
            raise ValueError("mitsuba_render: expected the default principal point (no offset)")
    m = setup.mirror
    axis = np.asarray(m.axis, float) / np.linalg.norm(m.axis)
    centre = np.asarray(m.center, float)
    half = m.height / 2 * axis
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 5},
        "sensor": {
            "type": "perspective",
            "fov_axis": "x",
            "fov": float(np.degrees(2 * np.arctan(w / (2 * cam.K[0, 0])))),
            "to_world": mi.ScalarTransform4f().look_at(origin=cam.position.tolist(),
                                                       target=(cam.position + cam.R[2]).tolist(),
                                                       up=(-cam.R[1]).tolist()),
            "film": {"type": "hdrfilm", "width": int(w), "height": int(h), "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "stratified", "sample_count": SPP},
        },
        "mirror": {"type": "cylinder", "p0": (centre - half).tolist(), "p1": (centre + half).tolist(),
                   "radius": float(m.radius), "bsdf": {"type": "conductor", "material": "none"}},
        "sun": {"type": "directional", "direction": list(LIGHT_TRAVEL),
                "irradiance": {"type": "rgb", "value": SUN_IRRADIANCE}},
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": ENV_RADIANCE}},
    }
    for k, c in enumerate(setup.objects):
        m4 = np.eye(4)
        m4[:3, :3] = c.rotation * (c.size / 2)
        m4[:3, 3] = c.center
        d[f"cube{k}"] = {"type": "cube", "to_world": mi.ScalarTransform4f(m4.tolist()),
                         "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(c.color)}}}
    return d


def mitsuba_render(setup, seed: int = 0) -> np.ndarray | None:
    """Render a `catadioptric.setup.Setup` with Mitsuba 3 (`scalar_rgb`) : (H, W, 3) uint8 sRGB, or None."""
    if not mitsuba_available():
        return None
    import mitsuba as mi
    from raytrace.render import linear_to_srgb8
    mi.set_variant("scalar_rgb")
    img = np.asarray(mi.render(mi.load_dict(_dict(setup)), seed=seed), dtype=np.float64)[:, :, :3]
    return linear_to_srgb8(img)
