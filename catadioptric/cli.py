"""The command line: `main(argv)` parses, calls the library, prints, and exits 1 on a known error.

Verbs: simulate, fit, design, reconstruct, report, response, lens, demo, depthmap. Errors of our packages print as one
line, `catadioptric: error: <message>`, with no traceback.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys

from catadioptric import __version__
from catadioptric.errors import CatadioptricError

__all__ = ["main", "known_errors"]


def known_errors() -> tuple[type, ...]:
    """The base errors of every package: these print as one line and exit 1."""
    from depth.errors import DepthError
    from raytrace.errors import RaytraceError
    from xslit_fit.errors import FitError
    return (CatadioptricError, DepthError, RaytraceError, FitError)


class Progress:
    """A rich progress bar for library callbacks `progress(done, total)`; silent when not a terminal
    and for work shorter than a second."""

    def __init__(self, label: str):
        self.label = label
        self._bar = None
        self._task = None
        self._start = None

    def __call__(self, done: int, total: int) -> None:
        import time
        if self._start is None:
            self._start = time.monotonic()
        if self._bar is None and time.monotonic() - self._start > 1.0 and sys.stderr.isatty():
            from rich.progress import Progress as RichProgress
            self._bar = RichProgress(transient=True)
            self._bar.start()
            self._task = self._bar.add_task(self.label, total=total)
        if self._bar is not None:
            self._bar.update(self._task, completed=done, total=total)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def _check_positive_int(value: int, flag: str) -> int:
    if value < 1:
        raise CatadioptricError(f"{flag}: expected an integer >= 1, got {value}")
    return value


def _cmd_simulate(args) -> int:
    from catadioptric.setup import load_setup
    from catadioptric.simulate import output_paths, simulate_to_files
    spp = _check_positive_int(args.spp, "--spp")
    if args.seed < 0:
        raise CatadioptricError(f"--seed: expected an integer >= 0, got {args.seed}")
    output_paths(args.output)  # validate the name before any work
    setup = load_setup(args.setup)
    with Progress("rendering") as bar:
        _, paths = simulate_to_files(setup, args.output, spp=spp, seed=args.seed, progress=bar)
    for path in paths:
        print(path)
    return 0


def _cmd_fit(args) -> int:
    import json

    import numpy as np
    from rich.console import Console
    from catadioptric import design
    from catadioptric.setup import load_setup
    setup = load_setup(args.setup)
    if args.tiles:
        with Progress("fitting tiles") as bar:
            tm = design.fit_tile_map(setup, args.tiles, progress=bar)
        result = {"tiles": design.tile_map_dict(tm)}
        if args.roi is None:
            result["mirror"] = None
    else:
        result = design.fit_region(setup, args.roi)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    console = Console(width=None if sys.stdout.isatty() else 120)
    if "tiles" in result:
        t = result["tiles"]
        valid = np.asarray(t["valid"])
        ratio = np.array([[np.nan if v is None else v for v in row] for row in t["ratio"]])
        rms = np.array([[np.nan if v is None else v for v in row] for row in t["rms_ray_distance"]])
        console.print(f"{valid.sum()} of {valid.size} tiles fitted; z2/z1 from {np.nanmin(ratio):.2f} to "
                      f"{np.nanmax(ratio):.2f}; rms ray-to-slit distance median {np.nanmedian(rms) * 1e3:.3f} mm, "
                      f"max {np.nanmax(rms) * 1e3:.3f} mm")
        return 0
    if not result["ok"]:
        console.print(f"no two-slit fit for ROI {result['roi']}: {result['reason']} ({result['glc_type']})")
        return 0
    console.print(f"ROI {result['roi']}: {result['n_rays']} rays, GLC type {result['glc_type']}")
    for i, s in enumerate(result["slits"], 1):
        console.print(f"  slit {i}: point {np.round(s['point'], 5).tolist()} direction {np.round(s['direction'], 5).tolist()}")
    console.print(f"  z1 = {result['z1']:.5f} m, z2 = {result['z2']:.5f} m, θ2 − θ1 = "
                  f"{result['theta2_deg'] - result['theta1_deg']:.2f}°, z2/z1 = {result['ratio']:.3f}")
    console.print(f"  rms ray-to-slit distance {result['rms_ray_distance']:.3e} m "
                  f"(max {result['max_ray_distance']:.3e} m), condition {result['condition']:.3g}")
    return 0


def _cmd_design(args) -> int:
    import io
    import json
    from pathlib import Path

    import numpy as np
    from rich.console import Console
    from rich.table import Table
    from catadioptric import design
    from catadioptric.outputs import OutputSet
    from catadioptric.setup import load_setup, setup_to_toml
    if args.plot and Path(args.plot).suffix.lower() != ".png":
        raise CatadioptricError(f"{args.plot}: --plot: expected an output file name ending in .png")
    if args.cube_size <= 0:
        raise CatadioptricError(f"--cube-size: expected a positive edge length in metres, got {args.cube_size}")
    if args.report:
        from catadioptric.report import check_output_dir
        check_output_dir(args.report)  # before any work: a bad folder must not leave a written --plot
    setup = load_setup(args.setup)
    if args.optimize:
        if args.depth_range is None:
            raise CatadioptricError("--optimize: expected --depth-range A B to optimise over")
        with Progress("searching setups") as bar:
            best, score, rows = design.optimize_setup(setup, args.depth_range, args.cube_size, progress=bar)
        print(f"# best of {len(rows)} setups: mean relative depth error {100 * score:.3f} % "
              f"for {100 * args.cube_size:.0f} cm cubes over {args.depth_range[0]}-{args.depth_range[1]} m")
        print(setup_to_toml(best))
        return 0
    if setup.uncertainty is not None:  # the setup's own σ: a cube's exact edges read at each depth, some seconds
        with Progress("carrying the setup's uncertainty") as bar:
            des = design.design_setup(setup, args.depth_range, args.cube_size, setup_std=setup.uncertainty.build(),
                                      progress=bar)
    else:
        des = design.design_setup(setup, args.depth_range, args.cube_size)
    tm = design.fit_tile_map(setup, args.tiles) if args.tiles else None
    if args.json:
        d = des.to_dict()
        if tm is not None:
            d["tiles"] = design.tile_map_dict(tm)
        print(json.dumps(d, indent=2))
    else:
        console = Console(width=None if sys.stdout.isatty() else 120)
        f = des.fit
        console.print(f"centre of the mirror image: slits z1 = {f['z1']:.4f} m, z2 = {f['z2']:.4f} m behind the "
                      f"virtual image plane ({des.plane_distance:.4f} m from the axis); baseline {f['baseline']:.4f} m, "
                      f"z2/z1 = {f['ratio']:.2f}, rms ray-to-slit {f['rms_ray_distance']:.2e} m")
        console.print(f"maximum discernible depth from the axis: {des.max_depth_1px:.1f} m (ε = 1 px), "
                      f"{des.max_depth_01px:.1f} m (ε = 0.1 px)")
        t = Table(title=f"unit square (r_o = 1); expected error for a {100 * des.cube_size:.0f} cm cube, ±1 px extents")
        unsure = des.setup_error
        for c in ("depth (m)", "AR r_i", "∂r_i/∂z (1/m)", "σ depth (mm)", "σ/depth (%)", "on the floor (%)",
                  *(("setup σ (mm)",) if unsure else ())):
            t.add_column(c, justify="right")
        rows = range(0, len(des.depths), max(1, len(des.depths) // 10))
        for i in rows:
            floor = des.floor_error[i] / des.depths[i]
            t.add_row(f"{des.depths[i]:.3f}", f"{des.aspect_ratio[i]:.4f}", f"{des.sensitivity[i]:.4f}",
                      f"{1e3 * des.expected_error[i]:.2f}", f"{100 * des.expected_error[i] / des.depths[i]:.2f}",
                      f"{100 * floor:.3f}" if np.isfinite(floor) else "unseen",
                      *((f"{1e3 * unsure['total'][i]:.2f}" if np.isfinite(unsure["total"][i]) else "unseen",)
                        if unsure else ()))
        t.caption = ("on the floor: a cube standing on the floor the mirror stands on (reconstruct --on-floor), its "
                     "bottom edge ±1 px; unseen: its floor point is not in the image"
                     + ("; setup σ: the depth σ the setup's \\[uncertainty] gives that cube, facing the axis at the "
                        "mirror centre's height, its edges exact (unseen: not wholly in the image)" if unsure else ""))
        console.print(t)
        if unsure:
            # which number of the setup to measure better: each one's share of the depth σ
            u = Table(title="depth σ (mm) per \\[uncertainty] number")
            u.add_column("number", justify="left", no_wrap=True)
            near_to_far = sorted({0, len(des.depths) // 2, len(des.depths) - 1})
            for i in near_to_far:
                u.add_column(f"at {des.depths[i]:.3f} m", justify="right")
            for name in unsure:
                u.add_row(name, *(f"{1e3 * unsure[name][i]:.2f}" if np.isfinite(unsure[name][i]) else "—"
                                  for i in near_to_far))
            console.print(u)
        if tm is not None:
            console.print(f"tiles: {tm.valid.sum()} of {tm.valid.size} fitted; z2/z1 {np.nanmin(tm.ratio):.2f}–"
                          f"{np.nanmax(tm.ratio):.2f}; baseline {np.nanmin(tm.baseline):.4f}–{np.nanmax(tm.baseline):.4f} m")
    if args.plot:
        buf = io.BytesIO()
        design.plot_design(des, buf)
        with OutputSet() as out:
            out.write_bytes(args.plot, buf.getvalue())
        print(args.plot)
    if args.report:
        from catadioptric.report import design_report
        with Progress("writing the design report") as bar:
            print(design_report(setup, args.report, depth_range=args.depth_range, design=des, progress=bar))
    return 0


def _cmd_reconstruct(args) -> int:
    from pathlib import Path
    from rich.console import Console
    from catadioptric import reconstruct as rc
    json_path = Path(args.output) if args.output else Path(args.image).with_suffix(".result.json")
    if json_path.suffix.lower() != ".json":
        raise CatadioptricError(f"{json_path}: -o: expected an output file name ending in .json")
    if args.overlay and Path(args.overlay).suffix.lower() != ".png":
        raise CatadioptricError(f"{args.overlay}: --overlay: expected an output file name ending in .png")
    workers = None if args.workers is None else _check_positive_int(args.workers, "--workers")
    with Progress("outlining and estimating cubes") as bar:
        setup, setup_path, image, rec = rc.run_reconstruction(args.image, args.setup, args.method,
                                                              args.cube_size, progress=bar,
                                                              blur_domain=args.blur_domain, workers=workers,
                                                              cube_size_std=args.cube_size_std,
                                                              on_floor=args.on_floor, floor_height=args.floor_height,
                                                              floor_std=args.floor_std, demosaic=args.demosaic)
    result = rc.result_dict(args.image, setup_path, rec, rc.raw_demosaic(setup, args.demosaic))
    truth = _truth_beside(args.image)
    overlay = rc.draw_overlay(image, rec) if args.overlay else None
    written = rc.write_outputs(result, json_path, args.overlay, overlay)
    console = Console(width=None if sys.stdout.isatty() else 120)
    rc.print_table(console, result, truth)
    if note := rc.floor_note(result, setup.mirror):
        console.print(note)
    if note := rc.setup_uncertainty_note(setup, result, setup_path):
        console.print(note, markup=False, soft_wrap=True)
    if not rec.cubes:
        print("no cube found (cubes are found by their colour, or, on a uniform background, as regions of "
              "another colour than it)" if not rec.refused else "no cube could be estimated")
    for p in written:
        print(p)
    return 0


def _truth_beside(image_path):
    """IMAGE.truth.json from `simulate`, when it lies beside the image (for the error columns)."""
    import json
    from pathlib import Path
    p = Path(image_path).with_suffix("")
    p = Path(f"{p}.truth.json")
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return None


def _cmd_report(args) -> int:
    from catadioptric import report
    with Progress("writing the report") as bar:
        index = report.report(args.input, args.output, args.setup, method=args.method, progress=bar)
    print(index)
    return 0


def _cmd_response(args) -> int:
    from raytrace.response import calibrate_response
    if len(args.times) != len(args.images):
        raise CatadioptricError(f"--times: expected one exposure time per image ({len(args.images)}), "
                                f"got {len(args.times)}")
    images = _same_size_images(args.images)
    response, agreement = calibrate_response(images, args.times)
    print(_response_toml(response, agreement, len(images)), end="")
    return 0


def _same_size_images(paths) -> list:
    """The images at `paths` (`catadioptric.reconstruct.read_image`), each of the first one's size."""
    from catadioptric import reconstruct as rc
    images = [rc.read_image(path) for path in paths]
    for path, im in zip(paths, images):
        if im.shape != images[0].shape:
            raise CatadioptricError(f"{path}: expected the size of {paths[0]}, {images[0].shape[1]}×"
                                    f"{images[0].shape[0]} pixels, got {im.shape[1]}×{im.shape[0]}")
    return images


