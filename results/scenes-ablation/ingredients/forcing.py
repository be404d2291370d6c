"""The cell pattern of the particles' in-plane force on the gas:

    python results/scenes-ablation/ingredients/forcing.py RUN.nc [...]

The secondary flow is driven by the curl of the in-plane momentum source the particles put
into the gas (source_uy, source_uz; the weight of suspended particles is mostly a gradient
field, which the cross-section pressure takes up). This script reads the solenoidal part of
that force with the same pattern metrics as the gas flow (``eulag.analysis._pattern``: the
stream function of the mirror-symmetrised field, its cell count, the sin 2θ / cos θ index, the
signs of its mirror-even vertical component along the vertical diameter from the bottom wall
up, and the rotation sense of its main pair), once at the station x = 3.555 m and once
averaged over the stations of the window 2.56-3.56 m (the last metre, over which the cross
flow at the station develops; the average lowers the Monte-Carlo noise of single stations).
The gas's own pattern at the station is in ``section_metrics.py`` (one folder up).

If the force has the gas's cell count, the pattern is in the forcing already; if the force had
four cells and the gas two, the gas's response (turbulent viscosity, the developing axial flow)
would have removed the second pair. The force's "strength" is left out: it is in N m-3, not a
speed. Printed as JSON, one object per dataset.
"""

import json
import sys

import numpy as np
import xarray as xr

from eulag import analysis as an

X = 3.56
WINDOW = (2.56, 3.56)


def force_pattern(geo, sy, sz) -> dict:
    """Pattern metrics of the in-plane force field (sy, sz) (nr, nt) [N m-3] on geo."""
    m = an._pattern(geo, sy, sz, 1.0, 0.1, 0.05, 3.0, 4, 0.05, 0.0)
    keep = ("count_symmetrised", "mode_index", "uy_sign_pattern", "main_pair_sense",
            "upper_lower_peak_ratio")
    out = {k: m[k] for k in keep}
    out["uy_sign_pattern"] = an.sign_text(m["uy_sign_pattern"])
    return out


def main():
    for path in sys.argv[1:]:
        ds = xr.open_dataset(path)
        geo = an.polar_section(ds)
        sec = an.section(ds, X)
        station = force_pattern(geo, sec["source_uy"].transpose("r", "theta").values,
                                sec["source_uz"].transpose("r", "theta").values)
        win = ds.sel(x=slice(*WINDOW))
        window = force_pattern(geo, win["source_uy"].mean("x").transpose("r", "theta").values,
                               win["source_uz"].mean("x").transpose("r", "theta").values)
        print(json.dumps({"dataset": path, "station_x": float(sec["x"]),
                          "window_stations": int(win.sizes["x"]),
                          "force_station": station, "force_window": window},
                         indent=1, default=float))


if __name__ == "__main__":
    main()
