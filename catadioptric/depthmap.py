"""The `depthmap` command: dense depth of an XSlit image from DDS line cues and the MRF (`run_depthmap`).

The XSlit is described by an `[xslit]` table, alone in its own TOML file (it is not a mirror setup,
so `catadioptric.setup.load_setup` is not involved), or by command-line options:

    [xslit]
    z1 = -3.6                 # slit depths, in the unit the depth map is written in
    z2 = -717.9
    theta1_deg = 45.0         # slit angles to the image x axis (default 0 and 90)
    theta2_deg = 135.0
    pitch = [0.358, 0.003618] # plane length per pixel along v1 and v2 (one number: isotropic)
    principal_px = [319.5, 239.5]   # optional, default the image centre
    base_ratios = [-1.0, 1.0]       # optional r_o of the 3D line directions sought; default the
                                    # image-x and image-y directions (3D horizontal and vertical)

Writes OUT.png (colour-mapped depth, near = red) and OUT.npy (float64 (H, W) depth z, NaN where no cue
reaches) beside it.
"""

from __future__ import annotations

import io
import tomllib
from pathlib import Path

import numpy as np

from catadioptric.errors import CatadioptricError
from catadioptric.outputs import OutputSet

__all__ = ["load_xslit_table", "run_depthmap"]

_KEYS = {"z1", "z2", "theta1_deg", "theta2_deg", "pitch", "principal_px", "base_ratios"}


def load_xslit_table(path) -> dict:
    """The `[xslit]` table of a TOML file as a dict (validated keys), or CatadioptricError."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise CatadioptricError(f"{p}: cannot read the XSlit description ({exc})") from None
    table = data.get("xslit")
    if not isinstance(table, dict):
        raise CatadioptricError(f"{p}: [xslit]: expected a table with z1, z2, pitch")
    unknown = set(table) - _KEYS
    if unknown:
        raise CatadioptricError(f"{p}: [xslit]: unknown key(s) {sorted(unknown)}; expected some of {sorted(_KEYS)}")
    for key in ("z1", "z2", "pitch"):
        if key not in table:
            raise CatadioptricError(f"{p}: [xslit].{key}: missing")
    return table


def run_depthmap(image_path, xslit: dict, output, method: str = "graphcut", lam: float = 2.0,
                 min_length: float = 15.0, progress=None) -> dict:
    """Compute and write the depth map; returns a summary dict (paths, counts, depth range)."""
    import cv2
    import matplotlib
    from depth.dense import dense_depth
    from depth.lines import XSlitSampling, line_cues
    from depth.xslit import XSlit
    from depth import dds

    out = Path(output)
    if out.suffix.lower() != ".png":
        raise CatadioptricError(f"{out}: -o: expected an output file name ending in .png")
    from catadioptric.reconstruct import decode_image_file
    img = decode_image_file(image_path, cv2.IMREAD_COLOR, expected="an XSlit image, PNG or JPEG")
    gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float64) / 255.0
    h, w = gray.shape
    xs = XSlit.from_degrees(float(xslit["z1"]), float(xslit["z2"]), float(xslit.get("theta1_deg", 0.0)),
                            float(xslit.get("theta2_deg", 90.0)))
    principal = xslit.get("principal_px") or ((w - 1) / 2.0, (h - 1) / 2.0)
    sampling = XSlitSampling(xs, xslit["pitch"], principal)
    if xslit.get("base_ratios") is not None:
        ro = np.asarray(xslit["base_ratios"], dtype=np.float64)
    else:
        ro = np.array([dds.ratio_from_angle(a, xs) for a in (0.0, np.pi / 2)
                       if abs(np.sin(a - xs.theta1)) > 1e-6 and abs(np.sin(a - xs.theta2)) > 1e-6])
        if ro.size == 0:
            raise CatadioptricError("[xslit]: the image axes are along the slits; give base_ratios")
    cues = line_cues(gray, sampling, ro, min_length=min_length)
    if not np.any(cues.valid):
        raise CatadioptricError(f"{image_path}: no line segment carries a depth (none in the AR ranges)")
    pts, zs = [], []
    for (u0, v0, u1, v1), z in zip(cues.segments[cues.valid], cues.depth[cues.valid]):
        n = max(2, int(np.hypot(u1 - u0, v1 - v0) / 2))
        t = np.linspace(0, 1, n)
        pts.append(np.column_stack([u0 + t * (u1 - u0), v0 + t * (v1 - v0)]))
        zs.append(np.full(n, z))
    rgb = img[:, :, ::-1].astype(np.float64) / 255.0
    d = dense_depth(rgb, np.concatenate(pts), np.concatenate(zs), method=method, lam=lam, progress=progress,
                    scale=60, sigma=0.5, min_size=40)
    npy = out.with_suffix(".npy")
    fin = d.depth[np.isfinite(d.depth)]
    lo, hi = (float(fin.min()), float(fin.max())) if fin.size else (0.0, 1.0)
    norm = (d.depth - lo) / max(hi - lo, 1e-12)
    colour = matplotlib.colormaps["turbo_r"](np.nan_to_num(norm, nan=0.0))[:, :, :3]
    colour[~np.isfinite(d.depth)] = 0.0
    ok, png = cv2.imencode(".png", (colour[:, :, ::-1] * 255).round().astype(np.uint8))
    if not ok:
        raise CatadioptricError(f"{out}: cannot encode the image")
    depth_file = io.BytesIO()
    np.save(depth_file, d.depth)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CatadioptricError(f"{out}: -o: cannot make the folder {out.parent} ({exc.strerror})") from None
    with OutputSet() as o:  # both files or neither (the image renamed into place first: the likelier refused)
        o.write_bytes(out, png.tobytes())
        o.write_bytes(npy, depth_file.getvalue())
    return {"png": str(out), "npy": str(npy), "segments": int(len(cues.segments)),
            "segments_with_depth": int(cues.valid.sum()), "superpixels": int(d.graph.n),
            "depth_min": lo, "depth_max": hi, "method": method}
