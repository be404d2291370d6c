import sys, time
sys.path.insert(0, "/work/main/tests/benchmarks")
import numpy as np, rans
from bench_gas_scene import _sources_from_checkpoint
from eulag.coupling import build_mesh
case, src, origin = _sources_from_checkpoint(sys.argv[1])
print(origin)
n, g = case.numerics, case.gas
mesh = build_mesh(case)
gas = rans.GasProperties(density=g.density, viscosity=g.viscosity)
for tol, retries in ((1e-6, True), (1e-4, False), (1e-4, True), (1e-6, True)):
    t = time.perf_counter()
    f = rans.solve(mesh, gas, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, src, tol=tol,
                   max_iterations=n.gas_max_iterations, station_retries=retries, require_convergence=False)
    print(f"tol {tol:g} retries {retries}: {time.perf_counter()-t:.1f} s, converged {f.converged}, "
          f"iterations {int(f.station_iterations.sum())}, coupled {int(f.station_coupled.sum())}, "
          f"-dp/dx {f.pressure_gradient.mean():.4f}", flush=True)
