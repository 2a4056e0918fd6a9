"""Edge-location error of `depth.measure.face_outline` on held-out scenes: where `EDGE_BIAS_PX` comes from.

The exact estimator's first-order uncertainty treats each measured side as its edge points plus one
common offset of the whole side (σ = `depth.estimate.EDGE_BIAS_PX`, `EDGE_BIAS_PX_BLURRED` for faces
with blurred edges, `EDGE_BIAS_PX_COMPRESSED` for JPEG images). This bench measures that offset: on scenes the reconstruct bench does not use
(`make_scenes(12, seed=77)`; that bench uses seeds 5 and 105), every usable front face detected by
the reconstruct pipeline is outlined, and each side's signed offset from the true side (the exact
reflection of the cube's edge, positive outward) is the median over its edge points. It prints,
per image variant and for sharp / blurred PNG faces (`FaceOutline.blurred`), the median offset m,
its robust spread sd (1.4826 × MAD), √(m² + sd²), the rms and the 90th percentile of |offset| (the
heavy tail the constants must also cover; see bench/README.md). Blurred faces are read in the blur
domain `depth.reconstruct` would choose (`depth.measure.blur_domain_verdict`); one more row shows the
blurred faces of the blur variant all read as optical (linear) blur, the reading before 2026-11-22.

Run: `python -m bench edges` (renders cached in bench/out/renders/). With `--holdout`, the same tables on the
`bench.holdout` renders instead (Mitsuba 3: another renderer, a floor, a sky and a sun).
"""

from __future__ import annotations

import sys

import numpy as np

SEED, N = 77, 12
VARIANTS = ("clean", "noise", "blur", "jpeg")


def side_offsets(measured: list, truth: list) -> np.ndarray:
    """Median signed offset (px, positive outward) of each measured side from its true side."""
    out = []
    for k, (p, t) in enumerate(zip(measured, truth)):
        if k < 2:  # left/right: horizontal distance at the same row
            o = np.argsort(t[:, 1])
            d = p[:, 0] - np.interp(p[:, 1], t[o, 1], t[o, 0])
        else:  # top/bottom: vertical distance at the same column
            o = np.argsort(t[:, 0])
            d = p[:, 1] - np.interp(p[:, 0], t[o, 0], t[o, 1])
        out.append(np.median(d) * (-1.0 if k in (0, 2) else 1.0))
    return np.array(out)


def side_face_widths(camera, mirror, truth_cube: dict, order) -> np.ndarray:
    """How far (px) the cube's side face shows beyond the left and right sides of its true front face (2,):
    the median over each side's length of the horizontal distance, outward, from the exact reflection of
    the front face's vertical edge to that of the back edge behind it, at the same height on the cube;
    0 or less where that side face is hidden. `order`: `true_sides`' (left, right, top, bottom) indices
    into the front face's corner-to-corner edges."""
    from raytrace.truth import reflection_pixels
    corners = np.asarray(truth_cube["front_face_corners"])
    normal = np.asarray(truth_cube["front_face_center"]) - np.asarray(truth_cube["center"])
    back = -truth_cube["size"] * normal / np.linalg.norm(normal)  # from a front vertex to the one behind it
    s = np.linspace(0.0, 1.0, 101)[:, None]
    out = []
    for k, sign in zip(order[:2], (-1.0, 1.0)):
        edge = corners[k] + s * (corners[(k + 1) % 4] - corners[k])
        front, behind = (reflection_pixels(camera, mirror, e)[0][:, 0] for e in (edge, edge + back))
        out.append(float(np.nanmedian(sign * (behind - front))))
    return np.array(out)


def _our_images(variant: str):
    """(setup, image (H, W, 3) uint8) of each of this bench's scenes, our render in `variant`."""
    from bench.bench_reconstruct import our_render, variant as degrade
    from bench.scenes import make_scenes
    for sc in make_scenes(N, SEED):
        yield sc.setup, degrade(our_render(sc.setup), variant, seed=int(sc.key[:8], 16))


def _holdout_images():
    """(setup, image) of every `bench.holdout` render (seeds `bench.holdout.SEEDS`, PNG, odd scenes grey)."""
    from bench.holdout import SEEDS, renders
    for seed in SEEDS:
        for _, setup, _, _, img in renders(seed):
            yield setup, img


