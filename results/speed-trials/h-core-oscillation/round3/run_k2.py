"""Proxy-h trial: the shipped loop (adaptive alpha, criteria, final passes), the k source
relaxed with its own weight alpha_k = MODE(alpha).
python run_k2.py LABEL MODE [SEED]   MODE: quarter (alpha/4) | cap075 (min(alpha, 0.075)) | same | fixed075; env NOADAPT=1: alpha never changed"""
import sys, time, json, math
from pathlib import Path
import numpy as np
import numba
from eulag.config import CASES_DIR, Case
from eulag.studies.ablation import PROXY_NUMERICS, extract_metrics
from eulag import runs
import eulag.coupling as C
label, mode = sys.argv[1], sys.argv[2]
seed = int(sys.argv[3]) if len(sys.argv) > 3 else 1
numba.set_num_threads(1)
ak_of = {"quarter": lambda a: a / 4, "cap075": lambda a: min(a, 0.075), "same": lambda a: a, "fixed075": lambda a: 0.075}[mode]

def relax(self, comp, sample, alpha):
    # eulag.coupling.CouplingLoop._relax with S_k blended at alpha_k and the k part of the
    # residual measured against alpha_k's noise (a modified copy: trial code)
    prev = self.sources
    shape = self.mesh.shape
    ak = ak_of(alpha)
    if prev is None:
        prev = {"momentum": np.zeros((3,) + shape), "k": np.zeros(shape)}
    else:
        prev = dict(prev)
        prev["k"] = np.where(prev["k"] < 0.0, prev["k"] * (self.gas.k / prev["k_ref"]), prev["k"])
    new = {"momentum": (1 - alpha) * prev["momentum"] + alpha * comp["momentum"],
           "k": (1 - ak) * prev["k"] + ak * comp["k"],
           "k_ref": self.gas.k.copy(), "eps_ref": self.gas.epsilon.copy()}
    if comp.get("drag") is not None:
        new["drag"] = self.case.numerics.drag_implicit_weight * alpha * comp["drag"]
        new["u_ref"] = np.stack([self.gas.ux, self.gas.uy, self.gas.uz])
    residual = math.nan
    if self.sources is not None:
        ratios = []
        for d, se, before, a in ((new["momentum"] - prev["momentum"], comp["se_momentum"], prev["momentum"], alpha),
                                 (new["k"] - prev["k"], comp["se_k"], prev["k"], ak)):
            fac = a * math.sqrt(2.0 / (2.0 - a))
            scale = np.sqrt(np.mean(new["momentum"] ** 2)) if d.ndim == 4 else np.sqrt(np.mean(new["k"] ** 2))
            noise = np.where(np.isfinite(se), fac * se, 0.0)
            noise = np.maximum(noise, C._FLOOR * a / alpha * scale + 1e-300)
            ratios.append((d / noise).ravel())
        z = np.concatenate(ratios)
        residual = float(np.sqrt(np.mean(z * z)))
    return new, residual

import os
if os.environ.get("NOADAPT"):
    C.CouplingLoop._adapt_relaxation = lambda self: None
if mode != "same":
    C.CouplingLoop._relax = relax
base = Case.from_toml(CASES_DIR / "scenes" / "scene_h.toml").replace(numerics={**PROXY_NUMERICS, "max_passes": 90})
case = base.replace(name=f"proxy_h_{label}", numerics={"seed": seed})
out = Path("/tmp/alpha") / f"{case.name}.nc"
t = time.perf_counter()
def prog(s):
    print(f"{label} pass {s.index} a={s.relaxation:.3g} res={s.residual:.3g} dp={s.pressure_gradient:.2f} t={time.perf_counter()-t:.0f}", flush=True)
res = runs.execute(case, out, resume=True, progress=prog, notify=lambda x: print("  NOTE", x, flush=True))
m = extract_metrics(res.dataset, case)
print(json.dumps(m, default=str))
print("converged", res.converged, res.stop_reason)
print("time", time.perf_counter() - t)
