"""Tests of raytrace.render: Embree vs the numpy twin, determinism, the XSlit aspect ratio, and Mitsuba 3."""

import os

import numpy as np
import pytest
from rt_scenes import cylinder, mirror_scene, small_camera

import raytrace.render as rr
from raytrace.camera import PinholeCamera, XSlitCamera
from raytrace.errors import RaytraceError
from raytrace.scene import Cube, DirectionalLight, GroundPlane, Scene
from raytrace.truth import cylinder_reflection_points, mirror_rays
from raytrace.render import linear_to_srgb8, render


def _boundary(ids):
    p = np.pad(ids, 1, mode="edge")
    h, w = ids.shape
    out = np.zeros(ids.shape, bool)
    for dy in range(3):
        for dx in range(3):
            out |= p[dy : dy + h, dx : dx + w] != ids
    return out


@pytest.fixture(scope="module")
def twin_pair():
    scene = mirror_scene(ground=GroundPlane(point=[0.0, -0.2, 0.0], checker=0.05), size=0.08)
    cam = small_camera()
    return scene, cam, render(scene, cam, spp=4, seed=0, workers=1), render(scene, cam, spp=4, seed=0, workers=1, backend="numpy")


def test_numpy_twin_agrees_with_embree(twin_pair):
    scene, cam, emb, twin = twin_pair
    assert len(np.unique(emb.object_id)) == 4  # background and all three cubes are seen
    same = emb.object_id == twin.object_id
    assert same.mean() >= 0.999
    assert np.all(_boundary(twin.object_id)[~same])
    np.testing.assert_array_equal(emb.via_mirror, twin.via_mirror)
    both = emb.via_mirror & twin.via_mirror
    assert both.sum() > 5000
    np.testing.assert_allclose(emb.reflected_dir[both], twin.reflected_dir[both], rtol=0, atol=1e-9)
    np.testing.assert_allclose(emb.mirror_point[both], twin.mirror_point[both], rtol=0, atol=1e-9)
    assert np.all(np.isnan(emb.reflected_dir[~emb.via_mirror]))


def test_truth_arrays_match_ray_map_and_distances(twin_pair):
    scene, cam, emb, _ = twin_pair
    rays = mirror_rays(cam, scene.mirror)
    np.testing.assert_array_equal(rays.hit.reshape(120, 160), emb.via_mirror)
    np.testing.assert_allclose(emb.reflected_dir.reshape(-1, 3)[rays.hit], rays.directions[rays.hit], atol=1e-12)
    # a pixel that sees a cube in the mirror: distance = |camera − mirror point| + |mirror point − surface|,
    # and the surface point lies on the cube's boundary
    ids = emb.object_id.reshape(-1)
    k = np.flatnonzero((ids == 0) & rays.hit)[0]
    m = rays.points[k]
    total = float(emb.ray_distance.reshape(-1)[k])
    surface = m + (total - np.linalg.norm(m - cam.position)) * rays.directions[k]
    local = (surface - scene.objects[0].center) @ scene.objects[0].rotation
    assert abs(np.max(np.abs(local)) - scene.objects[0].size / 2) < 1e-5  # float32 distance


def test_faces_differ_in_brightness_and_srgb(twin_pair):
    _, _, emb, _ = twin_pair
    img = emb.image[emb.object_id == 0]
    levels = np.unique(np.round(img[:, 0], 6))
    assert len(levels) >= 2  # at least two faces of cube 0 with different shading
    s = linear_to_srgb8(np.array([[[0.0, 0.0031308, 1.0]]]))
    assert s.dtype == np.uint8 and s.tolist() == [[[0, 10, 255]]]  # 12.92·0.0031308·255 = 10.3


