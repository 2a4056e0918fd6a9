"""HTML reports of a reconstruction or a design: `report`, `build_report`, `write_report`, `design_report`.

A report is a folder with `index.html` (self-contained: inline CSS, no script, no network) and its
pictures as PNG files beside it: an oblique 3D view and a view from above (pyvista, off-screen), the
aspect ratio of each cube on its local XSlit's DDAR curve, the map of local two-slit fit quality over
the mirror, the annotated image and a table of results (with errors when `simulate`'s truth is known).
Everything is computed in memory first and written all or nothing (`catadioptric.outputs.OutputSet`).
"""

from __future__ import annotations

import html
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from catadioptric.errors import CatadioptricError
from catadioptric.outputs import OutputSet

__all__ = ["GENERATOR", "ReportInput", "load_input", "truth_beside", "build_report", "write_report",
           "report", "design_report", "xslit_frame_of"]

GENERATOR = "catadioptric report"
PICTURES = ("view3d.png", "view_top.png", "aspect_ratio.png", "tile_map.png", "annotated.png")


@dataclass
class ReportInput:
    """What a reconstruction report is made of. image : (H, W, 3) uint8 RGB or None."""

    setup: object
    setup_path: Path
    result: dict
    image: np.ndarray | None = None
    truth: dict | None = None
    rec: object = None
    notes: list = field(default_factory=list)


def truth_beside(image_path) -> dict | None:
    """IMAGE.truth.json written by `simulate` beside IMAGE.png, or None (unreadable truth is ignored)."""
    p = Path(f"{Path(image_path).with_suffix('')}.truth.json")
    if not p.is_file():
        return None
    try:
        t = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    return t if isinstance(t, dict) and isinstance(t.get("cubes"), list) else None


def _read_result(path: Path) -> dict:
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise CatadioptricError(f"{path}: cannot read the result file: {exc}") from None
    try:
        result = json.loads(text)
    except ValueError as exc:
        raise CatadioptricError(f"{path}: invalid JSON: {exc}") from None
    if not isinstance(result, dict) or not isinstance(result.get("cubes"), list):
        raise CatadioptricError(f"{path}: cubes: expected a reconstruct result (an object with a list `cubes`)")
    keys = ("center", "size", "depth", "front_face_center", "front_face_corners_px", "aspect_ratio")
    for i, c in enumerate(result["cubes"]):
        missing = [k for k in keys if not isinstance(c, dict) or k not in c]
        if missing:
            raise CatadioptricError(f"{path}: cubes[{i}].{missing[0]}: missing key (expected a reconstruct result)")
        try:
            np.asarray([*c["center"], c["size"], c["depth"], *c["front_face_center"], c["aspect_ratio"]], dtype=float)
            if np.asarray(c["front_face_corners_px"], dtype=float).shape != (4, 2):
                raise ValueError
        except (TypeError, ValueError):
            raise CatadioptricError(f"{path}: cubes[{i}]: expected numbers (centre 3, corners 4×2)") from None
    return result


def _demosaic_of(result: dict, path: Path) -> str | None:
    """The `demosaic` a result's raw Bayer frame was made an image by (None where it names none); one-line error
    for one `depth.chroma.from_raw_frame` does not know."""
    from depth.chroma import DEMOSAICS
    demosaic = result.get("demosaic")
    if demosaic is not None and demosaic not in DEMOSAICS:
        raise CatadioptricError(f"{path}: demosaic: expected one of {', '.join(DEMOSAICS)}, got {demosaic!r}")
    return demosaic


