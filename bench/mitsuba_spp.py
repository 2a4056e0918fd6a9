"""Are the Mitsuba scenes' errors sampling noise? `python -m bench.mitsuba_spp [SPP]` (default 256).

Renders the reconstruct bench's 3 Mitsuba scenes (`make_scenes(3, seed=105)`, same light and
Gaussian pixel filter) again at SPP samples per pixel with another sampler seed, runs `exact` on them
and on the bench's 16-spp renders, and prints each cube's centre error ‖ĉ − c‖ / (distance of c to the
axis) and depth error in reported σ, side by side. Not part of `make bench` (about 3 min of rendering
at 256 spp on 2 cores; renders cached in bench/out/renders/).
"""

from __future__ import annotations

import sys

import numpy as np


def errors(image, setup) -> list:
    """(centre error %, depth error / σ) of each true cube of `setup` in `image`, None where not found."""
    from bench.bench_lighting import MATCH_PX
    from depth.reconstruct import reconstruct
    from raytrace.truth import cube_truth
    cam, mir = setup.camera.build(), setup.mirror.build()
    rec = reconstruct(image, cam, mir)
    out = []
    for cube in setup.objects:
        t = cube_truth(cam, mir, cube.build())
        px = np.mean(t["front_face_corners_px"], axis=0)
        dist = [np.linalg.norm(np.mean(c.corners_px, axis=0) - px) for c in rec.cubes]
        if not dist or min(dist) > MATCH_PX:
            out.append(None)
            continue
        found = rec.cubes[int(np.argmin(dist))]
        c = np.asarray(t["center"])
        depth = float(mir.distance_to_axis(c[None])[0])
        out.append((100.0 * float(np.linalg.norm(found.estimate.center - c)) / depth,
                    (found.depth - depth) / found.depth_std))
    return out


def main(argv=None) -> int:
    from bench import mitsuba_scenes as ms
    from bench.bench_lighting import mitsuba_cached
    from bench.bench_reconstruct import mitsuba_image
    from bench.scenes import make_scenes
    argv = sys.argv[1:] if argv is None else argv
    spp = int(argv[0]) if argv else 256
    if not ms.mitsuba_available():
        print("bench.mitsuba_spp: Mitsuba 3 is not installed (pip install -e '.[bench]')")
        return 0
    print(f"exact on the reconstruct bench's Mitsuba scenes: centre error % (depth error / σ), 16 spp vs {spp} spp")
    light = (ms.LIGHT_TRAVEL, ms.SUN_IRRADIANCE, ms.ENV_RADIANCE)
    for i, sc in enumerate(make_scenes(3, 105)):
        many = mitsuba_cached(sc.setup, f"seed1-{ms.LIGHT_TRAVEL}-{ms.ENV_RADIANCE}-{ms.SUN_IRRADIANCE}",
                              f"spp{spp}", *light, spp=spp, seed=1)
        for name, image in (("16", mitsuba_image(sc.setup)), (str(spp), many)):
            cells = ["—" if e is None else f"{e[0]:5.2f} ({e[1]:+.1f})" for e in errors(image, sc.setup)]
            print(f"  s{i:02d} {name:>5s} spp: " + "  ".join(cells), flush=True)
    return 0

if __name__ == "__main__":
    sys.exit(main())