def measure(variant: str, blur_domain: str = "auto", widths: list | None = None,
            images=None) -> tuple[np.ndarray, np.ndarray]:
    """Per-side offsets (N, 4) of every outlined face of the held-out scenes in `variant`, and
    whether each face's outline found its edges blurred (`FaceOutline.blurred`) (N,). Blurred faces
    are measured as `depth.reconstruct` does: `blur_domain` "auto" takes the image's
    `blur_domain_verdict`; "linear" or "encoded" force one reading. `widths`, given, gets each face's
    `side_face_widths` (a (2,) array per face, in the rows' order). `images`: (setup, uint8 image) pairs
    to measure instead of this bench's scenes (`variant` then says only whether they are JPEG)."""
    from bench.bench_lighting import MATCH_PX
    from bench.bench_reconstruct import true_sides
    from depth.measure import blur_domain_verdict, detect_cubes, face_outline
    from depth.reconstruct import despeckled
    from raytrace.truth import cube_truth, mirror_mask
    compressed = variant == "jpeg"
    rows, blurred = [], []
    for setup, img in _our_images(variant) if images is None else images:
        cam, mir = setup.camera.build(), setup.mirror.build()
        truth = [cube_truth(cam, mir, c.build()) for c in setup.objects]
        centres = np.array([np.mean(t["front_face_corners_px"], axis=0) for t in truth])
        img = img.astype(np.float64) / 255.0
        kw = dict(thin_strips=not compressed, channels="luma" if compressed else "colour")
        faces = [(det, face_outline(img, det.front_face_mask, **kw))
                 for det in detect_cubes(despeckled(img) if compressed else img, mirror_mask(cam, mir))
                 if det.usable]
        domain = blur_domain_verdict(img, [o for _, o in faces]) if blur_domain == "auto" else blur_domain
        for det, outline in faces:
            if not outline:
                continue
            if outline.blurred and domain == "encoded":
                outline = face_outline(img, det.front_face_mask, blur_domain="encoded", **kw)
            dist = np.linalg.norm(centres - outline.corners_px.mean(axis=0), axis=1)
            j = int(np.nanargmin(dist))
            if not dist[j] <= MATCH_PX:  # no cube's (a holdout's floor shadow, say)
                continue
            sides, order = true_sides(cam, mir, truth[j], per_side=400, ends=0.0)
            rows.append(side_offsets(outline.sides, [sides[i] for i in order]))
            blurred.append(outline.blurred)
            if widths is not None:
                widths.append(side_face_widths(cam, mir, truth[j], order))
    return np.array(rows), np.array(blurred, dtype=bool)


def _row(name: str, off: np.ndarray) -> str:
    med = float(np.median(off))
    rsd = float(1.4826 * np.median(np.abs(off - med)))
    return (f"{name:16s} {len(off):5d} {med:+7.3f} {rsd:9.3f} {np.hypot(med, rsd):9.3f} "
            f"{np.sqrt(np.mean(off ** 2)):6.3f} {np.percentile(np.abs(off), 90):9.3f}")


SUB_PIXEL_PX = 1.0
"""A side face showing less than this beyond the front face's side is `side_face_table`'s sub-pixel one."""


