"""A photograph through a distorting lens: `[camera] distortion` through `simulate` and `reconstruct`.

The scene (tests/data/wide_lens.toml) is seen through a wide-angle lens, 63° across, with a barrel distortion
that moves its cubes' faces by up to 5 px. Its image is made twice: by `catadioptric simulate` through the
distorted camera (our lens model), and by rendering the ideal camera's view on a wider canvas and resampling it
with OpenCV's own undistortion map (`cv2.undistortPoints`, `cv2.remap`), a distortion made by code other than ours.
"""

import dataclasses
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from catadioptric.cli import main
from catadioptric.setup import load_setup, save_setup

SETUP = Path(__file__).resolve().parents[1] / "data" / "wide_lens.toml"


def _errors(result: dict, truth: list) -> list:
    """Centre error ‖ĉ − c‖ / depth of each true cube (None where none was read within 20 px of its face)."""
    t_mid = np.array([np.mean(t["front_face_corners_px"], axis=0) for t in truth])
    out = [None] * len(truth)
    for c in result["cubes"]:
        d = np.linalg.norm(t_mid - np.mean(c["front_face_corners_px"], axis=0), axis=1)
        j = int(np.argmin(d))
        if d[j] <= 20.0:
            out[j] = float(np.linalg.norm(np.subtract(c["center"], truth[j]["center"])) / truth[j]["depth"])
    return out


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lens")
    assert main(["simulate", str(SETUP), "-o", str(folder / "mirror.png"), "--spp", "16"]) == 0
    setup = load_setup(folder / "mirror.toml")
    save_setup(dataclasses.replace(setup, camera=dataclasses.replace(setup.camera, distortion=None)),
               folder / "ideal.toml")
    return folder


def test_simulate_renders_through_the_lens_and_writes_it_into_the_setup_and_the_truth(rendered):
    """The written setup keeps the coefficients. Each true corner pixel's ray, traced through the distorted camera,
    meets the mirror at a point OpenCV's projectPoints puts on that pixel, and is reflected through the 3D corner;
    the ideal camera would have put the corners pixels away."""
    from raytrace.truth import mirror_rays
    setup = load_setup(rendered / "mirror.toml")
    assert setup.camera.distortion == (-0.25, 0.08, 5e-4, -3e-4, 0.0)
    truth = json.loads((rendered / "mirror.truth.json").read_text())["cubes"]
    cam, mirror = setup.camera.build(), setup.mirror.build()
    px = np.concatenate([t["front_face_corners_px"] for t in truth])
    corners = np.concatenate([t["front_face_corners"] for t in truth])
    rays = mirror_rays(cam, mirror, px)
    ref, _ = cv2.projectPoints(rays.points, cv2.Rodrigues(cam.R)[0], -cam.R @ cam.position, cam.K,
                               np.asarray(setup.camera.distortion))
    np.testing.assert_allclose(ref.reshape(-1, 2), px, atol=1e-6)
    to_corner = corners - rays.points
    off = np.linalg.norm(np.cross(to_corner, rays.directions), axis=1) / np.linalg.norm(to_corner, axis=1)
    assert off.max() < 1e-9
    ideal = load_setup(rendered / "ideal.toml").camera.build()
    ideal_rays = mirror_rays(ideal, mirror, px)
    to_corner = corners - ideal_rays.points
    miss = np.linalg.norm(np.cross(to_corner, ideal_rays.directions), axis=1)  # m: the ideal camera's rays miss
    assert miss.max() > 1e-3


def test_reconstruct_reads_through_the_lens_and_not_without_it(rendered):
    truth = json.loads((rendered / "mirror.truth.json").read_text())["cubes"]
    assert main(["reconstruct", str(rendered / "mirror.png"), "-o", str(rendered / "known.json")]) == 0
    known = _errors(json.loads((rendered / "known.json").read_text()), truth)
    assert None not in known and max(known) < 0.02
    assert main(["reconstruct", str(rendered / "mirror.png"), "--setup", str(rendered / "ideal.toml"),
                 "-o", str(rendered / "ignored.json")]) == 0
    ignored = _errors(json.loads((rendered / "ignored.json").read_text()), truth)
    # the same image read as if the lens were ideal: a cube lost or the median error at least twice as large
    found = [e for e in ignored if e is not None]
    assert len(found) < len(truth) or np.median(found) > 2 * np.median(known)


