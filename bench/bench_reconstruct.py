"""Reconstruction benchmark: `main()` runs `depth.reconstruct` on the `bench.scenes` cases and scores every estimator.

Cases: 20 seeded scenes rendered by our renderer (`catadioptric.simulate`, 16 spp as the Mitsuba renders) in four
variants (clean, Gaussian noise σ = 2/255, Gaussian blur σ = 0.7 px, JPEG quality 90), plus 3
scenes rendered by Mitsuba 3 with other lighting. For each estimator (exact, ddar, dds,
shape_prior, exact_shape_prior) and variant it reports detection recall and false positives (matched one-to-one by
the image position of the truth front-face corners), the median/max relative centre error
‖ĉ − c‖ / (distance from c to the mirror axis) for cubes facing the axis and for turned cubes,
the median/max size error, and the time per image. It also scores each estimator on *oracle*
outlines (edge points from the exact reflection of the true face edges) to separate model error
from measurement error, and prints PASS/FAIL against the targets of issue 5.

Run: `python -m bench reconstruct [--quick]`. Renders are cached in bench/out/renders/ by scene
hash; the JSON result goes to bench/out/reconstruct.json.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from bench.scenes import make_scenes, scene_hash
from depth.workers import available_cores

METHODS = ("exact", "ddar", "dds", "shape_prior", "exact_shape_prior")
SAME_SIZE_METHODS = ("shape_prior", "exact_shape_prior")
"""The methods that take the cubes to be of one size: scored on the scenes whose cubes are (`Scene.same_size`);
`exact_shape_prior` is run on those alone."""
VARIANTS = ("clean", "noise", "blur", "jpeg")
N_SCENES, N_MITSUBA, SEED, MITSUBA_SEED = 20, 3, 5, 105
QUICK_SCENES, QUICK_MITSUBA = 5, 1
SPP = 16  # as the Mitsuba renders; a camera integrates over the whole pixel
OUT = Path(__file__).resolve().parent / "out"
TARGETS = {"axis_median": 0.01, "axis_max": 0.03, "size_median": 0.01, "seconds_2048": 2.0}


# ---------------------------------------------------------------------------------------------
# Images
# ---------------------------------------------------------------------------------------------
def _cached(path: Path, make) -> np.ndarray:
    """An RGB uint8 image from the PNG cache, or made and cached."""
    if path.exists():
        return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    img = make()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.png")
    cv2.imwrite(str(tmp), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    tmp.replace(path)
    return img


def our_render(setup) -> np.ndarray:
    from catadioptric.simulate import simulate
    from raytrace.render import linear_to_srgb8
    key = scene_hash(setup, f"ours-spp{SPP}-rotated-seed0")
    return _cached(OUT / "renders" / f"{key}-ours.png",
                   lambda: linear_to_srgb8(simulate(setup, spp=SPP, seed=0).render.image))


def mitsuba_image(setup) -> np.ndarray | None:
    from bench import mitsuba_scenes as ms
    if not ms.mitsuba_available():
        return None
    key = scene_hash(setup, f"mitsuba-spp{ms.SPP}-{ms.LIGHT_TRAVEL}-{ms.ENV_RADIANCE}-{ms.SUN_IRRADIANCE}")
    return _cached(OUT / "renders" / f"{key}-mitsuba.png", lambda: ms.mitsuba_render(setup))


def variant(img: np.ndarray, name: str, seed: int) -> np.ndarray:
    """The image degraded by `name`: clean, noise (σ = 2/255), blur (Gaussian σ = 0.7 px) or jpeg (quality 90)."""
    if name == "clean":
        return img
    if name == "noise":
        rng = np.random.default_rng(seed)
        return np.clip(np.round(img + rng.normal(0.0, 2.0, img.shape)), 0, 255).astype(np.uint8)
    if name == "blur":
        return np.clip(np.round(cv2.GaussianBlur(img.astype(np.float64), (0, 0), 0.7)), 0, 255).astype(np.uint8)
    if name == "jpeg":
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])
        return cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    raise ValueError(f"variant: unknown {name!r}")


# ---------------------------------------------------------------------------------------------
# Scoring
# ---------------------------------------------------------------------------------------------
def _corner_error_px(found: np.ndarray, truth: np.ndarray) -> float:
    """Max over the four corners of the distance to the nearest-assigned truth corner (px)."""
    from scipy.optimize import linear_sum_assignment
    d = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=2)
    r, c = linear_sum_assignment(d)
    return float(d[r, c].max())


def score(result_cubes: list, truth: list, kinds: list, turns: list, tol_px: float = 20.0) -> dict:
    """One-to-one match of result cubes to truth cubes by front-face centroid (≤ tol_px); per-cube errors."""
    t_cent = np.array([np.mean(t["front_face_corners_px"], axis=0) for t in truth])
    taken = {}
    fp = 0
    for i, c in enumerate(result_cubes):
        m = np.mean(c["front_face_corners_px"], axis=0)
        d = np.linalg.norm(t_cent - m, axis=1)
        j = int(np.argmin(d))
        if d[j] <= tol_px and (j not in taken or d[j] < taken[j][1]):
            if j in taken:
                fp += 1
            taken[j] = (i, float(d[j]))
        else:
            fp += 1
    cubes = []
    for j, t in enumerate(truth):
        row = {"truth": j, "kind": kinds[j], "turn_deg": turns[j], "size": t["size"], "depth": t["depth"], "found": j in taken}
        if j in taken:
            c = result_cubes[taken[j][0]]
            row["centre_err"] = float(np.linalg.norm(np.subtract(c["center"], t["center"])) / t["depth"])
            row["size_err"] = float(c["size"] / t["size"] - 1.0)
            row["depth_err"] = float(c["depth"] / t["depth"] - 1.0)
            row["corner_err_px"] = _corner_error_px(np.asarray(c["front_face_corners_px"]), np.asarray(t["front_face_corners_px"]))
            row["edge_misfit_px"] = c.get("edge_misfit_px")
            # the estimated face's tilt out of the vertical: its normal's angle with the true face's plane's
            # vertical edge's normal plane (0 for a face upright as the truth; the truth cubes are upright)
            edge = np.subtract(t["front_face_corners"][0], t["front_face_corners"][3])
            n = np.asarray(c["front_face_normal"])
            row["tilt_deg"] = float(np.degrees(np.arcsin(min(abs(n @ edge) / np.linalg.norm(edge) / np.linalg.norm(n), 1.0))))
            # error in units of the reported first-order standard deviation
            unc = c.get("uncertainty", {})
            for key in ("depth", "size"):
                sd = unc.get(key)
                row[f"{key}_z"] = float((c[key] - t[key]) / sd) if sd and np.isfinite(sd) and sd > 0 else None
        cubes.append(row)
    return {"cubes": cubes, "false_positives": fp}


def true_sides(camera, mirror, truth_cube: dict, per_side: int = 80, ends: float = 0.03):
    """The exact image of a true front face's four edges ((per_side, 2) each, corner order, `ends`
    of each edge left out) and which of them are (left, right, top, bottom)."""
    from raytrace.truth import reflection_pixels
    c3 = np.asarray(truth_cube["front_face_corners"])
    s = np.linspace(ends, 1.0 - ends, per_side)[:, None]
    sides = [reflection_pixels(camera, mirror, c3[i] + s * (c3[(i + 1) % 4] - c3[i]))[0] for i in range(4)]
    mids = np.array([sd.mean(axis=0) for sd in sides])
    left, right = int(np.argmin(mids[:, 0])), int(np.argmax(mids[:, 0]))
    top, bottom = sorted((i for i in range(4) if i not in (left, right)), key=lambda i: mids[i, 1])
    return sides, (left, right, top, bottom)


def oracle_measurements(camera, mirror, truth: list, per_side: int = 80):
    """FaceMeasurements from the exact reflections of each true front face's edges (no image)."""
    from depth.estimate import FaceMeasurement
    out = []
    for t in truth:
        sides, (left, right, top, bottom) = true_sides(camera, mirror, t, per_side)
        px = np.asarray(t["front_face_corners_px"])

        def shared(a, b):
            return px[({a, (a + 1) % 4} & {b, (b + 1) % 4}).pop()]
        corners = np.array([shared(left, top), shared(right, top), shared(right, bottom), shared(left, bottom)])
        outline = np.concatenate([sides[i] for i in range(4)])
        order = np.argsort(np.arctan2(outline[:, 1] - outline[:, 1].mean(), outline[:, 0] - outline[:, 0].mean()))
        mask = np.zeros((camera.resolution[1], camera.resolution[0]), np.uint8)
        cv2.fillPoly(mask, [np.round(outline[order] * 16).astype(np.int32).reshape(-1, 1, 2)], 1, shift=4)
        mask = cv2.erode(mask, np.ones((3, 3), np.uint8))
        ys, xs = np.nonzero(mask)
        out.append(FaceMeasurement(tuple(sides[i] for i in (left, right, top, bottom)), corners,
                                   np.column_stack([xs, ys]).astype(np.float64), 0.05))
    return out


