"""Δp against the gas viscosity η with error bars: block means over a long window of each run.

Usage: python results/strauss-filled/grain-weights/eta-6s/eta_window.py RUN.nc [RUN.nc ...]
           [--t-min S] [--block S]

For each slug dataset: the mean pressure drop and grains in the tube over t ≥ t_min (default:
the second half of the run's window after its start state, as the study measures), with the
standard error from the scatter of block means (block length --block, default 0.5 s). The
errors printed for blocks of 0.1–1 s show whether the blocks are longer than the series'
correlation time: the error stops growing with the block length once they are. Then the
weighted least-squares slope of Δp against η with its standard error, and each step between
neighbouring η: the paper's Fig. 6 has Δp falling with η.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import xarray as xr

from eulag.slug import state_time


def block_mean(t: np.ndarray, v: np.ndarray, t0: float, block: float) -> tuple[float, float, int]:
    """Mean of v over t ≥ t0 and its standard error from the means of consecutive blocks."""
    sel = t >= t0
    t, v = t[sel], v[sel]
    if len(t) == 0:
        return math.nan, math.nan, 0
    idx = np.floor((t - t[0]) / block + 1e-9).astype(int)
    per_block = block / float(np.median(np.diff(t)))  # records in a full block
    full = [v[idx == k].mean() for k in range(idx.max() + 1) if (idx == k).sum() >= 0.9 * per_block]
    m = float(v.mean())
    if len(full) < 2:
        return m, math.nan, len(full)
    return m, float(np.std(full, ddof=1) / math.sqrt(len(full))), len(full)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--t-min", type=float, default=None)
    ap.add_argument("--block", type=float, default=0.5)
    a = ap.parse_args(argv)
    rows = []
    for path in a.runs:
        with xr.open_dataset(path) as ds:
            c = json.loads(ds.attrs["case"])
            t = ds["time"].values
            start = state_time(c)  # the filled-tube state's time (run from the repository root)
            t0 = a.t_min if a.t_min is not None else 0.5 * (start + float(t[-1]))
            dp, dp_se, nb = block_mean(t, ds["pressure_drop"].values, t0, a.block)
            n, n_se, _ = block_mean(t, ds["grains_in_tube"].values, t0, a.block)
            sweep = {b: block_mean(t, ds["pressure_drop"].values, t0, b)[1] for b in (0.1, 0.25, 0.5, 1.0)}
            whole = [ds["pressure_drop"].values[(t >= s0) & (t < s0 + a.block)].mean()
                     for s0 in np.arange(start, t[-1] - 0.5 * a.block, a.block)]
            g = ds["grains_in_tube"].values
            first_last = (g[t < start + 1.0].mean(), g[t > t[-1] - 1.0].mean())
            # the study's 3 s runs from the same state measure over 1.5-3 s after the start
            early = ds["pressure_drop"].values[(t >= start + 1.5 - 1e-9) & (t <= start + 3.0 + 1e-9)].mean()
        eta = c["gas"]["viscosity_Pa_s"]
        rows.append((eta, dp, dp_se, n, n_se, nb, t0, float(t[-1]), sweep, (min(whole), max(whole)), first_last, early))
    rows.sort()
    print(f"block {a.block:g} s; Δp and grains as mean ± standard error of the block means")
    print("| η [cP] | window [s] | blocks | Δp [Pa] | grains in the tube | Δp per grain [Pa] "
          "| Δp's standard error for blocks of 0.1 / 0.25 / 0.5 / 1 s [Pa] "
          "| block means of Δp over the whole run, min–max [Pa] | grains, first / last second of the run "
          "| Δp over 1.5–3 s after the start (the study's 3 s runs' window) [Pa] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for eta, dp, dp_se, n, n_se, nb, t0, t1, sweep, rng, fl, early in rows:
        sw = " / ".join(f"{sweep[b]:.0f}" for b in (0.1, 0.25, 0.5, 1.0))
        print(f"| {eta * 1e3:g} | {t0:.2f}–{t1:.2f} | {nb} | {dp:.0f} ± {dp_se:.0f} | {n:.0f} ± {n_se:.0f} "
              f"| {dp / n:.3f} | {sw} | {rng[0]:.0f}–{rng[1]:.0f} | {fl[0]:.0f} / {fl[1]:.0f} | {early:.1f} |")
    if len(rows) >= 2:
        x = np.array([r[0] * 1e3 for r in rows])
        y = np.array([r[1] for r in rows])
        s = np.array([r[2] for r in rows])
        w = 1.0 / s**2
        xm = np.sum(w * x) / np.sum(w)
        slope = np.sum(w * (x - xm) * y) / np.sum(w * (x - xm) ** 2)
        se = math.sqrt(1.0 / np.sum(w * (x - xm) ** 2))
        print(f"weighted slope dΔp/dη = {slope:.0f} ± {se:.0f} Pa per cP "
              f"({slope / se:+.1f} standard errors; the paper: Δp falls with η)")
        for i in range(len(rows) - 1):
            d = y[i + 1] - y[i]
            print(f"  {x[i]:g} → {x[i + 1]:g} cP: Δp {d:+.0f} ± {math.hypot(s[i], s[i + 1]):.0f} Pa")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
