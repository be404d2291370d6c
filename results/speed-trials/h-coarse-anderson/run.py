import sys, time, os
import numpy as np
from eulag.config import Case
import eulag.coupling as C
if os.environ.get("AA"): import coarse_anderson
case = Case.from_toml(sys.argv[1])
label = sys.argv[2]
if len(sys.argv) > 3: case = case.replace(numerics={"seed": int(sys.argv[3])})
loop = C.CouplingLoop(case, notify=lambda t: print("  NOTE", t, flush=True))
t0 = time.perf_counter()
for s in loop:
    h = loop.history
    crit = {c.name: c.value for c in loop.criteria} if loop.criteria else {}
    g = loop.gas; kax = float(np.mean(g.k[-5, 0]))
    print(f"{label} pass {s.index:3d} {s.phase[:2]} a={s.relaxation:.3g} res={s.residual:.3g} dp={s.pressure_gradient:.3f} kax={kax:.4f} "
          f"cm={h.collision_momentum[-1]:+.4f} " + " ".join(f"{k[:10]}={v:.3g}" for k, v in crit.items())
          + f" t={time.perf_counter()-t0:.0f}", flush=True)
print(label, "converged", loop.converged, "at", loop.converged_at, "passes", loop.pass_index, "stop", loop.stop_reason, flush=True)