def oracle_errors(camera, mirror, truth: list, same_size: bool = True) -> dict:
    """Per method, per truth cube: centre and size error from oracle outlines (model error only); `exact_shape_prior`
    only where the cubes are of one size (`same_size`)."""
    from depth.estimate import estimate_face, estimate_faces_exact_shape_prior, estimate_faces_shape_prior
    from raytrace.truth import mirror_rays

    def rays(px):
        r = mirror_rays(camera, mirror, px)
        return r.points, r.directions

    meas = oracle_measurements(camera, mirror, truth)
    out = {}
    for method in METHODS:
        if method == "exact_shape_prior" and not same_size:
            continue
        ests = (estimate_faces_shape_prior(rays, meas) if method == "shape_prior"
                else estimate_faces_exact_shape_prior(rays, meas, up=mirror.axis) if method == "exact_shape_prior"
                else [estimate_face(rays, m, method=method) for m in meas])
        rows = []
        for e, t in zip(ests, truth):
            if not e:
                rows.append({"failed": e.reason})
            else:
                rows.append({"centre_err": float(np.linalg.norm(e.center - np.asarray(t["center"])) / t["depth"]),
                             "size_err": float(e.size / t["size"] - 1.0),
                             # the depth σ the estimator reports at the nominal edge precision
                             # (`FaceMeasurement`'s defaults: each side 0.15 px, points 0.05 px)
                             "depth_sigma_rel": float(e.std.get("z", np.nan) / t["depth"])})
        out[method] = rows
    return out


