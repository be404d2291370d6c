"""The gas's cell pattern station by station along the pipe:

    python results/scenes-ablation/ingredients/along_pipe.py RUN.nc

At x = 0.3 ... 3.9 m: the symmetrised cell count, the sin 2θ / cos θ index, the signs of the
mirror-even u_y along the vertical diameter (bottom → top), the main pair's sense, and the
largest raw and interior solenoidal in-plane speeds in % of U0 (``eulag.analysis.pattern_metrics``).
"""

import sys

import xarray as xr

from eulag import analysis as an

STATIONS = (0.3, 0.6, 1.0, 1.5, 2.0, 2.5, 3.0, 3.3, 3.56, 3.9)   # m


def main(path):
    ds = xr.open_dataset(path)
    for x in STATIONS:
        m = an.pattern_metrics(ds, x)
        signs = an.sign_text(m["uy_sign_pattern"])
        print(f"x = {x:4} m: cells {m['count_symmetrised']}, index {m['mode_index']:.2f}, u_y {signs:3}, "
              f"{m['main_pair_sense']}, strength {m['strength']:.3f} %, interior {m['interior_solenoidal_max']:.3f} %")


if __name__ == "__main__":
    main(sys.argv[1])
