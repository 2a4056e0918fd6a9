"""Lateral chromatic aberration: reading images whose red and blue channels are magnified apart from green
(`[camera.red]`, `[camera.blue]`; `raytrace.chroma`, `depth.chroma`).

Scenes: `make_scenes(N_SCENES, SEED)`, the reconstruct bench's kind. Each gets an aberration drawn as a lens has it
(`aberration`): red magnified so that it images the image's farthest corner RED_SHIFT px (a range) farther out than
green, blue BLUE_SHIFT px farther in; a channel's focal lengths are green's times its magnification, about the
same principal point. Images of each, rendered through each channel's own camera and that channel kept:

- `ours`: our renderer (16 spp), `raytrace.render.render` of the aberrated camera;
- `mitsuba` (the first N_MITSUBA scenes): Mitsuba 3, one render per channel at that channel's focal length (its
  field of view), the reconstruct bench's lighting; a renderer and a pixel filter other than ours.

Each is read `declared` (the setup's channel lenses: red and blue resampled onto green's rays, `depth.chroma`, by
its default interpolation), `ignored` (read as if the lens had none), and the same scene's image without the
aberration (`clean`, each renderer's own, as the reconstruct bench renders it); and `declared, linear` (and so on):
the channels resampled by another interpolation instead (the image aligned by
`depth.chroma.aligned_to_green` and read through green's camera, which is what a declared reading does), one per
interpolation of `depth.chroma.INTERPOLATIONS` other than the default. Per
reading: recall, false positives, the centre error ‖ĉ − c‖ / (distance of c to the axis) (median, max, over 3 %),
depth within 1 / 2 / 3 σ; the time of a `declared` reading over the same image's `ignored` one (one process, each
the best of 2: the two readings' work differs where they see different faces), the alignment's own work (the image
read through red and blue lenses equal to green's, which resamples every channel and reads the same, over the
plain camera; alternated, the best of 2), and how far the aberration puts red and blue from green at the faces'
corners.

Run: `python -m bench chromatic [--quick]` (in `make bench`); renders are cached in bench/out/renders/, the result
goes to bench/out/chromatic.json.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

N_SCENES, SEED = 12, 5353
N_MITSUBA = 12
QUICK = 2
"""Scenes of each renderer with --quick."""
RED_SHIFT = (0.4, 1.2)
BLUE_SHIFT = (0.3, 1.0)
"""px: how far red images the farthest corner outward of green, and blue inward (drawn per scene)."""
def _others():
    from depth.chroma import INTERPOLATION, INTERPOLATIONS
    return [i for i in INTERPOLATIONS if i != INTERPOLATION]


READINGS = tuple(f"{renderer}, {reading}" for renderer in ("ours", "mitsuba")
                 for reading in ("clean", "declared", "ignored", *(f"declared, {i}" for i in _others())))


def aberration(setup, rng):
    """The setup with red magnified outward and blue inward (`RED_SHIFT`, `BLUE_SHIFT` at the farthest corner) as
    `[camera.red]` / `[camera.blue]` focal lengths."""
    from catadioptric.setup import ChannelConfig
    cam = setup.camera
    w, h = cam.resolution
    cx, cy = cam.principal
    corner = max(np.hypot(x - cx, y - cy) for x in (0, w - 1) for y in (0, h - 1))
    red = 1.0 + float(rng.uniform(*RED_SHIFT)) / corner
    blue = 1.0 - float(rng.uniform(*BLUE_SHIFT)) / corner
    fx, fy = cam.focal_px
    lensed = dataclasses.replace(cam, red=ChannelConfig(focal_px=(fx * red, fy * red)),
                                 blue=ChannelConfig(focal_px=(fx * blue, fy * blue)))
    return dataclasses.replace(setup, camera=lensed)


def mitsuba_aberrated(setup) -> np.ndarray | None:
    """Mitsuba's image through the aberrated camera: each channel from a render at that channel's focal length."""
    from bench.bench_reconstruct import mitsuba_image
    channels = []
    for k, name in enumerate(("red", "green", "blue")):
        lens = getattr(setup.camera, name, None)
        cam = dataclasses.replace(setup.camera, red=None, blue=None)
        if lens is not None:
            cam = dataclasses.replace(cam, focal_px=lens.focal_px)
        img = mitsuba_image(dataclasses.replace(setup, camera=cam))
        if img is None:
            return None
        channels.append(img[..., k])
    return np.stack(channels, axis=-1)


def corner_shifts(setup, truth) -> list:
    """px: how far red and blue image each face corner from green, over the scene's faces."""
    camera = setup.camera.build()
    out = []
    for name in ("red", "blue"):
        own = camera.channel_camera(name)
        for cube in truth:
            corners = np.asarray(cube["front_face_corners_px"], dtype=np.float64)
            o, d = camera.rays(corners)
            at, _ = own.project(o + d)
            out += np.linalg.norm(at - corners, axis=1).tolist()
    return out