class _RayMapMemo:
    """Memoises the full-image ray map of `raytrace.truth.mirror_rays` (pixels=None) per camera/mirror.

    Used only for the degraded variants, whose timing is not reported: the ray map depends on
    the setup alone, so the results are identical; the clean variant runs the untouched pipeline.
    """

    def __init__(self):
        import raytrace.truth as rt
        self.rt, self.orig, self.cache = rt, rt.mirror_rays, {}

    def __enter__(self):
        orig, cache = self.orig, self.cache

        def memo(camera, mirror, pixels=None):
            if pixels is not None:
                return orig(camera, mirror, pixels)
            key = (id(camera), id(mirror))
            if key not in cache:
                cache.clear()
                cache[key] = orig(camera, mirror)
            return cache[key]
        self.rt.mirror_rays = memo
        return self

    def __exit__(self, *exc):
        self.rt.mirror_rays = self.orig
        return False


# ---------------------------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------------------------
def with_truth(todo):
    """Per case (renderer, scene) of `todo`: (its index, renderer, scene, camera, mirror, the truth of its cubes
    (`raytrace.truth.cube_truth`))."""
    from raytrace.truth import cube_truth
    for n, (renderer, sc) in enumerate(todo):
        camera, mirror = sc.setup.camera.build(), sc.setup.mirror.build()
        yield n, renderer, sc, camera, mirror, [cube_truth(camera, mirror, c.build()) for c in sc.setup.objects]


def cases(quick: bool) -> list:
    ours = make_scenes(N_SCENES, SEED)
    mits = make_scenes(N_MITSUBA, MITSUBA_SEED)
    if quick:
        ours, mits = ours[:QUICK_SCENES], mits[:QUICK_MITSUBA]
    out = [("ours", s) for s in ours] + [("mitsuba", s) for s in mits]
    return out


