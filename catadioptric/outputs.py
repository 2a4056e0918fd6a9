"""All-or-nothing output files: `OutputSet` stages every file of a command and publishes them together.

A command first computes everything, then writes each output to a temporary file beside its final
path; only when all are written are they renamed into place. If anything fails, the temporaries are
removed and no earlier file is touched, so bad input never leaves a partial output.
"""

from __future__ import annotations

import contextlib
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
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".partial", dir=folder)
        except OSError as exc:
            raise CatadioptricError(f"{final}: cannot write in {folder} ({exc.strerror or exc})") from None
        os.close(fd)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; outputs get the usual permissions
        self._staged.append((Path(tmp), final))
        return Path(tmp)

    @contextlib.contextmanager
    def writing(self, final):
        """`path_for(final)`, for code that writes the file itself (numpy's archives): an OSError raised
        meanwhile (a full disk) is `final`'s one-line error."""
        tmp = self.path_for(final)
        try:
            yield tmp
        except OSError as exc:
            raise CatadioptricError(f"{final}: cannot write ({exc.strerror or exc})") from None

    def write_text(self, final, text: str) -> None:
        self.write_bytes(final, text.encode())

    def write_bytes(self, final, data: bytes) -> None:
        tmp = self.path_for(final)
        try:
            tmp.write_bytes(data)
        except OSError as exc:  # a full disk: say which output, not its temporary
            raise CatadioptricError(f"{final}: cannot write ({exc.strerror or exc})") from None

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

    def _final_of(self, path) -> Path | None:
        """The final path whose temporary is `path`, if it is one of ours."""
        for tmp, final in self._staged:
            if path is not None and Path(path) == tmp:
                return final
        return None

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            try:
                self.commit()
            except OSError as err:  # a rename refused: what was not renamed yet is removed
                final = self._final_of(err.filename) or Path(err.filename or "?")
                self.discard()
                raise CatadioptricError(f"{final}: cannot write ({err.strerror or err})") from None
            return False
        final = self._final_of(exc.filename) if isinstance(exc, OSError) else None
        self.discard()
        if final is not None:  # writing a staged file failed (a full disk): say which output, not its temporary
            raise CatadioptricError(f"{final}: cannot write ({exc.strerror or exc})") from None
        return False
