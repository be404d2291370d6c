"""Proxy-h loop experiment: python run_proxy.py CASE.toml LABEL [CONST=VALUE ...]"""
import sys, time, math
import numpy as np
from eulag.config import Case
import eulag.coupling as C
import os
if os.environ.get("INSTR"): import instr
if os.environ.get("HB_MU"): import hb
case = Case.from_toml(sys.argv[1])
label = sys.argv[2]
for kv in sys.argv[3:]:
    k, v = kv.split("=")
    setattr(C, k, type(getattr(C, k))(float(v)) if not isinstance(getattr(C, k), bool) else v == "1")
    print("set", k, getattr(C, k), flush=True)
if os.environ.get("NOADAPT"):
    C.CouplingLoop._adapt_relaxation = lambda self: None
loop = C.CouplingLoop(case, notify=lambda t: print("  NOTE", t, flush=True))
t0 = time.perf_counter()
for s in loop:
    h = loop.history
    crit = {c.name: c.value for c in loop.criteria} if loop.criteria else {}
    from particles.layout import CS_APP, CS_N, CS_OK
    st = loop.stats
    if st is not None and st.shape[1] > CS_APP:
        w = np.where(st[:, CS_OK] > 0, st[:, CS_N], 0.0)
        ap = [float(np.sum(w * st[:, CS_APP + i]) / np.sum(w)) for i in range(3)]
        print(f"   APP pass {s.index} n-weighted a = {ap[0]:+.4g} {ap[1]:+.4g} {ap[2]:+.3g} m/s2", flush=True)
    print(f"{label} pass {s.index:3d} a={s.relaxation:.3g} res={s.residual:.3g} dp={s.pressure_gradient:.3f} "
          f"cm={h.collision_momentum[-1]:+.4f} " + " ".join(f"{k[:10]}={v:.3g}" for k, v in crit.items())
          + f" t={time.perf_counter()-t0:.0f}", flush=True)
print(label, "converged", loop.converged, "at", loop.converged_at, "passes", loop.pass_index, flush=True)