def run(quick: bool = False, log=print) -> dict:
    from depth.reconstruct import reconstruct
    from raytrace.truth import cube_truth
    records, oracle = [], []
    t_start = time.perf_counter()
    todo = cases(quick)
    for n, (renderer, sc) in enumerate(todo):
        setup = sc.setup
        camera, mirror = setup.camera.build(), setup.mirror.build()
        truth = [cube_truth(camera, mirror, c.build()) for c in setup.objects]
        kinds, turns = [sc.kind] * len(truth), list(sc.turn_deg)
        t0 = time.perf_counter()
        base = our_render(setup) if renderer == "ours" else mitsuba_image(setup)
        t_render = time.perf_counter() - t0
        if base is None:
            log(f"  {sc.name} (mitsuba): Mitsuba 3 not installed (pip install -e '.[bench]'), skipped")
            continue
        variants = VARIANTS if renderer == "ours" else ("mitsuba",)
        for vname in variants:
            img = variant(base, vname if renderer == "ours" else "clean", seed=int(sc.key[:8], 16))
            memo = _RayMapMemo()
            for method in METHODS:
                if method == "exact_shape_prior" and not sc.same_size:
                    continue
                # Timed = the untouched pipeline: the default `exact` on every clean/Mitsuba image, and
                # every method on 2048x1536 ones. The rest reuse the setup's ray map (same results).
                timed = vname in ("clean", "mitsuba") and (method == "exact" or setup.camera.resolution[0] == 2048)
                t0 = time.perf_counter()
                # as `catadioptric reconstruct` does for a JPEG file
                kw = dict(method=method, compressed=vname == "jpeg")
                if timed:
                    rec = reconstruct(img, camera, mirror, **kw)
                else:
                    with memo:
                        rec = reconstruct(img, camera, mirror, **kw)
                dt = time.perf_counter() - t0
                one = again = None
                if timed and method == "exact" and setup.camera.resolution[0] == 2048:
                    # The same call in one process (the faces not spread over worker processes), then on
                    # the workers again: both find this process's memory faulted in by the timed run (a
                    # first call faults in a few hundred MB: 0.1-0.6 s of system time here), so their ratio
                    # in one run is the speed-up of the worker processes alone.
                    t0 = time.perf_counter()
                    reconstruct(img, camera, mirror, workers=1, **kw)
                    one = time.perf_counter() - t0
                    t0 = time.perf_counter()
                    reconstruct(img, camera, mirror, **kw)
                    again = time.perf_counter() - t0
                res = [c.to_dict() for c in rec.cubes]
                sc_ = score(res, truth, kinds, turns)
                records.append({"scene": sc.name, "renderer": renderer, "kind": sc.kind, "variant": vname,
                                "same_size": sc.same_size,
                                "method": method, "resolution": list(setup.camera.resolution),
                                "seconds": dt if timed else None, "seconds_raymap_cached": None if timed else dt,
                                "seconds_one_process": one, "seconds_again": again,
                                "false_positives": sc_["false_positives"], "cubes": sc_["cubes"],
                                "refused": [r.to_dict() for r in rec.refused], "blur_domain": rec.blur_domain})
        if renderer == "ours":
            oracle.append({"scene": sc.name, "kind": sc.kind, "turns": turns, "same_size": sc.same_size,
                           "errors": oracle_errors(camera, mirror, truth, sc.same_size)})
        log(f"  [{n + 1}/{len(todo)}] {sc.name} {renderer:7s} {sc.kind:6s} {setup.camera.resolution[0]}x"
            f"{setup.camera.resolution[1]} {len(truth)} cubes, image {t_render:.1f} s, elapsed "
            f"{time.perf_counter() - t_start:.0f} s")
    return {"records": records, "oracle": oracle, "quick": quick, "seconds_total": time.perf_counter() - t_start,
            "scenes": {sc.name + ("-mitsuba" if r == "mitsuba" else ""): {"kind": sc.kind, "key": sc.key,
                                                                          "setup": sc.setup.to_dict()}
                       for r, sc in todo}}


def _stats(values) -> tuple[float, float]:
    v = np.abs(np.asarray([x for x in values if x is not None], dtype=float))
    return (float(np.median(v)), float(v.max())) if v.size else (float("nan"), float("nan"))


def summarize(records: list, method: str, variant: str | None = None) -> dict:
    rs = [r for r in records if r["method"] == method and (variant is None or r["variant"] == variant)
          and (method not in SAME_SIZE_METHODS or r["same_size"])]
    cubes = [c for r in rs for c in r["cubes"]]
    found = [c for c in cubes if c["found"]]
    ax = [c["centre_err"] for c in found if c["kind"] == "axis"]
    tu = [c["centre_err"] for c in found if c["kind"] == "turned"]
    secs = [r["seconds"] for r in rs if r["seconds"] is not None]
    secs2k = [r["seconds"] for r in rs if r["seconds"] is not None and r["resolution"][0] == 2048]
    return {"images": len(rs), "cubes": len(cubes), "found": len(found),
            "false_positives": int(sum(r["false_positives"] for r in rs)),
            "axis": _stats(ax), "turned": _stats(tu), "size": _stats([c["size_err"] for c in found]),
            "axis_found": len(ax), "turned_found": len(tu),
            "seconds": _stats(secs) if secs else None, "seconds_2048": _stats(secs2k) if secs2k else None}


def _pct(x) -> str:
    return "   —  " if not np.isfinite(x) else f"{100 * x:6.2f}"


