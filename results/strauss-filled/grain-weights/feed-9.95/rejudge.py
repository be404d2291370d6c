"""Apply numerics.overlap_limit (eulag.slug.problem_overlap, added after these runs were made) to
finished slug datasets, in place: the attributes ``converged`` and ``stop_reason`` are set as a run
with the present code sets them; the trajectories are not touched.

    python results/strauss-filled/grain-weights/feed-9.95/rejudge.py RUN.nc [...]
"""

import json
import os
import sys

import xarray as xr

from eulag.slug import problem_overlap, validate_slug_case


def main():
    for path in sys.argv[1:]:
        with xr.open_dataset(path) as ds:
            ds = ds.load()
        limit = validate_slug_case(json.loads(ds.attrs["case"]))["numerics"]["overlap_limit"]
        problems = [f"{int(ds['grains_lost'])} grains lost"] if int(ds["grains_lost"]) else []
        overlap = problem_overlap(ds, limit)
        if overlap:
            problems.append(overlap)
        ds.attrs["converged"] = "false" if problems else "true"
        ds.attrs["stop_reason"] = "finished, but " + "; ".join(problems) if problems else "finished"
        tmp = path + ".tmp"
        ds.to_netcdf(tmp)
        os.replace(tmp, path)
        print(f"{os.path.basename(path)}: converged = {ds.attrs['converged']}; {ds.attrs['stop_reason']}")


if __name__ == "__main__":
    main()
