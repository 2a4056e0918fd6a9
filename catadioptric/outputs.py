"""All-or-nothing output files: `OutputSet` stages every file of a command and publishes them together.

A command first computes everything, then writes each output to a temporary file beside its final
path; only when all are written are they renamed into place. If anything fails, the temporaries are
removed and no earlier file is touched, so bad input never leaves a partial output.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from catadioptric.errors import CatadioptricError

__all__ = ["OutputSet"]


class OutputSet:
    """Stage files with `path_for(final)`, then `commit()`; use as a context manager."""

    def __init__(self):
        self._staged: list[tuple[Path, Path]] = []

    def path_for(self, final) -> Path:
        """A temporary path to write `final`'s content to (same folder, so the rename is atomic)."""
        final = Path(final)
        folder = final.parent if str(final.parent) else Path(".")
        if not folder.is_dir():
            raise CatadioptricError(f"{final}: the output folder {folder} does not exist")
        fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".partial", dir=folder)
        os.close(fd)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; outputs get the usual permissions
        self._staged.append((Path(tmp), final))
        return Path(tmp)

    def write_text(self, final, text: str) -> None:
        self.path_for(final).write_text(text)

    def write_bytes(self, final, data: bytes) -> None:
        self.path_for(final).write_bytes(data)

    def commit(self) -> list[Path]:
        """Rename every staged file into place; returns the final paths."""
        done = []
        for tmp, final in self._staged:
            os.replace(tmp, final)
            done.append(final)
        self._staged.clear()
        return done

    def discard(self) -> None:
        for tmp, _ in self._staged:
            tmp.unlink(missing_ok=True)
        self._staged.clear()

    def __enter__(self) -> "OutputSet":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.commit()
        else:
            self.discard()
        return False