def report(result: dict, log=print) -> dict:
    recs = result["records"]
    variants = [v for v in VARIANTS + ("mitsuba",) if any(r["variant"] == v for r in recs)]
    log("")
    log("centre error = |c_hat - c| / distance(c, axis), in %; size error in %; time: full pipeline, clean/mitsuba images")
    log("shape_prior and exact_shape_prior are scored on the scenes whose cubes share one size only")
    log(f"{'method':17s} {'variant':8s} {'found':>9s} {'FP':>3s} | {'axis med':>8s} {'max':>7s} | "
        f"{'turned med':>10s} {'max':>7s} | {'size med':>8s} {'max':>7s} | {'s/img':>5s}")
    table = {}
    for m in METHODS:
        for v in variants + [None]:
            s = summarize(recs, m, v)
            table[f"{m}/{v or 'all'}"] = s
            t = f"{s['seconds'][0]:5.2f}" if s["seconds"] else "    —"
            log(f"{m:17s} {v or 'ALL':8s} {s['found']:4d}/{s['cubes']:<4d} {s['false_positives']:3d} | "
                f"{_pct(s['axis'][0])}% {_pct(s['axis'][1])}% | {_pct(s['turned'][0]):>9s}% {_pct(s['turned'][1])}% | "
                f"{_pct(s['size'][0])}% {_pct(s['size'][1])}% | {t}")
    log("")
    log(f"time per image (full pipeline incl. the ray map; clean + Mitsuba images; faces on {available_cores()} "
        "worker processes): median / max seconds")
    for m in METHODS:
        s = table[f"{m}/all"]
        a, b = s["seconds"] or (np.nan, np.nan)
        c, d = s["seconds_2048"] or (np.nan, np.nan)
        log(f"  {m:17s} all sizes {a:5.2f} / {b:5.2f}    2048x1536 {c:5.2f} / {d:5.2f}")
    pairs = [(r["seconds_again"], r["seconds_one_process"]) for r in recs if r.get("seconds_one_process")]
    if pairs:
        par, one = np.array(pairs).T
        log(f"  exact, 2048x1536, each image run again after the timed run, in one process then on the workers: "
            f"median {np.median(one):.2f} / max {one.max():.2f} s against {np.median(par):.2f} / {par.max():.2f} s; "
            f"the workers {np.median(one / par):.2f}x faster (median of the per-image ratios)")
    # Oracle (model-only) errors.
    log("")
    log("model error only (oracle outlines from the exact reflection of the true face edges), centre error %:")
    oracle_summary = {}
    for m in METHODS:
        parts = []
        for kind in ("axis", "turned"):
            errs = [row.get("centre_err") for o in result["oracle"] if o["kind"] == kind
                    and (m not in SAME_SIZE_METHODS or o["same_size"]) for row in o["errors"].get(m, [])]
            fails = sum(e is None for e in errs)
            med, mx = _stats(errs)
            oracle_summary[f"{m}/{kind}"] = {"median": med, "max": mx, "failed": fails, "n": len(errs)}
            parts.append(f"{kind} med {_pct(med)} max {_pct(mx)} (failed {fails}/{len(errs)})")
        sz = [row.get("size_err") for o in result["oracle"] if m not in SAME_SIZE_METHODS or o["same_size"]
              for row in o["errors"].get(m, [])]
        parts.append(f"size med {_pct(_stats(sz)[0])} max {_pct(_stats(sz)[1])}")
        log(f"  {m:17s} " + "; ".join(parts))
    # Targets.
    log("")
    log("targets (all variants and renderers pooled):")
    verdicts = {}

    def verdict(name, ok, detail):
        verdicts[name] = {"pass": bool(ok), "detail": detail}
        log(f"  {'PASS' if ok else 'FAIL'}  {name}: {detail}")
    for m in METHODS:
        s = table[f"{m}/all"]
        verdict(f"{m}: every cube found, none invented", s["found"] == s["cubes"] and s["false_positives"] == 0,
                f"{s['found']}/{s['cubes']} found, {s['false_positives']} false positives")
    for m in METHODS:
        s = table[f"{m}/all"]
        ok = s["axis_found"] > 0 and s["axis"][0] <= TARGETS["axis_median"] and s["axis"][1] <= TARGETS["axis_max"]
        verdict(f"{m}: axis-facing centre error median <= 1 %, max <= 3 %", ok,
                f"median {_pct(s['axis'][0]).strip()} %, max {_pct(s['axis'][1]).strip()} % over {s['axis_found']} cubes")
    s = table["exact/all"]
    verdict("exact: turned <= 25 deg centre error median <= 1 %, max <= 3 %",
            s["turned_found"] > 0 and s["turned"][0] <= TARGETS["axis_median"] and s["turned"][1] <= TARGETS["axis_max"],
            f"median {_pct(s['turned'][0]).strip()} %, max {_pct(s['turned'][1]).strip()} % over {s['turned_found']} cubes")
    for m in METHODS:
        s = table[f"{m}/all"]
        verdict(f"{m}: size error median <= 1 %", s["size"][0] <= TARGETS["size_median"],
                f"median {_pct(s['size'][0]).strip()} %")
    for m in METHODS:
        s = table[f"{m}/all"]
        if s["seconds_2048"]:
            verdict(f"{m}: < 2 s per 2048x1536 image", s["seconds_2048"][1] < TARGETS["seconds_2048"],
                    f"median {s['seconds_2048'][0]:.2f} s, max {s['seconds_2048'][1]:.2f} s")
    return {"table": table, "oracle": oracle_summary, "targets": verdicts}


