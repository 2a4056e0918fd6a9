"""Report plots with matplotlib (Agg, no display): `aspect_ratio_plot`, `tile_map_plot`, `design_curves_plot`.

Each function draws one figure and returns PNG bytes. Inputs are plain numbers and arrays (the local
XSlit of each cube as `CubeCurve`, a `xslit_fit.tiles.TileMap`), so the plots can be checked
against independently computed values.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

__all__ = ["CubeCurve", "aspect_ratio_plot", "tile_map_plot", "design_curves_plot", "png_bytes"]


def _pyplot():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def png_bytes(fig, dpi: int = 100) -> bytes:
    """Render a figure to PNG bytes and close it."""
    plt = _pyplot()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()


@dataclass(frozen=True)
class CubeCurve:
    """One cube on its local XSlit's DDAR curve (paper's z, measured from the local virtual image plane).

    z1, z2 : slit depths (metres, < 0 behind the mirror); z : measured depth of the front face;
    aspect_ratio : measured r_i; z_std : σ of z; z_true : true depth of the face (NaN if unknown);
    color : RGB in [0, 1]; label : legend text.
    """

    z1: float
    z2: float
    z: float
    aspect_ratio: float
    z_std: float
    z_true: float = float("nan")
    color: tuple = (0.2, 0.2, 0.2)
    label: str = ""


def aspect_ratio_plot(curves: list, size=(7.0, 4.6), dpi: int = 100) -> bytes:
    """Aspect ratio r_i against depth z: each cube's theoretical curve (Eqn. ardef, r_o = 1), its
    measurement with a ±σ error bar, and the true depth (hollow marker on the curve) when known."""
    from depth import ddar
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=size, constrained_layout=True)
    zs = [c.z for c in curves] + [c.z_true for c in curves if np.isfinite(c.z_true)]
    z_hi = 1.35 * max(zs) if zs else 1.0
    for c in curves:
        z = np.linspace(max(1e-3, 0.02 * z_hi), z_hi, 300)
        ax.plot(z, ddar.aspect_ratio(z, c.z1, c.z2), color=c.color, lw=1.6, label=c.label)
        ax.errorbar([c.z], [c.aspect_ratio], xerr=[[c.z_std if np.isfinite(c.z_std) else 0.0]] * 2,
                    fmt="o", color=c.color, ms=6, mec="black", mew=0.8, capsize=4, elinewidth=1.5, zorder=3)
        if np.isfinite(c.z_true):
            ax.plot([c.z_true], [ddar.aspect_ratio(c.z_true, c.z1, c.z2)], "o", mfc="none", mec=c.color,
                    ms=11, mew=1.5, zorder=3)
    ax.set_xlabel("z: depth from the local virtual image plane (m)")
    ax.set_ylabel("image aspect ratio $r_i$ (square face, $r_o$ = 1)")
    ax.set_title("Depth-dependent aspect ratio of each cube's local XSlit")
    ax.grid(alpha=0.3)
    if curves:
        handles, labels = ax.get_legend_handles_labels()
        from matplotlib.lines import Line2D
        handles += [Line2D([], [], marker="o", ls="none", color="grey", mec="black", label="measured ± σ"),
                    Line2D([], [], marker="o", ls="none", mfc="none", mec="grey", ms=10, label="true depth")]
        ax.legend(handles=handles, fontsize=8, loc="lower right")
    return png_bytes(fig, dpi)


def tile_map_plot(tile_map, image_size, boxes=(), size=(11.0, 4.0), dpi: int = 100) -> bytes:
    """Two maps over the image: the rms ray-to-slit distance of each tile's two-slit fit (mm, log
    scale) and z2/z1. Invalid tiles (no mirror, failed fit) are left blank. boxes : (x0, y0, x1, y1, label)."""
    from matplotlib.colors import LogNorm
    from matplotlib.patches import Rectangle
    plt = _pyplot()
    w, h = image_size
    fig, axes = plt.subplots(1, 2, figsize=size, constrained_layout=True)
    rms_mm = np.where(tile_map.valid, tile_map.rms * 1e3, np.nan)
    ratio = np.where(tile_map.valid, tile_map.ratio, np.nan)
    b = tile_map.bounds
    xs = np.append(b[0, :, 0], b[0, -1, 2])
    ys = np.append(b[:, 0, 1], b[-1, 0, 3])
    finite = rms_mm[np.isfinite(rms_mm) & (rms_mm > 0)]
    norm = LogNorm(vmin=finite.min(), vmax=max(finite.max(), finite.min() * 1.01)) if finite.size else None
    panels = [(rms_mm, "rms ray-to-slit distance (mm)", "viridis", norm),
              (ratio, "z2 / z1", "plasma", None)]
    for ax, (data, title, cmap, nrm) in zip(axes, panels):
        m = ax.pcolormesh(xs, ys, np.ma.masked_invalid(data), cmap=cmap, norm=nrm, shading="flat")
        ax.set_xlim(0, w)
        ax.set_ylim(h, 0)
        ax.set_aspect("equal")
        ax.set_title(title)
        ax.set_xlabel("u (px)")
        ax.set_ylabel("v (px)")
        fig.colorbar(m, ax=ax, shrink=0.85)
        for x0, y0, x1, y1, label in boxes:
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="white", lw=1.2))
            ax.text(x0, y0 - 4, label, color="black", fontsize=7, va="bottom",
                    bbox=dict(fc="white", ec="none", alpha=0.7, pad=0.5))
    n_ok = int(tile_map.valid.sum())
    fig.suptitle(f"Local two-slit fits over the mirror: {n_ok} of {tile_map.valid.size} tiles fitted")
    return png_bytes(fig, dpi)


def design_curves_plot(depths, curves: list, size=(11.0, 4.0), dpi: int = 100) -> bytes:
    """Sensitivity |∂r_i/∂z| and the depth step one aspect-ratio step ε causes, against depth from the
    mirror axis, for several local XSlits. curves : dicts with z1, z2, plane_distance, eps, color, label."""
    from depth import ddar
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=size, constrained_layout=True)
    depths = np.asarray(depths, dtype=np.float64)
    for c in curves:
        z = depths - c["plane_distance"]
        ok = z > 0
        sens = np.abs(ddar.sensitivity(z[ok], c["z1"], c["z2"]))
        r = ddar.aspect_ratio(z[ok], c["z1"], c["z2"])
        step = ddar.depth_std_from_aspect_ratio(r, c["eps"], c["z1"], c["z2"])
        axes[0].plot(depths[ok], sens, color=c["color"], label=c["label"])
        axes[1].plot(depths[ok], step * 1e3, color=c["color"], label=c["label"])
    axes[0].set(xlabel="depth from the mirror axis (m)", ylabel="|∂r_i/∂z| (1/m)", yscale="log",
                title="Sensitivity (Eqn. sensit)")
    axes[1].set(xlabel="depth from the mirror axis (m)", ylabel="depth step for one AR step ε (mm)",
                yscale="log", title="Discernible depth step")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    return png_bytes(fig, dpi)
