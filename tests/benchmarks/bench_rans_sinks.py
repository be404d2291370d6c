"""Benchmark of the axial march under stiff, noisy particle sinks of turbulence.

    python tests/benchmarks/bench_rans_sinks.py [--length 1.0] [--relaxation 0.3] [--visits 1] [--seed 1]
                         [--section 20x40] [--direct] [--single]

The developing base pipe (D = 30.5 mm, U0 = 10 m/s, inlet k = 1 m2/s2, 100 axial cells per m,
20 x 40 cross-section, first cell y+ 30) is solved single phase, then with the sink of
turbulence that 1 µm tracers at eta = 2.2 put on it, S_k = -(3/C_T) c_p eps (README of the
stability study; c_p = eta rho, C_T = 0.24 from particles.kernel), relaxed by ``--relaxation`` as in the coupling loop's
first gas solve, and made noisy as a pass with few parcels samples it: per cell times
Poisson(v)/v for ``--visits`` v (0: smooth).  The sink is linear in k (k_reference = the
single-phase k, rans.Sources), and C_eps3 = 1.8 (particles.tracking) forms the epsilon sink.  Printed: wall time of
each solve, -dp/dx, whether every station converged, the stations retried with the coupled
cross-flow step, the outer iterations, the smallest k, and the linear solves (factorisations
and refinement sweeps of ``rans.linalg.LaggedFactor``).  This is where the march spends its
time in the tracer and 50 µm scene passes of the studies (stations of near-laminar cells).
``--section 40x80`` solves the 4x cells of the stability study; ``--direct`` factorises every
matrix (``rans.solver.REUSE_FACTORISATION = False``), for comparison; ``--single`` stops after
the single-phase solve.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from particles.kernel import C_T  # T_L = C_T (2/3) k/eps (Sommerfeld 2001)
from particles.tracking import C_EPS3  # S_eps = C_eps3 (eps/k) S_k (the reference paper)
from rans import PipeMesh, solve
from rans import kepsilon as ke
from rans import operators, solver
from rans.solver import GasProperties, Sources


class _Counted:
    """Counts the linear solves of the lagged factorisations made while it is active."""

    def __enter__(self):
        self.made = []
        self._orig = operators.Section.lagged_factor
        made, orig = self.made, self._orig

        def lagged_factor(sec, **kw):
            f = orig(sec, **kw)
            made.append(f)
            return f

        operators.Section.lagged_factor = lagged_factor
        return self

    def __exit__(self, *exc):
        operators.Section.lagged_factor = self._orig

    def totals(self, made=None):
        return {k: sum(getattr(f, k) for f in (self.made if made is None else made))
                for k in ("factorisations", "solves", "sweeps")}


def run(length=1.0, relaxation=0.3, visits=1.0, seed=1, section=(20, 40), sinks=True):
    D, U, k0, eta = 0.0305, 10.0, 1.0, 2.2
    gas = GasProperties(1.205, 1.81e-5)
    mesh = PipeMesh.build(D, length, "developing", axial_cells=int(round(100 * length)), radial_cells=section[0],
                          azimuthal_cells=section[1], first_cell_yplus=30.0, bulk_velocity=U,
                          density=gas.density, viscosity=gas.viscosity)
    eps0 = ke.inlet_epsilon(k0, D)
    t = time.perf_counter()
    single = solve(mesh, gas, U, k0, eps0)
    t_single = time.perf_counter() - t
    if not sinks:
        return single, t_single, None, None
    noise = 1.0
    if visits > 0:
        noise = np.random.default_rng(seed).poisson(visits, single.k.shape) / visits
    sk = -relaxation * (3.0 / C_T) * eta * gas.density * single.epsilon * noise
    src = Sources(np.zeros((3,) + single.k.shape), sk, np.zeros_like(sk), k_reference=single.k.copy(),
                  c_eps3=C_EPS3)
    t = time.perf_counter()
    stiff = solve(mesh, gas, U, k0, eps0, sources=src)
    return single, t_single, stiff, time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python tests/benchmarks/bench_rans_sinks.py", description=__doc__.splitlines()[0])
    ap.add_argument("--length", type=float, default=1.0, help="pipe length [m] (100 cells per m)")
    ap.add_argument("--relaxation", type=float, default=0.3, help="source under-relaxation")
    ap.add_argument("--visits", type=float, default=1.0, help="Poisson mean of the sink noise (0: smooth)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--section", default="20x40", help="radial x azimuthal cells")
    ap.add_argument("--direct", action="store_true", help="factorise every matrix (no lagged factorisations)")
    ap.add_argument("--single", action="store_true", help="the single-phase solve only")
    a = ap.parse_args(argv)
    section = tuple(int(v) for v in a.section.lower().split("x"))
    solver.REUSE_FACTORISATION = not a.direct
    with _Counted() as counted:
        single, t1, stiff, t2 = run(a.length, a.relaxation, a.visits, a.seed, section, sinks=not a.single)

    def solves(made):
        if a.direct:
            return "direct solves"
        return "{factorisations} factorisations for {solves} solves, {sweeps} refinement sweeps".format(
            **counted.totals(made))

    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}; "
          f"{section[0]}x{section[1]} section, {a.length:g} m")
    print(f"single phase: {t1:.1f} s, -dp/dx {single.pressure_gradient.mean():.3f} Pa/m, "
          f"{int(single.station_iterations.sum())} iterations; {solves(counted.made[:4])}")
    if stiff is not None:
        print(f"tracer sinks (relaxation {a.relaxation:g}, visits {a.visits:g}): {t2:.1f} s, -dp/dx "
              f"{stiff.pressure_gradient.mean():.4f} Pa/m, converged {stiff.converged}, stations that "
              f"kept the coupled cross-flow step {int(stiff.station_coupled.sum())}, iterations (kept "
              f"attempts) {int(stiff.station_iterations.sum())}, min k {stiff.k.min():.3g} m2/s2; "
              f"{solves(counted.made[4:])}")

if __name__ == "__main__":
    main()
