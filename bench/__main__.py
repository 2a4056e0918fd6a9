"""Run every `bench/bench_*.py` module's `main()` in turn: `python -m bench [NAME ...] [--flags]`.

Positional NAMEs select the modules whose name contains one of them (e.g. `python -m bench
reconstruct`); `--flags` (e.g. `--quick`) are left in `sys.argv` for the modules to read.
"""

import importlib
import pkgutil
import sys
from pathlib import Path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    wanted = [a for a in argv if not a.startswith("-")]
    names = sorted(m.name for m in pkgutil.iter_modules([str(Path(__file__).parent)]) if m.name.startswith("bench_"))
    if wanted:
        names = [n for n in names if any(w in n for w in wanted)]
        if not names:
            print(f"python -m bench: no benchmark matches {' '.join(wanted)}", file=sys.stderr)
            return 1
    for name in names:
        print(f"== bench.{name}", flush=True)
        importlib.import_module(f"bench.{name}").main()
    return 0


if __name__ == "__main__":
    sys.exit(main())
