"""Experiment 4 (paper Fig. CardDemo): depths and size of identical cards of unknown size from one XSlit image.

A PO-XSlit lens (the paper's Lego camera, slits in front of the sensor: z1 = 6.12 cm, z2 = 11.81 cm,
θ1 = 0, θ2 = 90°, scene at z > z2) views five identical 6.3 × 8.8 cm cards, upright and frontal, at
z = 40 … 100 cm. Rendered by analytic ray casting (8×8 samples, 8-bit, pitch 0.02 cm/px). Each
card's extents (κ_u, κ_v) along the slits come from its anti-aliased second moments
(`depth.ellipses.rectangle_extents`); the shape prior (Eqn. smshapeprior, `depth.priors.shape_prior`)
solves the 2K equations for the K depths and the common size (κ_x, κ_y).
"""

import time

import numpy as np
from scipy import ndimage

from _common import out_path, quantise, save_gray, table
from _planar import rect, render_planar
from depth.ellipses import rectangle_extents
from depth.lines import XSlitSampling
from depth.priors import shape_prior
from depth.xslit import XSlit

Z1, Z2 = 6.12, 11.81
CARD = (6.3, 8.8)           # width along v1 (x), height along v2 (y), cm
DEPTHS = np.array([40.0, 55.0, 70.0, 85.0, 100.0])
RES = (1000, 360)
PITCH = 0.02
FG, BG = 0.9, 0.1


def main():
    t0 = time.perf_counter()
    xs = XSlit.from_degrees(Z1, Z2, 0.0, 90.0)
    sampling = XSlitSampling(xs, (PITCH, PITCH), ((RES[0] - 1) / 2, (RES[1] - 1) / 2))
    s_u, s_v = xs.kappa_scales(DEPTHS)
    targets_u = np.linspace(-380, 380, len(DEPTHS))
    xs_pos = targets_u * PITCH / s_u
    cards = [rect((x, 0.0, z), (1, 0, 0), (0, 1, 0), CARD[0] / 2, CARD[1] / 2, FG) for x, z in zip(xs_pos, DEPTHS)]
    img, _, _ = render_planar(cards, sampling.rays, RES, samples=8, background=BG)
    img = quantise(img)
    save_gray(out_path("04_cards.png"), img)

    bg, fg = quantise(BG), quantise(FG)  # the two levels as the PNG stores them
    coverage = np.clip((img - bg) / (fg - bg), 0.0, 1.0)
    labels, n = ndimage.label(ndimage.binary_dilation(coverage > 0.5, iterations=2))
    if n != len(DEPTHS):
        raise SystemExit(f"found {n} cards, expected {len(DEPTHS)}")
    order = np.argsort([np.mean(np.nonzero(labels == k + 1)[1]) for k in range(n)])
    ext = np.array([rectangle_extents(np.where(labels == k + 1, coverage, 0.0), sampling) for k in order])
    # κ_u, κ_v of the image (signed: these slits flip the image, κ = s·κ_x with s < 0).
    kappa_uv = ext * np.sign(np.stack([s_u, s_v], axis=1))
    res = shape_prior(kappa_uv, Z1, Z2)
    err = 100 * (res.depths - DEPTHS) / DEPTHS
    rows = [(f"{z:.0f}", f"{e[0] / PITCH:.1f} x {e[1] / PITCH:.1f}", f"{zr:.2f}", f"{ee:+.3f}")
            for z, e, zr, ee in zip(DEPTHS, ext, res.depths, err)]
    print(f"PO-XSlit lens z1 = {Z1} cm, z2 = {Z2} cm; {len(DEPTHS)} identical {CARD[0]} x {CARD[1]} cm cards")
    print(table(["true z (cm)", "image size (px)", "recovered z (cm)", "error %"], rows))
    print(f"recovered card size {res.kappa_x:.3f} x {res.kappa_y:.3f} cm (true {CARD[0]} x {CARD[1]}), "
          f"size error {100 * (res.kappa_x / CARD[0] - 1):+.3f} % / {100 * (res.kappa_y / CARD[1] - 1):+.3f} %; "
          f"max |depth error| {np.max(np.abs(err)):.3f} %  [{time.perf_counter() - t0:.1f} s]")
    print("pinhole (z1 = z2): the 2K equations have rank K + 1 — one scale is free, depths and size are not recoverable")
    _figure(img, res, xs_pos, kappa_uv, sampling)


def _figure(img, res, xs_pos, kappa_uv, sampling):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(10, 4))
    ax.imshow(img, cmap="gray")
    cols = sampling.to_pixels(np.column_stack([kappa_uv[:, 0] * 0, kappa_uv[:, 1] * 0]))  # principal point
    s_u, _ = sampling.xslit.kappa_scales(DEPTHS)
    for x, z, zr, su in zip(xs_pos, DEPTHS, res.depths, s_u):
        u = su * x / PITCH + sampling.principal_px[0]
        ax.text(u, 20, f"{zr:.1f} cm\n(true {z:.0f})", color="yellow", ha="center", va="top", fontsize=8)
    ax.set_title(f"shape prior: card size {res.kappa_x:.2f} x {res.kappa_y:.2f} cm (true 6.3 x 8.8)")
    ax.axis("off")
    del cols
    fig.tight_layout()
    fig.savefig(out_path("04_cards_fig.png"), dpi=80)


if __name__ == "__main__":
    main()
