"""The built-in demo: `run_demo` / `run(args)` (simulate → reconstruct → table → report) and the paper's
arch-scene table `arch_table()`.

The mirror demo renders `catadioptric/data/demo.toml` (a cylinder mirror and five 4 cm cubes at
0.35–0.95 m from its axis), reconstructs the cubes from the 8-bit image, prints the results beside the
true values, and writes the image, setup, truth, result and HTML report into one folder, all or nothing.

The arch scene of the paper (section 5): a PO-XSlit with z1 = −3.2 cm, z2 = −346.7 cm viewing
circular arches (r_o = 1) between 900 cm and 2300 cm. For each depth the table gives the image
aspect ratio (Eqn. ardef), the depth recovered from it (Eqn. getz), the sensitivity |∂r_i/∂z|
(Eqn. sensit) and the depth error one AR step of ε = 1/L would cause.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from depth import ddar

__all__ = ["ARCH_Z1_CM", "ARCH_Z2_CM", "ArchRow", "arch_table", "print_arch_table", "demo_setup_path",
           "DemoRun", "run_demo", "run", "DEFAULT_DIR"]

DEFAULT_DIR = "catadioptric-demo"

ARCH_Z1_CM = -3.2
ARCH_Z2_CM = -346.7
ARCH_IMAGE_PX = 1000  # L: the paper's arch renders are about 1000 px across


@dataclass(frozen=True)
class ArchRow:
    depth_cm: float
    aspect_ratio: float
    recovered_cm: float
    sensitivity_per_cm: float
    depth_step_cm: float  # depth change for an AR change of ε = 1/L at this depth


def arch_table(depths_cm=(900, 1100, 1300, 1500, 1700, 1900, 2100, 2300), image_px: int = ARCH_IMAGE_PX
               ) -> tuple[list[ArchRow], dict]:
    """Rows of the arch table and the summary (AR limits, maximum discernible depth for ε = 1/L, 0.1/L)."""
    z = np.asarray(depths_cm, dtype=np.float64)
    r_i = ddar.aspect_ratio(z, ARCH_Z1_CM, ARCH_Z2_CM)
    z_back = ddar.depth_from_aspect_ratio(r_i, ARCH_Z1_CM, ARCH_Z2_CM)
    sens = np.abs(ddar.sensitivity(z, ARCH_Z1_CM, ARCH_Z2_CM))
    step = ddar.depth_std_from_aspect_ratio(r_i, 1.0 / image_px, ARCH_Z1_CM, ARCH_Z2_CM)
    rows = [ArchRow(*map(float, t)) for t in zip(z, r_i, z_back, sens, step)]
    summary = {
        "z1_cm": ARCH_Z1_CM, "z2_cm": ARCH_Z2_CM, "image_px": image_px,
        "ar_limits": ddar.aspect_ratio_limits(ARCH_Z1_CM, ARCH_Z2_CM),
        "max_depth_cm_1px": ddar.max_discernible_depth(ARCH_Z1_CM, ARCH_Z2_CM, image_size=image_px),
        "max_depth_cm_0.1px": ddar.max_discernible_depth(ARCH_Z1_CM, ARCH_Z2_CM, eps=0.1 / image_px),
    }
    return rows, summary


def print_arch_table(console) -> None:
    from rich.table import Table
    rows, s = arch_table()
    t = Table(title=f"Paper's arch scene: PO-XSlit z1 = {s['z1_cm']} cm, z2 = {s['z2_cm']} cm, r_o = 1")
    for col in ("depth (cm)", "AR r_i", "recovered (cm)", "|∂r_i/∂z| (1/cm)", f"Δz for ε=1/{s['image_px']} (cm)"):
        t.add_column(col, justify="right")
    for r in rows:
        t.add_row(f"{r.depth_cm:.1f}", f"{r.aspect_ratio:.5f}", f"{r.recovered_cm:.6f}",
                  f"{r.sensitivity_per_cm:.3e}", f"{r.depth_step_cm:.2f}")
    console.print(t)
    lo, hi = s["ar_limits"]
    console.print(f"reachable AR range ({lo:.4f}, {hi:.4f}); maximum discernible depth "
                  f"{s['max_depth_cm_1px'] / 100:.0f} m at ε = 1/{s['image_px']}, "
                  f"{s['max_depth_cm_0.1px'] / 100:.0f} m at ε = 0.1/{s['image_px']}")


def demo_setup_path() -> Path:
    """The built-in example setup shipped inside the package."""
    return Path(__file__).with_name("data") / "demo.toml"


@dataclass
class DemoRun:
    """What `run_demo` made: the result and truth dictionaries, the index.html path, stage times (s)."""

    result: dict
    truth: dict
    index: Path
    seconds: dict


def run_demo(out_dir, setup_path=None, spp: int = 4, window_size=(1200, 800), progress=None) -> DemoRun:
    """Simulate the demo setup, reconstruct it and write everything into `out_dir` (all or nothing).

    progress : callable(stage: str, done: int, total: int), optional; stages "simulate",
    "reconstruct", "report".
    """
    import json
    import time

    from catadioptric import reconstruct as rc
    from catadioptric import report
    from catadioptric.setup import load_setup, setup_to_toml
    from catadioptric.simulate import encode_png, simulate
    from depth.reconstruct import DEFAULT_METHOD, reconstruct
    from raytrace.render import linear_to_srgb8

    def stage(name):
        return (lambda d, t: progress(name, d, t)) if progress is not None else None

    out = report.check_output_dir(out_dir)
    setup_path = Path(setup_path) if setup_path else demo_setup_path()
    setup = load_setup(setup_path)
    seconds = {}
    t0 = time.monotonic()
    sim = simulate(setup, spp=spp, seed=0, progress=stage("simulate"))
    image = linear_to_srgb8(sim.render.image)  # exactly what demo.png holds (PNG is lossless)
    seconds["simulate"] = time.monotonic() - t0

    t0 = time.monotonic()
    rec = reconstruct(image, setup.camera.build(), setup.mirror.build(), method=DEFAULT_METHOD,
                      progress=stage("reconstruct"))
    result = rc.result_dict("demo.png", "demo.toml", rec)
    truth = dict(sim.truth, image="demo.png", setup="demo.toml")
    seconds["reconstruct"] = time.monotonic() - t0

    t0 = time.monotonic()
    inp = report.ReportInput(setup=setup, setup_path=Path("demo.toml"), result=result, image=image,
                             truth=truth, rec=rec)
    files = report.build_report(inp, window_size, progress=stage("report"))
    files.update({"demo.png": encode_png(image), "demo.toml": setup_to_toml(setup).encode(),
                  "demo.truth.json": (json.dumps(truth, indent=2) + "\n").encode(),
                  "demo.result.json": (json.dumps(result, indent=2) + "\n").encode()})
    index = report.write_report(files, out)
    seconds["report"] = time.monotonic() - t0
    return DemoRun(result=result, truth=truth, index=index, seconds=seconds)


def run(args) -> int:
    """`catadioptric demo [-o DIR]`: the paper's arch table, then the mirror demo with progress."""
    import time
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from catadioptric import reconstruct as rc
    from catadioptric.report import check_output_dir

    import sys
    console = Console(width=None if sys.stdout.isatty() else 120)
    out = check_output_dir(args.output or DEFAULT_DIR)
    print_arch_table(console)
    console.print()
    start = time.monotonic()
    labels = {"simulate": "simulating the mirror image", "reconstruct": "reconstructing the cubes",
              "report": "writing the report"}
    with Progress(TextColumn("{task.description:<28}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                  TimeElapsedColumn(), console=console) as bar:
        tasks = {k: bar.add_task(v, total=None, start=False) for k, v in labels.items()}

        def progress(stage, done, total):
            task = tasks[stage]
            if not bar.tasks[task].started:
                bar.start_task(task)
            bar.update(task, completed=done, total=total)

        demo = run_demo(out, progress=progress)
    console.print(f"simulate {demo.seconds['simulate']:.1f} s, reconstruct {demo.seconds['reconstruct']:.1f} s, "
                  f"report {demo.seconds['report']:.1f} s")
    rc.print_table(console, demo.result, demo.truth)
    console.print(f"demo finished in {time.monotonic() - start:.1f} s; open the report:")
    print(demo.index.resolve())
    return 0
