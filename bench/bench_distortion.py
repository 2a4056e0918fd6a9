"""Lens distortion: reading a photograph taken through a lens that bends its rays (`[camera] distortion`).

Scenes: `make_scenes(N_SCENES, SEED, distance=DISTANCE)`, the reconstruct bench's kind of scene seen through a
wide-angle lens (the camera 2.2–3.2 mirror radii from the axis, the mirror spanning 55–80 % of the image width:
60–73° across), each with a distortion drawn as such lenses have it (`lens`: barrel, k1 in [−0.30, −0.05],
k2 in [0, 0.12], p1 and p2 within ±1e-3). Images of each:

- `ours`: our renderer through the distorted camera (16 spp; our lens model, `raytrace.lens`, applied), and through
  the ideal camera for reference (`ours, undistorted`);
- `mitsuba` (the first N_MITSUBA scenes): Mitsuba 3 renders the ideal camera's view on a canvas wide enough for
  every distorted pixel, SUPERSAMPLE times finer at 1 sample per pixel; `raytrace.lens.distorted_image` averages
  SUPERSAMPLE² of its points over each pixel, taken to the ideal image by OpenCV's own `cv2.undistortPoints`: a
  renderer and a distortion other than ours. The canvas's centre averaged alike is the ideal camera's image
  (`mitsuba, undistorted`).

Readings, `exact`: `known` (the setup's coefficients), `ignored` (the ideal camera, as a setup without the key
reads the image), `undistorted` (the ideal camera's own image through it). Per reading: recall, false positives,
the centre error ‖ĉ − c‖ / (distance of c to the axis) (median, max, over 3 %), depth within 1 / 2 / 3 σ; the
time of `ours, known` over `ours, ignored` (the same image in one process: the two readings' work differs where they
see different faces), the work the lens alone adds (the image read through the ideal camera and through one whose
lens bends by 1e-12, every ray undistorted and the reading the same but for rounding; alternated, best of 2), and
how far the distortion moves the faces' corners.

Run: `python -m bench distortion [--quick]` (in `make bench`); renders are cached in bench/out/renders/, the result
goes to bench/out/distortion.json.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np

N_SCENES, SEED, DISTANCE = 12, 9191, (2.2, 3.2)
N_MITSUBA = 4
QUICK_SCENES = 2
READINGS = ("ours, known", "ours, ignored", "ours, undistorted", "mitsuba, known", "mitsuba, ignored",
            "mitsuba, undistorted")


def lens(rng) -> tuple:
    """OpenCV's (k1, k2, p1, p2, k3) of a wide-angle lens: barrel distortion and a little decentring."""
    return (round(float(rng.uniform(-0.30, -0.05)), 4), round(float(rng.uniform(0.0, 0.12)), 4),
            round(float(rng.uniform(-1e-3, 1e-3)), 6), round(float(rng.uniform(-1e-3, 1e-3)), 6), 0.0)


def scenes(quick: bool):
    """(scene, its distorted setup) of each bench scene."""
    from bench.scenes import make_scenes
    out = []
    for sc in make_scenes(QUICK_SCENES if quick else N_SCENES, SEED, distance=DISTANCE):
        rng = np.random.default_rng([SEED, int(sc.key[:8], 16)])
        cam = dataclasses.replace(sc.setup.camera, distortion=lens(rng))
        out.append((sc, dataclasses.replace(sc.setup, camera=cam)))
    return out


SUPERSAMPLE = 4
"""The ideal render's resolution over the image's, each way: a distorted pixel averages SUPERSAMPLE² samples of it."""


def opencv_ideal_pixels(camera):
    """Distorted pixels → ideal pixels of `camera` by OpenCV's `cv2.undistortPoints` (run to convergence), not ours."""
    import cv2
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    return lambda px: cv2.undistortPoints(px.reshape(-1, 1, 2), camera.K, camera.distortion, P=camera.K,
                                          criteria=crit).reshape(-1, 2)


