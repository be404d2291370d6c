"""Shared fixtures and helpers: reference data live in ../shared/data (read-only)."""

import csv
import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("EULAG_SHARED_DATA", REPO.parent / "shared" / "data"))


def read_reference_csv(name):
    """Rows (dicts of str) of a commented CSV file in shared/data; skips the test if it is absent."""
    path = SHARED_DATA / name
    if not path.exists():
        pytest.skip(f"reference data {path} not available")
    with open(path) as fh:
        lines = [line for line in fh if not line.startswith("#")]
    return list(csv.DictReader(lines))
