"""Experiment 2 (paper Fig. RealExTheo): a checkerboard's aspect ratio against depth for z2/z1 = 1.3, 1.59 and 2.0.

A PO-XSlit lens (slits in front of the sensor, like the paper's real lens: z1 = 6 cm, z2 = 7.8, 9.54 or
12 cm; θ1 = 0, θ2 = 90°) views an upright frontal checkerboard of 5 × 4 squares of 1.5 cm (r_o = 1)
moved from 30 to 125 cm. Each view is rendered by analytic ray casting (3×3 samples, 8-bit) on one
sensor of square 0.005 cm pixels, cropped to the board. The inner corners are found with
`cv2.findChessboardCornersSB`; an affine grid κ = c + i·g1 + j·g2 is fitted to them on the image plane
(κ coordinates on v1, v2) and the measured r_i is the square's extent along v1 over its extent along
v2. The predicted curve is Eqn. ardef, r_i = z2·(z − z1)/(z1·(z − z2))·r_o (`depth.ddar.aspect_ratio`).
"""

import time

import numpy as np

from _common import out_path, quantise, save_gray, table
from _planar import Patch, render_planar
from depth import ddar
from depth.lines import XSlitSampling
from depth.xslit import XSlit

Z1 = 6.0
RATIOS = (1.3, 1.59, 2.0)
DEPTHS = np.array([30.0, 45.0, 65.0, 90.0, 125.0])
SQUARE, COLS, ROWS = 1.5, 5, 4          # squares; inner corners (COLS − 1) × (ROWS − 1)
MARGIN = 1.0                            # white border around the squares (cm)
PITCH = 0.005


def board():
    """The checkerboard patch at z = 0 (moved by the caller): black/white squares, white border."""
    hw, hh = COLS * SQUARE / 2, ROWS * SQUARE / 2

    def shade(a, b):
        i, j = np.floor((a + hw) / SQUARE), np.floor((b + hh) / SQUARE)
        inside = (np.abs(a) < hw) & (np.abs(b) < hh)
        return np.where(inside & ((i + j) % 2 == 0), 0.1, 0.9)

    return lambda z: Patch(np.array([0.0, 0.0, z]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                           lambda a, b: (np.abs(a) <= hw + MARGIN) & (np.abs(b) <= hh + MARGIN), shade)


def measure(xs, z, make):
    """Render the board at depth z through XSlit xs; return (image, r_i measured, corners (N, 2) px)."""
    import cv2
    s_u, s_v = (np.abs(s) for s in xs.kappa_scales(z))
    w = int(np.ceil(2 * s_u * (COLS * SQUARE / 2 + MARGIN) / PITCH)) + 40
    h = int(np.ceil(2 * s_v * (ROWS * SQUARE / 2 + MARGIN) / PITCH)) + 40
    sampling = XSlitSampling(xs, (PITCH, PITCH), ((w - 1) / 2, (h - 1) / 2))
    img, _, _ = render_planar([make(z)], sampling.rays, (w, h), samples=3, background=0.5)
    img = quantise(img)
    g8 = np.rint(img * 255).astype(np.uint8)
    ok, corners = cv2.findChessboardCornersSB(g8, (COLS - 1, ROWS - 1), flags=cv2.CALIB_CB_ACCURACY)
    if not ok:
        return img, np.nan, None
    px = corners.reshape(-1, 2).astype(np.float64)
    # SB returns pattern_size[0] corners per row, row after row: i within a row, j across rows
    i, j = np.meshgrid(np.arange(COLS - 1), np.arange(ROWS - 1))
    design = np.column_stack([np.ones(i.size), i.ravel(), j.ravel()])
    coef = np.linalg.lstsq(design, sampling.kappa(px), rcond=None)[0]     # rows c, g1, g2 in κ
    g = coef[1:]
    g_u = g[np.argmax(np.abs(g[:, 0]))]          # the grid step along v1 (image width of a square)
    g_v = g[np.argmax(np.abs(g[:, 1]))]
    return img, abs(g_u[0]) / abs(g_v[1]), px


def main():
    t0 = time.perf_counter()
    make = board()
    rows, curves, shown = [], {}, None
    all_dev, all_rel = [], []
    for ratio in RATIOS:
        xs = XSlit.from_degrees(Z1, ratio * Z1, 0.0, 90.0)
        measured = []
        for z in DEPTHS:
            img, r_i, px = measure(xs, z, make)
            if shown is None and ratio == RATIOS[-1] and z == DEPTHS[1]:
                shown = (img, px)
                save_gray(out_path("02_checkerboard.png"), img)
            measured.append(r_i)
        measured = np.array(measured)
        pred = ddar.aspect_ratio(DEPTHS, Z1, ratio * Z1, 1.0)
        if not np.all(np.isfinite(measured)):
            raise SystemExit(f"z2/z1 = {ratio}: corners not found at depth(s) {DEPTHS[~np.isfinite(measured)]} cm")
        dev = measured - pred
        all_dev += list(dev)
        all_rel += list(dev / pred)
        curves[ratio] = measured
        rows.append((f"{ratio}", f"{ratio * Z1:.2f}", " / ".join(f"{m:.4f}" for m in measured),
                     " / ".join(f"{p:.4f}" for p in pred), f"{np.sqrt(np.mean(dev ** 2)):.4f}",
                     f"{100 * np.sqrt(np.mean((dev / pred) ** 2)):.3f}"))
    print(f"PO-XSlit lens z1 = {Z1} cm; checkerboard {COLS} x {ROWS} squares of {SQUARE} cm (r_o = 1) "
          f"at z = {', '.join(f'{z:.0f}' for z in DEPTHS)} cm; pitch {PITCH} cm/px")
    print(table(["z2/z1", "z2 (cm)", "measured r_i", "predicted r_i (Eqn. ardef)", "rms dev.", "rms dev. %"], rows))
    print(f"all {len(all_dev)} points: rms deviation {np.sqrt(np.mean(np.square(all_dev))):.4f} "
          f"({100 * np.sqrt(np.mean(np.square(all_rel))):.3f} %), max |dev| {np.max(np.abs(all_dev)):.4f}  "
          f"[{time.perf_counter() - t0:.1f} s]")
    _figure(curves, shown)


def _figure(curves, shown):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(10, 4), gridspec_kw={"width_ratios": [1.2, 1]})
    img, px = shown
    ax[0].imshow(img, cmap="gray")
    ax[0].plot(px[:, 0], px[:, 1], "r+", ms=8)
    ax[0].set_title(f"z2/z1 = {RATIOS[-1]}, z = {DEPTHS[1]:.0f} cm: SB corners")
    ax[0].axis("off")
    zz = np.linspace(DEPTHS[0] * 0.9, DEPTHS[-1] * 1.05, 200)
    for ratio, colour in zip(RATIOS, ("tab:blue", "tab:orange", "tab:green")):
        ax[1].plot(zz, ddar.aspect_ratio(zz, Z1, ratio * Z1, 1.0), "-", color=colour, label=f"predicted, z2/z1 = {ratio}")
        ax[1].plot(DEPTHS, curves[ratio], "o", color=colour, mfc="none", label="measured")
    ax[1].set_xlabel("depth z (cm)")
    ax[1].set_ylabel("image aspect ratio r_i")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_path("02_checkerboard_fig.png"), dpi=80)


if __name__ == "__main__":
    main()
