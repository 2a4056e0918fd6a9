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

Run: `python -m bench edges` (renders cached in bench/out/renders/).
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


def measure(variant: str, blur_domain: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Per-side offsets (N, 4) of every outlined face of the held-out scenes in `variant`, and
    whether each face's outline found its edges blurred (`FaceOutline.blurred`) (N,). Blurred faces
    are measured as `depth.reconstruct` does: `blur_domain` "auto" takes the image's
    `blur_domain_verdict`; "linear" or "encoded" force one reading."""
    from bench.bench_reconstruct import our_render, true_sides, variant as degrade
    from bench.scenes import make_scenes
    from depth.measure import blur_domain_verdict, detect_cubes, face_outline
    from depth.reconstruct import despeckled
    from raytrace.truth import cube_truth, mirror_mask
    compressed = variant == "jpeg"
    rows, blurred = [], []
    for sc in make_scenes(N, SEED):
        cam, mir = sc.setup.camera.build(), sc.setup.mirror.build()
        truth = [cube_truth(cam, mir, c.build()) for c in sc.setup.objects]
        centres = np.array([np.mean(t["front_face_corners_px"], axis=0) for t in truth])
        img = degrade(our_render(sc.setup), variant, seed=int(sc.key[:8], 16)).astype(np.float64) / 255.0
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
            j = int(np.argmin(np.linalg.norm(centres - outline.corners_px.mean(axis=0), axis=1)))
            sides, order = true_sides(cam, mir, truth[j], per_side=400, ends=0.0)
            rows.append(side_offsets(outline.sides, [sides[i] for i in order]))
            blurred.append(outline.blurred)
    return np.array(rows), np.array(blurred, dtype=bool)


def _row(name: str, off: np.ndarray) -> str:
    med = float(np.median(off))
    rsd = float(1.4826 * np.median(np.abs(off - med)))
    return (f"{name:16s} {len(off):5d} {med:+7.3f} {rsd:9.3f} {np.hypot(med, rsd):9.3f} "
            f"{np.sqrt(np.mean(off ** 2)):6.3f} {np.percentile(np.abs(off), 90):9.3f}")


def main() -> int:
    from depth.estimate import EDGE_BIAS_PX, EDGE_BIAS_PX_BLURRED, EDGE_BIAS_PX_COMPRESSED
    print(f"held-out scenes make_scenes({N}, seed={SEED}); per-side offset of measured edges from the truth, px "
          "(positive outward); PNG faces split by FaceOutline.blurred")
    print(f"{'variant':16s} {'sides':>5s} {'median':>7s} {'robust sd':>9s} {'√(m²+sd²)':>9s} {'rms':>6s} "
          f"{'90% |off|':>9s}")
    sharp, soft = [], []
    for v in VARIANTS:
        off, blurred = measure(v)
        print(_row(v, off.ravel()), f"  ({blurred.sum()}/{len(blurred)} faces blurred)", flush=True)
        if v != "jpeg":
            sharp.append(off[~blurred].ravel())
            soft.append(off[blurred].ravel())
    print(_row("PNG, sharp", np.concatenate(sharp)))
    print(_row("PNG, blurred", np.concatenate(soft)))
    off, blurred = measure("blur", blur_domain="linear")
    print(_row("blur, all linear", off[blurred].ravel()), "  (blurred faces read as optical blur: the σ = 0.7 px "
          "blur of the stored values moves edges toward the brighter side)")
    print(f"in use: EDGE_BIAS_PX = {EDGE_BIAS_PX} (PNG), EDGE_BIAS_PX_BLURRED = {EDGE_BIAS_PX_BLURRED} "
          f"(PNG, blurred edges), EDGE_BIAS_PX_COMPRESSED = {EDGE_BIAS_PX_COMPRESSED} (JPEG)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
