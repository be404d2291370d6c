"""eulag: steady Euler-Lagrange RANS for turbulent gas-particle flow in horizontal pipes."""

import functools

import rans  # noqa: F401  first: it sets single-threaded BLAS before numpy loads it (rans/__init__.py)

__version__ = "0.1.0"

__all__ = ["Case", "run", "execute", "load_case", "open_dataset", "analysis", "__version__"]


def __getattr__(name):
    """The Python API, imported on first use (``import eulag`` stays light for the CLI):

    eulag.Case (``Case.from_file(path or packaged name)``, ``Case.from_toml``, keywords via
    ``Case.from_dict``), eulag.run(case, out=None, **options) -> xarray.Dataset,
    eulag.execute(...) -> eulag.runs.RunResult (dataset and the loop's verdict),
    eulag.load_case(path or name), eulag.open_dataset(path), eulag.analysis."""
    if name == "Case":
        from eulag.config import Case

        return Case
    if name in ("run", "execute", "load_case"):
        from eulag import runs

        return getattr(runs, name)
    if name == "open_dataset":
        return open_dataset
    if name == "analysis":
        import importlib

        return importlib.import_module("eulag.analysis")
    raise AttributeError(f"module 'eulag' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))


def open_dataset(path):
    """A result file of ``eulag run`` as an in-memory ``xarray.Dataset`` (the file is closed).
    A path that is missing, a directory or not a NetCDF dataset raises ValueError with one line
    saying so (``FileNotFoundError`` for a missing file)."""
    import os
    from pathlib import Path

    import xarray as xr

    from eulag.arguments import short_reason

    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path = {type(path).__name__}: wrong type; allowed: the path of a result file (.nc)")
    if Path(path).is_dir():
        raise ValueError(f"{path}: is a directory; allowed: the path of a result file (.nc)")
    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such result file")
    try:
        with xr.open_dataset(path) as ds:
            return ds.load()
    except (ValueError, OSError) as exc:
        raise ValueError(f"{path}: cannot be read as a NetCDF dataset ({short_reason(exc)})") from None


@functools.lru_cache(maxsize=1)
def git_commit() -> str:
    """The short git commit of this eulag source tree (``" (with uncommitted changes)"`` appended
    when tracked files outside ``results/`` differ from it; "unknown ..." outside a git checkout).
    Written into every dataset (``eulag_commit``) and study report, so a result names the code that
    made it.  ``results/`` is left out of the check: a study rewrites its own committed table and
    records there before it asks, and they are not code."""
    from pathlib import Path

    return _commit_of(Path(__file__).resolve().parent.parent)


def _commit_of(repo) -> str:
    """``git_commit`` of the checkout at ``repo``."""
    import subprocess

    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=repo, capture_output=True,
                              text=True, timeout=10)
        if head.returncode != 0:
            return "unknown (not a git checkout)"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
                                ":(exclude)results"], cwd=repo, capture_output=True, text=True, timeout=10)
        return head.stdout.strip() + (" (with uncommitted changes)" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