def test_same_seed_same_bytes_and_parallel_tiles(monkeypatch):
    scene = mirror_scene(size=0.08)
    cam = small_camera()
    a = render(scene, cam, spp=4, seed=5, workers=1)
    b = render(scene, cam, spp=4, seed=5, workers=1)
    assert a.image.tobytes() == b.image.tobytes()
    c = render(scene, cam, spp=4, seed=6, workers=1)
    assert a.image.tobytes() != c.image.tobytes()
    assert np.array_equal(a.object_id, c.object_id)  # pixel centres do not depend on the seed
    monkeypatch.setattr(rr, "MIN_PARALLEL_PIXELS", 1000)
    monkeypatch.setattr(rr, "TILE_PIXELS", 4096)
    monkeypatch.setattr(rr, "CHUNK_PIXELS", 256)
    calls = []
    p = render(scene, cam, spp=4, seed=5, workers=2, progress=lambda d, t: calls.append((d, t)))
    s = render(scene, cam, spp=4, seed=5, workers=1)
    assert p.image.tobytes() == s.image.tobytes()
    assert np.array_equal(p.reflected_dir, s.reflected_dir, equal_nan=True)
    assert calls and calls[-1][0] == calls[-1][1]


def test_render_into_given_arrays_in_place_or_by_copy(monkeypatch, tmp_path):
    """`out=`: file-backed memmaps are written in place by the forked workers, other arrays by a copy."""
    scene = mirror_scene(size=0.08)
    cam = small_camera()
    monkeypatch.setattr(rr, "MIN_PARALLEL_PIXELS", 1000)
    monkeypatch.setattr(rr, "TILE_PIXELS", 4096)
    ref = render(scene, cam, spp=4, seed=5, workers=1)
    h, w = ref.object_id.shape
    maps = {name: np.memmap(tmp_path / name, dtype=dtype, mode="w+", shape=(h, w) + tail)
            for name, (tail, dtype) in rr.OUTPUTS.items() if name in ("mirror_point", "reflected_dir")}
    plain = {"image": np.full((h, w, 3), -1.0), "object_id": np.full((h, w), 99, dtype=np.int32)}
    got = render(scene, cam, spp=4, seed=5, workers=2, out={**maps, **plain})
    for name in ("mirror_point", "reflected_dir"):
        assert np.shares_memory(getattr(got, name), maps[name])
        reread = np.fromfile(tmp_path / name, dtype=np.float64).reshape(h, w, 3)  # what the workers wrote
        assert np.array_equal(reread, getattr(ref, name), equal_nan=True)
    assert got.image is plain["image"] and got.object_id is plain["object_id"]
    assert got.image.tobytes() == ref.image.tobytes()
    assert np.array_equal(got.object_id, ref.object_id)
    assert np.array_equal(got.ray_distance, ref.ray_distance)


def test_render_out_validation():
    scene, cam = mirror_scene(), small_camera()
    h, w = cam.resolution[1], cam.resolution[0]
    with pytest.raises(RaytraceError, match="unknown array 'colour'"):
        render(scene, cam, out={"colour": np.zeros((h, w, 3))})
    with pytest.raises(RaytraceError, match=r"out\['image'\]: expected a float64 array of shape \(120, 160, 3\)"):
        render(scene, cam, out={"image": np.zeros((h, w, 3), dtype=np.float32)})
    with pytest.raises(RaytraceError, match="C-contiguous writeable"):
        render(scene, cam, out={"object_id": np.zeros((w, h), dtype=np.int32).T})


def _edges_reference(key):
    """Some pixel of the 3×3 neighbourhood (clipped at the border) has a different key."""
    h, w = key.shape
    out = np.zeros(key.shape, bool)
    for y in range(h):
        for x in range(w):
            nb = key[max(y - 1, 0) : y + 2, max(x - 1, 0) : x + 2]
            out[y, x] = (nb != key[y, x]).any()
    return out


