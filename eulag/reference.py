"""Measured reference profiles for the figures and the studies: the commented CSV files that
``pipe.reference_data`` names (e.g. cases/tsuji_morikawa_1982_horizontal_eta2.2.csv).

Kept apart from :mod:`eulag.plots` so that reading a case (:mod:`eulag.config`, which checks the
file when the case is loaded) needs neither matplotlib nor the plotting code.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, Mapping

import numpy as np

__all__ = ["read_reference", "table_to_profiles"]

_Y_COLUMNS = {"y_over_D": 1.0, "y_over_R": 0.5}   # column -> factor to y/D
_U_COLUMNS = ("u_over_ub", "U_over_Ub", "U_over_Uref", "u")


def read_reference(path) -> dict[str, dict[str, np.ndarray]]:
    """Measured profiles from a commented CSV file (lines starting with '#' are skipped).

    Columns: ``phase`` (gas / particle; absent: gas), ``y_over_R`` or ``y_over_D``, and the
    normalised axial velocity ``U_over_Uref`` (or ``u_over_ub``). Returns
    ``{phase: {"y_over_D": array [1], "u": array [1], "column": name of the velocity column}}``.
    The file's header comments state the provenance and the velocity scale; read them.
    """
    path = Path(path)
    with open(path, newline="") as fh:
        lines = fh.readlines()
    rows = list(csv.DictReader([ln for ln in lines if not ln.lstrip().startswith("#")]))
    if not rows:
        raise ValueError(f"{path}: no data rows")
    table = {key: [row[key] for row in rows] for key in rows[0]}
    return table_to_profiles(table, str(path))


def table_to_profiles(table: Mapping[str, Any], where: str) -> dict[str, dict[str, np.ndarray]]:
    """{phase: {"y_over_D", "u"}} from a table (dict of equal-length columns)."""
    ycol = next((c for c in _Y_COLUMNS if c in table), None)
    ucol = next((c for c in _U_COLUMNS if c in table), None)
    if ycol is None or ucol is None:
        raise ValueError(f"{where}: reference data need a column y_over_R or y_over_D and one of "
                         f"{', '.join(_U_COLUMNS)}; found {', '.join(table)}")
    y = np.asarray(table[ycol], dtype=float) * _Y_COLUMNS[ycol]
    u = np.asarray(table[ucol], dtype=float)
    phase = np.asarray(table["phase"], dtype=str) if "phase" in table else np.full(y.size, "gas")
    out = {}
    for name in np.unique(phase):
        sel = phase == name
        out[str(name)] = {"y_over_D": y[sel], "u": u[sel], "column": ucol}
    return out
