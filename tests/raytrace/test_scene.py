"""Tests of raytrace.scene: cube geometry, the front face, the ground plane's checker."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from raytrace.errors import RaytraceError
from raytrace.mirror import CylinderMirror
from raytrace.scene import Cube, GroundPlane, Scene


def test_cube_vertices_and_mesh_agree_with_setup_definition():
    cube = Cube.from_euler_deg(0.04, [0.24, 0.03, 0.9], [10.0, -165.0, 5.0], [0.8, 0.1, 0.1])
    rot = Rotation.from_euler("xyz", [10.0, -165.0, 5.0], degrees=True)
    signs = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)]) * 0.02
    np.testing.assert_allclose(cube.vertices(), rot.apply(signs) + [0.24, 0.03, 0.9], atol=1e-15)
    mesh = trimesh.Trimesh(cube.mesh().vertices, cube.mesh().faces)  # merges the duplicated corners
    assert mesh.is_watertight and mesh.is_winding_consistent
    np.testing.assert_allclose(mesh.volume, 0.04**3, rtol=1e-12)  # positive: faces wound outward
    for f in range(6):
        np.testing.assert_allclose(mesh.face_normals[2 * f], cube.face_normals[f], atol=1e-12)


def test_front_face_points_toward_axis_and_corners_are_ccw():
    m = CylinderMirror(0.1, 0.5, [0, 0, 0], [0, 1, 0])
    rng = np.random.default_rng(5)
    for _ in range(20):
        c = rng.uniform([-0.5, -0.1, -0.5], [0.5, 0.1, 0.5])
        cube = Cube(0.04, c, Rotation.random(random_state=int(rng.integers(1e6))).as_matrix())
        face, corners, center = cube.front_face(m)
        toward = -np.array([c[0], 0.0, c[2]]) / np.hypot(c[0], c[2])
        assert np.argmax(cube.face_normals @ toward) == face
        n = cube.face_normals[face]
        np.testing.assert_allclose(center, c + 0.02 * n, atol=1e-15)
        for k in range(4):  # counter-clockwise about the outward normal
            e_a = corners[(k + 1) % 4] - corners[k]
            e_b = corners[(k + 2) % 4] - corners[(k + 1) % 4]
            assert np.cross(e_a, e_b) @ n > 0
        np.testing.assert_allclose(np.linalg.norm(np.diff(corners, axis=0, append=corners[:1]), axis=1), 0.04)


def test_ground_checker_alternates():
    g = GroundPlane(point=[0, -0.2, 0], normal=[0, 1, 0], checker=0.1)
    pts = np.array([[0.05, -0.2, 0.05], [0.15, -0.2, 0.05], [0.15, -0.2, 0.15]])
    par = g.cell_parity(pts)
    assert par[0] != par[1] and par[0] == par[2]


def test_scene_validation():
    with pytest.raises(RaytraceError, match=r"objects\[0\]: expected a Cube"):
        Scene(None, ["cube"])
    with pytest.raises(RaytraceError, match="size: expected a positive"):
        Cube(0.0, [0, 0, 0])
    with pytest.raises(RaytraceError, match="rotation: expected an orthonormal"):
        Cube(0.1, [0, 0, 0], np.diag([1.0, 1.0, 2.0]))