def load_input(input_path, setup_path=None, method=None, progress=None) -> ReportInput:
    """An image (reconstructed now) or a RESULT.json (read, with its setup and image beside it)."""
    from catadioptric import reconstruct as rc
    from catadioptric.setup import load_setup
    path = Path(input_path)
    if not path.exists():
        raise CatadioptricError(f"{path}: no such file")
    if path.suffix.lower() == ".json":
        result = _read_result(path)
        if setup_path is None:
            name = result.get("setup")
            if not isinstance(name, str) or not name:
                raise CatadioptricError(f"{path}: setup: no setup named in the result; pass --setup SETUP.toml")
            setup_path = path.parent / name
        setup = load_setup(setup_path)
        notes, image, truth = [], None, None
        img_name = result.get("image")
        if isinstance(img_name, str) and img_name:
            img_path = path.parent / img_name
            if img_path.is_file():
                image = rc.camera_image(img_path, setup, setup_path, _demosaic_of(result, path))  # (its size checked)
                truth = truth_beside(img_path)
            else:
                notes.append(f"The image {img_name} is not beside the result: no annotated image.")
        return ReportInput(setup=setup, setup_path=Path(setup_path), result=result, image=image, truth=truth,
                           notes=notes)
    setup, setup_path, image, rec = rc.run_reconstruction(path, setup_path, method, progress=progress)
    result = rc.result_dict(path, setup_path, rec, rc.raw_demosaic(setup))
    return ReportInput(setup=setup, setup_path=Path(setup_path), result=result, image=image,
                       truth=truth_beside(path), rec=rec)


def xslit_frame_of(local_xslit: dict):
    """(origin (3,), e_z (3,), z1, z2) of a cube's `local_xslit` result entry, or None.

    The virtual image plane is parallel to both slits, so e_z = ±unit(d1 × d2), oriented so that
    the slits lie at signed distances z1, z2 from the plane (docs/CONVENTIONS.md); each slit's point
    may be anywhere on its line. The origin is where the slits' projections onto the plane cross.
    """
    try:
        z1, z2 = float(local_xslit["z1"]), float(local_xslit["z2"])
        (p1, d1), (p2, d2) = ((np.asarray(s["point"], dtype=np.float64), np.asarray(s["direction"], dtype=np.float64))
                              for s in local_xslit["slits"][:2])
    except (KeyError, TypeError, ValueError, IndexError):
        return None
    n = np.cross(d1, d2)
    if not (np.all(np.isfinite(n)) and np.isfinite(z1) and np.isfinite(z2)) or np.linalg.norm(n) < 1e-9 \
            or z1 == z2 or z1 == 0 or z2 == 0 or p1.shape != (3,) or p2.shape != (3,):
        return None
    n /= np.linalg.norm(n)
    if (p2 - p1) @ n * (z2 - z1) < 0:
        n = -n
    c1, c2 = p1 @ n - z1, p2 @ n - z2  # the plane is {x : x·n = c}
    if abs(c1 - c2) > 1e-6 + 1e-3 * abs(z2 - z1):
        return None  # the slit depths do not match the slits' positions
    c = 0.5 * (c1 + c2)
    q1, q2 = p1 - (p1 @ n - c) * n, p2 - (p2 @ n - c) * n  # projections onto the plane
    t = np.linalg.lstsq(np.column_stack([d1, -d2]), q2 - q1, rcond=None)[0]
    return q1 + t[0] * d1, n, z1, z2


def _overlay_source(inp: ReportInput, hit_mask: np.ndarray):
    """A `draw_overlay`-compatible reconstruction (the real one, or one rebuilt from the result dict)."""
    if inp.rec is not None:
        return inp.rec
    cubes = []
    for c in inp.result["cubes"]:
        px = np.asarray(c["front_face_corners_px"], dtype=np.float64)
        bbox = c.get("bbox_px") or [int(px[:, 0].min()), int(px[:, 1].min()), int(px[:, 0].max()) + 1,
                                    int(px[:, 1].max()) + 1]
        cubes.append(SimpleNamespace(corners_px=px, bbox=tuple(int(x) for x in bbox), depth=float(c["depth"]),
                                     edge_misfit_px=c.get("edge_misfit_px")))
    refused = [SimpleNamespace(bbox=tuple(int(x) for x in r["bbox_px"])) for r in inp.result.get("refused", [])
               if isinstance(r, dict) and len(r.get("bbox_px", [])) == 4]
    return SimpleNamespace(cubes=cubes, refused=refused, mirror_mask=hit_mask)


