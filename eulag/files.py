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



def target_problem(path: Path) -> str | None:
    """Why a file cannot be written at ``path`` the way :func:`atomic_write` writes (a temporary
    file beside it, renamed over it), as the end of a one-line message; None when it can: a
    symbolic link, a directory or another non-regular file in its place, or a parent directory
    that does not exist or is not writable."""
    path = Path(path)
    if path.is_symlink():
        return ("is a symbolic link (the file is written beside it and renamed over it, which would replace the "
                "link); allowed: a regular file path")
    if path.is_dir():
        return "is a directory; allowed: a file path"
    if path.exists() and not path.is_file():
        return "exists and is not a regular file (a device, pipe or socket); allowed: a regular file path"
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        return f"directory {parent} does not exist; allowed: a path in an existing directory"
    if not os.access(parent, os.W_OK):
        return f"directory {parent} is not writable"
    return None
