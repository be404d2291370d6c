"""Proxy-h trial: alpha fixed at the case's value, the k source relaxed with its own weight.
python run_k.py LABEL ALPHA ALPHA_K [MAX_PASSES]   (ALPHA_K = 'same' for the shipped blend)"""
import sys, time, json, math
from pathlib import Path
import numpy as np
import numba
from eulag.config import CASES_DIR, Case
from eulag.studies.ablation import PROXY_NUMERICS
from eulag import runs
import eulag.coupling as C
label, alpha, ak = sys.argv[1], float(sys.argv[2]), sys.argv[3]
maxp = int(sys.argv[4]) if len(sys.argv) > 4 else 45
numba.set_num_threads(1)
C.CouplingLoop._adapt_relaxation = lambda self: None
orig = C.CouplingLoop._relax
if ak != "same":
    ak = float(ak)
    def relax(self, comp, sample, alpha):
        prev = self.sources
        new, residual = orig(self, comp, sample, alpha)
        if prev is not None:
            pk = np.where(prev["k"] < 0.0, prev["k"] * (self.gas.k / prev["k_ref"]), prev["k"])
            new["k"] = (1 - ak) * pk + ak * comp["k"]
        return new, residual
    C.CouplingLoop._relax = relax
base = Case.from_toml(CASES_DIR / "scenes" / "scene_h.toml").replace(numerics={**PROXY_NUMERICS, "max_passes": maxp})
case = base.replace(name=f"proxy_h_{label}", numerics={"relaxation": alpha})
loop = C.CouplingLoop(case, notify=lambda t: print("  NOTE", t, flush=True))
t0 = time.perf_counter()
from particles.layout import CS_APP
for s in loop:
    g = loop.gas
    nx, nr, nt = g.k.shape
    i = int(np.argmin(np.abs(loop.mesh.x - 3.55)))
    kax = float(np.mean(g.k[i, 0])); kmean = float(np.mean(g.k[i])); kwall = float(np.mean(g.k[i, -1]))
    print(f"{label} pass {s.index:3d} a={s.relaxation:.3g} res={s.residual:.3g} dp={s.pressure_gradient:.2f} "
          f"cm={loop.history.collision_momentum[-1]:+.4f} kax={kax:.4f} kmean={kmean:.3f} kwall={kwall:.3f} "
          f"t={time.perf_counter()-t0:.0f}", flush=True)
    if s.index >= maxp - 3:
        break
