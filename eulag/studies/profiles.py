"""Profiles along the vertical diameter against measurements or a reference run: the
Tsuji-Morikawa measurement file, a dataset's profile at the measured points, the deviation in
% and the Pareto front of error against run time."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from eulag.analysis import attr as _attr


def read_measurements(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """{phase: {"y_over_R": array, "u": array}} from the Tsuji-Morikawa CSV (its velocities are
    normalised by a reference velocity, see the file's header)."""
    from eulag import plots

    prof = plots.read_reference(path)
    return {ph: {"y_over_R": 2.0 * p["y_over_D"], "u": np.asarray(p["u"], dtype=float)}
            for ph, p in prof.items()}


def provenance(path: Path) -> list[str]:
    """The header comment lines of a measurement file (its provenance), without the '#'."""
    out = []
    with open(path) as fh:
        for line in fh:
            if not line.startswith("#"):
                break
            out.append(line[1:].rstrip())
    return out


def diameter_profile(ds, var: str, x: float, y_over_R: np.ndarray, *, wall_value: float | None = None,
                     scale: float = 1.0) -> np.ndarray:
    """``var`` along the vertical diameter at the station nearest x, interpolated linearly at
    ``y_over_R``; NaN cells (no particles) are dropped; beyond the outermost cell centres the
    value is the wall value when given (gas: no slip), else the outermost cell's. Divided by
    ``scale``."""
    from eulag import analysis as an

    y, v = an.vertical_profile(ds, var, x)
    R = 0.5 * float(_attr(ds, "pipe.diameter"))
    ok = np.isfinite(v)
    y, v = y[ok] / R, v[ok]
    if y.size == 0:
        return np.full(np.shape(y_over_R), np.nan)
    if wall_value is not None:
        y = np.concatenate([[-1.0], y, [1.0]])
        v = np.concatenate([[wall_value], v, [wall_value]])
    return np.interp(np.asarray(y_over_R, dtype=float), y, v) / scale


def profile_deviation(sim: np.ndarray, ref: np.ndarray, se: np.ndarray | None = None) -> dict[str, float]:
    """Deviation of a simulated profile from a reference one at the same points, both in the same
    normalised units; returned in % of those units: rms, max (absolute), bias (mean signed) and
    stderr (RMS over the points of the simulation's standard error, when ``se`` is given)."""
    sim = np.asarray(sim, dtype=float)
    ref = np.asarray(ref, dtype=float)
    ok = np.isfinite(sim) & np.isfinite(ref)
    out = {"rms": math.nan, "max": math.nan, "bias": math.nan, "stderr": math.nan, "points": int(ok.sum())}
    if not ok.any():
        return out
    d = 100.0 * (sim[ok] - ref[ok])
    out.update(rms=float(np.sqrt(np.mean(d * d))), max=float(np.max(np.abs(d))), bias=float(np.mean(d)))
    if se is not None:
        s = 100.0 * np.asarray(se, dtype=float)[ok]
        s = s[np.isfinite(s)]
        if s.size:
            out["stderr"] = float(np.sqrt(np.mean(s * s)))
    return out


def pareto_front(times, errors) -> list[int]:
    """Indices of the non-dominated points (no other point is at least as fast and as accurate
    and strictly better in one), sorted by time. NaN points are never on the front."""
    t = np.asarray(times, dtype=float)
    e = np.asarray(errors, dtype=float)
    idx = [i for i in range(t.size) if np.isfinite(t[i]) and np.isfinite(e[i])]
    front = []
    for i in idx:
        dominated = any((t[j] <= t[i] and e[j] <= e[i]) and (t[j] < t[i] or e[j] < e[i]) for j in idx)
        if not dominated:
            front.append(i)
    return sorted(front, key=lambda i: (t[i], e[i]))
