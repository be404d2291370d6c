"""Do the cross-section runs repeat the earlier runs of the same cases (the recording must not
change a run)?  Run from the repository root:

    python results/strauss-filled/grain-weights/cross-section/repeat_check.py HORIZONTAL.nc VERTICAL.nc

HORIZONTAL.nc (vs1_10s.toml) against the records of eta-15s at 0.0673 cP (its CSV, 3 decimals);
VERTICAL.nc (vertical_10s.toml) against vertical-10s/measure_t6.5.json (means over t >= 6.5 s).
"""
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

HERE = Path(__file__).resolve().parent
h, v = xr.open_dataset(sys.argv[1]), xr.open_dataset(sys.argv[2])
ref = pd.read_csv(HERE.parent / "eta-15s" / "timeseries_eta_6.73e-05.csv", comment="#")
ref = ref[ref.time_s <= float(h.time[-1]) + 1e-9]
assert np.allclose(ref.time_s.values, h.time.values)
print(f"horizontal: {len(ref)} records; largest |dp - eta-15s| {np.max(np.abs(ref.pressure_drop_Pa.values - h.pressure_drop.values)):.2g} Pa, "
      f"largest |grains - eta-15s| {np.max(np.abs(ref.grains_in_tube.values - h.grains_in_tube.values))}; "
      f"wall time {h.attrs['wall_time_s']:.0f} s, {h.attrs['wall_time_s'] / 10 / float(h.grains_in_tube.mean()):.3f} s per grain and simulated second")
m = json.loads((HERE.parent / "vertical-10s" / "measure_t6.5.json").read_text())
w = v.sel(time=slice(6.5, 10.0))
print(f"vertical: t >= 6.5 s dp {float(w.pressure_drop.mean()):.2f} Pa (vertical-10s {m['pressure_drop_Pa']:.2f}), grains "
      f"{float(w.grains_in_tube.mean()):.1f} ({m['grains_in_tube']:.1f}); wall time {v.attrs['wall_time_s']:.0f} s, "
      f"{v.attrs['wall_time_s'] / 10 / float(v.grains_in_tube.mean()):.3f} s per grain and simulated second")
