"""A setup measured off: how far `exact`'s readings move, and whether the setup's σ (`[uncertainty]`) covers it.

On the reconstruct bench's scenes (`bench_reconstruct.cases`: our clean renders and the Mitsuba renders), and on
`bench_on_floor`'s (clean renders of ours and its Mitsuba floor scenes, read `--on-floor`), each image is read
through its true setup, then through `DRAWS` setups drawn off it by N(0, σ) in every number of
`SIGMA` (the camera's place, turn, focal lengths and principal point; the mirror's radius, place and axis;
seeded per image and draw), once without the setup's σ and once with it (`reconstruct(setup_std=)`). The truth
is the true setup's: a cube's depth is its distance from the true axis, the reading's from the drawn axis.

Per reading: recall, false positives, centre error ‖ĉ − c‖ / (distance of c to the axis) (median, max, over 3 %),
how often the depth lies within 1 / 2 / 3 reported σ, and the median of the setup's share of the depth σ over the
image's own. Then the time of a reading with the setup's σ over the same reading without it (the same drawn
setup, the same process, each tracing its own ray map, the first of the two taking turns; median and max).

Run: `python -m bench setup_error [--quick]`; renders are cached in bench/out/renders/ (as `bench_reconstruct`'s),
the result goes to bench/out/setup_error.json. On the scenes of cubes of one size, two more readings through the same
drawn setups: `exact_shape_prior`, and `exact` at the true size.
"""

from __future__ import annotations

import sys
import time

import numpy as np

READINGS = ("exact, true setup", "exact, setup drawn off", "exact, setup drawn off, σ carried")
FLOOR_READINGS = ("on the floor, true setup", "on the floor, setup drawn off", "on the floor, drawn off, σ carried")
"""The same on `bench_on_floor`'s scenes (clean renders of ours and the Mitsuba floor scenes), `--on-floor`: the
floor at the (drawn) mirror's lower end."""
ONE_SIZE_READINGS = ("one size, true setup", "one size, setup drawn off", "one size, drawn off, σ carried")
"""The same on the reconstruct bench's scenes of one size, `exact_shape_prior` (through the same drawn setups)."""
KNOWN_SIZE_READINGS = ("size known, true setup", "size known, drawn off", "size known, drawn off, σ carried")
"""The same on those scenes, `exact` at the true size (`cube_size`)."""
DRAWS = 3
"""Setups drawn per image."""
SIGMA = {"camera_position": 0.001, "camera_rotation_deg": 0.05, "focal_px": 0.002, "principal_px": 1.0,
         "mirror_radius": 0.0001, "mirror_center": 0.001, "mirror_axis_deg": 0.1}
"""The setup's σ: a camera and mirror placed to a millimetre and a tenth of a degree, a focal length calibrated
to 0.2 % (`focal_px` here is relative: times the scene's fx), its principal point to a pixel, the mirror's radius
to 0.1 mm."""


def setup_std(camera):
    """`SIGMA` for `camera` (its focal σ in pixels)."""
    from depth.setup_error import SetupStd
    return SetupStd(**{**SIGMA, "focal_px": SIGMA["focal_px"] * float(camera.K[0, 0])})


