"""Experiment 3 (paper Fig. maxscene) and §4.3: DDS on a corridor and a facade, then dense depth by MRF.

XSlit θ1 = 45°, θ2 = 135° (a PO-XSlit turned so 3D horizontal/vertical lines align with neither slit):
- corridor: z1 = −3.6 cm, z2 = −717.9 cm;
- facade: z1 = −3.1 cm, z2 = −4895.9 cm. The paper prints +4895.9; in our frame (slits behind the
  image plane, scene at z > 0) a slit at +49 m would lie inside the scene and Eqn. getz would only
  hold beyond it, so we take both slits behind the plane, as for the corridor.
Images are rendered by analytic ray casting (3×3 samples, 8-bit) with pitches p1, p2 along v1, v2
chosen so the scene looks isotropic at mid depth. LSD segments are grouped into 3D horizontal
(r_o = −1) and vertical (r_o = +1) by the AR ranges of Eqn. ratiorange; each grouped segment gets a
DDS depth (sparse map); `depth.dense` blends them over Felzenszwalb superpixels and solves the MRF by
α-expansion (graph cuts) and by the quadratic sparse solve. Errors are against the renderer's exact z.
A pinhole rendering of the same scene shows the degenerate case.
"""

import time

import numpy as np

from _common import out_path, quantise, save_gray, table
from _planar import rect, render_planar
from depth.dense import dense_depth, superpixel_graph
from depth.lines import XSlitSampling, detect_segments, line_cues
from depth.xslit import XSlit

RES = (640, 480)


def stripes(period, lo, hi, axis, offset=0.0):
    return lambda a, b: lo + (hi - lo) * (np.floor(((a, b)[axis] + offset) / period) % 2)


def grid(period, lo, hi):
    return lambda a, b: lo + (hi - lo) * ((np.floor(a / period) + np.floor(b / period)) % 2)


def corridor():
    zc, hz = 1325.0, 1175.0
    return [rect((0, -150, zc), (1, 0, 0), (0, 0, 1), 150, hz, stripes(150, 0.25, 0.55, 1, zc)),
            rect((0, 150, zc), (1, 0, 0), (0, 0, 1), 150, hz, stripes(150, 0.6, 0.85, 1, zc + 75)),
            rect((-150, 0, zc), (0, 0, 1), (0, 1, 0), hz, 150, stripes(200, 0.3, 0.7, 0, zc)),
            rect((150, 0, zc), (0, 0, 1), (0, 1, 0), hz, 150, stripes(200, 0.45, 0.8, 0, zc + 100)),
            rect((0, 0, 2500), (1, 0, 0), (0, 1, 0), 150, 150, grid(50, 0.15, 0.9))]


def facade():
    blocks = [(-900, 2000, 0.35, 0.8), (0, 2800, 0.2, 0.65), (900, 3600, 0.4, 0.9)]
    return [rect((x, 0, z), (1, 0, 0), (0, 1, 0), 450, 600, grid(150, lo, hi)) for x, z, lo, hi in blocks] + \
        [rect((0, 0, 6000), (1, 0, 0), (0, 1, 0), 3000, 3000, grid(500, 0.05, 0.2))]


SCENES = {
    "corridor": dict(z1=-3.6, z2=-717.9, patches=corridor, z_ref=700.0, half=(150 * np.sqrt(2), 300)),
    "facade": dict(z1=-3.1, z2=-4895.9, patches=facade, z_ref=2800.0, half=(1350 * np.sqrt(2), 300)),
}


def make_sampling(cfg):
    xs = XSlit.from_degrees(cfg["z1"], cfg["z2"], 45.0, 135.0)
    s_u, s_v = xs.kappa_scales(cfg["z_ref"])
    p1 = s_u * cfg["half"][0] / cfg["half"][1]
    return xs, XSlitSampling(xs, (p1, p1 * s_v / s_u), ((RES[0] - 1) / 2, (RES[1] - 1) / 2))


def cue_points(cues, step=2.0):
    """Pixels and depths sampled every `step` px along the segments that carry a DDS depth."""
    pts, zs = [], []
    for (u0, v0, u1, v1), z in zip(cues.segments[cues.valid], cues.depth[cues.valid]):
        n = max(2, int(np.hypot(u1 - u0, v1 - v0) / step))
        t = np.linspace(0, 1, n)
        pts.append(np.column_stack([u0 + t * (u1 - u0), v0 + t * (v1 - v0)]))
        zs.append(np.full(n, z))
    return (np.concatenate(pts), np.concatenate(zs)) if pts else (np.zeros((0, 2)), np.zeros(0))


def rel_err(est, truth):
    ok = np.isfinite(est) & np.isfinite(truth)
    e = np.abs(est[ok] - truth[ok]) / truth[ok]
    return float(np.median(e) * 100), float(np.mean(e) * 100), float(ok.mean() * 100)


