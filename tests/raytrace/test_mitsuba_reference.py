"""Our renderer against an image made by another renderer: Mitsuba 3 front-face masks shipped as data."""

import cv2
import numpy as np
import pytest

from mitsuba_reference import COLOURS, DATA, reference_scene
from raytrace.render import render
from raytrace.scene import Scene


def front_face_masks_ours():
    cam, mirror, cubes = reference_scene()
    r = render(Scene(mirror, cubes), cam, spp=1, workers=1)
    h, w = r.object_id.shape
    p = r.mirror_point.reshape(-1, 3)
    d = r.reflected_dir.reshape(-1, 3)
    masks = []
    for k, cube in enumerate(cubes):
        _, corners, centre = cube.front_face(mirror)
        e1, e2 = corners[1] - corners[0], corners[3] - corners[0]
        n = np.cross(e1, e2)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = ((centre - p) @ n) / (d @ n)
            q = p + t[:, None] * d - corners[0]
            a, b = q @ e1 / (e1 @ e1), q @ e2 / (e2 @ e2)
        on_face = (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1) & (t > 0)
        masks.append((r.object_id.reshape(-1) == k) & r.via_mirror.reshape(-1) & on_face)
    return [m.reshape(h, w) for m in masks]


def test_front_faces_overlap_mitsuba_with_iou_098():
    theirs = cv2.cvtColor(cv2.imread(str(DATA)), cv2.COLOR_BGR2RGB).astype(float) / 255.0
    ours = front_face_masks_ours()
    for k, mine in enumerate(ours):
        other = np.linalg.norm(theirs - COLOURS[2 * k], axis=2) < 0.5
        assert mine.sum() > 500
        iou = (mine & other).sum() / (mine | other).sum()
        assert iou >= 0.98, (k, iou)


def test_shipped_reference_is_still_what_mitsuba_renders():
    pytest.importorskip("mitsuba")
    from mitsuba_reference import render_reference
    fresh = np.clip(render_reference(spp=16), 0, 1)
    shipped = cv2.cvtColor(cv2.imread(str(DATA)), cv2.COLOR_BGR2RGB).astype(float) / 255.0
    for k in range(2):
        a = np.linalg.norm(fresh - COLOURS[2 * k], axis=2) < 0.5
        b = np.linalg.norm(shipped - COLOURS[2 * k], axis=2) < 0.5
        assert (a & b).sum() / (a | b).sum() > 0.99