def _exposure_time(text: str) -> float:
    """An exposure time as a number or a fraction ("1/250")."""
    num, _, den = text.partition("/")
    try:
        return float(num) / float(den) if den else float(num)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"expected an exposure time (a number or a fraction such as 1/250), "
                                         f"got {text!r}") from None


def _response_toml(response, agreement, n_images: int) -> str:
    """The `[camera] response` TOML lines of a calibrated response (one list a channel, R, G, B), with comments
    on where it came from and how well its exposures agree."""
    table = response.table
    lines = [f"# the camera's response (catadioptric response), from {n_images} exposures: each code's light, R, G, B",
             "# successive exposures read through it agree on each pixel's light to "
             + ("(no pixel well exposed in two)" if agreement is None else
                f"{100 * agreement['median']:.2f} % (median), {100 * agreement['p90']:.2f} % (90th percentile) "
                f"over {agreement['values']} pixel channels"),
             "[camera]", "response = ["]
    for k in range(3):
        rows = [", ".join(f"{v:.7g}" for v in table[a:a + 8, k]) for a in range(0, 256, 8)]
        lines.append("  [" + ",\n   ".join(rows) + "],")
    lines.append("]")
    return "\n".join(lines) + "\n"


def _board_size(text: str) -> tuple[int, int]:
    """A chessboard's inner corners as COLSxROWS ("9x6")."""
    cols, sep, rows = text.lower().replace("×", "x").partition("x")
    try:
        size = (int(cols), int(rows))
    except ValueError:
        size = None
    if not sep or size is None or min(size) < 3:
        raise argparse.ArgumentTypeError(f"expected the inner corners as COLSxROWS, each >= 3 (e.g. 9x6), got {text!r}")
    return size