@pytest.mark.parametrize("shape", [(1, 1), (1, 6), (6, 1), (5, 7), (23, 17)])
def test_edge_pixels_are_those_with_a_different_neighbour(shape):
    rng = np.random.default_rng(shape[0] * 31 + shape[1])
    for levels in (2, 5):
        key = rng.integers(0, levels, size=shape)
        assert np.array_equal(rr._edges(key), _edges_reference(key))
    blocks = np.kron(rng.integers(0, 3, size=(4, 4)), np.ones((6, 6), dtype=int))  # larger flat areas
    assert np.array_equal(rr._edges(blocks), _edges_reference(blocks))


def test_srgb_over_several_blocks_matches_the_formula(monkeypatch):
    monkeypatch.setattr(rr, "SRGB_BLOCK", 1000)
    x = np.random.default_rng(2).uniform(-0.2, 1.2, size=(31, 29, 3))  # 2697 values: 3 blocks
    c = np.clip(x, 0, 1)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    expected = np.floor(srgb * 255 + 0.5)
    got = linear_to_srgb8(x)
    assert got.shape == x.shape and got.dtype == np.uint8
    off = np.abs(got.astype(int) - expected)
    assert off.max() <= 1 and (off == 0).mean() > 0.999  # ±1 only at exact .5 ties (round half to even)
    assert np.array_equal(linear_to_srgb8(x.astype(np.float32)), linear_to_srgb8(x.astype(np.float32).astype(np.float64)))


def test_keep_freed_memory_on_glibc():
    import platform
    if platform.libc_ver()[0] != "glibc":
        pytest.skip("not glibc")
    assert rr.keep_freed_memory() is True


def test_plain_pages_turns_numpys_huge_page_advice_off_unless_its_variable_says(monkeypatch):
    from numpy._core.multiarray import _set_madvise_hugepage

    # it returns the setting it replaces
    before = _set_madvise_hugepage(True)
    try:
        monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
        assert rr.plain_pages() is True
        assert _set_madvise_hugepage(True) is False  # it was off
        monkeypatch.setenv("NUMPY_MADVISE_HUGEPAGE", "1")  # the user's word stands
        assert rr.plain_pages() is False
        assert _set_madvise_hugepage(True) is True  # left on
    finally:
        _set_madvise_hugepage(before)


def test_adaptive_matches_full_supersampling():
    """Flat shading: pixels without an edge in their 3×3 neighbourhood have the exact average at their centre."""
    scene = mirror_scene(size=0.08)
    cam = small_camera()
    a = render(scene, cam, spp=4, seed=1, workers=1)
    f = render(scene, cam, spp=4, seed=1, workers=1, adaptive=False)
    assert a.rays_traced < f.rays_traced / 2
    np.testing.assert_allclose(a.image, f.image, atol=1e-12)


def test_render_validation():
    scene = mirror_scene()
    with pytest.raises(RaytraceError, match="spp: expected an integer >= 1"):
        render(scene, small_camera(), spp=0)
    with pytest.raises(RaytraceError, match="backend: expected 'embree' or 'numpy'"):
        render(scene, small_camera(), backend="optix")


def test_xslit_render_of_frontal_square_shows_paper_aspect_ratio():
    """Aspect ratio of a square at depth z: r_i = z2 (z − z1) / (z1 (z − z2)) (paper Eqn. pinproj, r_o = 1)."""
    z1, z2, z = -0.2, -0.5, 0.4
    size = 0.04
    cam = XSlitCamera((320, 200), z1, z2, 0.0, np.pi / 2, pitch=1e-4)
    cube = Cube(size, [0.0, 0.0, z + size / 2], np.eye(3), [1.0, 1.0, 1.0])
    scene = Scene(None, [cube], light=DirectionalLight([0.0, 0.0, -1.0], intensity=0.5, ambient=0.5), background=[0.0, 0.0, 0.0])
    r = render(scene, cam, spp=256, seed=0, workers=1)
    lum = r.image[..., 0]
    c = lum[100, 160]
    assert c == pytest.approx(1.0)
    cover = lum / c
    rows = np.flatnonzero(np.all(cover[:, 140:180] > 0.999, axis=1))
    cols = np.flatnonzero(np.all(cover[90:110, :] > 0.999, axis=0))
    width_u = cover[rows[5:-5]].sum(axis=1).mean()  # along v1 = e_x (slit 1)
    width_v = cover[:, cols[5:-5]].sum(axis=0).mean()  # along v2 = e_y (slit 2)
    expected = z2 * (z - z1) / (z1 * (z - z2))
    assert width_u / width_v == pytest.approx(expected, rel=2e-3)
    # absolute size too: κ_u = −z2/(z − z2)·κ_x
    assert width_u * 1e-4 == pytest.approx(-z2 / (z - z2) * size, rel=2e-3)


