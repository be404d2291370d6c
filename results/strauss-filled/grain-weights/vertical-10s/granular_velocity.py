"""The slug velocity measured as Strauß, McNamara & Herrmann measure it (§3.2: "for each slug, the
centre of mass, the minimal porosity, the maximal granular velocity and the slug length"; Fig. 10
shows the maximal granular velocity, saturating at 0.3 m/s, the value §4 sets beside the
vertical plugs' 0.17 m/s), beside the speed of the slug centres.

    python granular_velocity.py RUN.nc T_MIN [--t-max T] [--x0 0.15] [--x1 0.4] [--block 0.5]

Over slugs of >= 100 grains centred in [x0, x1] with record time in [T_MIN, T_MAX]: the mean of each
record's maximal slice grain velocity in the slug (`eulag.slug.summarize`), its standard error
from the means of consecutive blocks of BLOCK seconds (full blocks only), and the centres'
speed from the catalogue's links.
"""

import argparse

import numpy as np
import xarray as xr

from eulag.slug import summarize


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run")
    ap.add_argument("t_min", type=float)
    ap.add_argument("--t-max", type=float, default=None)
    ap.add_argument("--x0", type=float, default=0.15)
    ap.add_argument("--x1", type=float, default=0.4)
    ap.add_argument("--block", type=float, default=0.5)
    a = ap.parse_args()
    ds = xr.open_dataset(a.run)
    if a.t_max is not None:  # records and catalogue up to t_max
        ds = ds.sel(time=slice(None, a.t_max + 1e-9)).isel(slug=np.flatnonzero(ds["slug_time"].values <= a.t_max + 1e-9))
    s = summarize(ds, x_window=(a.x0, a.x1), t_min=a.t_min)
    st, sx = ds["slug_time"].values, ds["slug_position"].values
    sel = (st >= a.t_min) & (ds["slug_grains"].values >= 100) & (sx >= a.x0) & (sx <= a.x1)
    mv = ds["slug_max_velocity"].values
    t_end = float(ds["time"].values[-1])
    starts = np.arange(a.t_min, t_end - a.block + 1e-9, a.block)
    blocks = np.array([mv[sel & (st >= b) & (st < b + a.block)].mean() for b in starts
                       if (sel & (st >= b) & (st < b + a.block)).any()])
    se = blocks.std(ddof=1) / np.sqrt(len(blocks)) if len(blocks) > 1 else float("nan")
    print(f"{a.run}: t >= {a.t_min:g} s (to {t_end:g} s), slugs centred in {a.x0:g}-{a.x1:g} m, "
          f"{s['slug_records']} slug records")
    print(f"  maximal granular velocity in the slug: {s['slug_max_grain_velocity_m_s']:.3f} m/s "
          f"(standard error {se:.3f} from {len(blocks)} blocks of {a.block:g} s: "
          + " ".join(f"{b:.3f}" for b in blocks) + ")")
    print(f"  slug centres' speed: {s['slug_velocity_m_s']:.3f} m/s ({s['slug_velocity_links']} links)")
    print(f"  minimum slug porosity {s['slug_min_porosity']:.3f}, grains in the tube {s['grains_in_tube']:.0f}, "
          f"dp {s['pressure_drop_Pa']:.0f} Pa")


if __name__ == "__main__":
    main()