def _cmd_lens(args) -> int:
    import numpy as np

    from raytrace.chroma import calibrate_channels
    if not (np.isfinite(args.square) and args.square > 0):
        raise CatadioptricError(f"--square: expected the squares' side, > 0, got {args.square}")
    images = _same_size_images(args.images)
    calibration = calibrate_channels(images, args.board, args.square)
    print(_lens_toml(calibration, args.images, args.board), end="")
    return 0


def _lens_toml(cal, paths, board) -> str:
    """The `[camera]` lines (focal_px, principal_px, distortion: green's) and `[camera.red]` / `[camera.blue]` tables
    of a channel calibration, with comments on where they came from and how well they fit."""
    import numpy as np

    def numbers(values):
        return "[" + ", ".join(f"{float(v):.10g}" for v in values) + "]"

    def table(K, dist):
        return [f"focal_px = {numbers([K[0, 0], K[1, 1]])}", f"principal_px = {numbers([K[0, 2], K[1, 2]])}",
                f"distortion = {numbers(np.ravel(dist)[:5])}"]

    unused = [str(paths[k]) for k in range(len(paths)) if k not in cal.views]
    rms = cal.rms_px
    lines = [f"# the lens (catadioptric lens), from {len(cal.views)} of {len(paths)} views of a {board[0]}×{board[1]} "
             "chessboard" + (f" (not found in: {', '.join(unused)})" if unused else ""),
             f"# rms reprojection error: green {rms['green']:.3f} px, red {rms['red']:.3f} px, "
             f"blue {rms['blue']:.3f} px",
             f"# at the image's farthest corner red images {cal.corner_shift_px['red']:.2f} px and blue "
             f"{cal.corner_shift_px['blue']:.2f} px from green",
             f"# the boards spanned {100 * cal.coverage:.0f} % of the image"
             + ("" if cal.coverage >= 0.5 else ": beyond it the channels are extrapolated; take views nearer the "
                "image's edges and corners"),
             "# (merge the [camera] keys into your setup's [camera] table)",
             "[camera]", *table(cal.K, cal.distortion), "", "[camera.red]", *table(cal.red.K, cal.red.distortion),
             "", "[camera.blue]", *table(cal.blue.K, cal.blue.distortion)]
    return "\n".join(lines) + "\n"


