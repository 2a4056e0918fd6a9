"""Experiment 1 (paper Fig. circlescene): depth of concentric circular arches from their ellipses' aspect ratios.

A PO-XSlit (z1 = −3.2 cm, z2 = −346.7 cm, θ1 = 0, θ2 = 90°; slits behind the image plane, scene at
z > 0, docs/CONVENTIONS.md) views 8 identical rings (radius 300 cm, width 16 cm, r_o = 1) centred on
the optical axis at z = 900 … 2300 cm. The image is rendered by analytic ray casting through the
ideal XSlit (4×4 samples per pixel, 8-bit), sampled with pitches 0.22 cm/px along v1 and
0.0028 cm/px along v2 so both ellipse axes span hundreds of pixels. Each ring's two sub-pixel
iso-contours get a float64 direct ellipse fit in κ coordinates; r_i = half-extent along v1 / along v2;
z from Eqn. getz with r_o = 1. Paper: 906.6 and 2281.0 cm for 900 and 2300 cm (< 2 %).
"""

import time

import numpy as np

from _common import out_path, quantise, save_gray, table
from _planar import annulus, render_planar
from depth import ddar
from depth.ellipses import closed_contours, ellipse_ratio
from depth.lines import XSlitSampling
from depth.xslit import XSlit

Z1, Z2 = -3.2, -346.7
DEPTHS = np.linspace(900.0, 2300.0, 8)
RADIUS, WIDTH = 300.0, 16.0
RES = (820, 820)


def main():
    t0 = time.perf_counter()
    xs = XSlit.from_degrees(Z1, Z2, 0.0, 90.0)
    sampling = XSlitSampling(xs, (0.22, 0.0028), ((RES[0] - 1) / 2, (RES[1] - 1) / 2))
    rings = [annulus((0, 0, z), (1, 0, 0), (0, 1, 0), RADIUS - WIDTH / 2, RADIUS + WIDTH / 2) for z in DEPTHS]
    img, _, _ = render_planar(rings, sampling.rays, RES, samples=4)
    img = quantise(img)
    save_gray(out_path("01_arches.png"), img)
    fits = []
    for c in closed_contours(img, 0.5, min_points=100):
        r, fit = ellipse_ratio(c, sampling)
        if fit:
            fits.append((fit.half_extent((1, 0)), r))
    fits.sort(reverse=True)  # outer contour of the nearest ring first
    if len(fits) != 2 * len(DEPTHS):
        raise SystemExit(f"found {len(fits)} ellipses, expected {2 * len(DEPTHS)}")
    rows, errs = [], []
    for k, z_true in enumerate(DEPTHS):
        r_i = 0.5 * (fits[2 * k][1] + fits[2 * k + 1][1])
        z = float(ddar.depth_from_aspect_ratio(r_i, Z1, Z2, 1.0))
        r_true = float(ddar.aspect_ratio(z_true, Z1, Z2, 1.0))
        err = 100 * (z - z_true) / z_true
        errs.append(abs(err))
        rows.append((f"{z_true:.0f}", f"{r_true:.4f}", f"{r_i:.4f}", f"{z:.1f}", f"{err:+.3f}"))
    print(f"PO-XSlit z1 = {Z1} cm, z2 = {Z2} cm; {len(DEPTHS)} rings of r_o = 1; image {RES[0]}x{RES[1]}")
    print(table(["true z (cm)", "true r_i", "measured r_i", "recovered z (cm)", "error %"], rows))
    print(f"near/far arch: {rows[0][3]} cm / {rows[-1][3]} cm (paper 906.6 / 2281.0); "
          f"max |error| {max(errs):.3f} %, mean {np.mean(errs):.3f} %  [{time.perf_counter() - t0:.1f} s]")
    _figure(img, DEPTHS, [float(r[3]) for r in rows])


def _figure(img, truth, est):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(9, 4))
    ax[0].imshow(img, cmap="gray")
    ax[0].set_title("XSlit image of the arches (anisotropic pitch)")
    ax[0].axis("off")
    ax[1].plot(truth, truth, "k-", lw=0.8, label="truth")
    ax[1].plot(truth, est, "ro", label="from ellipse AR")
    ax[1].set_xlabel("true z (cm)")
    ax[1].set_ylabel("recovered z (cm)")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(out_path("01_arches_fig.png"), dpi=80)


if __name__ == "__main__":
    main()