def run(quick: bool = False, log=print) -> dict:
    from bench.bench_reconstruct import mitsuba_image, our_render, score
    from bench.scenes import make_scenes
    from depth.chroma import aligned_to_green
    from depth.reconstruct import reconstruct
    from raytrace.truth import cube_truth
    records, ratios, work, shifts, t_start = [], [], [], [], time.perf_counter()
    n = QUICK if quick else N_SCENES
    todo = [(j, renderer, sc) for j, sc in enumerate(make_scenes(n, SEED)) for renderer in ("ours", "mitsuba")
            if renderer == "ours" or j < (QUICK if quick else N_MITSUBA)]
    for i, (j, renderer, sc) in enumerate(todo):
        rng = np.random.default_rng([SEED, j])
        lensed = aberration(sc.setup, rng)
        camera, mirror = sc.setup.camera.build(), sc.setup.mirror.build()
        lensed_camera = lensed.camera.build()
        truth = [cube_truth(camera, mirror, c.build()) for c in sc.setup.objects]
        if renderer == "ours":
            clean, aberrated = our_render(sc.setup), our_render(lensed)  # (each channel through its own camera)
            shifts += corner_shifts(lensed, truth)
        else:
            clean, aberrated = mitsuba_image(sc.setup), mitsuba_aberrated(lensed)
            if clean is None or aberrated is None:
                log("  Mitsuba 3 is not installed: its readings skipped")
                continue
        jobs = [("clean", clean, camera), ("declared", aberrated, lensed_camera), ("ignored", aberrated, camera)]
        jobs += [(f"declared, {i}", aligned_to_green(aberrated, lensed_camera, i), camera) for i in _others()]
        seconds = {}
        for reading, image, cam in jobs:
            t = time.perf_counter()
            rec = reconstruct(image, cam, mirror)
            seconds[reading] = time.perf_counter() - t
            s = score([c.to_dict() for c in rec.cubes], truth, [sc.kind] * len(truth), list(sc.turn_deg))
            records.append({"renderer": renderer, "scene": sc.name, "reading": f"{renderer}, {reading}",
                            "seconds": seconds[reading], "false_positives": s["false_positives"], "cubes": s["cubes"]})
        for cam, reading in ((lensed_camera, "declared"), (camera, "ignored")):  # again: the best of 2 each
            t = time.perf_counter()
            reconstruct(aberrated, cam, mirror)
            seconds[reading] = min(seconds[reading], time.perf_counter() - t)
        ratios.append(seconds["declared"] / seconds["ignored"])
        work.append(alignment_work(aberrated, camera, mirror))
        log(f"  [{i + 1}/{len(todo)}] {renderer} {sc.name}: {len(truth)} cubes, time declared / ignored "
            f"{ratios[-1]:.2f}, the alignment's own work {work[-1]:.3f}; elapsed {time.perf_counter() - t_start:.0f} s")
    return {"records": records, "time_declared_over_ignored": ratios, "alignment_work": work, "corner_shift_px": shifts,
            "quick": quick, "seconds_total": time.perf_counter() - t_start}


def alignment_work(image, camera, mirror) -> float:
    """The time of a reading through a camera whose red and blue lenses are green's own (every channel resampled
    and stored again, the image and so the reading the same) over the plain camera's: alternated, the best of 2."""
    from depth.chroma import aligned_to_green
    from depth.reconstruct import reconstruct
    from raytrace.chroma import ChannelLens
    same = dataclasses.replace(camera, red=ChannelLens(camera.K, camera.distortion),
                               blue=ChannelLens(camera.K, camera.distortion))
    assert np.array_equal(aligned_to_green(image, same), image)  # (the same reading: nothing moves)
    best = {}
    for cam in (same, camera, same, camera):
        t = time.perf_counter()
        reconstruct(image, cam, mirror)
        best[cam is same] = min(best.get(cam is same, np.inf), time.perf_counter() - t)
    return best[True] / best[False]


def report(result: dict, log=print) -> dict:
    from bench.bench_known_size import reading_table, summarize
    readings = [r for r in READINGS if any(rec["reading"] == r for rec in result["records"])]
    out = reading_table(result["records"], readings, summarize, log)
    ratios, shifts = result["time_declared_over_ignored"], np.asarray(result["corner_shift_px"])
    out["time_declared_over_ignored"] = {"median": float(np.median(ratios)), "max": float(np.max(ratios))}
    out["corner_shift_px"] = {"median": float(np.median(shifts)), "max": float(np.max(shifts))}
    log(f"red and blue from green at the faces' corners (ours): median {np.median(shifts):.2f} px, max "
        f"{np.max(shifts):.2f} px")
    log(f"time, an image read with its channel lenses declared over the same image read without (best of 2 each, "
        f"one process): median {np.median(ratios):.3f}, max {np.max(ratios):.3f} ({len(ratios)} images)")
    work = result["alignment_work"]
    out["alignment_work"] = {"median": float(np.median(work)), "max": float(np.max(work))}
    log(f"the alignment's own work: a reading through red and blue lenses equal to green's (every channel resampled, "
        f"the same reading) over the plain camera's (alternated, best of 2): median {np.median(work):.3f}, max "
        f"{np.max(work):.3f}")
    return out


def main(argv=None) -> int:
    from bench.bench_known_size import written_main
    return written_main("chromatic", "lateral chromatic aberration: our renders and Mitsuba's{quick} through "
                        "red and blue lenses of their own; each read declared, ignored, and without the aberration",
                        run, report, argv)
