"""Cubes standing on a floor: how well `exact` reads them when told so (`--on-floor`).

Scenes as the reconstruct bench draws them (`bench.scenes.make_scenes(..., standing=True)`: the same ranges of
mirror radius, camera distance, resolution, cube size, turn and azimuth), but every cube standing on the floor
the mirror stands on (its lower end). Our renders (16 spp, the checkered ground there) in the reconstruct bench's
four variants (clean, noise, blur, JPEG), and Mitsuba 3 renders of other scenes (16 spp, a plain floor of a
drawn grey, the lighting bench's sky map and a sun from a drawn direction and strength: another renderer under
other light). Three readings of each image:

- `exact`: the size read from each face's own edges (the default);
- `exact, on the floor`: `floor_height` the floor's true height (`catadioptric reconstruct --on-floor`);
- `exact, floor ±1 mm`: `floor_height` drawn off the true one by N(0, 1 mm) (seeded per image), with `floor_std`
  1 mm: a floor that was itself measured, its σ carried into each depth's.

Per reading: recall, false positives, the centre error ‖ĉ − c‖ / (distance of c to the axis) (median, max, over
3 %), the size error's median, how often the depth lies within 1 / 2 / 3 reported σ, and the time per image
(the untouched pipeline on clean and Mitsuba images, each reading in turn; the other variants share the setup's
ray map, which gives the same results).

Run: `python -m bench on_floor [--quick]`; renders are cached in bench/out/renders/, the result goes to
bench/out/on_floor.json.
"""

from __future__ import annotations

import contextlib
import sys
import time

import numpy as np

N_SCENES, SEED = 12, 6006
N_MITSUBA, MITSUBA_SEED = 4, 6106
QUICK_SCENES, QUICK_MITSUBA = 3, 1
READINGS = ("exact", "exact, on the floor", "exact, floor ±1 mm")
FLOOR_SIGMA = 0.001
"""The σ (m) of the floor height drawn for `exact, floor ±1 mm` (and given as its `floor_std`)."""


def cases(quick: bool) -> list:
    """(renderer, scene) pairs: our renders' scenes, then the Mitsuba ones."""
    from bench.scenes import make_scenes
    ours = make_scenes(QUICK_SCENES if quick else N_SCENES, SEED, standing=True)
    mits = make_scenes(QUICK_MITSUBA if quick else N_MITSUBA, MITSUBA_SEED, standing=True)
    return [("ours", s) for s in ours] + [("mitsuba", s) for s in mits]


def mitsuba_floor_render(setup, index: int) -> np.ndarray | None:
    """Mitsuba render of `setup` on a plain grey floor (albedo drawn per scene) under the lighting bench's sky map
    and a sun of a drawn direction and strength; None without Mitsuba 3."""
    from bench import mitsuba_scenes as ms
    from bench.bench_lighting import mitsuba_cached, sky_map
    if not ms.mitsuba_available():
        return None
    rng = np.random.default_rng(MITSUBA_SEED + index)
    travel = (float(rng.uniform(-1, 1)), float(-rng.uniform(0.3, 1.0)), float(rng.uniform(-1, 1)))
    sun, albedo = float(rng.uniform(1.0, 3.0)), float(rng.uniform(0.2, 0.7))
    return mitsuba_cached(setup, f"onfloor-{albedo}-{travel}-{sun}", "onfloor", travel, sun, 0.0,
                          sky_map=sky_map(), floor_albedo=albedo)


def _kwargs(reading: str, floor_height: float, rng) -> dict:
    """`reconstruct`'s arguments for `reading` of an image whose cubes stand on a floor at `floor_height`."""
    if reading == "exact, on the floor":
        return dict(floor_height=floor_height)
    if reading == "exact, floor ±1 mm":
        return dict(floor_height=floor_height + rng.normal(0.0, FLOOR_SIGMA), floor_std=FLOOR_SIGMA)
    return {}


