"""Small shared scenes for the raytrace tests: `small_camera`, `cylinder`, `three_cubes`."""


from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube, Scene


def small_camera(width=160, height=120):
    """The SETUP_FORMAT example camera scaled to a small image (same field of view)."""
    return PinholeCamera.from_look_at((width, height), 3500.0 * width / 1600, None, [0.0, 0.0, 0.55], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])


def cylinder():
    return CylinderMirror(0.1, 0.49, [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])


def three_cubes(size=0.04):
    return [
        Cube.from_euler_deg(size, [0.24, 0.03, 0.90], [0.0, -165.0, 0.0], [0.8, 0.1, 0.1]),
        Cube.from_euler_deg(size, [-0.2, -0.05, 0.8], [0.0, 160.0, 0.0], [0.1, 0.7, 0.2]),
        Cube.from_euler_deg(size, [0.0, 0.08, 0.7], [10.0, 180.0, 0.0], [0.2, 0.3, 0.9]),
    ]


def mirror_scene(ground=None, size=0.04):
    return Scene(cylinder(), three_cubes(size), ground=ground)
