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


def test_cube_hits_agrees_with_trimesh_ray_casts():
    """`Cube.hits` (slab test) against trimesh's ray–triangle intersection on the cube's own mesh, for
    random rays from outside and from inside the cube, plus rays parallel to a pair of faces."""
    rng = np.random.default_rng(3)
    cube = Cube(0.3, np.array([0.1, -0.2, 0.5]), Rotation.from_euler("xyz", [20, -35, 50], degrees=True).as_matrix())
    origins = cube.center + rng.uniform(-0.6, 0.6, (400, 3))
    targets = cube.center + rng.uniform(-0.25, 0.25, (400, 3))
    dirs = targets - origins
    dirs[::2] *= -1.0  # half of them point away from the cube
    local = np.zeros((40, 3))
    local[:, 0] = 1.0  # along the local x axis, at heights inside and outside the slab of y and z
    local_origins = np.column_stack([np.full(40, -1.0), rng.uniform(-0.3, 0.3, (40, 2))])
    origins = np.vstack([origins, cube.center + local_origins @ cube.rotation.T])
    dirs = np.vstack([dirs, local @ cube.rotation.T])
    mesh = trimesh.Trimesh(cube.vertices(), _box_faces(), process=False)
    expected = np.zeros(len(origins), dtype=bool)
    expected[mesh.ray.intersects_first(origins, dirs) >= 0] = True
    inside = np.all(np.abs((origins - cube.center) @ cube.rotation) < cube.size / 2, axis=1)
    expected |= inside  # a ray from inside meets the cube at t = 0
    got = cube.hits(origins, dirs)
    assert got.sum() > 50 and (~got).sum() > 50
    assert np.array_equal(got, expected)


def test_cube_entry_faces_are_the_faces_trimesh_rays_meet_first():
    """`Cube.entry_faces` against trimesh's first ray–triangle hit on a box built from the vertices alone
    (`_box_faces`, its quads mapped to `FACE_AXES` here): from outside, the face met first; from inside,
    behind the cube or beside it, −1."""
    rng = np.random.default_rng(5)
    cube = Cube(0.2, np.array([-0.1, 0.3, 0.4]), Rotation.from_euler("xyz", [-40, 15, 70], degrees=True).as_matrix())
    origins = cube.center + rng.uniform(-0.5, 0.5, (2000, 3))
    dirs = cube.center + rng.uniform(-0.15, 0.15, (2000, 3)) - origins
    dirs[::3] *= -1.0  # a third point away from the cube
    mesh = trimesh.Trimesh(cube.vertices(), _box_faces(), process=False)
    tri = mesh.ray.intersects_first(origins, dirs)
    quad_face = np.array([1, 0, 3, 2, 5, 4])  # _box_faces' quads: −x, +x, −y, +y, −z, +z
    expected = np.where(tri >= 0, quad_face[tri // 2], -1)
    inside = np.all(np.abs((origins - cube.center) @ cube.rotation) < cube.size / 2, axis=1)
    expected[inside] = -1
    got = cube.entry_faces(origins, dirs)
    assert np.all(np.bincount(got[got >= 0], minlength=6) > 20) and np.count_nonzero(got < 0) > 200
    assert np.array_equal(got, expected)
    # rays exactly parallel to four faces (an axis-aligned cube), between their planes or beside them
    square = Cube(0.2, np.array([-0.1, 0.3, 0.4]))
    along = np.column_stack([np.full(40, -1.0), rng.uniform(-0.15, 0.15, (40, 2))])
    tri = trimesh.Trimesh(square.vertices(), _box_faces(), process=False).ray.intersects_first(
        square.center + along, np.tile([1.0, 0.0, 0.0], (40, 1)))
    got = square.entry_faces(square.center + along, np.tile([1.0, 0.0, 0.0], (40, 1)))
    assert np.count_nonzero(got == 1) > 10 and np.count_nonzero(got < 0) > 10  # through −x, or beside
    assert np.array_equal(got, np.where(tri >= 0, quad_face[tri // 2], -1))
    nan = np.full((1, 3), np.nan)
    assert cube.entry_faces(nan, dirs[:1])[0] == -1 and cube.entry_faces(origins[:1], nan)[0] == -1


def _box_faces():
    """Triangles of the cube with `Cube.vertices`' numbering (bit 0: x, bit 1: y, bit 2: z)."""
    quads = [(0, 2, 6, 4), (1, 5, 7, 3), (0, 4, 5, 1), (2, 3, 7, 6), (0, 1, 3, 2), (4, 6, 7, 5)]
    return np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
