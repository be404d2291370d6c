"""Argument types and message helpers shared by the command-line front-ends (``eulag.cli``,
``eulag.studies``, ``eulag.runs``)."""

from __future__ import annotations

import argparse

__all__ = ["positive_int", "short_reason", "unreadable_archive_reason"]


def positive_int(text: str) -> int:
    """An integer >= 1 (argparse type; the error names the value and what is allowed)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer; allowed: an integer >= 1") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is out of range; allowed: an integer >= 1")
    return value


def short_reason(exc: BaseException, limit: int = 160) -> str:
    """An exception's message for a one-line error: its first sentence on one line, at most
    ``limit`` characters (xarray's "cannot open" error goes on with installation advice)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    head = text.split(". ")[0]
    return head if len(head) <= limit else head[:limit - 3] + "..."


def unreadable_archive_reason(exc: BaseException) -> str:
    """Why a checkpoint (a NumPy .npz archive) could not be read, for a one-line error: numpy's
    own text for a file that is not an archive suggests loading it with pickles allowed, which
    a foreign file must never be."""
    import zipfile

    if isinstance(exc, (ValueError, zipfile.BadZipFile, EOFError)):
        return "not a NumPy .npz archive (truncated, or another kind of file)"
    if isinstance(exc, KeyError):
        return f"an .npz archive without the entry {exc}"
    return short_reason(exc)
