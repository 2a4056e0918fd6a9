"""raytrace: what a pinhole camera sees in a curved mirror.

Cameras, mirrors, scenes, Embree tracing, shading and exact ground truth.
This package never reads or writes files and never prints.
"""
