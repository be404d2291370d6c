"""Speed of the slug model (prints figures; not a timed test).

    python tests/benchmarks/bench_dem.py [--grains 3200] [--parallel]

A periodic 7 mm tube packed with the relaxed feed packing (porosity 0.57) at the paper's
grain size, gas at v_s = 1 m/s through it: the coupled loop of eulag.slug (DEM steps of
t_c/30, a gas step every 10⁻⁴ s).  Warm-up first (numba compile and caches are excluded),
then 0.02 s of simulated time.  Printed: grain-steps per second per core, the share of wall
time in the gas part (transfer both ways + pressure solve), and a physical check — the
packing stays intact (no grain lost, max overlap < 1 % of d).
"""

import argparse
import math
import os
import platform
import time

import numba

from eulag.slug import _Simulation, validate_slug_case


def case(grains, parallel):
    v_p = math.pi / 6 * 1.4e-3**3
    length = grains * v_p / (0.43 * math.pi * 3.5e-3**2)
    length = 0.014 * max(1, round(length / 0.014))
    return {"model": "dem-darcy",
            "tube": {"length_m": length, "periodic": True},
            "initial": {"plug_length_m": length, "plug_start_m": 0.0},
            "numerics": {"cells_x": max(3, int(round(length / 3.5e-3))), "end_time_s": 1.0, "parallel": parallel}}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--grains", type=int, default=3200)
    ap.add_argument("--parallel", action="store_true", help="prange kernels on all numba threads")
    ap.add_argument("--time", type=float, default=0.02, help="simulated seconds to time")
    a = ap.parse_args()
    sim = _Simulation(validate_slug_case(case(a.grains, a.parallel)))
    for _ in range(5):  # warm-up: compile
        sim.gas_step_advance()
    sim.t_gas = sim.t_total = 0.0
    n_gas = int(round(a.time / sim.gas_dt))
    t0 = time.perf_counter()
    for _ in range(n_gas):
        sim.gas_step_advance()
    wall = time.perf_counter() - t0
    n = int((sim.grains.status[: sim.grains.n] == sim.FREE).sum())
    cores = numba.get_num_threads() if a.parallel else 1
    gsps = n * n_gas * sim.n_sub / wall
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, "
          f"load {os.getloadavg()[0]:.1f}; numba threads used: {cores}")
    print(f"grains {n}, DEM dt {sim.dt:.3g} s ({sim.n_sub} per gas step), simulated {a.time} s in {wall:.2f} s")
    print(f"grain-steps per second: {gsps:.3g} total, {gsps / cores:.3g} per core")
    print(f"gas share of wall time: {sim.t_gas / sim.t_total:.1%}")
    print(f"max overlap/d {sim.max_overlap / sim.d:.4f}, grains lost {sim.lost}")
    assert sim.lost == 0 and sim.max_overlap < 0.01 * sim.d


if __name__ == "__main__":
    main()
