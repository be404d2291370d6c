"""Where the pressure drop goes: the grains' share of Δp·A, the part carried by empty (capped) gas
cells and the wall friction per grain, from the filled horizontal tube.

    python results/strauss-filled/grain-weights/momentum_closure.py [V_S ...] [--duration S]
        (defaults: 1 and 4 m/s, 1.5 s each; output: momentum_closure.txt)

Continues the filled tube (results/strauss/state_horizontal_t13.25.npz) with the shipped model
(cases/slug/strauss_horizontal.toml) at each superficial velocity v_s for ``--duration`` seconds
and averages over the second half, every 100 gas steps:

* N, the free grains in the tube, and Δp, the inlet pressure above the outlet's;
* r = Σ (gas force on the grains, x) / (Δp A): the share of the pressure drop the grains carry.
  The rest is the gas's own resistance in the cells where the permeability is capped at the
  empty tube's (κ ≤ D²/32, docs/slug.md), i.e. the gas rubbing on the tube wall above a bed;
* Δp_cap, the pressure drop across the capped cells (area-weighted);
* F_c/(μ m g): the net contact force on the grains (walls and grains, x) per grain, in units of
  the sliding friction of a grain resting on the bottom (what the gas must overcome to move it).

Strauß et al.'s Fig. 1 (v_s ≈ 1 m/s: 3,200 grains, 10 hPa/m) and Fig. 4 (4 m/s: 1,400 grains,
10 hPa/m) give 0.164 and 0.375 Pa per grain, i.e. 0.95 and 2.2 μ m g / A per grain, if all of
Δp·A went to the grains.  A diagnostic for docs/slug.md ("Measured against the paper").
"""

import argparse
import math
import tomllib
from pathlib import Path

import numpy as np

from darcy import carman_kozeny
from eulag.slug import _Simulation, read_state, validate_slug_case

ROOT = Path(__file__).resolve().parents[3]
CASE = ROOT / "cases" / "slug" / "strauss_horizontal.toml"
STATE = ROOT / "results" / "strauss" / "state_horizontal_t13.25.npz"
T0 = 13.25


def closure(vs, duration):
    with open(CASE, "rb") as fh:
        case = tomllib.load(fh)
    case.setdefault("initial", {})["state"] = str(STATE)
    case["gas"]["superficial_velocity_m_s"] = vs
    case["numerics"]["end_time_s"] = T0 + duration
    c = validate_slug_case(case)
    sim = _Simulation(c)
    st, _ = read_state(c["initial"]["state"], c)
    sim.start_from(st)
    length, area = sim.grid.length, sim.grid.cross_area
    g = sim.grains
    mass = c["grains"]["density_kg_m3"] * math.pi / 6.0 * c["grains"]["diameter_m"] ** 3
    mu_m_g = c["grains"]["wall_friction"] * mass * 9.81
    nsteps = int(round(duration / sim.gas_dt))
    rows = []
    for k in range(nsteps):
        sim.gas_step_advance()
        if k % 100 or k < nsteps // 2:
            continue
        n = g.n
        inside = (g.status[:n] == 0) & (g.pos[:n, 0] >= 0.0) & (g.pos[:n, 0] < length)
        dp = sim.darcy.inlet_pressure()
        capped = carman_kozeny(sim.phi, sim.d, sim.darcy.kappa_max) >= 0.999 * sim.darcy.kappa_max
        grad = sim.darcy.gradient()[..., 0]
        dp_cap = -float((grad * capped * sim.grid.area[None]).sum()) * sim.grid.lx / area
        rows.append((inside.sum(), dp, sim.gas_force[:n][inside, 0].sum(), g.force[:n][inside, 0].sum(), dp_cap))
    n, dp, fg, fc, dp_cap = np.mean(np.array(rows, dtype=float), axis=0)
    return (f"v_s {vs:4.1f} m/s, t = {T0 + duration / 2:.2f}-{T0 + duration:.2f} s ({len(rows)} samples): "
            f"N {n:6.0f}, dp {dp:6.1f} Pa ({dp / n:.3f} Pa per grain = {dp * area / n / mu_m_g:.2f} mu m g / A), "
            f"r {fg / (dp * area):.3f}, dp across capped cells {dp_cap:5.1f} Pa ({dp_cap / dp:.2f} of dp), "
            f"contact force per grain {-fc / n / mu_m_g:.2f} mu m g")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("velocities", nargs="*", type=float, default=[1.0, 4.0])
    ap.add_argument("--duration", type=float, default=1.5)
    a = ap.parse_args()
    for vs in a.velocities:
        print(closure(vs, a.duration), flush=True)


if __name__ == "__main__":
    main()