def canvas_pad(camera) -> int:
    """Pixels by which the ideal canvas must exceed `camera`'s image each way to hold every distorted pixel's
    ideal point (OpenCV's undistortion of the image's border, 1 px beyond it), and 4 more."""
    import cv2
    w, h = camera.resolution
    t = np.linspace(-1.0, 1.0, 513)
    border = np.concatenate([np.column_stack([(w - 1) / 2 + (w + 1) / 2 * t, np.full_like(t, y)]) for y in (-1.0, h)]
                            + [np.column_stack([np.full_like(t, x), (h - 1) / 2 + (h + 1) / 2 * t]) for x in (-1.0, w)])
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    ideal = cv2.undistortPoints(border.reshape(-1, 1, 2), camera.K, camera.distortion, P=camera.K,
                                criteria=crit).reshape(-1, 2)
    return int(np.ceil(max(0.0, -ideal[:, 0].min(), ideal[:, 0].max() - (w - 1), -ideal[:, 1].min(),
                           ideal[:, 1].max() - (h - 1)))) + 4


def hi_res_canvas(setup, pad: int, factor: int = SUPERSAMPLE):
    """`setup` with its ideal camera widened by `pad` px each way and `factor` times the resolution (the pixel
    convention of `raytrace.lens.distorted_image`): the principal point stays the canvas's centre where it was the
    image's."""
    c = setup.camera
    (w, h), (cx, cy) = c.resolution, c.principal
    cam = dataclasses.replace(c, distortion=None, resolution=(factor * (w + 2 * pad), factor * (h + 2 * pad)),
                              focal_px=(factor * c.focal_px[0], factor * c.focal_px[1]),
                              principal_px=(factor * (cx + pad) + (factor - 1) / 2,
                                            factor * (cy + pad) + (factor - 1) / 2))
    return dataclasses.replace(setup, camera=cam)


def mitsuba_images(setup, distorted_camera) -> tuple[np.ndarray, np.ndarray] | None:
    """`setup` (ideal camera) rendered by Mitsuba 3 on a canvas wide enough for every pixel of `distorted_camera`,
    SUPERSAMPLE times finer at 1 sample per pixel (cached as the renders are): (the image `distorted_camera` takes,
    `raytrace.lens.distorted_image` through OpenCV's undistortion; the ideal camera's, its centre averaged alike),
    or None without Mitsuba."""
    from bench import mitsuba_scenes as ms
    from bench.bench_lighting import mitsuba_cached
    from raytrace.lens import distorted_image
    if not ms.mitsuba_available():
        return None
    pad, f = canvas_pad(distorted_camera), SUPERSAMPLE
    hi = mitsuba_cached(hi_res_canvas(setup, pad), f"hi{f}", "hires", ms.LIGHT_TRAVEL, ms.SUN_IRRADIANCE,
                        ms.ENV_RADIANCE, spp=1)
    ideal_camera = dataclasses.replace(distorted_camera, distortion=None)
    return (distorted_image(hi, distorted_camera, pad, f, opencv_ideal_pixels(distorted_camera)),
            distorted_image(hi, ideal_camera, pad, f, lambda px: px))