def _fmt(x, spec=".4f"):
    return "—" if x is None or not np.isfinite(x) else format(x, spec)


def _table_html(result: dict, truth: dict | None, colors) -> str:
    from catadioptric.reconstruct import match_truth, size_set_aside_note
    cubes = result["cubes"]
    matches = match_truth(result, truth) if truth else [None] * len(cubes)
    head = ["#", "depth (m)", "±σ (m)", "size (m)", "centre (m)", "AR r_i", "z1 (m)", "z2 (m)",
            "fit rms (µm)", "method"]
    if truth:
        head += ["true depth (m)", "depth error", "centre error", "size error"]
    rows = []
    for i, (c, t) in enumerate(zip(cubes, matches)):
        lx = c.get("local_xslit") or {}
        sw = "#%02x%02x%02x" % tuple(int(255 * v) for v in colors[i])
        size = _fmt(c["size"]) + (" *" if c.get("size_set_aside") else "")  # (exact_shape_prior: set aside)
        cells = [f'<span class="sw" style="background:{sw}"></span>{i}', _fmt(c["depth"]),
                 _fmt(c.get("uncertainty", {}).get("depth")), size,
                 "[" + ", ".join(f"{x:+.3f}" for x in c["center"]) + "]", _fmt(c["aspect_ratio"], ".3f"),
                 _fmt(lx.get("z1")), _fmt(lx.get("z2")), _fmt(1e6 * lx.get("rms_ray_distance", np.nan), ".1f"),
                 html.escape(str(c.get("method", result.get("method", ""))))]
        if truth:
            if t is None:
                cells += ["—"] * 4
            else:
                cerr = np.linalg.norm(np.subtract(c["center"], t["center"])) / t["depth"]
                cells += [_fmt(t["depth"]), f"{100 * (c['depth'] / t['depth'] - 1):+.2f} %", f"{100 * cerr:.2f} %",
                          f"{100 * (c['size'] / t['size'] - 1):+.2f} %"]
        rows.append("<tr>" + "".join(f"<td>{x}</td>" for x in cells) + "</tr>")
    refused = "".join(f"<li>cube at {html.escape(str(r.get('bbox_px')))}: {html.escape(str(r.get('reason')))}</li>"
                      for r in result.get("refused", []) if isinstance(r, dict))
    table = ("<table><thead><tr>" + "".join(f"<th>{h}</th>" for h in head) + "</tr></thead><tbody>"
             + "".join(rows) + "</tbody></table>")
    if note := size_set_aside_note(cubes):  # exact_shape_prior
        table += f'<p class="note">{html.escape(note, quote=False)}</p>'
    if not cubes:
        table = "<p>No cube was recovered.</p>"
    if refused:
        table += f"<p>Refused (seen but not estimated):</p><ul>{refused}</ul>"
    return table


_CSS = """body{font-family:system-ui,sans-serif;max-width:1250px;margin:1.5em auto;padding:0 1em;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;margin-top:1.6em;border-bottom:1px solid #ddd}
img{max-width:100%;border:1px solid #ddd}figure{margin:0.8em 0}figcaption{color:#555;font-size:0.9em}
table{border-collapse:collapse;font-size:0.88em}td,th{border:1px solid #ccc;padding:3px 7px;text-align:right}
th{background:#f3f3f3}.sw{display:inline-block;width:0.8em;height:0.8em;margin-right:4px;border:1px solid #555}
.note{color:#8a5a00}code{background:#f3f3f3;padding:0 3px}"""


def _page(title: str, subtitle: str, sections: list) -> str:
    body = "".join(sections)
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta name="generator" content="{GENERATOR}"><title>{html.escape(title)}</title>'
            f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1><p>{subtitle}</p>{body}</body></html>\n")


