"""Files that a kill cannot leave half-written: :func:`atomic_write`, which every model's datasets
and checkpoints go through, and the pattern of the temporary files it leaves when the process
is killed in the middle (which the run layer removes when a run starts)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write", "savez_atomic"]


def atomic_write(path: str | os.PathLike, write) -> Path:
    """Call ``write(tmp_path)`` on a temporary file beside ``path``, fsync it, rename it over ``path``.

    On any failure (including KeyboardInterrupt) the temporary file is removed and ``path``
    is left as it was, so a reader never sees a partial file.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    os.close(fd)
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def savez_atomic(path: str | os.PathLike, arrays: dict) -> Path:
    """``np.savez(path, **arrays)`` through :func:`atomic_write` (a checkpoint that a kill never
    leaves half-written); ``path`` keeps its name (no ``.npz`` appended)."""
    import numpy as np

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)

    return atomic_write(path, write)

