"""The recorded cross-section of slug runs against SMH §3.4 and §4 (Figs. 17-19).

    python results/strauss-filled/grain-weights/cross-section/layers.py RUN.nc [RUN.nc ...] [--t-min T]

For each dataset: the records while a slug passes the slice at half the tube length and between
slugs, the layer velocity profile in each (grain-weighted mean, rms about it, grains per record;
eulag.slug.cross_section_layers), the numbers of eulag.slug.layer_shear, and the mean solids
fraction of the slice in and between slugs (upper and lower half).  --t-min defaults to the
statistics window of the run (eulag.slug.statistics_window: the second half of a run continued
from a state, t >= min(end/2, 6 s) from an empty tube).
"""
import argparse
import json

import numpy as np
import xarray as xr

from eulag.slug import cross_section_layers, layer_shear, statistics_window


def report(path, t_min=None):
    ds = xr.open_dataset(path)
    case = json.loads(ds.attrs["case"])
    if t_min is None:
        t_min = statistics_window(case, times=ds["time"].values)[0]
    lay = cross_section_layers(ds, t_min=t_min)
    radial = ds.attrs.get("layer_coordinate", "height") == "radius"
    coord = "radius" if radial else "height"
    print(f"{path}: {case.get('name')}, {case['tube']['orientation']}, slice at x = {100 * lay.attrs['section_x_m']:.4g} cm, "
          f"t >= {t_min:.4g} s: {lay.attrs['records_slug']} records in a slug (slice porosity < 0.6), "
          f"{lay.attrs['records_between']} between")
    print(f"  layer {coord} [mm] | in slugs: u [m/s]  rms  grains/record | between: u [m/s]  rms  grains/record")
    for i, h in enumerate(ds["layer"].values):
        row = [lay[f"{v}_{tag}"].values[i] for tag in ("slug", "between") for v in ("velocity", "velocity_rms", "grains")]
        print(f"  {1e3 * h:+6.2f} | " + "  ".join(f"{v:7.3f}" if np.isfinite(v) else "      —" for v in row[:3]) +
              " | " + "  ".join(f"{v:7.3f}" if np.isfinite(v) else "      —" for v in row[3:]))
    num = layer_shear(lay)
    print("  in slugs: " + ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in num.items()))
    z = ds["section_z"].values
    for tag in ("slug", "between"):
        img = lay[f"section_{tag}"].values
        inside = ds["section_pixel_inside"].values >= 0.5
        lo, hi = inside & (z[:, None] < 0), inside & (z[:, None] > 0)
        w = ds["section_pixel_inside"].values
        print(f"  slice solids fraction, {tag}: lower half {np.sum((img * w)[lo]) / np.sum(w[lo]):.3f}, "
              f"upper half {np.sum((img * w)[hi]) / np.sum(w[hi]):.3f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--t-min", type=float, default=None)
    a = ap.parse_args()
    for p in a.runs:
        report(p, a.t_min)


if __name__ == "__main__":
    main()