def _figure(src: str, alt: str, caption: str) -> str:
    return (f'<figure><img src="{src}" alt="{html.escape(alt)}"><figcaption>{caption}</figcaption></figure>')


def _tiles_for(resolution, n: int = 16) -> tuple[int, int]:
    w, h = resolution
    return max(1, round(n * h / w)), n


def _tile_map(camera, mirror, n: int = 16, progress=None):
    """`fit_tiles` over the ray map of every `stride`-th pixel (each tile's fit subsamples its rays
    anyway); tile bounds are returned in full-image pixels."""
    import dataclasses
    from raytrace.truth import mirror_rays
    from xslit_fit.tiles import fit_tiles
    w, h = camera.resolution
    stride = max(1, round(max(w, h) / 640))
    us, vs = np.arange(0, w, stride, dtype=np.float64), np.arange(0, h, stride, dtype=np.float64)
    gu, gv = np.meshgrid(us, vs)
    r = mirror_rays(camera, mirror, np.column_stack([gu.ravel(), gv.ravel()]))
    shape = (len(vs), len(us))
    tm = fit_tiles(r.points.reshape(*shape, 3), r.directions.reshape(*shape, 3), r.hit.reshape(shape),
                   tiles=_tiles_for((w, h), n), max_rays_per_tile=400, progress=progress)
    return dataclasses.replace(tm, bounds=np.minimum(tm.bounds * stride, [w, h, w, h]))


def _xslit_slits(local_xslit: dict, half_length: float) -> list:
    out = []
    for k, s in enumerate((local_xslit or {}).get("slits", [])[:2]):
        p, d = np.asarray(s["point"], dtype=np.float64), np.asarray(s["direction"], dtype=np.float64)
        d = d / np.linalg.norm(d)
        out.append((np.array([p - half_length * d, p + half_length * d]), k))
    return out


