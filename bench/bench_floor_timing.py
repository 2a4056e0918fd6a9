"""Time `reconstruct` on the lighting bench's grey floor scenes, against another revision in one run.

The grey floor scenes (`bench_lighting`'s ``floor any-sun grey``: grey cubes before a sky over a floor,
found without colour, several blobs refused) are the slowest images this project has: they miss the
2 s target by far more than the reconstruct bench's images do (`bench_command_timing`). This bench times them here and, with
``--against=REV``, in a git worktree of REV as well, the two alternated round by round in fresh
processes (the machine is noisy: a ratio from one run, not figures from two), and says whether both
give the same cubes.

Run: ``python -m bench floor_timing [--against=REV] [--rounds=N] [--scenes=11,3,0]``
(``--against=HEAD~1`` or a commit; the ``=`` is needed: ``python -m bench`` takes a bare word for a
bench's name). Each round times every scene twice per revision, ``reconstruct`` with its default
workers, after one untimed call; the renders come from bench/out/renders (made by ``python -m bench
lighting`` when missing).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENES = (11, 3, 0)
"""Floor scenes timed by default: 11 and 3 are 2048×1536, 0 is 1024×768; 11 is the slowest."""

_TIME_HERE = r"""
import hashlib, json, sys, time
root, scenes, repeats = sys.argv[1], [int(s) for s in sys.argv[2].split(",")], int(sys.argv[3])
sys.path.insert(0, root)
from bench.bench_lighting import FLOOR_N, FLOOR_SEED, floor_render, greyed
from bench.scenes import make_scenes
import contextlib, importlib
from depth.reconstruct import reconstruct
from raytrace.render import keep_freed_memory
keep_freed_memory()
# the estimators' modules here, as a process that has reconstructed before has them (since 68, a process's
# first call imports them in a helper process, its second beside the detection); in a revision without
# these names, its first, untimed call imports them (a revision before the seventy-fourth session's also
# names scipy.ndimage in depth.measure.IMAGE_MODULES)
with contextlib.suppress(ImportError):
    import depth.measure
    from depth.estimate import SOLVER_MODULES
    for name in getattr(depth.measure, "IMAGE_MODULES", ()) + SOLVER_MODULES:
        importlib.import_module(name)
made = make_scenes(FLOOR_N, FLOOR_SEED)
out = {}
for index in scenes:
    setup = greyed(made[index].setup)
    camera, mirror = setup.camera.build(), setup.mirror.build()
    image = floor_render(setup, index, 0)
    rec = reconstruct(image, camera, mirror)  # untimed: first-call imports and caches
    seconds = []
    for _ in range(repeats):
        t = time.perf_counter()
        rec = reconstruct(image, camera, mirror)
        seconds.append(time.perf_counter() - t)
    found = json.dumps([[c.to_dict() for c in rec.cubes], [r.reason for r in rec.refused]], sort_keys=True)
    out[index] = {"seconds": seconds, "shape": list(image.shape[:2]), "cubes": len(rec.cubes),
                  "refused": len(rec.refused), "digest": hashlib.sha256(found.encode()).hexdigest()}
print(json.dumps(out))
"""


def _flag(name: str, default: str | None) -> str | None:
    for arg in sys.argv[1:]:
        if arg.startswith(f"--{name}="):
            return arg.split("=", 1)[1]
    return default


def _time(root: Path, scenes, repeats: int) -> dict:
    """Per scene: seconds per call, image shape, cubes found and refused, and a digest of the results,
    from a fresh process running the code under `root`."""
    done = subprocess.run([sys.executable, "-c", _TIME_HERE, str(root), ",".join(map(str, scenes)), str(repeats)],
                          capture_output=True, text=True, cwd=tempfile.gettempdir(), check=False)
    if done.returncode != 0:
        tail = done.stderr.strip().splitlines()[-1:] or ["(no message)"]
        raise SystemExit(f"bench floor_timing: the run under {root} failed: {tail[0]}")
    return {int(k): v for k, v in json.loads(done.stdout.strip().splitlines()[-1]).items()}


def _worktree(rev: str, where: Path, bench: str = "floor_timing") -> Path:
    """A detached worktree of `rev` under `where`, sharing this checkout's cached renders (`bench` names the
    bench in the error)."""
    path = where / "base"
    done = subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(path), rev],
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"bench {bench}: --against={rev}: not a revision of this repository "
                         f"({done.stderr.strip().splitlines()[-1] if done.stderr.strip() else 'git failed'})")
    (path / "bench" / "out").mkdir(parents=True, exist_ok=True)
    (path / "bench" / "out" / "renders").symlink_to(ROOT / "bench" / "out" / "renders")
    compiled(path)
    return path


PACKAGES = ("raytrace", "xslit_fit", "depth", "catadioptric")


def compiled(root: Path) -> None:
    """Byte-compile the packages under `root`, so that no timed process compiles them from source: where
    PYTHONDONTWRITEBYTECODE is set (as on this project's VM in the sixty-eighth session) a process writes no
    .pyc, and a fresh worktree, which has none, compiled every module in every run (`depth.measure` alone
    72 ms of a command's start-up, 8 ms from its .pyc) while the checkout, with older .pyc files, compiled
    only its edited modules."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", *PACKAGES], cwd=root, capture_output=True, check=True)


def main() -> int:
    against = _flag("against", None)
    rounds = int(_flag("rounds", "3"))
    scenes = [int(s) for s in _flag("scenes", ",".join(map(str, SCENES))).split(",")]
    if rounds < 1:
        raise SystemExit(f"bench floor_timing: --rounds: expected an integer >= 1, got {rounds}")
    with tempfile.TemporaryDirectory() as tmp:
        compiled(ROOT)
        base = _worktree(against, Path(tmp)) if against else None
        try:
            runs = {"here": [], "base": []}
            for k in range(rounds):
                for name, root in (("base", base), ("here", ROOT)):
                    if root is None:
                        continue
                    runs[name].append(_time(root, scenes, 2))
                    print(f"  round {k + 1}/{rounds} {name}: " + ", ".join(
                        f"s{i} {' '.join(f'{t:.2f}' for t in r['seconds'])} s" for i, r in runs[name][-1].items()),
                        flush=True)
        finally:
            if base is not None:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)],
                               capture_output=True, check=False)
    print(f"\nfloor scenes (grey cubes), reconstruct with its default workers, {rounds} round(s) of 2 calls"
          + (f"; base = {against}" if against else ""))
    for i in scenes:
        here = np.concatenate([r[i]["seconds"] for r in runs["here"]])
        first = runs["here"][0][i]
        line = (f"  scene {i:2d} {first['shape'][1]}x{first['shape'][0]}: {first['cubes']} found, "
                f"{first['refused']} refused; here {here.min():.2f}-{here.max():.2f} s (median {np.median(here):.2f})")
        if runs["base"]:
            base_s = np.concatenate([r[i]["seconds"] for r in runs["base"]])
            same = {r[i]["digest"] for r in runs["base"] + runs["here"]}
            line += (f"; base {base_s.min():.2f}-{base_s.max():.2f} s (median {np.median(base_s):.2f}); "
                     f"here / base {np.median(here) / np.median(base_s):.3f}; results "
                     + ("the same" if len(same) == 1 else "DIFFER"))
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
