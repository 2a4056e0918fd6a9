"""raytrace: what a pinhole camera sees in a curved mirror.

Cameras, mirrors, scenes, Embree tracing, shading and exact ground truth.
This package never reads or writes files and never prints.
"""

from .camera import PinholeCamera, PushbroomCamera, XSlitCamera, pixel_grid, pixel_sample_offsets, sample_offsets
from .errors import RaytraceError
from .mirror import MIRRORS, CylinderMirror, MeshMirror, reflect
from .render import Render, linear_to_srgb8  # `render()` itself: raytrace.render.render (the module keeps its name)
from .scene import Cube, DirectionalLight, GroundPlane, Scene
from .truth import MirrorRays, cube_truth, mirror_rays, reflection_pixels

__all__ = [
    "PinholeCamera", "XSlitCamera", "PushbroomCamera", "pixel_grid", "sample_offsets", "pixel_sample_offsets",
    "RaytraceError", "MIRRORS", "CylinderMirror", "MeshMirror", "reflect",
    "Render", "linear_to_srgb8",
    "Cube", "DirectionalLight", "GroundPlane", "Scene",
    "MirrorRays", "mirror_rays", "reflection_pixels", "cube_truth",
]
