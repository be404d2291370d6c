"""Station -dp/dx of scene g's gas solved on each final pass's own sources (as the dataset's
replicas are), to give the spread of the station value. The k reference of the sinks is the
checkpoint's gas (the dataset's field), where the run used its last relaxed iterate. Trial code."""
import sys
from pathlib import Path
import numpy as np
from eulag.config import Case, CASES_DIR
from eulag import coupling
import rans
case = Case.from_toml(CASES_DIR / "scenes" / "scene_g.toml")
ck = Path(sys.argv[1])
loop = coupling.CouplingLoop(case, checkpoint=ck, resume=True)
z = np.load(ck)
n, g = case.numerics, case.gas
i = int(np.argmin(np.abs(np.asarray(loop.mesh.x) - 3.555)))
vals, means = [], []
for r in range(3):
    d = {"momentum": z[f"final_{r}_momentum"], "k": z[f"final_{r}_k"], "k_ref": loop.gas.k, "eps_ref": loop.gas.epsilon}
    f = rans.solve(loop.mesh, loop.gas_props, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, loop._gas_sources(d),
                   tol=n.gas_tolerance, max_iterations=n.gas_max_iterations, initial=None,
                   turbulence_relaxation=1.0, momentum_relaxation=1.0, require_convergence=True, station_retries=True)
    vals.append(float(f.pressure_gradient[i])); means.append(float(np.mean(f.pressure_gradient)))
    print(r, vals[-1], means[-1], flush=True)
v = np.array(vals)
print(f"station -dp/dx per final pass {np.round(v, 2).tolist()}; mean {v.mean():.2f}, standard error of the mean {v.std(ddof=1)/np.sqrt(3):.2f}; pipe means {np.round(means, 2).tolist()}")