def _mitsuba_masks(cam, mirror, cubes, spp):
    mi = pytest.importorskip("mitsuba")
    from mitsuba_reference import sensor_and_mirror
    mi.set_variant("scalar_rgb")
    scene = sensor_and_mirror(cam, mirror, spp)
    for k, cube in enumerate(cubes):
        m4 = np.eye(4)
        m4[:3, :3] = cube.rotation * (cube.size / 2)
        m4[:3, 3] = cube.center
        rgb = [0.0, 0.0, 0.0]
        rgb[k] = 1.0
        scene[f"cube{k}"] = {
            "type": "cube",
            "to_world": mi.ScalarTransform4f(m4.tolist()),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": rgb}},
        }
    img = np.array(mi.render(mi.load_dict(scene)))[..., :3]
    return img


def test_cube_masks_agree_with_mitsuba():
    pytest.importorskip("mitsuba")
    mirror = cylinder()
    cubes = [Cube.from_euler_deg(0.1, [0.35, 0.0, 0.75], [0.0, -150.0, 0.0]), Cube.from_euler_deg(0.08, [-0.3, 0.05, 0.8], [0.0, 160.0, 0.0])]
    # aim a narrow camera at the mirror point that shows cube 0, so each cube covers many pixels
    eye = np.array([0.0, 0.0, 0.55])
    aim, ok = cylinder_reflection_points(mirror, eye, np.array([c.center for c in cubes]))
    assert ok.all()
    look = 0.5 * (aim[0] + aim[1])
    cam = PinholeCamera.from_look_at((200, 240), 1200.0, None, eye, look, [0.0, 1.0, 0.0])
    ours = render(Scene(mirror, cubes), cam, spp=1, workers=1)
    theirs = _mitsuba_masks(cam, mirror, cubes, spp=64)
    for k in range(len(cubes)):
        a = ours.object_id == k
        b = theirs[..., k] > 0.5
        assert a.sum() > 500
        iou = (a & b).sum() / (a | b).sum()
        assert iou >= 0.98, (k, iou)


def test_the_workers_use_the_bvhs_built_before_they_fork(tmp_path, monkeypatch):
    """A worker that builds an Embree scene runs Embree's task scheduler as the parent left it, without its threads
    (a `make test` hung so, in a worker's first query): `render` builds and commits its BVHs before forking, and the
    workers query those. Every Embree scene of a two-worker render is built in this process."""
    builders = tmp_path / "built_by"
    real = rr.build_scene

    def recorded(triangles):
        with open(builders, "a") as f:
            f.write(f"{os.getpid()}\n")
        return real(triangles)

    monkeypatch.setattr(rr, "build_scene", recorded)
    scene = mirror_scene(ground=GroundPlane(point=[0.0, -0.2, 0.0], checker=0.05))
    cam = small_camera(320, 240)  # above MIN_PARALLEL_PIXELS: its tiles go to the workers
    assert cam.resolution[0] * cam.resolution[1] >= rr.MIN_PARALLEL_PIXELS
    out = render(scene, cam, spp=2, seed=0, workers=2)
    assert {int(line) for line in builders.read_text().split()} == {os.getpid()}
    np.testing.assert_array_equal(out.image, render(scene, cam, spp=2, seed=0, workers=1).image)
