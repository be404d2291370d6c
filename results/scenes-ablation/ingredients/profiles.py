"""Window means (stations 2.56-3.56 m) of the mirror-symmetrised in-plane particle force on the
gas, the particle concentration and the vertical velocities of both phases, read at points of
the right half of the section (the cell nearest each point; rows y/R from the top wall down,
columns z/R = 0 (vertical diameter), 0.2, 0.4, 0.6, 0.8):

    python results/scenes-ablation/ingredients/profiles.py RUN.nc
"""
import sys

import numpy as np
import xarray as xr

from eulag import analysis as an

WINDOW = (2.56, 3.56)
ROWS = (0.85, 0.6, 0.3, 0.0, -0.3, -0.6, -0.85)    # y/R
COLUMNS = (0.0, 0.2, 0.4, 0.6, 0.8)                 # z/R
FIELDS = (("source_uy", 1), ("source_uz", -1), ("particle_concentration", 1),
          ("particle_uy", 1), ("gas_uy", 1))        # name, mirror parity


def main(path):
    ds = xr.open_dataset(path)
    geo = an.polar_section(ds)
    radius = geo.radius
    window = ds.sel(x=slice(*WINDOW)).mean("x")

    def nearest(a, y, z):
        i = np.unravel_index(np.argmin((geo.y - y) ** 2 + (geo.z - z) ** 2), a.shape)
        return a[i]

    for name, parity in FIELDS:
        a = an.mirror_average(window[name].transpose("r", "theta").values, parity)
        print(f"{name} [{ds[name].attrs.get('units', '')}]")
        for yr in ROWS:
            cells = [f"{nearest(a, yr * radius, zr * radius):9.3g}" for zr in COLUMNS if yr**2 + zr**2 < 0.95]
            print(f"  y/R={yr:5.2f} " + " ".join(cells))


if __name__ == "__main__":
    main(sys.argv[1])
