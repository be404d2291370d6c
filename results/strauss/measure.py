"""Numbers of a slug run (a finished dataset or a running run's checkpoint) for the table in README.md.

    python results/strauss/measure.py CASE.toml RUN.nc|RUN.nc.checkpoint [--t-min 1.0] [--x0 0] [--x1 0.525]
"""

import argparse
import json
import tomllib

import xarray as xr

from eulag.slug import dataset_from_checkpoint, summarize


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("run")
    ap.add_argument("--t-min", type=float, default=1.0)
    ap.add_argument("--x0", type=float, default=0.0)
    ap.add_argument("--x1", type=float, default=0.525)
    ap.add_argument("--min-grains", type=int, default=100)
    ap.add_argument("--development", action="store_true",
                    help="also the slug centres' speed, the maximal granular velocity (SMH Fig. 10's measure) and "
                         "the minimum porosity in 5 cm bins along the tube (SMH Figs. 9-10)")
    a = ap.parse_args()
    with open(a.case, "rb") as fh:
        case = tomllib.load(fh)
    ds = dataset_from_checkpoint(case, a.run) if a.run.endswith(".checkpoint") else xr.open_dataset(a.run)
    s = summarize(ds, x_window=(a.x0, a.x1), t_min=a.t_min, min_grains=a.min_grains)
    s["max_overlap_per_d"] = float(ds["max_overlap_per_d"].max())
    s["grains_lost"] = int(ds["grains_lost"])
    s["source"] = ds.attrs.get("partial", "finished run")
    print(json.dumps(s, indent=1))
    if a.development:
        L = json.loads(ds.attrs["case"])["tube"]["length_m"]
        print("x_from_m x_to_m slug_records slug_velocity_m_s slug_max_grain_velocity_m_s slug_min_porosity slug_grains")
        for x0 in [i * 0.05 for i in range(int(L / 0.05) + 1)]:
            b = summarize(ds, x_window=(x0, x0 + 0.05), t_min=a.t_min, min_grains=a.min_grains)
            print(f"{x0:.2f} {x0 + 0.05:.2f} {b['slug_records']:5d} {b['slug_velocity_m_s']:.3f} "
                  f"{b.get('slug_max_grain_velocity_m_s', float('nan')):.3f} "
                  f"{b.get('slug_min_porosity', float('nan')):.3f} {b.get('slug_grains', float('nan')):.0f}")


if __name__ == "__main__":
    main()