def command_seconds(quick: bool, log=print) -> dict | None:
    """Wall time of `catadioptric reconstruct IMAGE.png -o OUT.json` on each clean 2048x1536 image of ours,
    each in a fresh process as a user runs it: start-up (Python and the imports: about 0.45 s here), reading
    the image, the ray map, the first call's memory faulted in afresh, and the JSON written. The pipeline's own
    time is the table's; this is what the command costs. (`bench_command_timing` writes the images and runs
    the command, and times it against another revision.)"""
    import tempfile

    from bench.bench_command_timing import ROOT, _images, _run
    if not any(r == "ours" and sc.setup.camera.resolution[0] == 2048 for r, sc in cases(quick)):
        return None
    with tempfile.TemporaryDirectory() as tmp:
        secs = [_run(ROOT, png, png.with_suffix(".result.json")) for png in _images(Path(tmp), quick)]
    s = {"median": float(np.median(secs)), "max": float(max(secs)), "seconds": secs, "images": len(secs)}
    log(f"  exact, 2048x1536: `catadioptric reconstruct IMAGE.png -o OUT.json` as a fresh process (start-up and "
        f"imports included), {len(secs)} clean images: median {s['median']:.2f} / max {s['max']:.2f} s")
    return s


def failures(result: dict, method: str = "exact", limit: int = 15, log=print) -> list:
    """The worst cubes of `method` (missed or largest centre error), with measurement vs model diagnosis."""
    oracle = {o["scene"]: o["errors"][method] for o in result["oracle"]}
    rows = []
    for r in result["records"]:
        if r["method"] != method:
            continue
        for c in r["cubes"]:
            orc = oracle.get(r["scene"], [None] * (c["truth"] + 1))[c["truth"]]
            o_err = orc.get("centre_err") if orc else None
            bad = (not c["found"]) or c["centre_err"] > TARGETS["axis_max"]
            if not bad:
                continue
            if not c["found"]:
                why = "missed: " + ("; ".join(sorted({x["reason"] for x in r["refused"]})) or "not detected")
            elif o_err is not None and o_err > TARGETS["axis_max"]:
                why = f"model (oracle error {100 * o_err:.2f} %)"
            else:
                why = f"measurement (corner error {c['corner_err_px']:.2f} px; oracle {'—' if o_err is None else f'{100 * o_err:.2f} %'})"
            rows.append({"scene": r["scene"], "renderer": r["renderer"], "variant": r["variant"], "cube": c["truth"],
                         "kind": c["kind"], "turn_deg": c["turn_deg"], "size": c["size"], "depth": c["depth"],
                         "centre_err": c.get("centre_err"), "corner_err_px": c.get("corner_err_px"), "why": why})
    rows.sort(key=lambda x: -(x["centre_err"] if x["centre_err"] is not None else 9.9))
    n_miss = sum(x["centre_err"] is None for x in rows)
    log("")
    log(f"{method}: {len(rows)} failing cube results ({n_miss} missed, {len(rows) - n_miss} with centre error > 3 %); worst {limit}:")
    for x in rows[:limit]:
        e = "missed" if x["centre_err"] is None else f"{100 * x['centre_err']:6.2f} %"
        log(f"  {x['scene']}/{x['cube']} {x['renderer']:7s} {x['variant']:7s} {x['kind']:6s} turn {x['turn_deg']:+6.1f}° "
            f"size {100 * x['size']:.1f} cm depth {x['depth']:.3f} m: {e} — {x['why']}")
    return rows