def side_face_table(beside: dict, log=print) -> None:
    """The left/right sides' offsets (`measure`) split by the side face beyond them (`side_face_widths` w):
    hidden (w ≤ 0), sub-pixel (0 < w < `SUB_PIXEL_PX`) or wider. Beside a sub-pixel side face the outline
    cannot tell the two edges apart; the measured side lies at a share α = offset / w of the side face's
    width: 0 at the front face's edge, 1 at the back edge, the cube's outer contour, as `exact` reads a
    side with no distinct side face beside it. α is where the side face's brightness lies between the
    outside's (0) and the front face's (1). `beside`: variant → (offsets (N, 2), widths (N, 2), blurred (N,))."""
    log("left/right sides by the side face beyond them (w, px); α = offset / w beside a sub-pixel one (0: the front "
        "face's edge, 1: the back edge)")
    log(f"{'variant':8s} {'hidden':>6s} {'median':>7s} {'sub-px':>6s} {'median':>7s} {'α q25':>6s} {'α med':>6s} "
        f"{'α q75':>6s} {'wider':>5s} {'median':>7s}")
    for v, (off, w, blurred) in beside.items():
        faces = ~blurred if v in ("clean", "noise") else np.ones_like(blurred)  # (blur: its faces are blurred)
        off, w = off[faces].ravel(), w[faces].ravel()
        hidden, sub = w <= 0.0, (w > 0.0) & (w < SUB_PIXEL_PX)
        wider = w >= SUB_PIXEL_PX
        share = off[sub] / w[sub]
        cells = [f"{v:8s}"]
        for sel in (hidden, sub):
            cells += [f"{sel.sum():6d}", f"{np.median(off[sel]):+7.3f}" if sel.any() else f"{'—':>7s}"]
        cells += [f"{q:6.2f}" for q in np.percentile(share, [25, 50, 75])] if sub.any() else [f"{'—':>6s}"] * 3
        cells += [f"{wider.sum():5d}", f"{np.median(off[wider]):+7.3f}" if wider.any() else f"{'—':>7s}"]
        log(" ".join(cells) + ("   (sharp faces)" if v in ("clean", "noise") else "   (all faces)"))


def holdout_table(log=print) -> None:
    """Both tables on the Mitsuba holdout renders (`python -m bench edges --holdout`): another renderer (a
    Gaussian pixel filter, which reads most faces as blurred), a floor, a sky and a sun."""
    from bench import mitsuba_scenes as ms
    if not ms.mitsuba_available():
        log("bench edges --holdout: Mitsuba 3 is not installed (pip install -e '.[bench]'); skipped")
        return
    log("holdout renders (bench.holdout seeds, PNG, odd scenes grey); per-side offset of measured edges from the "
        "truth, px (positive outward)")
    widths = []
    off, blurred = measure("clean", widths=widths, images=_holdout_images())
    log(f"{'faces':16s} {'sides':>5s} {'median':>7s} {'robust sd':>9s} {'√(m²+sd²)':>9s} {'rms':>6s} {'90% |off|':>9s}")
    log(_row("all", off.ravel()), f"  ({blurred.sum()}/{len(blurred)} faces blurred)")
    log(_row("sharp", off[~blurred].ravel()))
    log(_row("blurred", off[blurred].ravel()))
    side_face_table({"holdout": (off[:, :2], np.array(widths).reshape(-1, 2), blurred)}, log)


def main() -> int:
    from depth.estimate import EDGE_BIAS_PX, EDGE_BIAS_PX_BLURRED, EDGE_BIAS_PX_COMPRESSED
    if "--holdout" in sys.argv:
        holdout_table()
        return 0
    print(f"held-out scenes make_scenes({N}, seed={SEED}); per-side offset of measured edges from the truth, px "
          "(positive outward); PNG faces split by FaceOutline.blurred")
    print(f"{'variant':16s} {'sides':>5s} {'median':>7s} {'robust sd':>9s} {'√(m²+sd²)':>9s} {'rms':>6s} "
          f"{'90% |off|':>9s}")
    sharp, soft, beside = [], [], {}
    for v in VARIANTS:
        widths = []
        off, blurred = measure(v, widths=widths)
        beside[v] = (off[:, :2], np.array(widths).reshape(-1, 2), blurred)
        print(_row(v, off.ravel()), f"  ({blurred.sum()}/{len(blurred)} faces blurred)", flush=True)
        if v != "jpeg":
            sharp.append(off[~blurred].ravel())
            soft.append(off[blurred].ravel())
    print(_row("PNG, sharp", np.concatenate(sharp)))
    print(_row("PNG, blurred", np.concatenate(soft)))
    off, blurred = measure("blur", blur_domain="linear")
    print(_row("blur, all linear", off[blurred].ravel()), "  (blurred faces read as optical blur: the σ = 0.7 px "
          "blur of the stored values moves edges toward the brighter side)")
    side_face_table(beside)
    print(f"in use: EDGE_BIAS_PX = {EDGE_BIAS_PX} (PNG), EDGE_BIAS_PX_BLURRED = {EDGE_BIAS_PX_BLURRED} "
          f"(PNG, blurred edges), EDGE_BIAS_PX_COMPRESSED = {EDGE_BIAS_PX_COMPRESSED} (JPEG)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
