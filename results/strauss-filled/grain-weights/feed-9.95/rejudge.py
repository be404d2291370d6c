"""Apply numerics.overlap_limit (eulag.slug.verdict, added after these runs were made) to
finished slug datasets, in place: the attributes ``converged`` and ``stop_reason`` are set as a run
with the present code sets them; the trajectories are not touched.

    python results/strauss-filled/grain-weights/feed-9.95/rejudge.py RUN.nc [...]
"""

import os
import sys

import xarray as xr

from eulag.slug import verdict


def main():
    for path in sys.argv[1:]:
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        converged, reason = verdict(ds)
        ds.attrs["converged"] = "true" if converged else "false"
        ds.attrs["stop_reason"] = reason
        tmp = path + ".tmp"
        ds.to_netcdf(tmp)
        os.replace(tmp, path)
        print(f"{os.path.basename(path)}: converged = {ds.attrs['converged']}; {ds.attrs['stop_reason']}")


if __name__ == "__main__":
    main()