def build_report(inp: ReportInput, window_size=(1200, 800), progress=None) -> dict:
    """Compute every file of the report in memory: {file name: bytes}."""
    from catadioptric import plots, views
    from catadioptric.reconstruct import draw_overlay, match_truth
    from catadioptric.simulate import encode_png
    from raytrace.truth import mirror_rays

    total = 5
    step = (lambda i: progress(i, total)) if progress is not None else (lambda i: None)
    camera, mirror = inp.setup.camera.build(), inp.setup.mirror.build()
    w, h = camera.resolution
    result, truth = inp.result, inp.truth
    cubes = result["cubes"]
    colors = views.cube_palette(len(cubes))
    matches = match_truth(result, truth) if truth else [None] * len(cubes)
    files: dict[str, bytes] = {}

    # 1. The per-pixel ray map and the local fit quality over the mirror.
    tm = _tile_map(camera, mirror)
    boxes = [(*(c.get("bbox_px") or _corner_box(c)), f"#{i}") for i, c in enumerate(cubes)]
    files["tile_map.png"] = plots.tile_map_plot(tm, (w, h), boxes)
    step(1)

    # 2. 3D views.
    solids = [views.CubeSolid(views.cube_from_result(c, camera, mirror), colors[i], f"#{i} {c['depth']:.3f} m")
              for i, c in enumerate(cubes)]
    true_cubes = [v for v in (views.cube_from_truth(t) for t in (truth or {}).get("cubes", [])) if v is not None]
    slits = [s for c in cubes for s in _xslit_slits(c.get("local_xslit"), 0.6 * mirror.radius)]
    model = views.scene_model(camera, mirror, solids, true_cubes, slits)
    files["view3d.png"] = encode_png(views.render_view(model, "perspective", window_size).image)
    step(2)
    files["view_top.png"] = encode_png(views.render_view(model, "top", window_size).image)
    step(3)

    # 3. Aspect ratio against depth on each cube's local XSlit.
    curves = []
    for i, (c, t) in enumerate(zip(cubes, matches)):
        fr = xslit_frame_of(c.get("local_xslit") or {})
        if fr is None:
            inp.notes.append(f"Cube #{i} has no usable local XSlit in the result: it is not in the "
                             "aspect-ratio plot.")
            continue
        origin, n, z1, z2 = fr
        z = float((np.asarray(c["front_face_center"]) - origin) @ n)
        z_true = float((np.asarray(t["front_face_center"]) - origin) @ n) if t else float("nan")
        curves.append(plots.CubeCurve(z1=z1, z2=z2, z=z, aspect_ratio=float(c["aspect_ratio"]),
                                      z_std=float(c.get("uncertainty", {}).get("depth", np.nan)),
                                      z_true=z_true, color=colors[i],
                                      label=f"#{i}: z1 = {100 * z1:.1f} cm, z2 = {100 * z2:.1f} cm"))
    files["aspect_ratio.png"] = plots.aspect_ratio_plot(curves)
    step(4)

    # 4. The annotated image.
    if inp.image is not None:
        hit = inp.rec.mirror_mask if inp.rec is not None else mirror_rays(camera, mirror).hit.reshape(h, w)
        files["annotated.png"] = encode_png(draw_overlay(inp.image, _overlay_source(inp, hit)))
    step(5)

    # 5. The page.
    title = f"Reconstruction of {result.get('image', 'an image')}"
    floor = result.get("floor")  # (`reconstruct --on-floor`)
    on_floor = "" if not isinstance(floor, dict) else (
        f", standing on a floor {float(floor['height']):+.4f} m along the mirror's axis"
        + (f" (±{float(floor['std']):.4f} m)" if floor.get("std") else ""))
    carried = result.get("setup_uncertainty")  # (a setup with an `[uncertainty]` table)
    unsure = "" if not isinstance(carried, dict) else (
        "; ±σ including the setup's own σ ("
        + ", ".join(f"{html.escape(str(k))} {html.escape(str(v))}" for k, v in carried.items()) + ")")
    sub = (f"{len(cubes)} cube(s), method <code>{html.escape(str(result.get('method', '')))}</code>{on_floor}, setup "
           f"<code>{html.escape(inp.setup_path.name)}</code>{unsure}; "
           + ("errors against the simulation's truth." if truth else "no ground truth beside the image."))
    notes = "".join(f'<p class="note">{html.escape(n)}</p>' for n in inp.notes)
    sec = [notes, "<h2>Results</h2>", _table_html(result, truth, colors),
           "<h2>3D view</h2>",
           _figure("view3d.png", "3D view of camera, mirror, rays and cubes",
                   "The camera (black dot) and its frustum, the cylinder mirror (blue), a sparse fan of camera "
                   "rays (orange) and their reflections (red), each cube's two local virtual slits (green: "
                   "slit 1, along the mirror axis; purple: slit 2, across it), the reconstructed cubes (solid, "
                   "labelled with their depth from the mirror axis)"
                   + (" and the true cubes (black outlines)." if true_cubes else ".")),
           _figure("view_top.png", "view from above",
                   "From above, along the mirror axis: grey rings are distances from the axis."),
           "<h2>Aspect ratio against depth</h2>",
           _figure("aspect_ratio.png", "aspect ratio against depth",
                   "Each cube's local XSlit gives its own curve r_i(z) = z2(z − z1)/(z1(z − z2)) for a square "
                   "face (r_o = 1, Eqn. ardef). Dots: the measured aspect ratio at the recovered depth with its "
                   "±σ bar" + ("; rings: the true depth on the curve." if truth else ".")),
           "<h2>Local XSlit fit over the mirror</h2>",
           _figure("tile_map.png", "fit quality map",
                   "Two slits fitted to the reflected rays of each tile: rms ray-to-slit distance (left) and "
                   "z2/z1 (right). Blank tiles see no mirror. White boxes: the cubes.")]
    if "annotated.png" in files:
        sec += ["<h2>Annotated image</h2>",
                _figure("annotated.png", "annotated image",
                        "Face outlines (yellow), corners (magenta) and depths from the mirror axis.")]
    files["index.html"] = _page(title, sub, sec).encode()
    files["result.json"] = (json.dumps(result, indent=2) + "\n").encode()
    return files