def _cmd_demo(args) -> int:
    from catadioptric import demo
    return demo.run(args)


def _cmd_depthmap(args) -> int:
    from catadioptric import depthmap as dmap
    if args.setup is None and (args.xslit is None or args.pitch is None):
        raise CatadioptricError("depthmap: give --setup XSLIT.toml (an [xslit] table) or --xslit and --pitch")
    table = dmap.load_xslit_table(args.setup) if args.setup else {}
    if args.xslit is not None:
        table.update(z1=args.xslit[0], z2=args.xslit[1], theta1_deg=args.xslit[2], theta2_deg=args.xslit[3])
    if args.pitch is not None:
        table["pitch"] = args.pitch
    with Progress("dense depth") as bar:
        summary = dmap.run_depthmap(args.image, table, args.output, method=args.method, lam=args.lam, progress=bar)
    print(f"{summary['segments_with_depth']}/{summary['segments']} line segments with a DDS depth, "
          f"{summary['superpixels']} superpixels, depth {summary['depth_min']:.4g}..{summary['depth_max']:.4g}")
    print(summary["png"])
    print(summary["npy"])
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="catadioptric",
        description="Absolute depth and size from one image of a cylindrical mirror (XSlit DDAR/DDS).")
    p.add_argument("--version", action="version", version=f"catadioptric {__version__}")
    sub = p.add_subparsers(dest="verb", metavar="VERB", required=True)

    s = sub.add_parser("simulate", help="render what the camera sees in the mirror, with exact ground truth")
    s.add_argument("setup", metavar="SETUP.toml", help="the setup file: camera, mirror and objects")
    s.add_argument("-o", "--output", metavar="OUT.png", required=True,
                   help="the image; OUT.toml, OUT.truth.json and OUT.gt.npz (ground truth) are written beside it")
    s.add_argument("--spp", type=int, default=4, help="samples per pixel at edges (default 4)")
    s.add_argument("--seed", type=int, default=0, help="seed of the pixel sample pattern (default 0)")
    s.set_defaults(func=_cmd_simulate)

    f = sub.add_parser("fit", help="fit virtual slits (XSlit/GLC) to the mirror's reflected rays")
    f.add_argument("setup", metavar="SETUP.toml", help="the setup file ([camera] and [mirror] are read)")
    f.add_argument("--roi", type=float, nargs=4, metavar=("X0", "Y0", "X1", "Y1"),
                   help="fit the rays of this pixel rectangle (default: the whole mirror)")
    f.add_argument("--tiles", type=int, metavar="N", help="fit each tile of an N×N grid over the image instead")
    f.add_argument("--json", action="store_true", help="print the fit as JSON")
    f.set_defaults(func=_cmd_fit)

    d = sub.add_parser("design", help="slits, sensitivity and discernible depth of a mirror setup")
    d.add_argument("setup", metavar="SETUP.toml", help="the setup file ([camera], [mirror], optional [uncertainty])")
    d.add_argument("--depth-range", type=float, nargs=2, metavar=("A", "B"),
                   help="depths from the mirror's axis to design for (m; default: 2 to 10 mirror radii beyond it)")
    d.add_argument("--json", action="store_true", help="print the design as JSON")
    d.add_argument("--plot", metavar="OUT.png", help="also write the sensitivity and discernible-depth curves")
    d.add_argument("--optimize", action="store_true",
                   help="search camera distance and mirror radius (±50 %%) for the least expected depth error; prints TOML")
    d.add_argument("--cube-size", type=float, default=0.04, metavar="S", help="cube edge for the expected error (m)")
    d.add_argument("--tiles", type=int, metavar="N", help="also fit an N×N tile map")
    d.add_argument("--report", metavar="DIR", help="also write an HTML design report (3D view, curves, tile map)")
    d.set_defaults(func=_cmd_design)

    r = sub.add_parser("reconstruct", help="cube depths, sizes and positions from one mirror image")
    r.add_argument("image", metavar="IMAGE.png", help="the photograph of the mirror (8-bit RGB PNG or JPEG)")
    r.add_argument("--setup", metavar="SETUP.toml",
                   help="the setup file (default: IMAGE.toml beside the image; [camera] and [mirror] are read)")
    r.add_argument("--cube-size", type=float, metavar="S",
                   help="the cubes' edge length when known (m): it fixes each cube's size")
    r.add_argument("--cube-size-std", type=float, metavar="SD",
                   help="the σ of --cube-size (m), carried through the exact estimator's fit into each depth's σ")
    r.add_argument("--on-floor", action="store_true",
                   help="the cubes stand on the floor the mirror stands on (its lower end): the floor fixes each "
                        "cube's size (method exact)")
    r.add_argument("--floor-height", type=float, metavar="H",
                   help="the cubes stand on a floor square to the mirror's axis, H m along it from the mirror's "
                        "centre (instead of --on-floor's)")
    r.add_argument("--floor-std", type=float, metavar="SD",
                   help="the σ of the floor's height (m), carried into each depth's σ")
    r.add_argument("--method", default=None,
                   help="exact (default), ddar, dds, shape_prior (the paper's, for cubes of one size) or "
                        "exact_shape_prior (cubes of one size: each fitted by exact at their common size)")
    r.add_argument("-o", "--output", metavar="OUT.json", help="the result file (default: IMAGE.result.json)")
    r.add_argument("--overlay", metavar="OUT.png", help="also draw the faces, their corners and depths on the image")
    r.add_argument("--blur-domain", default=None, metavar="D",
                   help="where a blurred image was blurred: auto (default: from the image), encoded (image "
                        "software blurred the stored values) or linear (optics, a renderer's pixel filter)")
    r.add_argument("--workers", type=int, default=None, metavar="N",
                   help="processes the faces are measured in (default: every core; the result is the same)")
    r.add_argument("--demosaic", default=None, metavar="D",
                   help="how a raw Bayer frame ([camera] mosaic) is made an image: two-colour (default), VNG, "
                        "bilinear or edge-aware")
    r.set_defaults(func=_cmd_reconstruct, without_cycle_collector=True)

    rp = sub.add_parser("report", help="an HTML report with 3D views, plots and annotated images")
    rp.add_argument("input", metavar="IMAGE.png|RESULT.json",
                    help="an image (reconstructed now) or a reconstruct result (its setup and image read beside it)")
    rp.add_argument("--setup", metavar="SETUP.toml",
                    help="the setup file (default: the one the result names, or IMAGE.toml beside the image)")
    rp.add_argument("-o", "--output", metavar="DIR", required=True, help="the folder index.html is written in")
    rp.add_argument("--method", default=None, help="estimator when IMAGE.png is given (as reconstruct)")
    rp.set_defaults(func=_cmd_report)

    rs = sub.add_parser("response", help="a camera's response from one scene at several exposure times: prints its "
                                         "[camera] response")
    rs.add_argument("images", metavar="IMAGE", nargs="+",
                    help="one still scene, each image at another exposure time, the camera's other settings unchanged")
    rs.add_argument("--times", type=_exposure_time, nargs="+", required=True, metavar="T",
                    help="each image's exposure time, in their order (any unit; a fraction such as 1/250 too)")
    rs.set_defaults(func=_cmd_response)

    ln = sub.add_parser("lens", help="a lens's intrinsics from chessboard views, each colour channel's own (lateral "
                                     "chromatic aberration): prints its [camera] lines")
    ln.add_argument("images", metavar="IMAGE", nargs="+",
                    help="views of a flat chessboard in different poses (at least 3 where the board is found)")
    ln.add_argument("--board", type=_board_size, required=True, metavar="COLSxROWS",
                    help="the chessboard's inner corners, columns × rows (e.g. 9x6)")
    ln.add_argument("--square", type=float, default=1.0, metavar="S",
                    help="the squares' side (any unit: it does not enter the intrinsics; default 1)")
    ln.set_defaults(func=_cmd_lens)

    dm = sub.add_parser("demo", help="run the built-in example")
    dm.add_argument("-o", "--output", metavar="DIR", default=None,
                    help="folder for the demo's image, result and report (default ./catadioptric-demo)")
    dm.set_defaults(func=_cmd_demo)

    dp = sub.add_parser("depthmap", help="dense depth of an XSlit image from line slopes (DDS) and an MRF")
    dp.add_argument("image", metavar="IMAGE.png", help="an XSlit image")
    dp.add_argument("--setup", metavar="XSLIT.toml", help="a TOML file with an [xslit] table")
    dp.add_argument("--xslit", type=float, nargs=4, metavar=("Z1", "Z2", "THETA1", "THETA2"),
                    help="slit depths and angles (degrees), instead of or over --setup")
    dp.add_argument("--pitch", type=float, nargs=2, metavar=("P1", "P2"), help="plane length per pixel along v1, v2")
    dp.add_argument("--method", choices=("graphcut", "quadratic"), default="graphcut",
                    help="the MRF's solver: graph cuts (default) or the continuous quadratic solve")
    dp.add_argument("--lam", type=float, default=2.0, help="smoothness weight λ (default 2)")
    dp.add_argument("-o", "--output", metavar="DEPTH.png", required=True,
                    help="the depth map's picture; the metric depths as DEPTH.npy beside it")
    dp.set_defaults(func=_cmd_depthmap)
    return p


