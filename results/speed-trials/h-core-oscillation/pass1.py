"""One Lagrangian pass (the collision-free first pass) of scene g's proxy grid in its
single-phase gas: section totals of the sampled sources, per seed and code version.

    PYTHONPATH=<checkout> python pass1.py SEED PARCELS      (prints one JSON line)

Trial code, not part of the product."""
import sys, json
import numpy as np
from eulag.config import Case, CASES_DIR
from eulag import coupling
from eulag.studies.ablation import PROXY_NUMERICS
seed, parcels = int(sys.argv[1]), int(sys.argv[2])
num = dict(PROXY_NUMERICS); num.update(seed=seed, parcels_start=parcels, parcels=parcels)
case = Case.from_toml(CASES_DIR / "scenes" / "scene_g.toml").replace(numerics=num)
loop = coupling.CouplingLoop(case)
loop.step()
s = loop.last_sample
c = loop._computed_sources(s)
V = loop.mesh.volume
mom = c["momentum"]; k = c["k"]
nx = mom.shape[1]
out = {}
for lo, hi, lab in ((0, nx, "all"), (nx // 2, nx, "x>2m"), (int(nx * 0.85), nx, "x>3.4m")):
    out[f"Sx_{lab}"] = float(np.sum(mom[0, lo:hi] * V[lo:hi]))
    out[f"Sy_{lab}"] = float(np.sum(mom[1, lo:hi] * V[lo:hi]))
    out[f"Sk_{lab}"] = float(np.sum(k[lo:hi] * V[lo:hi]))
    out[f"mass_{lab}"] = float(np.sum(s.concentration[lo:hi] * V[lo:hi]))
b = s.budget
out.update({kk: float(np.ravel(v)[0]) for kk, v in b.items() if np.size(v) >= 1})
print(json.dumps(out))