def run(name, cfg):
    xs, sampling = make_sampling(cfg)
    img, ztrue, _ = render_planar(cfg["patches"](), sampling.rays, RES, samples=3)
    img = quantise(img)
    save_gray(out_path(f"03_{name}.png"), img)
    cues = line_cues(img, sampling, [-1.0, 1.0], min_length=15)
    mid = np.rint((cues.segments[:, :2] + cues.segments[:, 2:]) / 2).astype(int)
    zmid = ztrue[np.clip(mid[:, 1], 0, RES[1] - 1), np.clip(mid[:, 0], 0, RES[0] - 1)]
    v = cues.valid & np.isfinite(zmid)
    seg_err = np.abs(cues.depth[v] - zmid[v]) / zmid[v] * 100
    px, pz = cue_points(cues)
    t0 = time.perf_counter()
    graph = superpixel_graph(img, scale=60, sigma=0.5, min_size=40)
    t_sp = time.perf_counter() - t0
    out = {"segments": (len(cues.segments), int(cues.valid.sum()), float(np.median(seg_err)))}
    maps = {}
    for method in ("graphcut", "quadratic"):
        t1 = time.perf_counter()
        d = dense_depth(img, px, pz, method=method, lam=2.0, graph=graph)
        dt = time.perf_counter() - t1
        maps[method] = d.depth
        out[method] = rel_err(d.depth, ztrue) + (dt,)
    sparse_map = np.full(ztrue.shape, np.nan)
    ij = np.rint(px).astype(int)
    inb = (ij[:, 0] >= 0) & (ij[:, 0] < RES[0]) & (ij[:, 1] >= 0) & (ij[:, 1] < RES[1])
    sparse_map[ij[inb, 1], ij[inb, 0]] = pz[inb]
    const = np.full(ztrue.shape, np.nanmedian(np.where(np.isfinite(ztrue), ztrue, np.nan)))
    out["oracle constant"] = rel_err(const, ztrue)
    out["superpixels"] = (graph.n, t_sp)
    _figure(name, img, sparse_map, maps, ztrue)
    return out, xs, sampling


def pinhole_check(name, cfg):
    """Same scene through a pinhole at the origin: segment angles of a 3D direction do not depend on depth."""
    f = 500.0
    def rays(px):
        d = np.column_stack([(px[:, 0] - (RES[0] - 1) / 2) / f, (px[:, 1] - (RES[1] - 1) / 2) / f, np.ones(len(px))])
        return np.zeros_like(d), d / np.linalg.norm(d, axis=1, keepdims=True)
    img, _, _ = render_planar(cfg["patches"](), rays, RES, samples=2)
    seg = detect_segments(quantise(img), 15)
    ang = np.degrees(np.arctan2(seg[:, 3] - seg[:, 1], seg[:, 2] - seg[:, 0])) % 180
    dev = np.minimum(np.abs(ang - 90), np.minimum(ang, 180 - ang))  # from the nearer of 0° and 90°
    frontal = dev < 5.0
    return int(frontal.sum()), float(np.median(dev[frontal])) if frontal.any() else float("nan")


def main():
    rows, seg_rows = [], []
    for name, cfg in SCENES.items():
        t0 = time.perf_counter()
        out, xs, s = run(name, cfg)
        n, nv, med = out["segments"]
        seg_rows.append((name, f"{xs.z1:g}, {xs.z2:g}", f"{s.pitch[0]:.4g}, {s.pitch[1]:.4g}", n, nv, f"{med:.2f}"))
        for method in ("graphcut", "quadratic"):
            med_e, mean_e, cov, dt = out[method]
            rows.append((name, method, f"{med_e:.2f}", f"{mean_e:.2f}", f"{cov:.0f}", f"{dt:.2f}"))
        med_e, mean_e, cov = out["oracle constant"]
        rows.append((name, "pinhole baseline: one depth = true median (oracle scale)", f"{med_e:.2f}",
                     f"{mean_e:.2f}", f"{cov:.0f}", "-"))
        nsp, tsp = out["superpixels"]
        print(f"{name}: {nsp} superpixels in {tsp:.2f} s; total {time.perf_counter() - t0:.1f} s")
    print(table(["scene", "z1, z2 (cm)", "pitch p1, p2 (cm/px)", "LSD segments", "with DDS depth",
                 "median segment depth error %"], seg_rows))
    print(table(["scene", "solver", "median rel. error %", "mean rel. error %", "coverage %", "time (s)"], rows))
    for name, cfg in SCENES.items():
        n, spread = pinhole_check(name, cfg)
        print(f"pinhole {name}: {n} segments within 5° of horizontal/vertical, median deviation {spread:.3f}° "
              f"(the rest are receding lines): a frontal line keeps its 3D slope at every depth, so r_i = r_o "
              f"and Eqn. getz is 0/0; depth.xslit.XSlit(z1 = z2) raises DegenerateGeometryError")


def _figure(name, img, sparse_map, maps, ztrue):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 5, figsize=(17, 3.2))
    fin = ztrue[np.isfinite(ztrue)]
    lo, hi = np.percentile(fin, 1), np.percentile(fin, 99)
    ax[0].imshow(img, cmap="gray")
    ax[0].set_title(f"XSlit {name}")
    for a, m, t in zip(ax[1:], [sparse_map, maps["graphcut"], maps["quadratic"], ztrue],
                       ["sparse DDS depth", "MRF graph cut", "quadratic", "truth"]):
        im = a.imshow(m, cmap="turbo", vmin=lo, vmax=hi)
        a.set_title(t)
    for a in ax:
        a.axis("off")
    fig.colorbar(im, ax=ax[-1], label="z (cm)")
    fig.tight_layout()
    fig.savefig(out_path(f"03_{name}_fig.png"), dpi=70)


if __name__ == "__main__":
    main()
