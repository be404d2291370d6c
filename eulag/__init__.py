"""eulag: steady Euler-Lagrange RANS for turbulent gas-particle flow in horizontal pipes."""

import functools

import rans  # noqa: F401  first: it sets single-threaded BLAS before numpy loads it (rans/__init__.py)

__version__ = "0.1.0"


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
