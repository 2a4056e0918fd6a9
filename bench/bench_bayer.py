"""A colour camera's Bayer mosaic: reading images demosaiced from one (`[camera] demosaiced`).

A colour sensor records one channel per pixel through an RGGB filter mosaic; the camera (or a raw converter)
interpolates the other two. Red and blue are then interpolated over three pixels of four and green over one of two,
so a face's edges come out with colour fringes and steps, as a JPEG image's chroma does. Images: the held-out
Mitsuba 3 renders of seeds 4040 and 6060 (`bench.holdout`, 61 cubes) and `make_scenes(6, 4242)` by our renderer
(23 cubes), as `bench_response` takes them; each recorded through an RGGB mosaic (`raytrace.chroma.bayer_mosaic`) and
demosaiced by OpenCV's three algorithms (VNG, as `simulate` does; bilinear; edge-aware), each read `ignored` (as the
full-colour image it claims to be) and `declared` (`[camera] demosaiced`: read as a JPEG image is, its edges on
luma, its cubes found on the despeckled image); VNG's image through JPEG at quality 90 (a camera's JPEG, read as
compressed); and the raw frame of each (the light of each pixel's own channel, 16 bits, `[camera] mosaic`) made into
an image by `depth.chroma.from_raw_frame`'s demosaics (`RAW_READINGS`) and read as `catadioptric reconstruct` reads
it, with each demosaic's time. Per reading: recall, false positives, the centre error ‖ĉ − c‖ / (distance of c to the
axis) (median, max, over 3 %), depth within 1 / 2 / 3 σ.

Run: `python -m bench bayer [--quick]` (in `make bench`); renders are cached in bench/out/renders/, the result goes
to bench/out/bayer.json.
"""

from __future__ import annotations

import time

import numpy as np

DEMOSAICS = ("VNG", "bilinear", "edge-aware")
RAW_READINGS = ("raw, two-colour", "raw, two-colour, as full colour", "raw, bilinear", "raw, edge-aware")
"""The same images' raw frames (`[camera] mosaic`: the light of each pixel's own channel, 16 bits), made into images by
`depth.chroma.from_raw_frame`'s demosaics and read as `catadioptric reconstruct` reads them (compressed), and the
two-colour one also as a full-colour image. (Its VNG image is the `VNG` one: asserted, not read again.)"""
READINGS = tuple(f"{renderer}, {reading}" for renderer in ("mitsuba", "ours")
                 for reading in ("as rendered", *(f"{d}, {how}" for d in DEMOSAICS for how in ("ignored", "declared")),
                                 "VNG, JPEG", *RAW_READINGS))


def _demosaic(raw: np.ndarray, name: str) -> np.ndarray:
    import cv2
    code = {"VNG": cv2.COLOR_BayerRGGB2RGB_VNG, "bilinear": cv2.COLOR_BayerRGGB2RGB,
            "edge-aware": cv2.COLOR_BayerRGGB2RGB_EA}[name]
    return cv2.cvtColor(raw, code)


def run(quick: bool = False, log=print) -> dict:
    from bench.bench_reconstruct import score, variant
    from bench.bench_response import images
    from depth.reconstruct import reading_region, reconstruct
    from depth.chroma import from_raw_frame
    from raytrace.chroma import bayer_mosaic, demosaiced
    from raytrace.response import srgb_to_linear
    from raytrace.truth import cube_truth
    records, seconds, t_start = [], {}, time.perf_counter()
    todo = images(quick)
    for n, (renderer, name, setup, sc, img) in enumerate(todo):
        camera, mirror = setup.camera.build(), setup.mirror.build()
        truth = [cube_truth(camera, mirror, c.build()) for c in setup.objects]
        raw = bayer_mosaic(img)
        made = {d: _demosaic(raw, d) for d in DEMOSAICS}
        assert np.array_equal(made["VNG"], demosaiced(img))  # (what `simulate` makes)
        jobs = [("as rendered", img, False)]
        for d in DEMOSAICS:
            jobs += [(f"{d}, ignored", made[d], False), (f"{d}, declared", made[d], True)]
        jobs.append(("VNG, JPEG", variant(made["VNG"], "jpeg", seed=0), True))
        frame = np.round(bayer_mosaic(srgb_to_linear(img / 255.0)) * 65535.0).astype(np.uint16)
        assert np.array_equal(from_raw_frame(frame, "RGGB", "VNG"), made["VNG"])  # (its light's codes are the image's)
        for d in ("two-colour", "bilinear", "edge-aware"):
            t = time.perf_counter()
            image = from_raw_frame(frame, "RGGB", d, where=reading_region(camera, mirror))  # (as the command does)
            seconds.setdefault(d, []).append((time.perf_counter() - t) / frame.size * 1e6)
            jobs.append((f"raw, {d}", image, True))
            if d == "two-colour":
                jobs.append(("raw, two-colour, as full colour", image, False))
        for reading, image, compressed in jobs:
            rec = reconstruct(image, camera, mirror, compressed=compressed)
            s = score([c.to_dict() for c in rec.cubes], truth, [sc.kind] * len(truth), list(sc.turn_deg))
            records.append({"renderer": renderer, "scene": name, "reading": f"{renderer}, {reading}",
                            "false_positives": s["false_positives"], "cubes": s["cubes"]})
        log(f"  [{n + 1}/{len(todo)}] {renderer} {name}: {len(truth)} cubes; "
            f"elapsed {time.perf_counter() - t_start:.0f} s")
    return {"records": records, "demosaic_seconds_per_megapixel": seconds, "quick": quick,
            "seconds_total": time.perf_counter() - t_start}


def report(result: dict, log=print) -> dict:
    from bench.bench_known_size import reading_table, summarize
    out = reading_table(result["records"], READINGS, summarize, log)
    times = result.get("demosaic_seconds_per_megapixel", {})
    out["demosaic_seconds_per_megapixel"] = {d: float(np.median(t)) for d, t in times.items()}
    if times:
        log("raw frame to image, seconds per megapixel (median): "
            + ", ".join(f"{d} {np.median(t):.3f}" for d, t in times.items()))
    return out


def main(argv=None) -> int:
    from bench.bench_known_size import written_main
    return written_main("bayer", "Bayer mosaic: Mitsuba holdout and our renders{quick} recorded through an RGGB "
                        "mosaic, demosaiced by " + ", ".join(DEMOSAICS) + "; each read ignored and declared; and their "
                        "raw frames", run, report, argv)
