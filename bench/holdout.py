"""Held-out renders: `python -m bench.holdout SEED [--grey] [--jpeg] [--method=M]` (SEED 8080, 9090, 7070, 6060,
5050, 4040 or 3030 as in bench/README.md; 1010, 2020, 1111, 1212, 1313 and 1414, read first in the ninety-sixth
session, 1515 and 1616, read first in the ninety-eighth, and 1717 and 1818, read first in the hundred-and-first, as
in the README).

Eight scenes no bench tunes on (`make_scenes(8, seed=SEED)`), rendered by Mitsuba 3 (16 spp) standing
on a floor (albedo drawn per scene) under the lighting bench's sky map and a sun from a direction and
of a strength drawn from `default_rng(SEED + 7)`; the odd scenes' cubes painted grey, white or black
(`bench_lighting.greyed`), or every scene's with --grey; with --jpeg each render is put through OpenCV's
JPEG coder at quality 90 (the reconstruct bench's JPEG variant) and reconstructed as compressed: JPEG
images no JPEG change was tuned on. `exact` on each (or --method's estimator: `shape_prior` and `exact_shape_prior`
on the scenes whose cubes are of one size alone, 2 and 5 of each seed); per cube the centre error
‖ĉ − c‖ / (distance of c to the axis) in %, the signed depth error in % and in reported σ, the turn and the edge
misfit, the refusals, each cube invented (`bench_lighting.invented_line`), then recall, false positives,
the error median / 90th percentile / max, and how many depths were read nearer and further than the truth
with the signed median (a bias the unsigned figures hide).
Not part of `make bench` (the first run renders for about 5 min on 2 cores; renders are cached in
bench/out/renders/, and the results written to bench/out/holdout-SEED[-grey][-jpeg][-M].json, M where not exact).
"""

from __future__ import annotations

import json
import sys

import numpy as np


SEEDS = (3030, 4040, 5050, 6060, 7070, 8080, 9090)
"""The seeds bench/README.md reports."""


def renders(seed: int, all_grey: bool = False):
    """The held-out scenes of `seed`, each as (index, setup as rendered, scene of `make_scenes(8, seed)`, whether
    its cubes were painted grey, the Mitsuba render (H, W, 3) uint8), rendering those not cached yet."""
    from bench.bench_lighting import greyed, mitsuba_cached, sky_map
    from bench.scenes import make_scenes
    rng = np.random.default_rng(seed + 7)
    for i, sc in enumerate(make_scenes(8, seed)):
        travel = (float(rng.uniform(-1, 1)), float(-rng.uniform(0.3, 1.0)), float(rng.uniform(-1, 1)))
        sun, albedo = float(rng.uniform(1.0, 3.0)), float(rng.uniform(0.2, 0.7))
        grey = bool(i % 2 or all_grey)
        setup = greyed(sc.setup) if grey else sc.setup
        img = mitsuba_cached(setup, f"holdout{seed}-floor{albedo}-{travel}-{sun}", "holdout", travel, sun, 0.0,
                             sky_map=sky_map(), floor_albedo=albedo)
        yield i, setup, sc, grey, img


