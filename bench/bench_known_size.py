"""Known cube size: how well `exact` reads the cubes when their edge length is given (`--cube-size`).

On the reconstruct bench's scenes whose cubes are of one size (`bench_reconstruct.cases`, `Scene.same_size`: six of
our renders in its four variants, and one Mitsuba render), four readings of each image:

- `exact`: the size read from each face's own edges (the default);
- `exact, size known`: `cube_size` the true edge length;
- `exact, size ±1 %`: `cube_size` drawn off the true one by N(0, 1 %) (seeded per image), with `cube_size_std`
  1 % of it: a size that was itself measured, its σ carried through each fit (`depth.estimate.with_size_std`);
- `exact_shape_prior`: the size unknown but common to the cubes.

Per reading: recall, false positives, the centre error ‖ĉ − c‖ / (distance of c to the axis) (median, max, over
3 %) and how often the depth lies within 1 / 2 / 3 reported σ. Not timed (the ray map is shared by the readings
of one image, as `bench_reconstruct` does for its untimed runs).

Run: `python -m bench known_size [--quick]`; renders are cached in bench/out/renders/ (as `bench_reconstruct`'s),
the result goes to bench/out/known_size.json.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

READINGS = ("exact", "exact, size known", "exact, size ±1 %", "exact_shape_prior")
SIZE_SIGMA = 0.01
"""The relative σ of the size drawn for `exact, size ±1 %` (and given as its `cube_size_std`)."""


def _kwargs(reading: str, size: float, rng) -> dict:
    """`reconstruct`'s arguments for `reading` of an image of cubes of edge length `size`."""
    if reading == "exact, size known":
        return dict(method="exact", cube_size=size)
    if reading == "exact, size ±1 %":
        return dict(method="exact", cube_size=size * (1.0 + rng.normal(0.0, SIZE_SIGMA)),
                    cube_size_std=SIZE_SIGMA * size)
    return dict(method=reading)


def variant_images(renderer: str, sc, base):
    """(variant, image, its seeded generator) of scene `sc`'s render `base`: ours in the reconstruct bench's four
    variants, a Mitsuba render as it is (this bench's and `bench_on_floor`'s)."""
    from bench.bench_reconstruct import VARIANTS, variant
    key = int(sc.key[:8], 16)
    for vname in VARIANTS if renderer == "ours" else ("mitsuba",):
        yield (vname, variant(base, vname if renderer == "ours" else "clean", seed=key),
               np.random.default_rng([key, (*VARIANTS, "mitsuba").index(vname)]))


def run(quick: bool = False, log=print) -> dict:
    from bench.bench_reconstruct import _RayMapMemo, cases, mitsuba_image, our_render, score, with_truth
    from depth.reconstruct import reconstruct
    records = []
    todo = [(r, sc) for r, sc in cases(quick) if sc.same_size]
    t_start = time.perf_counter()
    for n, renderer, sc, camera, mirror, truth in with_truth(todo):
        setup = sc.setup
        sizes = {round(t["size"], 12) for t in truth}
        assert len(sizes) == 1, f"{sc.name}: cubes of one size expected, got {sorted(sizes)}"
        base = our_render(setup) if renderer == "ours" else mitsuba_image(setup)
        if base is None:
            log(f"  {sc.name} (mitsuba): Mitsuba 3 not installed (pip install -e '.[bench]'), skipped")
            continue
        for vname, img, rng in variant_images(renderer, sc, base):
            with _RayMapMemo():
                for reading in READINGS:
                    kw = _kwargs(reading, truth[0]["size"], rng)
                    rec = reconstruct(img, camera, mirror, compressed=vname == "jpeg", **kw)
                    s = score([c.to_dict() for c in rec.cubes], truth, [sc.kind] * len(truth), list(sc.turn_deg))
                    records.append({"scene": sc.name, "renderer": renderer, "variant": vname, "reading": reading,
                                    "cube_size": kw.get("cube_size"), "false_positives": s["false_positives"],
                                    "cubes": s["cubes"]})
        log(f"  [{n + 1}/{len(todo)}] {sc.name} {renderer:7s} {len(truth)} cubes of {truth[0]['size'] * 100:.2f} cm, "
            f"elapsed {time.perf_counter() - t_start:.0f} s")
    return {"records": records, "quick": quick, "seconds_total": time.perf_counter() - t_start}


