"""The dataset's final gas solve of scene g (sources of the averaged final passes, applied as
sampled), redone from the checkpoint with the code on PYTHONPATH: the station's -dp/dx.
Trial code, not part of the product.
    python final_solve.py save CKPT OUT.npz     (the averaged sources, with this code)
    python final_solve.py solve OUT.npz         (the solve, with the code on PYTHONPATH)"""
import sys, time
import numpy as np
from eulag.config import Case, CASES_DIR
from eulag import coupling
import rans

case = Case.from_toml(CASES_DIR / "scenes" / "scene_g.toml")
if sys.argv[1] == "save":
    from pathlib import Path
    loop = coupling.CouplingLoop(case, checkpoint=Path(sys.argv[2]), resume=True)
    avg = loop._computed_sources(loop.sample())
    np.savez(sys.argv[3], momentum=avg["momentum"], k=avg["k"], k_ref=loop.gas.k, eps_ref=loop.gas.epsilon,
             dp_relaxed=loop.gas.pressure_gradient)
    print("saved; relaxed iterate's station -dp/dx", loop.gas.pressure_gradient[np.argmin(np.abs(np.asarray(loop.mesh.x) - 3.555))])
else:
    z = np.load(sys.argv[2])
    loop = coupling.CouplingLoop(case)
    d = {"momentum": z["momentum"], "k": z["k"], "k_ref": z["k_ref"], "eps_ref": z["eps_ref"]}
    n, g = case.numerics, case.gas
    t0 = time.perf_counter()
    f = rans.solve(loop.mesh, loop.gas_props, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, loop._gas_sources(d),
                   tol=n.gas_tolerance, max_iterations=n.gas_max_iterations, initial=None,
                   turbulence_relaxation=1.0, momentum_relaxation=1.0, require_convergence=True, station_retries=True)
    i = int(np.argmin(np.abs(np.asarray(loop.mesh.x) - 3.555)))
    print(f"station -dp/dx {f.pressure_gradient[i]:.4f}  mean {np.mean(f.pressure_gradient):.4f}  converged {f.converged}  {time.perf_counter()-t0:.1f} s")
