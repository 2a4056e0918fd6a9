"""A small version of the demo setup, shared by the report and demo tests."""


# The demo's mirror and two of its cubes, seen by a 320×240 camera with a narrow field of view; one
# cube is narrow enough to be refused, which reports must list. Shared by the report and demo tests.
SMALL_DEMO = {
    "units": "m",
    "camera": {"resolution": [320, 240], "focal_px": [1400.0, 1400.0], "position": [0.0, 0.0, 0.55],
               "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]},
    "mirror": {"type": "cylinder", "radius": 0.1, "height": 0.49, "center": [0.0, 0.0, 0.0],
               "axis": [0.0, 1.0, 0.0]},
    "objects": [
        {"type": "cube", "size": 0.04, "center": [0.1873, -0.03, 0.4636], "rotation_deg": [0.0, -158.0, 0.0],
         "color": [0.1, 0.65, 0.15]},
        {"type": "cube", "size": 0.04, "center": [0.0993, -0.02, 0.9448], "rotation_deg": [0.0, -174.0, 0.0],
         "color": [0.75, 0.15, 0.75]},
    ],
}
