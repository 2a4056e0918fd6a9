"""Time `catadioptric reconstruct IMAGE.png -o OUT.json` as fresh processes, against another revision in one run.

The issue's speed target is under 2 s per 2048×1536 image on this machine, and this VM's speed changes from
session to session. This bench times the command as a user runs it (start-up, imports, reading the image,
the ray map, the JSON written) on the reconstruct bench's five clean 2048×1536 images (our renderer, as
`bench_reconstruct.command_seconds` does) and, with ``--against=REV``, the same command from a git worktree
of REV, the two alternated image by image and round by round (the order reversed every other round), so that
their ratio comes from one run. It also says whether both revisions write the same cubes and refusals.

Run: ``python -m bench command_timing [--against=REV] [--rounds=N] [--raw [--demosaic=D]]`` (the ``=`` is needed,
as for ``floor_timing``). The renders come from bench/out/renders (made by our renderer when missing). ``--raw``
times the same images as raw Bayer frames (`[camera] mosaic`; the command's ``--demosaic D``), which a revision
before the ninety-fourth session's cannot read.

``--instructions`` counts instead of timing: each image's command once per revision under Valgrind's
callgrind (every process it forks followed), the user-space instructions of all its processes summed, and
the ratio per image. A forked process starts with its parent's counts (callgrind copies them with the rest
of the process), so each process's "Collected" total holds its parent's instructions up to the fork too:
summed, the parent's were counted again for each helper and worker it forked (the helper's imports once a
worker). Hence ``--dump-before=fork``: the parent writes its counts out and zeroes them before each fork,
and the totals of all the files written (each process's own instructions, in parts) are summed. On this
VM wall and CPU times of one command vary by 10–20 % from run to run, which hides a change of a few per
cent; instruction counts repeat to a small fraction of that (8a3d0f6's s03 counted twice: 9.458 and 9.456
G). They leave out the kernel's work (page faults, forks: a sixth of the command's CPU) and weigh every
instruction alike, so they say whether a change does less work, not how much sooner the command ends.
Needs ``valgrind`` (apt); about 4 minutes an image, the two revisions side by side.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from bench.bench_floor_timing import ROOT, _flag, _worktree, compiled

TARGET_SECONDS = 2.0
_CONSOLE = "from catadioptric.cli import console; console()"  # the console script's entry point


def _images(where: Path, quick: bool = False, raw: bool = False) -> list[Path]:
    """The reconstruct bench's clean 2048×1536 images of our renderer (of its quick cases with `quick`), each
    written under `where` as PNG beside its setup; with `raw`, as the raw Bayer frame of each (RGGB, 16 bits, the
    light of each pixel's own channel) beside its setup with `[camera] mosaic`."""
    import dataclasses

    from bench.bench_reconstruct import cases, our_render
    from catadioptric.setup import save_setup
    from raytrace.chroma import bayer_mosaic
    from raytrace.response import srgb_to_linear

    out = []
    for renderer, sc in cases(quick):
        if renderer == "ours" and sc.setup.camera.resolution[0] == 2048:
            png, setup, img = where / f"{sc.name}.png", sc.setup, our_render(sc.setup)
            if raw:
                cv2.imwrite(str(png), np.round(bayer_mosaic(srgb_to_linear(img / 255.0)) * 65535).astype(np.uint16))
                setup = dataclasses.replace(setup, camera=dataclasses.replace(setup.camera, mosaic="RGGB"))
            else:
                cv2.imwrite(str(png), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
            save_setup(setup, png.with_suffix(".toml"))
            out.append(png)
    return out


def _run(root: Path, png: Path, out: Path, extra: tuple = ()) -> float:
    """Wall time of one fresh `catadioptric reconstruct` (with `extra` arguments) whose packages are those under
    `root` (its working directory, first on the path of `python -c`)."""
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _CONSOLE, "reconstruct", str(png), "-o", str(out), *extra],
                          cwd=root, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        tail = done.stderr.strip().splitlines()[-1:] or ["(no message)"]
        raise SystemExit(f"bench command_timing: reconstruct {png.name} under {root} failed: {tail[0]}")
    return seconds


def _result(path: Path) -> str:
    """The cubes and refusals a result file holds, as canonical JSON (file names left out)."""
    data = json.loads(path.read_text())
    return json.dumps([data["cubes"], data["refused"]], sort_keys=True)


def _instructions(root: Path, png: Path, out: Path, tmp: Path) -> subprocess.Popen:
    """The started callgrind run of one fresh `catadioptric reconstruct` under `root` (see `_collected`)."""
    tag = f"{png.stem}.{root.name}"
    return subprocess.Popen(["valgrind", "--tool=callgrind", "--trace-children=yes", "--dump-before=fork",
                             f"--callgrind-out-file={tmp / tag}.%p.callgrind", sys.executable, "-c", _CONSOLE,
                             "reconstruct", str(png), "-o", str(out)],
                            cwd=root, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _collected(run: subprocess.Popen, what: str, files) -> int:
    """The user-space instructions of every process of an `_instructions` run, once it has finished: the
    "totals:" of the files it wrote (`files()`: each process's, and the parts a parent dumped before each
    fork), which count each instruction once (see the module's docstring: the processes' "Collected" lines
    do not)."""
    _, err = run.communicate()
    if run.returncode != 0:
        tail = [line for line in err.strip().splitlines() if "Collected" not in line][-1:] or ["(no message)"]
        raise SystemExit(f"bench command_timing: --instructions: {what} failed: {tail[0]}")
    totals = [int(line.split()[1]) for path in files() for line in path.read_text().splitlines()
              if line.startswith("totals:")]
    if not totals:
        raise SystemExit(f"bench command_timing: --instructions: {what}: callgrind wrote no counts")
    return sum(totals)


def _count(images: list, roots: dict, tmp: Path, against: str | None) -> int:
    """`--instructions`: each image once per revision under callgrind (the revisions side by side)."""
    if shutil.which("valgrind") is None:
        raise SystemExit("bench command_timing: --instructions: valgrind not found (apt install valgrind)")
    counts = {name: {} for name in roots}
    for png in images:
        runs = {name: _instructions(root, png, tmp / f"{png.stem}.{name}.json", tmp) for name, root in roots.items()}
        for name, run in runs.items():
            def files(png=png, root=roots[name]):
                return tmp.glob(f"{png.stem}.{root.name}.*.callgrind*")
            counts[name][png.stem] = _collected(run, f"{png.name} under {roots[name]}", files)
        for leftover in tmp.glob(f"{png.stem}.*.callgrind*"):
            leftover.unlink()
        print(f"  {png.stem}: " + " / ".join(f"{name} {counts[name][png.stem] / 1e9:.3f} G" for name in roots),
              flush=True)
    print(f"\n`catadioptric reconstruct IMAGE.png -o OUT.json` under callgrind (every process), user-space "
          f"instructions, {len(images)} clean 2048x1536 images" + (f"; base = {against}" if against else ""))
    for png in images:
        line = f"  {png.stem}: here {counts['here'][png.stem] / 1e9:.2f} G"
        if "base" in roots:
            line += (f", base {counts['base'][png.stem] / 1e9:.2f} G, here / base "
                     f"{counts['here'][png.stem] / counts['base'][png.stem]:.3f}")
        print(line)
    return 0


def main() -> int:
    against = _flag("against", None)
    rounds = int(_flag("rounds", "3"))
    if rounds < 1:
        raise SystemExit(f"bench command_timing: --rounds: expected an integer >= 1, got {rounds}")
    raw = "--raw" in sys.argv[1:]
    demosaic = _flag("demosaic", None)
    extra = ("--demosaic", demosaic) if demosaic else ()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        images = _images(tmp, raw=raw)
        compiled(ROOT)
        base = _worktree(against, tmp, bench="command_timing") if against else None
        roots = {"here": ROOT} | ({"base": base} if base is not None else {})
        if "--instructions" in sys.argv[1:]:
            try:
                return _count(images, roots, tmp, against)
            finally:
                if base is not None:
                    subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)],
                                   capture_output=True, check=False)
        seconds = {name: {png.stem: [] for png in images} for name in roots}
        results = {name: {} for name in roots}
        try:
            for k in range(rounds):
                for png in images:
                    for name in (list(roots) if k % 2 == 0 else list(roots)[::-1]):
                        out = tmp / f"{png.stem}.{name}.json"
                        seconds[name][png.stem].append(_run(roots[name], png, out, extra))
                        results[name].setdefault(png.stem, set()).add(_result(out))
                print(f"  round {k + 1}/{rounds}: " + "; ".join(
                    f"{png.stem} " + " / ".join(f"{name} {seconds[name][png.stem][-1]:.2f}" for name in roots)
                    for png in images), flush=True)
        finally:
            if base is not None:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)],
                               capture_output=True, check=False)
    what = ("raw Bayer frames (RGGB, 16 bits" + (f", --demosaic {demosaic})" if demosaic else ")")) if raw else "images"
    print(f"\n`catadioptric reconstruct IMAGE.png -o OUT.json`, fresh processes, {len(images)} clean 2048x1536 "
          f"{what}, {rounds} round(s)" + (f"; base = {against}" if against else ""))
    medians = {name: {stem: float(np.median(v)) for stem, v in per.items()} for name, per in seconds.items()}
    for png in images:
        line = f"  {png.stem}: here median {medians['here'][png.stem]:.2f} s"
        if base is not None:
            same = len(results["here"][png.stem] | results["base"][png.stem]) == 1
            line += (f", base {medians['base'][png.stem]:.2f} s, here / base "
                     f"{medians['here'][png.stem] / medians['base'][png.stem]:.3f}, results "
                     + ("the same" if same else "DIFFER"))
        print(line)
    for name in roots:
        m = list(medians[name].values())
        print(f"  {name}: median over images {np.median(m):.2f} s, slowest image {max(m):.2f} s; "
              f"under {TARGET_SECONDS:.0f} s: {'yes' if max(m) < TARGET_SECONDS else 'no'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
