"""The command line: `main(argv)` parses, calls the library, prints, and exits 1 on a known error.

Verbs: simulate, fit, design, reconstruct, report, demo. Errors of our packages print as one line,
`catadioptric: error: <message>`, with no traceback.
"""

from __future__ import annotations

import argparse
import sys

from catadioptric import __version__
from catadioptric.errors import CatadioptricError

__all__ = ["main", "known_errors"]


def known_errors() -> tuple[type, ...]:
    """The base errors of every package: these print as one line and exit 1."""
    from depth.errors import DepthError
    errors: list[type] = [CatadioptricError, DepthError]
    for module, name in (("raytrace.errors", "RaytraceError"), ("xslit_fit.errors", "FitError")):
        try:
            mod = __import__(module, fromlist=[name])
            errors.append(getattr(mod, name))
        except (ImportError, AttributeError):
            pass
    return tuple(errors)


class NotAvailable(Exception):
    """A verb whose work is not built yet: exit 2."""


def _not_available(verb: str):
    def run(args):
        raise NotAvailable(f"`catadioptric {verb}` is not available yet in version {__version__}")
    return run


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
    from catadioptric.simulate import output_paths, simulate, write_simulation
    spp = _check_positive_int(args.spp, "--spp")
    if args.seed < 0:
        raise CatadioptricError(f"--seed: expected an integer >= 0, got {args.seed}")
    output_paths(args.output)  # validate the name before any work
    setup = load_setup(args.setup)
    with Progress("rendering") as bar:
        sim = simulate(setup, spp=spp, seed=args.seed, progress=bar)
    for path in write_simulation(sim, args.output):
        print(path)
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
    with Progress("measuring cubes") as bar:
        setup, setup_path, image, rec = rc.run_reconstruction(args.image, args.setup, args.method,
                                                              args.cube_size, progress=bar)
    result = rc.result_dict(args.image, setup_path, rec)
    truth = _truth_beside(args.image)
    overlay = rc.draw_overlay(image, rec) if args.overlay else None
    written = rc.write_outputs(result, json_path, args.overlay, overlay)
    rc.print_table(Console(width=None if sys.stdout.isatty() else 120), result, truth)
    if not rec.cubes:
        print("no cube found" if not rec.refused else "no cube could be estimated")
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


def _cmd_demo(args) -> int:
    from catadioptric import demo
    return demo.run(args)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="catadioptric",
        description="Absolute depth and size from one image of a cylindrical mirror (XSlit DDAR/DDS).")
    p.add_argument("--version", action="version", version=f"catadioptric {__version__}")
    sub = p.add_subparsers(dest="verb", metavar="VERB", required=True)

    s = sub.add_parser("simulate", help="render what the camera sees in the mirror, with exact ground truth")
    s.add_argument("setup", metavar="SETUP.toml")
    s.add_argument("-o", "--output", metavar="OUT.png", required=True)
    s.add_argument("--spp", type=int, default=4, help="samples per pixel at edges (default 4)")
    s.add_argument("--seed", type=int, default=0)
    s.set_defaults(func=_cmd_simulate)

    f = sub.add_parser("fit", help="fit virtual slits (XSlit/GLC) to the mirror's reflected rays")
    f.add_argument("setup", metavar="SETUP.toml")
    f.add_argument("--roi", type=float, nargs=4, metavar=("X0", "Y0", "X1", "Y1"))
    f.add_argument("--tiles", type=int, metavar="N")
    f.add_argument("--json", action="store_true")
    f.set_defaults(func=_not_available("fit"))

    d = sub.add_parser("design", help="slits, sensitivity and discernible depth of a mirror setup")
    d.add_argument("setup", metavar="SETUP.toml")
    d.add_argument("--depth-range", type=float, nargs=2, metavar=("A", "B"))
    d.add_argument("--json", action="store_true")
    d.add_argument("--plot", metavar="OUT.png")
    d.add_argument("--optimize", action="store_true")
    d.set_defaults(func=_not_available("design"))

    r = sub.add_parser("reconstruct", help="cube depths, sizes and positions from one mirror image")
    r.add_argument("image", metavar="IMAGE.png")
    r.add_argument("--setup", metavar="SETUP.toml")
    r.add_argument("--cube-size", type=float, metavar="S")
    r.add_argument("--method", default=None,
                   help="exact (default), ddar, dds or shape_prior")
    r.add_argument("-o", "--output", metavar="OUT.json")
    r.add_argument("--overlay", metavar="OUT.png")
    r.set_defaults(func=_cmd_reconstruct)

    rp = sub.add_parser("report", help="an HTML report with 3D views, plots and annotated images")
    rp.add_argument("input", metavar="IMAGE.png|RESULT.json")
    rp.add_argument("--setup", metavar="SETUP.toml")
    rp.add_argument("-o", "--output", metavar="DIR", required=True)
    rp.set_defaults(func=_not_available("report"))

    dm = sub.add_parser("demo", help="run the built-in example")
    dm.add_argument("-o", "--output", metavar="DIR", default=None)
    dm.set_defaults(func=_cmd_demo)
    return p


def main(argv=None) -> int:
    """Entry point of the `catadioptric` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except NotAvailable as exc:
        print(f"catadioptric: {exc}", file=sys.stderr)
        return 2
    except known_errors() as exc:
        print(f"catadioptric: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("catadioptric: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