def _corner_box(c: dict) -> list:
    px = np.asarray(c["front_face_corners_px"], dtype=np.float64)
    return [px[:, 0].min(), px[:, 1].min(), px[:, 0].max(), px[:, 1].max()]


def check_output_dir(out_dir) -> Path:
    """The report folder: new, empty, or a previous report (its index.html says GENERATOR)."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise CatadioptricError(f"{out}: -o: expected a folder for the report, got a file")
    if out.is_dir() and any(out.iterdir()):
        index = out / "index.html"
        try:
            ours = index.is_file() and f'content="{GENERATOR}"' in index.read_text(errors="replace")[:2000]
        except OSError:
            ours = False
        if not ours:
            raise CatadioptricError(f"{out}: -o: the folder is not empty and holds no previous report; "
                                    "choose a new or empty folder")
    if not out.parent.is_dir():
        raise CatadioptricError(f"{out}: -o: the parent folder {out.parent} does not exist")
    return out


def write_report(files: dict, out_dir) -> Path:
    """Write the report's files into out_dir all or nothing; returns the path of index.html."""
    out = check_output_dir(out_dir)
    created = not out.exists()
    if created:
        try:
            out.mkdir()
        except OSError as exc:
            raise CatadioptricError(f"{out}: cannot make the report's folder ({exc.strerror})") from None
    try:
        with OutputSet() as o:
            for name, data in files.items():
                o.write_bytes(out / name, data)
    except BaseException:
        if created:
            for p in out.iterdir():
                p.unlink()
            out.rmdir()
        raise
    return out / "index.html"


def report(input_path, out_dir, setup_path=None, method=None, window_size=(1200, 800), progress=None) -> Path:
    """`catadioptric report`: reconstruct (or read) then write the report; returns index.html's path."""
    check_output_dir(out_dir)  # refuse a bad folder before any work
    inp = load_input(input_path, setup_path, method)
    return write_report(build_report(inp, window_size, progress), out_dir)