def main(argv=None) -> int:
    from bench import mitsuba_scenes as ms
    from bench.bench_lighting import invented_line, match
    from bench.bench_reconstruct import OUT, SAME_SIZE_METHODS, variant
    from depth.reconstruct import ALL_METHODS, reconstruct
    from raytrace.truth import cube_truth

    argv = sys.argv[1:] if argv is None else argv
    args = [a for a in argv if not a.startswith("--")]
    methods = [a.split("=", 1)[1] for a in argv if a.startswith("--method=")] or ["exact"]
    if len(args) != 1 or not args[0].isdigit() or len(methods) != 1 or methods[0] not in ALL_METHODS:
        print("usage: python -m bench.holdout SEED [--grey] [--jpeg] [--method=M]   (SEED: a whole number, e.g. 8080 "
              f"or 9090; M: one of {', '.join(ALL_METHODS)}, default exact)", file=sys.stderr)
        return 2
    seed, all_grey, jpeg, method = int(args[0]), "--grey" in argv, "--jpeg" in argv, methods[0]
    if not ms.mitsuba_available():
        print("bench.holdout: Mitsuba 3 is not installed (pip install -e '.[bench]'); skipped")
        return 0
    res, fps = {}, []
    for i, setup, sc, grey, img in renders(seed, all_grey):
        if method in SAME_SIZE_METHODS and not sc.same_size:
            continue
        if jpeg:
            img = variant(img, "jpeg", seed=0)
        cam, mir = setup.camera.build(), setup.mirror.build()
        rec = reconstruct(img, cam, mir, method=method, compressed=jpeg)
        truth = [cube_truth(cam, mir, c.build()) for c in setup.objects]
        pairs, extra = match(rec.cubes, truth)
        fps += [{"scene": i, "at_px": np.round(np.mean(cube.corners_px, axis=0), 1).tolist(),
                 "size_mm": round(cube.estimate.size * 1e3, 2), "depth_m": round(cube.depth, 4),
                 "depth_std_m": round(cube.depth_std, 4), "misfit_px": round(float(cube.estimate.rms_residual), 3)}
                for cube in extra]
        for cube, j in pairs:
            c = np.asarray(truth[j]["center"])
            depth = float(mir.distance_to_axis(c[None])[0])
            res[f"{i}/{j}"] = {"centre_err_pct": float(np.linalg.norm(cube.estimate.center - c) / depth * 100),
                               "depth_err_pct": float((cube.depth - depth) / depth * 100),
                               "depth_sigmas": float((cube.depth - depth) / cube.depth_std),
                               "turn_deg": float(sc.turn_deg[j]), "misfit_px": float(cube.estimate.rms_residual),
                               "tilt_deg": float(np.degrees(np.arcsin(min(abs(float(cube.estimate.normal @ mir.axis)), 1.0))))}
        for j in range(len(truth)):
            res.setdefault(f"{i}/{j}", None)
        cells = [f"{j}: " + ("missed" if res[f"{i}/{j}"] is None else
                             f"{res[f'{i}/{j}']['centre_err_pct']:.2f} % ({res[f'{i}/{j}']['depth_sigmas']:+.1f} σ)")
                 for j in range(len(truth))]
        print(f"  s{i} {'grey ' if grey else 'colour'} " + ", ".join(cells), flush=True)
        for r in rec.refused:
            print(f"      refused {r.bbox}: {r.reason}")
        for cube in extra:
            print(f"      {invented_line(cube)}")
    e = np.array([v["centre_err_pct"] for v in res.values() if v])
    z = np.abs([v["depth_sigmas"] for v in res.values() if v])
    signed = np.array([v["depth_err_pct"] for v in res.values() if v])
    print(f"holdout {seed}{' (all grey)' if all_grey else ''}{' (JPEG)' if jpeg else ''}"
          f"{f' ({method})' if method != 'exact' else ''}: found {len(e)} of {len(res)}, {len(fps)} false "
          f"positives; centre error median {np.median(e):.2f} %, 90th pct {np.percentile(e, 90):.2f} %, max "
          f"{e.max():.1f} %; depth within 1 / 2 / 3 σ {100 * np.mean(z <= 1):.0f} / {100 * np.mean(z <= 2):.0f} / "
          f"{100 * np.mean(z <= 3):.0f} %; depth read nearer / further than the truth {np.sum(signed < 0)} / "
          f"{np.sum(signed > 0)}, signed median {np.median(signed):+.2f} %")
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / (f"holdout-{seed}{'-grey' if all_grey else ''}{'-jpeg' if jpeg else ''}"
                  f"{f'-{method}' if method != 'exact' else ''}.json")
    path.write_text(json.dumps({"cubes": res, "false_positives": fps}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
