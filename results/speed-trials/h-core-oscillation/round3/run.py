"""Proxy-h relaxation trial: python run.py LABEL RELAXATION MODE   (MODE: shipped | fixed | floor)"""
import sys, time, json
from pathlib import Path
import numba
from eulag.config import CASES_DIR, Case
from eulag.studies.ablation import PROXY_NUMERICS, extract_metrics
from eulag import runs
import eulag.coupling as C
label, alpha, mode = sys.argv[1], float(sys.argv[2]), sys.argv[3]
scene = sys.argv[4] if len(sys.argv) > 4 else "h"
numba.set_num_threads(1)
orig = C.CouplingLoop._adapt_relaxation
if mode == "fixed":
    C.CouplingLoop._adapt_relaxation = lambda self: None
elif mode == "floor":  # stagnation halving not below case alpha / 2
    def adapt(self):
        a0 = self.case.numerics.relaxation
        before = self.alpha
        orig(self)
        if self.alpha < before and self.alpha < a0 / 2 - 1e-12:
            self.alpha = before
            print("  (floor: halving refused)", flush=True)
    C.CouplingLoop._adapt_relaxation = adapt
base = Case.from_toml(CASES_DIR / "scenes" / f"scene_{scene}.toml").replace(numerics={**PROXY_NUMERICS, "max_passes": 90})
import os
case = base.replace(name=f"proxy_{scene}_{label}", numerics={"relaxation": alpha, **({"drag_implicit_weight": float(os.environ["W"])} if os.environ.get("W") else {}), **({"axial_cells": int(os.environ["AXIAL"])} if os.environ.get("AXIAL") else {}), **({"coupling_tolerance": float(os.environ["TOL"]), "max_passes": int(os.environ.get("MAXP", 80))} if os.environ.get("TOL") else {})})
out = Path("/tmp/alpha") / f"{case.name}.nc"
t = time.perf_counter()
def prog(s):
    print(f"{label} pass {s.index} a={s.relaxation:.3g} res={s.residual:.3g} dp={s.pressure_gradient:.2f} t={time.perf_counter()-t:.0f}", flush=True)
res = runs.execute(case, out, resume=True, progress=prog, notify=lambda x: print('  NOTE', x, flush=True))
m = extract_metrics(res.dataset, case)
print(json.dumps(m, default=str))
print("time", time.perf_counter() - t)