def run(quick: bool = False, log=print) -> dict:
    from bench import bench_on_floor
    from bench.bench_reconstruct import _RayMapMemo, cases, mitsuba_image, our_render, score, with_truth
    from depth.reconstruct import reconstruct
    from depth.setup_error import drawn
    records, times = [], []
    floating, standing = cases(quick), bench_on_floor.cases(quick)
    todo = [(r, sc, False) for r, sc in floating] + [(r, sc, True) for r, sc in standing]
    t_start = time.perf_counter()
    for n, renderer, sc, camera, mirror, truth in with_truth([(r, sc) for r, sc, _ in todo]):
        setup = sc.setup
        on_floor = todo[n][2]
        if not on_floor:
            img = our_render(setup) if renderer == "ours" else mitsuba_image(setup)
        else:
            img = our_render(setup) if renderer == "ours" else bench_on_floor.mitsuba_floor_render(
                setup, sum(1 for r, _, floor in todo[:n] if r == renderer and floor))
        if img is None:
            log(f"  {sc.name} (mitsuba): Mitsuba 3 not installed (pip install -e '.[bench]'), skipped")
            continue
        std = setup_std(camera)
        rng = np.random.default_rng([int(sc.key[:8], 16), 7])
        readings = FLOOR_READINGS if on_floor else READINGS
        # the other readings of a scene of cubes of one size: (their names, `reconstruct`'s arguments)
        others = [] if on_floor or not sc.same_size else [(ONE_SIZE_READINGS, dict(method="exact_shape_prior")),
                                                          (KNOWN_SIZE_READINGS, dict(cube_size=truth[0]["size"]))]

        def read(cam, mir, **kw):
            """`reconstruct` through (cam, mir); on the floor at the mirror's lower end for a standing scene."""
            return reconstruct(img, cam, mir, **(dict(floor_height=-mir.height / 2.0) if on_floor else {}), **kw)

        def scored(reading, rec, draw):
            s = score([c.to_dict() for c in rec.cubes], truth, [sc.kind] * len(truth), list(sc.turn_deg))
            shares = [c.estimate.setup_std["depth"] / np.sqrt(max(c.depth_std ** 2 - c.estimate.setup_std["depth"] ** 2,
                                                                   1e-300))
                      for c in rec.cubes if c.estimate.setup_std is not None]
            records.append({"scene": sc.name, "renderer": renderer, "reading": reading, "draw": draw,
                            "false_positives": s["false_positives"], "cubes": s["cubes"], "shares": shares})
        with _RayMapMemo():
            scored(readings[0], read(camera, mirror), None)
            for names, kw in others:
                scored(names[0], read(camera, mirror, **kw), None)
        for draw in range(DRAWS):
            cam, mir = drawn(camera, mirror, std, rng)
            # each traces its own ray map (no memo), the first of the two taking turns
            recs, seconds = {}, {}
            for carry in ((False, True) if draw % 2 == 0 else (True, False)):
                t0 = time.perf_counter()
                recs[carry] = read(cam, mir, setup_std=std if carry else None)
                seconds[carry] = time.perf_counter() - t0
            plain, carried = recs[False], recs[True]
            times.append({"scene": sc.name, "renderer": renderer, "draw": draw, "plain_s": seconds[False],
                          "carried_s": seconds[True], "resolution": list(setup.camera.resolution),
                          "on_floor": on_floor})
            scored(readings[1], plain, draw)
            scored(readings[2], carried, draw)
            with _RayMapMemo():  # (untimed)
                for names, kw in others:
                    scored(names[1], read(cam, mir, **kw), draw)
                    scored(names[2], read(cam, mir, setup_std=std, **kw), draw)
        log(f"  [{n + 1}/{len(todo)}] {sc.name} {renderer:7s}{' standing' if on_floor else ''} {len(truth)} cubes, "
            f"elapsed {time.perf_counter() - t_start:.0f} s")
    return {"records": records, "times": times, "sigma": SIGMA, "draws": DRAWS, "quick": quick,
            "seconds_total": time.perf_counter() - t_start}


def summarize(records: list, reading: str) -> dict:
    from bench.bench_known_size import summarize as readings_summary
    out = readings_summary(records, reading)
    shares = [s for r in records if r["reading"] == reading for s in r["shares"]]
    out["setup_share_median"] = float(np.median(shares)) if shares else None
    return out


def report(result: dict, log=print) -> dict:
    from bench.bench_known_size import reading_table
    out = reading_table(result["records"], READINGS + FLOOR_READINGS + ONE_SIZE_READINGS + KNOWN_SIZE_READINGS,
                        summarize, log, extra=(
        ("setup σ / image σ (median)", lambda s: "—" if s["setup_share_median"] is None
         else f"{s['setup_share_median']:.2f}"),))
    for floor in (False, True):
        ratios = np.array([t["carried_s"] / t["plain_s"] for t in result["times"] if t.get("on_floor", False) == floor])
        if len(ratios):
            log(f"time with the setup's σ over without (same drawn setup{', on the floor' if floor else ''}): median "
                f"{np.median(ratios):.3f}, max {ratios.max():.3f} over {len(ratios)} readings")
            out["time_ratio" + ("_on_floor" if floor else "")] = {"median": float(np.median(ratios)),
                                                                   "max": float(ratios.max())}
    return out


def main(argv=None) -> int:
    from bench.bench_known_size import written_main
    return written_main("setup_error", "a setup measured off: the reconstruct bench's clean and Mitsuba images{quick}, "
                        f"{DRAWS} setups drawn per image; readings " + ", ".join(READINGS), run, report, argv)


if __name__ == "__main__":
    sys.exit(main())
