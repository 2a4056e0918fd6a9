"""Reconstruction under lighting the reconstruct bench never uses, rendered by Mitsuba 3.

The issue warns that results will be checked on unseen scenes rendered by another renderer with
other lighting. This bench renders 6 scenes no other bench uses (`make_scenes(6, seed=777)`) with
Mitsuba 3 (`scalar_rgb`, 16 spp, Gaussian pixel filter) under three lights:

- ``sun-front``: sun from above the camera's side, weak sky;
- ``sky-only``: a uniform environment and no sun. Every face of a cube then receives the same
  light, so front, side and top faces look alike and only the cube's outline is left: the worst
  case for telling the front face from the others;
- ``sun-low-side``: a low sun from the side, weak sky;
- ``sun-front grey``: the first light again, the cubes painted white, grey and black in turn
  (`GREYS`): found only by their difference from the uniform sky seen in the mirror.

and runs `depth.reconstruct` (`exact`) on each image. Per light it prints recall, false positives,
the median / 90th percentile / max of the centre error ‖ĉ − c‖ / (distance of c to the axis), the
median size error, and how many depth errors fall within 1 / 2 reported σ.

Run: `python -m bench lighting` (renders cached in bench/out/renders/; Mitsuba via the `bench` extra).
"""

from __future__ import annotations

import numpy as np

SEED, N = 777, 6
LIGHTS = {  # sun travel direction, sun irradiance, sky radiance
    "sun-front": ((-0.4, -0.8, 0.6), 2.0, 0.35),
    "sky-only": ((0.0, -1.0, 0.0), 0.0, 1.0),
    "sun-low-side": ((1.0, -0.3, 0.1), 2.5, 0.25),
}
MATCH_PX = 20.0
GREYS = ((0.9, 0.9, 0.9), (0.45, 0.45, 0.45), (0.06, 0.06, 0.06))
"""Albedos given in turn to the cubes of the grey run: white, grey and black (no colour to find them by)."""


def greyed(setup):
    """`setup` with its cubes painted in `GREYS`, in turn."""
    import dataclasses
    objects = tuple(dataclasses.replace(o, color=GREYS[k % len(GREYS)]) for k, o in enumerate(setup.objects))
    return dataclasses.replace(setup, objects=objects)


def render(setup, light: str) -> np.ndarray:
    """Mitsuba render of `setup` under `light` (uint8 sRGB), from the cache when there."""
    import mitsuba as mi
    from bench import mitsuba_scenes as ms
    from bench.bench_reconstruct import OUT, _cached
    from bench.scenes import scene_hash
    from raytrace.render import linear_to_srgb8
    travel, sun, sky = LIGHTS[light]
    key = scene_hash(setup, f"mitsuba-spp{ms.SPP}-{light}-{travel}-{sun}-{sky}")

    def make():
        mi.set_variant("scalar_rgb")
        scene = setup.build_scene()
        d = ms.scene_dict(setup.camera.build(), scene.mirror, scene.objects, ms.SPP, travel, sun, sky,
                          rfilter="gaussian")
        return linear_to_srgb8(np.asarray(mi.render(mi.load_dict(d), seed=0), dtype=np.float64)[:, :, :3])
    return _cached(OUT / "renders" / f"{key}-mitsuba-{light}.png", make)


def score(light: str, grey: bool = False) -> dict:
    """Reconstruct every scene under `light` (its cubes `greyed` when `grey`); per-cube errors and σ
    ratios."""
    from bench.scenes import make_scenes
    from depth.reconstruct import reconstruct
    from raytrace.truth import cube_truth
    centre, size, zs, found, total, fp, domains = [], [], [], 0, 0, 0, []
    for sc in make_scenes(N, SEED):
        setup = greyed(sc.setup) if grey else sc.setup
        cam, mir = setup.camera.build(), setup.mirror.build()
        rec = reconstruct(render(setup, light), cam, mir)
        domains.append(rec.blur_domain)
        truth = [cube_truth(cam, mir, c.build()) for c in sc.setup.objects]
        px_true = np.array([np.mean(t["front_face_corners_px"], axis=0) for t in truth])
        used = set()
        for cube in rec.cubes:
            dist = np.linalg.norm(px_true - np.mean(cube.corners_px, axis=0), axis=1)
            j = int(np.argmin(dist))
            if dist[j] > MATCH_PX or j in used:
                fp += 1
                continue
            used.add(j)
            t, obj = truth[j], sc.setup.objects[j]
            c = np.asarray(t["center"])
            depth = float(mir.distance_to_axis(c[None])[0])
            centre.append(np.linalg.norm(cube.estimate.center - c) / depth)
            size.append(abs(cube.estimate.size - obj.size) / obj.size)
            zs.append(abs(cube.depth - depth) / cube.depth_std if cube.depth_std > 0 else np.inf)
        found += len(used)
        total += len(truth)
    return {"found": found, "total": total, "fp": fp, "centre": np.array(centre), "size": np.array(size),
            "z": np.array(zs), "encoded": domains.count("encoded"), "linear": domains.count("linear")}


def main() -> int:
    from bench import mitsuba_scenes as ms
    if not ms.mitsuba_available():
        print("bench lighting: Mitsuba 3 is not installed (pip install -e '.[bench]'); skipped")
        return 0
    print(f"unseen scenes make_scenes({N}, seed={SEED}), Mitsuba 3 {ms.SPP} spp, exact estimator; "
          "centre error = |c_hat - c| / distance(c, axis)")
    print(f"{'light':14s} {'found':>7s} {'FP':>3s} | {'centre med':>10s} {'p90':>6s} {'max':>6s} | "
          f"{'size med':>8s} | within 1 / 2 sigma | blur domain chosen: encoded / linear")
    for light, grey in [(light, False) for light in LIGHTS] + [("sun-front", True)]:
        r = score(light, grey)
        c, sz, z = r["centre"] * 100, r["size"] * 100, r["z"]
        print(f"{light + (' grey' if grey else ''):14s} {r['found']:3d}/{r['total']:<3d} {r['fp']:3d} | {np.median(c):9.2f}% "
              f"{np.percentile(c, 90):5.1f}% {c.max():5.1f}% | {np.median(sz):7.2f}% | "
              f"{np.mean(z <= 1) * 100:3.0f} / {np.mean(z <= 2) * 100:3.0f} % | {r['encoded']} / {r['linear']}",
              flush=True)
    return 0
