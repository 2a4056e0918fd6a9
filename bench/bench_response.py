"""A camera's response: reading images whose 8-bit values are not sRGB (`[camera] response`).

A pixel across an edge mixes the two sides' light; the outline reads that mix in linear light, so an image
stored through another curve than sRGB (a camera's tone curve, a renderer's view transform, a gamma) puts its
sub-pixel edges off. Images: the held-out Mitsuba 3 renders of seeds MITSUBA_SEEDS (`bench.holdout`, PNG, odd
scenes grey: another renderer, a floor, a sky and a sun; its Gaussian pixel filter blurs every edge over a pixel
or two) and the first N_OURS scenes of `make_scenes(N_OURS, SEED)` by our renderer (sharp edges), each stored
again through each of RESPONSES (its sRGB values decoded to light and stored as that camera would,
`raytrace.response.CameraResponse.encode8`):

- `gamma 2.2`: stored = light ** (1 / 2.2), the curve sRGB approximates;
- `gamma 1.8`;
- `tone curve`: sRGB after a highlight roll-off (light → light (1 + k) / (1 + k light), k = 1.5), as a camera's
  rendering or a renderer's view transform has one, given as a table of 256 values;
- `log`: stored = log(1 + 30 light) / log(31), a camera's log profile, as a table.

Each is read `declared` (the setup's `response`) and `ignored` (read as sRGB, as a setup without the key reads
it), beside the `sRGB` image as rendered; the `tone curve` image and the sRGB one also through JPEG (quality 90,
`bench_reconstruct.variant`, read as compressed): the coder works on the stored values, which the readings of
encoded values (luma, chroma) take as sRGB's. Per reading: recall, false positives, the centre error ‖ĉ − c‖ /
(distance of c to the axis) (median, max, over 3 %), depth within 1 / 2 / 3 σ, the depth error's signed median; and
the time of a `declared` reading over the same image's `ignored` one (one process, each the best of 2).

Run: `python -m bench response [--quick]` (in `make bench`); renders are cached in bench/out/renders/, the result
goes to bench/out/response.json.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

MITSUBA_SEEDS = (4040, 6060)
N_OURS, SEED = 6, 4242
QUICK = 2
"""Images of each renderer with --quick."""
RESPONSES = ("gamma 2.2", "gamma 1.8", "tone curve", "log")
JPEG_RESPONSE = "tone curve"
"""The response whose image is also put through JPEG (quality 90, the reconstruct bench's) after it is stored."""
READINGS = tuple(reading for renderer in ("mitsuba", "ours") for reading in (
    f"{renderer}, sRGB", *(f"{renderer}, {r}, {how}" for r in RESPONSES for how in ("declared", "ignored")),
    f"{renderer}, sRGB JPEG", *(f"{renderer}, {JPEG_RESPONSE} JPEG, {how}" for how in ("declared", "ignored"))))
ROLL_OFF = 1.5
LOG_A = 30.0


def response(name: str):
    """The `raytrace.response.CameraResponse` of one of RESPONSES, built from its setup value."""
    from raytrace.response import as_response, srgb_to_linear
    codes = np.arange(256) / 255.0
    if name.startswith("gamma"):
        return as_response(float(name.split()[1]))
    if name == "tone curve":  # the light whose roll-off is sRGB-decoded code: y (1 + k) / (1 + k y) inverted
        y = srgb_to_linear(codes)
        return as_response((y / (1.0 + ROLL_OFF - ROLL_OFF * y)).tolist())
    if name == "log":
        return as_response((np.expm1(codes * np.log1p(LOG_A)) / LOG_A).tolist())
    raise ValueError(name)


def images(quick: bool):
    """(renderer, scene name, setup, scene of `make_scenes`, sRGB uint8 image) of every bench image."""
    from bench.bench_reconstruct import our_render
    from bench.holdout import renders
    from bench.scenes import make_scenes
    out = []
    for seed in MITSUBA_SEEDS:
        for i, setup, sc, _, img in renders(seed):
            out.append(("mitsuba", f"h{seed}/s{i}", setup, sc, img))
    out = out[:QUICK] if quick else out
    for sc in make_scenes(QUICK if quick else N_OURS, SEED):
        out.append(("ours", sc.name, sc.setup, sc, our_render(sc.setup)))
    return out


def run(quick: bool = False, log=print) -> dict:
    from bench.bench_reconstruct import score, variant
    from depth.reconstruct import reconstruct
    from raytrace.response import srgb_to_linear
    from raytrace.truth import cube_truth
    records, ratios, t_start = [], [], time.perf_counter()
    todo = images(quick)
    curves = {name: response(name) for name in RESPONSES}
    for n, (renderer, name, setup, sc, img) in enumerate(todo):
        camera, mirror = setup.camera.build(), setup.mirror.build()
        truth = [cube_truth(camera, mirror, c.build()) for c in setup.objects]
        light = srgb_to_linear(img / 255.0)
        jobs = [(f"{renderer}, sRGB", img, camera)]
        stored = {r: curve.encode8(light) for r, curve in curves.items()}
        for r, curve in curves.items():
            jobs += [(f"{renderer}, {r}, declared", stored[r], dataclasses.replace(camera, response=curve)),
                     (f"{renderer}, {r}, ignored", stored[r], camera)]
        coded = variant(stored[JPEG_RESPONSE], "jpeg", seed=0)
        jobs += [(f"{renderer}, sRGB JPEG", variant(img, "jpeg", seed=0), camera),
                 (f"{renderer}, {JPEG_RESPONSE} JPEG, declared", coded,
                  dataclasses.replace(camera, response=curves[JPEG_RESPONSE])),
                 (f"{renderer}, {JPEG_RESPONSE} JPEG, ignored", coded, camera)]
        seconds = {}
        for reading, image, cam in jobs:
            t = time.perf_counter()
            rec = reconstruct(image, cam, mirror, compressed="JPEG" in reading)
            seconds[reading] = time.perf_counter() - t
            s = score([c.to_dict() for c in rec.cubes], truth, [sc.kind] * len(truth), list(sc.turn_deg))
            records.append({"renderer": renderer, "scene": name, "reading": reading, "seconds": seconds[reading],
                            "false_positives": s["false_positives"], "cubes": s["cubes"]})
        # the work a declared response adds: the same image read both ways again, the best of 2 each
        r0 = RESPONSES[0]
        for cam, reading in ((dataclasses.replace(camera, response=curves[r0]), f"{renderer}, {r0}, declared"),
                             (camera, f"{renderer}, {r0}, ignored")):
            t = time.perf_counter()
            reconstruct(stored[r0], cam, mirror)
            seconds[reading] = min(seconds[reading], time.perf_counter() - t)
        ratios.append(seconds[f"{renderer}, {r0}, declared"] / seconds[f"{renderer}, {r0}, ignored"])
        log(f"  [{n + 1}/{len(todo)}] {renderer} {name}: {len(truth)} cubes, time declared / ignored {ratios[-1]:.2f}; "
            f"elapsed {time.perf_counter() - t_start:.0f} s")
    return {"records": records, "time_declared_over_ignored": ratios, "quick": quick,
            "seconds_total": time.perf_counter() - t_start}


def summarize(records: list, reading: str) -> dict:
    """`bench_known_size.summarize`'s figures of `reading`, and its depth error's signed median."""
    from bench.bench_known_size import summarize as base
    s = base(records, reading)
    signed = [c["depth_err"] for r in records if r["reading"] == reading for c in r["cubes"] if c["found"]]
    s["depth_signed_median"] = float(np.median(signed)) if signed else None
    return s


def report(result: dict, log=print) -> dict:
    from bench.bench_known_size import reading_table
    out = reading_table(result["records"], READINGS, summarize, log,
                        extra=(("depth signed median", lambda s: f"{100 * s['depth_signed_median']:+.2f} %"),))
    ratios = result["time_declared_over_ignored"]
    out["time_declared_over_ignored"] = {"median": float(np.median(ratios)), "max": float(np.max(ratios))}
    log(f"time, an image read with its response declared over the same image read as sRGB (best of 2 each, one "
        f"process): median {np.median(ratios):.3f}, max {np.max(ratios):.3f} ({len(ratios)} images)")
    return out


def main(argv=None) -> int:
    from bench.bench_known_size import written_main
    return written_main("response", "camera response: Mitsuba holdout and our renders{quick} stored through "
                        + ", ".join(RESPONSES) + "; each read declared and ignored", run, report, argv)