def run(quick: bool = False, log=print) -> dict:
    from bench.bench_reconstruct import our_render, score
    from depth.reconstruct import reconstruct
    from raytrace.truth import cube_truth
    records, t_start = [], time.perf_counter()
    todo = scenes(quick)
    first = todo[0][0].setup
    reconstruct(our_render(first), first.camera.build(), first.mirror.build())  # imports and helper, before timing
    for n, (sc, setup_d) in enumerate(todo):
        cam_d, cam_0, mirror = setup_d.camera.build(), sc.setup.camera.build(), sc.setup.mirror.build()
        truth = {"known": [cube_truth(cam_d, mirror, c.build()) for c in sc.setup.objects],
                 "undistorted": [cube_truth(cam_0, mirror, c.build()) for c in sc.setup.objects]}
        truth["ignored"] = truth["known"]
        moved = max(float(np.linalg.norm(np.subtract(a["front_face_corners_px"], b["front_face_corners_px"]),
                                         axis=1).max()) for a, b in zip(truth["known"], truth["undistorted"]))
        images = {"ours": (our_render(setup_d), our_render(sc.setup))}
        if n < N_MITSUBA:
            images["mitsuba"] = mitsuba_images(sc.setup, cam_d)
            if images["mitsuba"] is None:
                log(f"  {sc.name}: Mitsuba 3 not installed (pip install -e '.[bench]'), its images skipped")
        seconds = {}
        for reading in READINGS:
            which, how = reading.split(", ")
            if images.get(which) is None:
                continue
            img = images[which][1 if how == "undistorted" else 0]
            t = time.perf_counter()
            rec = reconstruct(img, cam_d if how == "known" else cam_0, mirror)
            seconds[reading] = time.perf_counter() - t
            s = score([c.to_dict() for c in rec.cubes], truth[how], [sc.kind] * len(sc.setup.objects),
                      list(sc.turn_deg))
            records.append({"scene": sc.name, "reading": reading, "distortion": list(setup_d.camera.distortion),
                            "corner_move_px": moved, "seconds": seconds[reading],
                            "false_positives": s["false_positives"], "cubes": s["cubes"]})
        # the work the lens adds, alone: the same image read through the ideal camera and through one whose lens
        # bends by 1e-12 (every ray undistorted, the reading the same but for rounding), alternated, best of 2
        cam_eps = dataclasses.replace(cam_0, distortion=[1e-12, 0.0, 0.0, 0.0])
        lens_cost = {}
        for cam in (cam_0, cam_eps, cam_eps, cam_0):
            t = time.perf_counter()
            reconstruct(images["ours"][0], cam, mirror)
            lens_cost[cam is cam_eps] = min(lens_cost.get(cam is cam_eps, np.inf), time.perf_counter() - t)
        records[-1]["lens_cost_seconds"] = {"through_lens": lens_cost[True], "ideal": lens_cost[False]}
        log(f"  [{n + 1}/{len(todo)}] {sc.name} {sc.setup.camera.resolution[0]}×{sc.setup.camera.resolution[1]} "
            f"k1 {setup_d.camera.distortion[0]:+.3f}, corners moved up to {moved:.1f} px, time known / ignored "
            f"{seconds['ours, known'] / seconds['ours, ignored']:.2f}, through a lens {lens_cost[True]:.2f} / "
            f"{lens_cost[False]:.2f} s; elapsed {time.perf_counter() - t_start:.0f} s")
    return {"records": records, "quick": quick, "seconds_total": time.perf_counter() - t_start}


def report(result: dict, log=print) -> dict:
    from bench.bench_known_size import reading_table, summarize
    records = result["records"]
    out = reading_table(records, READINGS, summarize, log)
    ratios = []
    for name in sorted({r["scene"] for r in records}):
        sec = {r["reading"]: r["seconds"] for r in records if r["scene"] == name}
        ratios.append(sec["ours, known"] / sec["ours, ignored"])
    if ratios:
        out["time_known_over_ignored"] = {"median": float(np.median(ratios)), "max": float(np.max(ratios))}
        log(f"time, an image read with its distortion over the same image read without it (one process): median "
            f"{np.median(ratios):.2f}, max {np.max(ratios):.2f} ({len(ratios)} scenes)")
    costs = [r["lens_cost_seconds"] for r in records if "lens_cost_seconds" in r]
    if costs:
        ratio = [c["through_lens"] / c["ideal"] for c in costs]
        extra = [c["through_lens"] - c["ideal"] for c in costs]
        out["lens_cost"] = {"median": float(np.median(ratio)), "max": float(np.max(ratio)),
                            "extra_seconds_median": float(np.median(extra)), "extra_seconds_max": float(np.max(extra))}
        log(f"the work the lens adds (the same image read through a lens bending by 1e-12 over the ideal camera, best "
            f"of 2, alternated): median {np.median(ratio):.3f}, max {np.max(ratio):.3f}; {np.median(extra):+.3f} s "
            f"(median), {np.max(extra):+.3f} s at most")
    moves = list({r["scene"]: r["corner_move_px"] for r in records}.values())
    if moves:
        log(f"the distortion moves the faces' corners by up to {np.median(moves):.1f} px (median over the scenes), "
            f"{np.max(moves):.1f} px at most")
    return out


def main(argv=None) -> int:
    from bench.bench_known_size import written_main
    return written_main("distortion", "lens distortion: wide-angle scenes{quick} through a distorted lens; readings "
                        + ", ".join(READINGS), run, report, argv)


if __name__ == "__main__":
    sys.exit(main())