def summarize(records: list, reading: str) -> dict:
    """Recall, false positives, centre error (median, max, over 3 %) and depth within 1 / 2 / 3 σ of `reading`."""
    rows = [c for r in records if r["reading"] == reading for c in r["cubes"]]
    found = [c for c in rows if c["found"]]
    err = np.array([c["centre_err"] for c in found])
    z = np.array([abs(c["depth_z"]) for c in found if c.get("depth_z") is not None])
    return {"found": len(found), "cubes": len(rows),
            "false_positives": sum(r["false_positives"] for r in records if r["reading"] == reading),
            "centre_median": float(np.median(err)) if len(err) else None,
            "centre_max": float(err.max()) if len(err) else None,
            "over_3pct": int(np.sum(err > 0.03)),
            "depth_within_1_2_3_sigma": [float(np.mean(z <= k)) for k in (1, 2, 3)] if len(z) else None}


def report(result: dict, log=print) -> dict:
    return reading_table(result["records"], READINGS, summarize, log)


def reading_table(records: list, readings, summary, log=print, extra: tuple = ()) -> dict:
    """Log a line per reading of `records` (its `summary(records, reading)`: recall, false positives, centre
    error median / max / over 3 %, depth within 1 / 2 / 3 σ, then each of `extra`'s (header, cell of a summary)
    columns); returns {reading: its summary}."""
    out = {}
    width = max(20, *(len(reading) for reading in readings))
    log(f"{'reading':{width}s} {'found':>9s} {'FP':>3s} | {'centre med':>10s} {'max':>8s} {'> 3 %':>5s} | "
        + " | ".join(["depth within 1 / 2 / 3 σ", *(header for header, _ in extra)]))
    for reading in readings:
        s = out[reading] = summary(records, reading)
        if s["centre_median"] is None:
            log(f"{reading:{width}s} {s['found']:>4d}/{s['cubes']:<4d} {s['false_positives']:>3d} | none found")
            continue
        within = " / ".join(f"{100 * v:.0f}" for v in s["depth_within_1_2_3_sigma"])
        log(f"{reading:{width}s} {s['found']:>4d}/{s['cubes']:<4d} {s['false_positives']:>3d} | "
            f"{100 * s['centre_median']:>9.2f}% {100 * s['centre_max']:>7.2f}% {s['over_3pct']:>5d} | "
            + " | ".join([f"{within} %", *(cell(s) for _, cell in extra)]))
    return out


def written_main(name: str, banner: str, run, report, argv=None) -> int:
    """A readings bench's `main` (this one's, `bench_on_floor`'s): print `banner`, `run(quick)`, `report` its result
    (its summary kept in it) and write it to bench/out/NAME.json (NAME-quick.json with --quick)."""
    from bench.bench_reconstruct import OUT
    argv = sys.argv[1:] if argv is None else argv
    quick = "--quick" in argv
    print(banner.format(quick=" (quick)" if quick else ""), flush=True)
    result = run(quick)
    result["summary"] = report(result)
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / (f"{name}-quick.json" if quick else f"{name}.json")
    path.write_text(json.dumps(result, indent=1))
    print(f"wrote {path}; total {result['seconds_total']:.0f} s")
    return 0


def main(argv=None) -> int:
    return written_main("known_size", "known cube size: the reconstruct bench's scenes of one size{quick}; readings "
                        + ", ".join(READINGS), run, report, argv)


if __name__ == "__main__":
    sys.exit(main())