def calibration(result: dict, log=print) -> dict:
    """How well the reported uncertainties cover the errors: the fraction of found cubes whose depth
    (size) error is within 1, 2 and 3 reported standard deviations (a calibrated Gaussian σ: 68 /
    95 / 99.7 %), per method and variant."""
    out = {}
    log("")
    log("reported uncertainty vs actual error: % of found cubes with |error| <= 1 / 2 / 3 sigma (depth; size)")
    variants = [v for v in VARIANTS + ("mitsuba",) if any(r["variant"] == v for r in result["records"])]
    for m in METHODS:
        for v in variants + [None]:
            cells = []
            for key in ("depth", "size"):
                z = np.abs([c[f"{key}_z"] for r in result["records"] if r["method"] == m and (v is None or r["variant"] == v)
                            for c in r["cubes"] if c["found"] and c.get(f"{key}_z") is not None])
                frac = [float(np.mean(z <= k)) if len(z) else np.nan for k in (1, 2, 3)]
                out[f"{m}/{v or 'all'}/{key}"] = {"within_1_2_3_sigma": frac, "n": int(len(z))}
                cells.append(" / ".join("  —" if np.isnan(f) else f"{100 * f:3.0f}" for f in frac))
            log(f"  {m:17s} {v or 'ALL':8s} {cells[0]}  ;  {cells[1]}")
    return out


def corner_stats(result: dict, log=print) -> dict:
    """Corner error (px) of `exact`'s reported front faces vs truth, per variant (since the ninety-first session where
    its pose puts them, `depth.reconstruct._front_face_px`; the measured outline's corners before)."""
    out = {}
    log("")
    log("exact's reported front-face corners vs truth (px, max over 4 corners per face): median / 90th pct / max")
    for v in VARIANTS + ("mitsuba",):
        e = [c["corner_err_px"] for r in result["records"] if r["method"] == "exact" and r["variant"] == v
             for c in r["cubes"] if c["found"]]
        if e:
            out[v] = [float(np.median(e)), float(np.percentile(e, 90)), float(np.max(e))]
            log(f"  {v:8s} {out[v][0]:5.2f} / {out[v][1]:5.2f} / {out[v][2]:6.2f}   ({len(e)} faces)")
    log("")
    log("images with blurred faces, by the blur domain reconstruct chose (auto): encoded / linear")
    for v in VARIANTS + ("mitsuba",):
        doms = [r.get("blur_domain") for r in result["records"] if r["method"] == "exact" and r["variant"] == v]
        if doms:
            out[f"blur_domain/{v}"] = {d: doms.count(d) for d in ("encoded", "linear")}
            log(f"  {v:8s} {doms.count('encoded'):3d} / {doms.count('linear'):3d}   of {len(doms)} images")
    return out


def misfit_flags(result: dict, log=print) -> dict:
    """How well `exact`'s edge-misfit flag (rms > `depth.estimate.EDGE_MISFIT_WARN_PX`) picks out the
    cubes more than 3 % off, per variant and pooled."""
    from depth.estimate import EDGE_MISFIT_WARN_PX
    out = {}
    log("")
    log(f"exact's edge misfit (rms px) above {EDGE_MISFIT_WARN_PX} (flagged by catadioptric reconstruct) vs centre "
        "error > 3 %: flagged (> 3 % off, median error) ; not flagged (> 3 % off) ; misfit median / max")
    for v in VARIANTS + ("mitsuba", None):
        cubes = [c for r in result["records"] if r["method"] == "exact" and (v is None or r["variant"] == v)
                 for c in r["cubes"] if c["found"] and c.get("edge_misfit_px") is not None]
        if not cubes:
            continue
        mis = np.array([c["edge_misfit_px"] for c in cubes])
        err = np.array([c["centre_err"] for c in cubes])
        flag = mis > EDGE_MISFIT_WARN_PX
        row = {"flagged": int(flag.sum()), "flagged_over_3pct": int(np.sum(err[flag] > 0.03)),
               "flagged_median_err": float(np.median(err[flag])) if flag.any() else None,
               "unflagged": int((~flag).sum()), "unflagged_over_3pct": int(np.sum(err[~flag] > 0.03)),
               "misfit_median_max": [float(np.median(mis)), float(mis.max())]}
        out[v or "all"] = row
        med = "—" if row["flagged_median_err"] is None else f"{100 * row['flagged_median_err']:.1f} %"
        log(f"  {v or 'ALL':8s} {row['flagged']:3d} ({row['flagged_over_3pct']:3d}, {med:>7s}) ; "
            f"{row['unflagged']:3d} ({row['unflagged_over_3pct']:3d}) ; {row['misfit_median_max'][0]:.3f} / "
            f"{row['misfit_median_max'][1]:.3f}")
    return out


PRECISION_BINS_PX = (0.1, 0.3)
"""Bins (px) of the side offset that moves a cube's depth by 3 % (`precision_limit`)."""


