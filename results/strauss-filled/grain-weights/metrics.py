"""The strauss study's numbers (eulag.studies.strauss.extract_metrics) of the runs of this folder.

    python results/strauss-filled/grain-weights/metrics.py RUN.nc ...   (from the repository root)

Prints one JSON line per run: the window's mean pressure drop and grains in the tube, the
regime by the study's rule, the slug catalogue (velocity, minimum porosity, grains per slug).
"""

import json
import sys
from types import SimpleNamespace

import xarray as xr

from eulag.studies.strauss import extract_metrics

KEYS = ("pressure_drop_Pa", "pressure_drop_per_length_Pa_m", "grains_in_tube", "regime", "dense_share",
        "moving_share_all", "slug_velocity_m_s", "slug_min_porosity", "slug_length_m", "slug_grains",
        "slug_records", "outflow_per_feed", "max_overlap_per_d", "grains_lost", "wall_time_s")

for path in sys.argv[1:]:
    with xr.open_dataset(path) as ds:
        case = SimpleNamespace(data=json.loads(ds.attrs["case"]))  # the validated case the run wrote
        m = extract_metrics(ds, case)
    print(json.dumps({"run": path, **{k: m.get(k) for k in KEYS}}))