def run(quick: bool = False, log=print) -> dict:
    from bench.bench_known_size import variant_images
    from bench.bench_reconstruct import _RayMapMemo, our_render, score, with_truth
    from depth.reconstruct import reconstruct
    records = []
    todo = cases(quick)
    t_start = time.perf_counter()
    for n, renderer, sc, camera, mirror, truth in with_truth(todo):
        setup = sc.setup
        floor = -mirror.height / 2.0
        lows = [float((np.asarray(t["center"]) - mirror.center) @ mirror.axis) - t["size"] / 2.0 for t in truth]
        assert np.allclose(lows, floor, atol=1e-5), f"{sc.name}: cubes off the floor by {np.subtract(lows, floor)}"
        index = sum(1 for r, _ in todo[:n] if r == renderer)
        base = our_render(setup) if renderer == "ours" else mitsuba_floor_render(setup, index)
        if base is None:
            log(f"  {sc.name} (mitsuba): Mitsuba 3 not installed (pip install -e '.[bench]'), skipped")
            continue
        for vname, img, rng in variant_images(renderer, sc, base):
            timed = vname in ("clean", "mitsuba")
            with _RayMapMemo() if not timed else contextlib.nullcontext():  # (timed: the untouched pipeline)
                for reading in READINGS:
                    kw = _kwargs(reading, floor, rng)
                    t0 = time.perf_counter()
                    rec = reconstruct(img, camera, mirror, compressed=vname == "jpeg", **kw)
                    seconds = time.perf_counter() - t0
                    s = score([c.to_dict() for c in rec.cubes], truth, [sc.kind] * len(truth), list(sc.turn_deg))
                    records.append({"scene": sc.name, "renderer": renderer, "variant": vname, "reading": reading,
                                    "resolution": list(setup.camera.resolution),
                                    "floor_height": kw.get("floor_height"), "seconds": seconds if timed else None,
                                    "false_positives": s["false_positives"], "cubes": s["cubes"],
                                    "refused": [r.reason for r in rec.refused]})
        log(f"  [{n + 1}/{len(todo)}] {sc.name} {renderer:7s} {len(truth)} cubes, elapsed "
            f"{time.perf_counter() - t_start:.0f} s")
    return {"records": records, "quick": quick, "seconds_total": time.perf_counter() - t_start}


def summarize(records: list, reading: str) -> dict:
    """`bench_known_size.summarize` of `reading` (recall, false positives, centre error, depth within 1 / 2 / 3 σ),
    with the size error's median and the median time per image."""
    from bench.bench_known_size import summarize as known_size_summary
    size = [abs(c["size_err"]) for r in records if r["reading"] == reading for c in r["cubes"] if c["found"]]
    seconds = [r["seconds"] for r in records if r["reading"] == reading and r["seconds"] is not None]
    return {**known_size_summary(records, reading), "size_median": float(np.median(size)) if size else None,
            "seconds_median": float(np.median(seconds)) if seconds else None}


def time_ratios(records: list) -> dict:
    """Per timed image, the time of each floor reading over `exact`'s on the same image, in the same run: median
    and max."""
    by_image = {}
    for r in records:
        if r["seconds"] is not None:
            by_image.setdefault((r["scene"], r["renderer"], r["variant"]), {})[r["reading"]] = r["seconds"]
    out = {}
    for reading in READINGS[1:]:
        ratios = [t[reading] / t["exact"] for t in by_image.values() if reading in t and "exact" in t]
        out[reading] = {"median": float(np.median(ratios)), "max": float(np.max(ratios)), "images": len(ratios)} \
            if ratios else None
    return out


def report(result: dict, log=print) -> dict:
    from bench.bench_known_size import reading_table
    out = reading_table(result["records"], READINGS, summarize, log, extra=(
        ("size med", lambda s: f"{100 * s['size_median']:.2f} %"),
        ("s / image", lambda s: "—" if s["seconds_median"] is None else f"{s['seconds_median']:.2f}")))
    ratios = out["time_ratio"] = time_ratios(result["records"])
    for reading, r in ratios.items():
        if r is not None:
            log(f"time, {reading} / exact on the same image: median {r['median']:.2f}, max {r['max']:.2f} "
                f"({r['images']} images)")
    return out


def main(argv=None) -> int:
    from bench.bench_known_size import written_main
    return written_main("on_floor", f"cubes on the floor: {N_SCENES} scenes of ours x 4 variants + {N_MITSUBA} Mitsuba "
                        f"scenes{{quick}}; readings {', '.join(READINGS)}", run, report, argv)


if __name__ == "__main__":
    sys.exit(main())
