"""Experiment 6 (paper Fig. cyldemo): cubes seen in a cylindrical mirror, reconstructed from the one image.

Runs the project's two commands on the built-in setup (catadioptric/data/demo.toml: camera 0.55 m
from the axis of a 10 cm-radius mirror, five 4 cm cubes 0.35–0.95 m from the axis):

    catadioptric simulate catadioptric/data/demo.toml -o examples/out/06/mirror.png
    catadioptric reconstruct examples/out/06/mirror.png --method M -o examples/out/06/mirror.M.json \
        --overlay examples/out/06/overlay.M.png          (M = exact, then ddar: the paper's Eqn. getz)

then tabulates each cube's image aspect ratio and its recovered depth and size against the
simulator's exact truth (mirror.truth.json).
"""

import contextlib
import io
import json
import time

import numpy as np

from _common import ROOT, out_path, table
from catadioptric.cli import main as cli

METHODS = ("exact", "ddar")
SETUP = ROOT.parent / "catadioptric" / "data" / "demo.toml"


def main():
    t0 = time.perf_counter()
    out = out_path("06")
    out.mkdir(exist_ok=True)
    png = out / "mirror.png"
    with contextlib.redirect_stdout(io.StringIO()):
        if cli(["simulate", str(SETUP), "-o", str(png)]) != 0:
            raise SystemExit("simulate failed")
        t1 = time.perf_counter()
        for method in METHODS:
            if cli(["reconstruct", str(png), "--method", method, "-o", str(out / f"mirror.{method}.json"),
                    "--overlay", str(out / f"overlay.{method}.png")]) != 0:
                raise SystemExit(f"reconstruct --method {method} failed")
    t2 = time.perf_counter()
    truth = json.loads((out / "mirror.truth.json").read_text())["cubes"]
    print(f"demo.toml: {len(truth)} cubes (simulate {t1 - t0:.1f} s, reconstruct x{len(METHODS)} {t2 - t1:.1f} s)")
    for method in METHODS:
        _tabulate(json.loads((out / f"mirror.{method}.json").read_text()), truth)
    print(f"figures: {png}, {out / 'overlay.exact.png'}")


def _tabulate(res, truth):
    rows, errs, size_errs = [], [], []
    for c in res["cubes"]:
        d = [np.linalg.norm(np.subtract(c["center"], t["center"])) for t in truth]
        t = truth[int(np.argmin(d))]
        e = 100 * (c["depth"] - t["depth"]) / t["depth"]
        es = 100 * (c["size"] - t["size"]) / t["size"]
        errs.append(abs(e))
        size_errs.append(abs(es))
        rows.append((f"{t['depth']:.4f}", f"{c.get('aspect_ratio', float('nan')):.2f}", c["method"],
                     f"{c['depth']:.4f}", f"{e:+.2f}", f"{c['size'] * 100:.2f}", f"{es:+.2f}"))
    rows.sort()
    print(table(["true depth (m)", "image AR r_i", "method", "depth (m)", "depth error %", "size (cm)", "size error %"],
                rows))
    if errs:
        print(f"{rows[0][2]}: {len(rows)}/{len(truth)} cubes; depth error: median {np.median(errs):.2f} %, max {np.max(errs):.2f} %; "
              f"size error: median {np.median(size_errs):.2f} %, max {np.max(size_errs):.2f} %")


if __name__ == "__main__":
    main()
