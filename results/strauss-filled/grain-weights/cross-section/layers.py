"""The recorded cross-section of slug runs against SMH §3.4 and §4 (Figs. 17-19).

    python results/strauss-filled/grain-weights/cross-section/layers.py RUN.nc [RUN.nc ...] [--t-min T]

For each dataset: the records while a slug passes the slice at half the tube length and between
slugs, the layer velocity profile in each (grain-weighted mean, rms about it, grains per record;
eulag.slug.cross_section_layers), the numbers of eulag.slug.layer_shear, and the mean solids
fraction of the slice in and between slugs (lower and upper half; in a vertical tube core and ring).  --t-min defaults to the
statistics window of the run (eulag.slug.statistics_window: the second half of a run continued
from a state, t >= min(end/2, 6 s) from an empty tube).
"""
import argparse
import json

import numpy as np
import xarray as xr

from eulag.slug import cross_section_layers, layer_shear, section_porosity, statistics_window


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
    for tag in ("slug", "between"):
        num = layer_shear(lay, tag)
        print(f"  {'in slugs' if tag == 'slug' else 'between slugs'}: " +
              ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in num.items()))
    # per passage of a slug (a run of consecutive in-slug records): lowest/first and uppermost/last
    # populated layer, grain-weighted; mean and standard error over the passages
    t = ds["time"].values
    phi_s = section_porosity(ds)
    ins = (t >= t_min) & (phi_s < 0.6)
    n, u = ds["layer_grains"].values, ds["layer_velocity"].values
    runs, start = [], None
    for i, flag in enumerate(list(ins) + [False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            runs.append((start, i))
            start = None
    diffs = []
    for a, b in runs:
        nn, uu = n[a:b].sum(axis=0), (n[a:b] * u[a:b]).sum(axis=0)
        ok = np.flatnonzero(nn > 0)
        if len(ok) >= 2:
            diffs.append(uu[ok[-1]] / nn[ok[-1]] - uu[ok[0]] / nn[ok[0]])
    if diffs:
        se = np.std(diffs, ddof=1) / np.sqrt(len(diffs)) if len(diffs) > 1 else float("nan")
        print(f"  per slug passage ({len(diffs)}): last minus first layer {np.mean(diffs):+.3f} +- {se:.3f} m/s "
              f"(range {min(diffs):+.3f} to {max(diffs):+.3f})")
    z, y = ds["section_z"].values, ds["section_y"].values
    w = ds["section_pixel_inside"].values
    inside = w >= 0.5
    R = 0.5 * case["tube"]["diameter_m"]
    if radial:   # a vertical tube: core (r < R/2) and outer ring
        r = np.hypot(z[:, None], y[None, :])
        parts = (("core r < R/2", inside & (r < 0.5 * R)), ("ring r > R/2", inside & (r >= 0.5 * R)))
    else:
        parts = (("lower half", inside & (z[:, None] < 0)), ("upper half", inside & (z[:, None] > 0)))
    for tag in ("slug", "between"):
        img = lay[f"section_{tag}"].values
        print(f"  slice solids fraction, {tag}: " + ", ".join(f"{name} {np.sum((img * w)[m]) / np.sum(w[m]):.3f}"
                                                            for name, m in parts))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--t-min", type=float, default=None)
    a = ap.parse_args()
    for p in a.runs:
        report(p, a.t_min)


if __name__ == "__main__":
    main()