def test_an_image_distorted_by_opencv_is_read_as_well_as_the_undistorted_one(tmp_path):
    """The ideal camera's view, rendered 4 times finer on a canvas wide enough, made into the distorted camera's
    image by `raytrace.lens.distorted_image` through OpenCV's undistortion map (each pixel averaging 16 points),
    and into the ideal camera's alike. Read with the setup's coefficients, each cube lies within 1 percentage point
    of its reading in the ideal image; read as if the lens were ideal, a cube is lost or the median error doubles."""
    from catadioptric.simulate import simulate
    from depth.reconstruct import reconstruct
    from raytrace.lens import distorted_image
    from raytrace.render import linear_to_srgb8
    from raytrace.truth import cube_truth
    setup = load_setup(SETUP)
    cam_d, mirror = setup.camera.build(), setup.mirror.build()
    ideal_setup = dataclasses.replace(setup, camera=dataclasses.replace(setup.camera, distortion=None))
    cam_0 = ideal_setup.camera.build()
    (w, h), (cx, cy), f, pad = setup.camera.resolution, setup.camera.principal, 4, 80
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)

    def opencv(px):
        return cv2.undistortPoints(px.reshape(-1, 1, 2), cam_d.K, cam_d.distortion, P=cam_d.K,
                                   criteria=crit).reshape(-1, 2)
    border = np.array([[-1.0, -1.0], [w, -1.0], [-1.0, h], [w, h], [cx, -1.0], [-1.0, cy]])
    assert np.abs(opencv(border) - border).max() < pad - 1  # the canvas holds every pixel's ideal point
    canvas = dataclasses.replace(ideal_setup.camera, resolution=(f * (w + 2 * pad), f * (h + 2 * pad)),
                                 focal_px=tuple(f * v for v in setup.camera.focal_px),
                                 principal_px=(f * (cx + pad) + (f - 1) / 2, f * (cy + pad) + (f - 1) / 2))
    hi = linear_to_srgb8(simulate(dataclasses.replace(setup, camera=canvas), spp=1, seed=0).render.image)
    images = {"known": (distorted_image(hi, cam_d, pad, f, opencv), cam_d),
              "undistorted": (distorted_image(hi, cam_0, pad, f, lambda px: px), cam_0)}
    images["ignored"] = (images["known"][0], cam_0)
    errors = {}
    for name, (img, cam) in images.items():
        truth = [cube_truth(cam_d if name != "undistorted" else cam_0, mirror, o.build()) for o in setup.objects]
        rec = reconstruct(img, cam, mirror)
        errors[name] = _errors({"cubes": [cube.to_dict() for cube in rec.cubes]}, truth)
    assert None not in errors["known"] and None not in errors["undistorted"]
    np.testing.assert_allclose(errors["known"], errors["undistorted"], atol=0.01)
    found = [e for e in errors["ignored"] if e is not None]
    assert len(found) < len(setup.objects) or np.median(found) > 2 * np.median(errors["known"])


def test_the_distortions_sigma_is_carried_as_whole_runs_through_the_moved_lens_say(rendered, capsys):
    """`[uncertainty] distortion`: each coefficient's σ. Its share of each cube's depth σ is the root sum of squares
    of what whole runs of the command make of the lens moved by ±σ in k1 and in k2 (half their difference): within
    5 % and 0.3 mm, the whole refits' own scatter on the near cube (47 px wide, 0.29 m off: its depth's move per σ
    0.22, 0.18 and 0.81 mm for σ 1, 3 and 10 times these, where the first order gives 0.10, 0.29 and 1.02 mm);
    the result names it."""
    import tomli_w
    import tomllib
    setup = tomllib.loads((rendered / "mirror.toml").read_text())
    sigma = [0.1, 0.05]
    setup["uncertainty"] = {"distortion": sigma}
    (rendered / "unsure.toml").write_text(tomli_w.dumps(setup))
    assert main(["reconstruct", str(rendered / "mirror.png"), "--setup", str(rendered / "unsure.toml"),
                 "-o", str(rendered / "unsure.json")]) == 0
    unsure = json.loads((rendered / "unsure.json").read_text())
    assert unsure["setup_uncertainty"] == {"distortion": sigma}
    halves = []
    for k, s in enumerate(sigma):
        ends = []
        for sign in (1.0, -1.0):
            moved = tomllib.loads((rendered / "mirror.toml").read_text())
            moved["camera"]["distortion"][k] += sign * s
            (rendered / "moved.toml").write_text(tomli_w.dumps(moved))
            assert main(["reconstruct", str(rendered / "mirror.png"), "--setup", str(rendered / "moved.toml"),
                         "-o", str(rendered / "moved.json")]) == 0
            ends.append([c["depth"] for c in json.loads((rendered / "moved.json").read_text())["cubes"]])
        halves.append(0.5 * (np.array(ends[0]) - np.array(ends[1])))
    whole_runs = np.sqrt(np.sum(np.square(halves), axis=0))
    shares = [c["uncertainty_from_setup"]["depth"] for c in unsure["cubes"]]
    assert len(shares) == len(whole_runs) == 4
    np.testing.assert_allclose(shares, whole_runs, rtol=0.05, atol=3e-4)
    assert min(whole_runs) > 1e-4  # each cube moves with the lens