def precision_limit(result: dict, method: str = "exact", log=print) -> dict:
    """Where the 3 % target asks for what: for each cube of our scenes, the side offset that moves its
    depth by 3 % (from the depth σ `method` reports on the cube's oracle outline, exact edges, at the
    nominal precision of a whole side off by 0.15 px: 0.15 px × 3 % / σ, first order), and the image
    results over 3 % off counted per bin of it (below 0.1 px, 0.1–0.3 px, above). Sides are read to
    0.02 px typically, but 10 % of them are off by over 0.18 px (`python -m bench edges`): where 0.1 px
    already costs 3 %, the target is out of reach for such sides."""
    from depth.estimate import EDGE_BIAS_PX  # the oracle measurements' side offset (`FaceMeasurement` default)

    limit = TARGETS["axis_max"]
    px3 = {}
    for o in result["oracle"]:
        for k, row in enumerate(o["errors"][method]):
            sig = row.get("depth_sigma_rel")
            if sig is not None and np.isfinite(sig) and sig > 0:
                px3[(o["scene"], k)] = EDGE_BIAS_PX * limit / sig
    out = {}
    log("")
    lo, hi = PRECISION_BINS_PX
    log(f"{method}: side offset (px) that moves the depth by 3 % (oracle outline, first order): results > 3 % off, "
        f"of all, for cubes where it is < {lo} / {lo}-{hi} / > {hi} px (max error)")
    if not px3:
        return out
    v3 = np.array(list(px3.values()))
    for v in VARIANTS + (None,):
        res = [(px3.get((r["scene"], c["truth"])), c["centre_err"]) for r in result["records"]
               if r["method"] == method and r["renderer"] == "ours" and (v is None or r["variant"] == v)
               for c in r["cubes"] if c["found"]]
        cells, row = [], {}
        for name, a, b in (("below", 0.0, lo), ("mid", lo, hi), ("above", hi, np.inf)):
            e = np.array([err for p, err in res if p is not None and a <= p < b])
            row[name] = {"over_3pct": int(np.sum(e > limit)), "n": len(e),
                         "max": float(e.max()) if len(e) else None}
            cells.append(f"{row[name]['over_3pct']:3d} of {len(e):3d} ({'—' if not len(e) else f'{100 * e.max():.1f} %'})")
        out[v or "all"] = row
        log(f"  {v or 'ALL':8s} " + " / ".join(cells))
    out["px_for_3pct"] = {"median": float(np.median(v3)), "min": float(v3.min()), "n": len(v3),
                          "below": int(np.sum(v3 < lo)), "mid": int(np.sum((v3 >= lo) & (v3 < hi)))}
    log(f"  side offset for 3 %: median {np.median(v3):.2f} px, min {v3.min():.3f} px; {int(np.sum(v3 < lo))} of "
        f"{len(v3)} cubes below {lo} px, {int(np.sum((v3 >= lo) & (v3 < hi)))} in {lo}-{hi} px")
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    quick = "--quick" in argv
    t = time.perf_counter()
    print(f"reconstruct bench: {QUICK_SCENES if quick else N_SCENES} scenes x {len(VARIANTS)} variants (ours) + "
          f"{QUICK_MITSUBA if quick else N_MITSUBA} Mitsuba scenes; estimators {', '.join(METHODS)}", flush=True)
    result = run(quick)
    summary = report(result)
    command = command_seconds(quick)
    if command:
        ok = command["max"] < TARGETS["seconds_2048"]
        summary["targets"]["exact: < 2 s per 2048x1536 image, the command"] = {
            "pass": ok, "detail": f"median {command['median']:.2f} s, max {command['max']:.2f} s"}
        print(f"  {'PASS' if ok else 'FAIL'}  exact: < 2 s per 2048x1536 image, `catadioptric reconstruct` as a "
              f"fresh process: median {command['median']:.2f} s, max {command['max']:.2f} s")
    corners = corner_stats(result)
    calib = calibration(result)
    flags = misfit_flags(result)
    fails = failures(result, "exact")
    limit = precision_limit(result)
    OUT.mkdir(parents=True, exist_ok=True)
    out = {"summary": summary, "corner_error_px": corners, "calibration": calib, "misfit_flags": flags,
           "failures_exact": fails, "precision_limit": limit, "command_seconds": command, **result}
    (OUT / "reconstruct.json").write_text(json.dumps(out, indent=1, default=float) + "\n")
    print(f"\nwrote {OUT / 'reconstruct.json'}; total {time.perf_counter() - t:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
