"""The Mitsuba 3 reference scene shipped as tests/data/mitsuba_front_faces.png, and its generator.

Two cubes in a cylindrical mirror; in Mitsuba each cube's front face emits one pure colour and the
rest of the cube another (four rectangles/cubes with area emitters, black background), so the image
gives per-face masks rendered by another renderer. Regenerate (needs the `bench` extra) with
`.venv/bin/python tests/raytrace/mitsuba_reference.py`.
"""

from pathlib import Path

import numpy as np

from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube
from raytrace.truth import cylinder_reflection_points

DATA = Path(__file__).resolve().parents[1] / "data" / "mitsuba_front_faces.png"
#: emitted colour of (cube 0 front face, cube 0 rest, cube 1 front face, cube 1 rest)
COLOURS = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 0.0]])


def reference_scene():
    mirror = CylinderMirror(0.1, 0.49, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    cubes = [Cube.from_euler_deg(0.1, [0.35, 0.0, 0.75], [0.0, -150.0, 0.0]),
             Cube.from_euler_deg(0.08, [-0.3, 0.05, 0.8], [0.0, 160.0, 0.0])]
    eye = np.array([0.0, 0.0, 0.55])
    aim, _ = cylinder_reflection_points(mirror, eye, np.array([c.center for c in cubes]))
    cam = PinholeCamera.from_look_at((200, 240), 1200.0, None, eye, 0.5 * (aim[0] + aim[1]), [0.0, 1.0, 0.0])
    return cam, mirror, cubes


def sensor_and_mirror(cam, mirror, spp: int) -> dict:
    """The Mitsuba 3 scene dict of our camera (GEOMETRY_NOTES mapping, box filter) and cylinder mirror."""
    import mitsuba as mi
    w, h = cam.resolution
    half = mirror.height / 2 * mirror.axis
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 4},
        "sensor": {"type": "perspective", "fov_axis": "x", "fov": float(np.degrees(2 * np.arctan(w / (2 * cam.K[0, 0])))),
                   "to_world": mi.ScalarTransform4f().look_at(origin=cam.position.tolist(),
                                                              target=(cam.position + cam.R[2]).tolist(),
                                                              up=(-cam.R[1]).tolist()),
                   "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
                   "sampler": {"type": "stratified", "sample_count": spp}},
        "mirror": {"type": "cylinder", "p0": (mirror.center - half).tolist(), "p1": (mirror.center + half).tolist(),
                   "radius": mirror.radius, "bsdf": {"type": "conductor", "material": "none"}},
    }


def render_reference(spp: int = 256) -> np.ndarray:
    """Render with Mitsuba 3 (scalar_rgb): (H, W, 3) float linear RGB."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    cam, mirror, cubes = reference_scene()
    scene = sensor_and_mirror(cam, mirror, spp)
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    for k, cube in enumerate(cubes):
        m4 = np.eye(4)
        m4[:3, :3] = cube.rotation * (cube.size / 2 * 0.999)  # the rest, just inside the front face
        m4[:3, 3] = cube.center
        scene[f"cube{k}"] = {"type": "cube", "to_world": mi.ScalarTransform4f(m4.tolist()), "bsdf": black,
                             "emitter": {"type": "area", "radiance": {"type": "rgb", "value": COLOURS[2 * k + 1].tolist()}}}
        _, corners, centre = cube.front_face(mirror)
        e1 = (corners[1] - corners[0]) / 2
        e2 = (corners[3] - corners[0]) / 2
        n = np.cross(e1, e2)
        n /= np.linalg.norm(n)
        if np.dot(n, centre - cube.center) < 0:  # emit outward
            e1 = -e1
        f4 = np.eye(4)
        f4[:3, 0], f4[:3, 1], f4[:3, 2], f4[:3, 3] = e1, e2, np.cross(e1, e2) / np.linalg.norm(np.cross(e1, e2)), centre
        scene[f"front{k}"] = {"type": "rectangle", "to_world": mi.ScalarTransform4f(f4.tolist()), "bsdf": black,
                              "emitter": {"type": "area", "radiance": {"type": "rgb", "value": COLOURS[2 * k].tolist()}}}
    return np.array(mi.render(mi.load_dict(scene)))[..., :3]


if __name__ == "__main__":  # pragma: no cover - regenerates the shipped data
    import cv2
    img = np.clip(render_reference(), 0, 1)
    cv2.imwrite(str(DATA), cv2.cvtColor(np.round(img * 255).astype(np.uint8), cv2.COLOR_RGB2BGR))
    print(DATA)