def design_report(setup, out_dir, depth_range=None, design=None, window_size=(1200, 800), progress=None) -> Path:
    """A report of a setup's design: 3D view of the setup, sensitivity and discernible-depth curves of
    local XSlits across the mirror, the tile map, and the design numbers at the image centre.

    setup : catadioptric.setup.Setup or a path to a setup file; design : a `catadioptric.design.Design`
    (computed with `design_setup` when not given). Returns the path of index.html.
    """
    from catadioptric import plots, views
    from catadioptric.setup import Setup, load_setup
    from catadioptric.simulate import encode_png

    check_output_dir(out_dir)
    name = "setup"
    if not isinstance(setup, Setup):
        name = Path(setup).name
        setup = load_setup(setup)
    camera, mirror = setup.camera.build(), setup.mirror.build()
    w, h = camera.resolution
    files: dict[str, bytes] = {}
    tm = _tile_map(camera, mirror, progress=progress)
    files["tile_map.png"] = plots.tile_map_plot(tm, (w, h))

    # Local XSlits along the middle tile row: their slits in 3D and their curves.
    ny, nx = tm.shape
    row = ny // 2
    cols = [j for j in range(nx) if tm.valid[row, j]]
    picks = sorted(set(cols[k] for k in np.linspace(0, len(cols) - 1, min(5, len(cols))).round().astype(int))) \
        if cols else []
    colors = views.cube_palette(len(picks))
    slits, curves = [], []
    for k, j in enumerate(picks):
        fr = tm.frames[row][j]
        slits += _xslit_slits({"slits": [{"point": ln.point, "direction": ln.direction} for ln in fr.slits]},
                              0.6 * mirror.radius)
        x0, y0, x1, y1 = tm.bounds[row, j]
        curves.append({"z1": fr.z1, "z2": fr.z2, "plane_distance": float(mirror.distance_to_axis(fr.origin[None])[0]),
                       "eps": 1.0 / max(w, h), "color": colors[k], "label": f"tile at u = {(x0 + x1) // 2} px"})
    objects = [views.CubeSolid(_config_cube(o), (0.6, 0.6, 0.6)) for o in setup.objects]
    model = views.scene_model(camera, mirror, objects, (), slits)
    files["view3d.png"] = encode_png(views.render_view(model, "perspective", window_size).image)
    far = max(model.rings) if model.rings else 1.0
    lo = mirror.radius * 1.5
    depths = np.linspace(lo, max(far, 3 * lo), 200) if depth_range is None else np.linspace(*map(float, depth_range), 200)
    files["design_curves.png"] = plots.design_curves_plot(depths, curves)
    numbers = ""
    from catadioptric.design import design_setup, plot_design
    if design is None:
        try:
            design = design_setup(setup, depth_range)
        except CatadioptricError:  # no XSlit fit at the image centre: the page goes without it
            design = None
    if design is not None:
        buf = io.BytesIO()
        plot_design(design, buf)
        files["design.png"] = buf.getvalue()
        f = design.fit
        numbers = (f"<table><tbody><tr><th>z1 (m)</th><td>{_fmt(f.get('z1'))}</td></tr>"
                   f"<tr><th>z2 (m)</th><td>{_fmt(f.get('z2'))}</td></tr>"
                   f"<tr><th>z2/z1</th><td>{_fmt(f.get('ratio'), '.2f')}</td></tr>"
                   f"<tr><th>max discernible depth, ε = 1 px (m)</th><td>{_fmt(design.max_depth_1px, '.2f')}</td></tr>"
                   f"<tr><th>max discernible depth, ε = 0.1 px (m)</th><td>{_fmt(design.max_depth_01px, '.2f')}</td></tr>"
                   "</tbody></table>")
    sec = ["<h2>Design numbers at the image centre</h2>", numbers or "<p>Not available.</p>"]
    if "design.png" in files:
        sec.append(_figure("design.png", "design curves at the image centre",
                           "At the image centre: DDAR curve, sensitivity and expected depth error of a cube."))
    sec += ["<h2>3D view of the setup</h2>",
            _figure("view3d.png", "3D view of the setup",
                    "Camera and frustum, mirror (blue), a ray fan (orange, red), the virtual slits of tiles along "
                    "the middle row of the image (green: slit 1, purple: slit 2) and the setup's objects (grey)."),
            "<h2>Sensitivity and discernible depth across the mirror</h2>",
            _figure("design_curves.png", "sensitivity and discernible depth",
                    f"For the local XSlits of tiles along the middle image row: |∂r_i/∂z| (Eqn. sensit) and the "
                    f"depth change one aspect-ratio step ε = 1/{max(w, h)} causes."),
            "<h2>Local XSlit fit over the mirror</h2>",
            _figure("tile_map.png", "fit quality map",
                    "Rms ray-to-slit distance and z2/z1 of each tile's two-slit fit.")]
    files["index.html"] = _page(f"Design of {name}", f"Camera {w}×{h} px, cylinder mirror radius "
                                f"{mirror.radius:g} m, height {mirror.height:g} m.", sec).encode()
    return write_report(files, out_dir)


def _config_cube(obj) -> np.ndarray:
    """(8, 3) vertices of a setup's cube (hexahedron order)."""
    r = np.asarray(obj.rotation, dtype=np.float64)
    s = obj.size / 2
    local = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                      [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=np.float64) * s
    return local @ r.T + np.asarray(obj.center, dtype=np.float64)
