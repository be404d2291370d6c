"""Space-time porosity image of a slug run, as SMH Figs. 1 and 4 draw it (dark = dense).

    python results/strauss/plot_spacetime.py CASE.toml RUN.nc|RUN.nc.checkpoint OUT.png [--t0 0] [--t1 4]

The figure is :func:`eulag.plots.slug_spacetime` (the study draws it for its default,
vertical and long runs); this script draws it for any run or a running run's checkpoint.
"""

import argparse
import math
import tomllib

import xarray as xr

from eulag.slug import dataset_from_checkpoint
from eulag.plots import slug_spacetime as plot_spacetime


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("run")
    ap.add_argument("png")
    ap.add_argument("--t0", type=float, default=0.0)
    ap.add_argument("--t1", type=float, default=math.inf)
    a = ap.parse_args()
    with open(a.case, "rb") as fh:
        case = tomllib.load(fh)
    ds = dataset_from_checkpoint(case, a.run) if a.run.endswith(".checkpoint") else xr.open_dataset(a.run)
    plot_spacetime(ds, a.png, a.t0, a.t1, title=case.get("name", ""))


if __name__ == "__main__":
    main()
