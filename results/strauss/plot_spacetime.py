"""Space-time porosity image of a slug run, as SMH Figs. 1 and 4 draw it (dark = dense).

    python results/strauss/plot_spacetime.py CASE.toml RUN.nc|RUN.nc.checkpoint OUT.png [--t0 0] [--t1 4]
"""

import argparse
import tomllib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import xarray as xr  # noqa: E402

from eulag.slug import dataset_from_checkpoint  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("run")
    ap.add_argument("png")
    ap.add_argument("--t0", type=float, default=0.0)
    ap.add_argument("--t1", type=float, default=1e9)
    a = ap.parse_args()
    with open(a.case, "rb") as fh:
        case = tomllib.load(fh)
    ds = dataset_from_checkpoint(case, a.run) if a.run.endswith(".checkpoint") else xr.open_dataset(a.run)
    ds = ds.sel(time=slice(a.t0, a.t1))
    fig, ax = plt.subplots(figsize=(9, 3.2))
    im = ax.pcolormesh(ds["time"], ds["x"] * 100, ds["porosity"].T, cmap="gray", vmin=0.4, vmax=1.0, shading="auto")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("x [cm]")
    ax.set_title(f"porosity, {case.get('name', '')} ({ds.attrs.get('partial', 'finished run')})", fontsize=9)
    fig.colorbar(im, ax=ax, label="porosity")
    fig.tight_layout()
    fig.savefig(a.png, dpi=120)


if __name__ == "__main__":
    main()
