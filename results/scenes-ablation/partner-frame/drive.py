"""One proxy run of a scene (its case file on eulag.studies.ablation.PROXY_NUMERICS) with the
label's change, its section metrics printed as one JSON line:

    python drive.py SCENE SEED LABEL > SCENE_LABEL_sSEED.json

LABEL: eulag (the defaults), full (physics.partner_covariance = "full"), response
(physics.langevin_drift_form = "response"), nodrift. The "cartesian" and "polar" rows of the
README ran this script's earlier form in a tree with polar_trial.patch applied, with
EULAG_PARTNER_FRAME=cartesian or polar (and the label set to match), each with its own
NUMBA_CACHE_DIR; the dataset goes to /tmp/rs.
"""
import json, sys, time
scene, seed, label = sys.argv[1], int(sys.argv[2]), sys.argv[3]
changes = {"eulag": {}, "cartesian": {}, "polar": {}, "response": {"physics": {"langevin_drift_form": "response"}},
           "nodrift": {"physics": {"langevin_drift_correction": False}},
           "full": {"physics": {"partner_covariance": "full"}}}[label]
from eulag.config import CASES_DIR, Case
from eulag.studies.ablation import PROXY_NUMERICS
import eulag.runs
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent.parent))
from section_metrics import particle_distribution
from eulag.studies.scenes import scene_metrics
import xarray as xr
case = Case.from_toml(CASES_DIR / "scenes" / f"scene_{scene}.toml")
num = dict(PROXY_NUMERICS, seed=seed)
case = case.replace(numerics=num, **changes)
out = f"/tmp/rs/{scene}_{label}_s{seed}.nc"
t = time.time()
eulag.runs.run(case, out)
ds = xr.open_dataset(out)
m = {k: v for k, v in scene_metrics(ds, 3.56).items() if k != "figures"}
m.update(particle_distribution(ds))
m["time"] = time.time() - t
m["converged"] = str(bool(ds["converged"].values))
kax = float(ds["gas_k"].sel(x=3.55, method="nearest").isel(r=0).mean())
m["axis_k"] = kax
print(json.dumps({"run": out, **m}, default=lambda v: float(v) if hasattr(v, '__float__') else str(v)))
