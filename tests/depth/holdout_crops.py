"""Crops of held-out Mitsuba renders kept in tests/data, each with the setup and the cube that read it (a helper
module of the tests beside it, not a test module: imported by name, as pytest puts this directory on the path)."""

from pathlib import Path

import cv2

from raytrace.camera import PinholeCamera
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube

DATA = Path(__file__).resolve().parents[1] / "data"


def holdout_crop(name: str, origin, size, full_resolution, focal_px: float, camera_position, mirror, cube):
    """(8-bit RGB image, camera, mirror, cube) of the crop `name` in tests/data: `size` (w, h) px from `origin`
    (x, y) of a render `full_resolution` (W, H) px whose camera, `focal_px` px, stands at `camera_position` looking
    at the origin, y up, its principal point at the render's centre (moved here to the crop's). `mirror`: the
    cylinder's (radius, height) about the y axis; `cube`: (edge length, centre, turn about y in degrees, grey)."""
    image = cv2.cvtColor(cv2.imread(str(DATA / name)), cv2.COLOR_BGR2RGB)
    principal = ((full_resolution[0] - 1) / 2.0 - origin[0], (full_resolution[1] - 1) / 2.0 - origin[1])
    camera = PinholeCamera.from_look_at(tuple(size), (focal_px, focal_px), principal, camera_position, (0, 0, 0),
                                        (0, 1, 0))
    radius, height = mirror
    edge, centre, turn_deg, grey = cube
    return (image, camera, CylinderMirror(radius, height, (0, 0, 0), (0, 1, 0)),
            Cube.from_euler_deg(edge, centre, (0.0, turn_deg, 0.0), (grey, grey, grey)))