def main(argv=None, *, one_shot: bool = False) -> int:
    """Entry point of the `catadioptric` console script; returns the exit status.

    `one_shot`: the process ends with this command (`console`). A command marked
    `without_cycle_collector` then runs with Python's cycle collector off, and leaves it off for the
    process's end. `reconstruct` allocates few reference cycles, but its imports (scipy, on a thread
    while the cubes are detected) create most of the 58 000 objects alive at its end (`console`), and the
    collections they trigger stop the detection too (they hold the interpreter lock); turned back on, the collector's next pass walks
    everything allocated meanwhile (39 ms). Measured on a 2048×1536 image with `gc.callbacks`: 43–47 ms of
    collections in the parent process, almost none in the workers. The reports' figures (matplotlib) are
    made of cycles: those commands keep it."""
    if one_shot:
        gc.disable()  # (the parser's own allocations trigger collections too)
    parser = build_parser()
    args = parser.parse_args(argv)
    if one_shot and not getattr(args, "without_cycle_collector", False):
        gc.enable()
    from raytrace.render import keep_freed_memory, plain_pages
    keep_freed_memory()  # this process is ours: reuse freed memory rather than re-fault it,
    plain_pages()  # and fault it in 4 KiB pages, without compacting memory for huge ones
    try:
        return int(args.func(args) or 0)
    except known_errors() as exc:
        print(f"catadioptric: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("catadioptric: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError as exc:
        if not _reader_gone(sys.stdout):  # a pipe of the command's own, not its output's: an error to report
            print(f"catadioptric: error: {exc}", file=sys.stderr)
            return 1
        _to_nowhere(sys.stdout)  # whatever read the output stopped reading (`| head`): end quietly, as Unix
        return 1  # tools do
    except OSError as exc:  # a file the command could not read or write (a folder it may not write in)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"catadioptric: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1


def console() -> None:
    """Entry point of the `catadioptric` console script: `main` in a process of its own, which then exits
    with its status.

    When `main` returns, its outputs are written and closed (`catadioptric.outputs.OutputSet`); what the
    interpreter's exit adds is its teardown, the last collections and the freeing of every module and
    object, only for the process to end. `_end_process` ends it without that. Fresh `reconstruct`
    processes on the five clean 2048×1536 images of the bench, interleaved 6 times with the code before
    (which froze the objects alive, `gc.freeze`, so that the last collections skipped the 58 000 the
    imports leave: 126–132 → 44–66 ms from the last output to the process's end): the medians 0.91–0.94×
    the time before. Where that cannot be done, the interpreter exits as usual, the objects frozen."""
    # One OpenBLAS thread a process, unless the environment says otherwise: set before numpy loads OpenBLAS
    # (this module imports it only where used), and inherited by the processes the command forks, whose
    # scipy loads its own. The command spreads its work over processes itself, and an idle OpenBLAS thread
    # spins for a while after it is started or woken, on the core the other process needs: a `reconstruct`
    # of a 2048×1536 image, 8 runs alternated with two threads, took 4.65 s of CPU (median) against 4.91 s,
    # its imports alone 0.93–1.00 s against 1.22–1.26 s (seventy-second session).
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    status = main(one_shot=True)
    gc.freeze()
    _end_process(status)
    sys.exit(status)


def _end_process(status: int) -> None:
    """End this process now with `status` (1 instead of 0 where a standard stream's reader has gone, as
    `main` ends such a command), as `sys.exit` would but without the interpreter's teardown: the `atexit`
    functions run (`atexit._run_exitfuncs`, which the interpreter's exit calls) and the standard streams
    are flushed first. Returns where another thread is alive (the interpreter would wait for it) or a
    flush fails otherwise (the interpreter reports that itself)."""
    import atexit
    import os
    import threading

    if threading.active_count() > 1:
        return
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except BrokenPipeError:  # its reader has gone (`| head`)
            _to_nowhere(stream)
            status = status or 1
        except (OSError, ValueError):
            return
    os._exit(status)


def _reader_gone(stream) -> bool:
    """Whether `stream` (a standard stream) is a pipe whose reader has gone (polled: an error is pending on
    its write end); True where that cannot be told."""
    import select
    try:
        poller = select.poll()
        poller.register(stream.fileno(), 0)
        return any(events & select.POLLERR for _, events in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll on this platform, or no descriptor
        return True


def _to_nowhere(stream) -> None:
    """Send what is still to be written to `stream` (a standard stream whose reader has gone) nowhere, so
    that no later flush fails (Python's note on SIGPIPE)."""
    import os
    os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())


if __name__ == "__main__":  # pragma: no cover
    console()
