"""How much gas–solid slip the drag allows in the deposit, and what sets the deposit's speed.
Q_s = 0.8 m3/h, modified Berzi, 16 x 32 (cases/two_fluid/ding_qs0.8.toml).

    python results/ding-friction/deposit_balance.py        (output: deposit_balance.txt)

A diagnostic for docs/two-fluid.md ("Measured reasons where it differs", reason 1): solves the
developed section, then prints

* the slip the three-zone drag law (as the case blends it) lets the whole α_g G hold,
  β(α_s, slip) · slip = α_g G, at a range of α_s, and the multiple of α_g G a 2 m/s slip would
  need (the paper's Δp implies solids ≈ 2 m/s behind the gas);
* each deposit cell's own balance: the slip the model has against α_g G/β (the gas's viscous
  term is negligible where the particles have put out its turbulence);
* the axial forces on the deposit (α_s > 0.4) per unit length: both phases' share of G, the drag,
  the net viscous inflow across the deposit's edge, and the wall forces under it.
"""

import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from eulag.two_fluid import problem_from_case
from tfm.drag import three_zone_drag
from tfm.section import _harmonic, _Solver, solve_section

CASE = Path(__file__).resolve().parents[2] / "cases" / "two_fluid" / "ding_qs0.8.toml"


def main():
    with open(CASE, "rb") as fh:
        pb = problem_from_case(tomllib.load(fh))
    _, st, ok, _ = solve_section(pb)
    s = _Solver(pb)
    c = s.closures(st)
    sec, A, G = s.sec, s.A, st.G
    print(f"{CASE.name}, friction {pb.friction!r}: converged {ok}, -dp/dx {G:.1f} Pa/m, "
          f"dp over 2.4 m {G * 2.4 / 1e3:.3f} kPa")

    def beta(a, slip):
        return float(three_zone_drag(np.array([a]), pb.rho_g, pb.mu_g, pb.d_s, np.array([slip]),
                                     pb.mckeen_scale, pb.drag_blend)[0])

    print("\nslip that the whole alpha_g G holds, beta(alpha_s, slip) slip = alpha_g G:")
    for a in (0.55, 0.50, 0.45, 0.40, 0.245, 0.10, 0.01):
        slip = brentq(lambda v: beta(a, v) * v - (1.0 - a) * G, 1e-12, 100.0)
        need = beta(a, 2.0) * 2.0 / ((1.0 - a) * G)
        print(f"  alpha_s {a:5.3f}: {slip:.4f} m/s; a slip of 2 m/s needs {need:6.1f} x alpha_g G")

    a, ag = c["a"], 1.0 - c["a"]
    dep = a > 0.4
    sl = st.ug - st.us
    est = ag * G / c["beta"]
    print(f"\ndeposit (alpha_s > 0.4): {dep.sum()} cells, {A[dep].sum() / s.Atot:.2f} of the section")
    print(f"  slip u_g - u_s: {sl[dep].min():.4f} to {sl[dep].max():.4f} m/s; "
          f"alpha_g G / beta: {est[dep].min():.4f} to {est[dep].max():.4f} m/s")
    i = np.flatnonzero(dep)[np.argmax(a[dep])]
    print(f"  densest cell (alpha_s {a[i]:.3f}, beta {c['beta'][i]:.3g} kg/m3/s): slip {sl[i]:.4f}, "
          f"alpha_g G / beta {est[i]:.4f} m/s")

    # forces on the deposit per unit length [N/m]; the viscous terms as the solver assembles them
    mu_g = ag * (pb.mu_g + pb.rho_g * c["nut"])
    mu_s = a * (c["mukc"] + c["muf"])
    visc_g = -(s.laplacian(_harmonic(mu_g[sec.P], mu_g[sec.N])) @ st.ug)
    visc_s = -(s.laplacian(_harmonic(mu_s[sec.P], mu_s[sec.N])) @ st.us)
    s.momentum(st, c)  # sets the wall coefficients of this state (s.tau_sw, s.hg)
    w = sec.wall
    under = dep[w]
    solids_wall = s.tau_sw * sec.wall_arc  # eq. 24's shear magnitude, against u_s > 0
    gas_wall = s.hg * st.ug[w] * sec.wall_arc
    drag = np.sum((c["beta"] * sl * A)[dep])
    print("\naxial forces on the deposit per unit length [N/m]:")
    print(f"  gas:    alpha_g G {np.sum((ag * G * A)[dep]):.4f}, drag -{drag:.4f}, "
          f"viscous inflow {visc_g[dep].sum():+.4f}, gas wall under it -{gas_wall[under].sum():.4f}")
    print(f"  solids: alpha_s G {np.sum((a * G * A)[dep]):.4f}, drag +{drag:.4f}, "
          f"viscous inflow {visc_s[dep].sum():+.4f}, solids wall under it -{solids_wall[under].sum():.4f}")
    print(f"whole section: G A {G * s.Atot:.4f} = solids wall {solids_wall.sum():.4f} + gas wall "
          f"{gas_wall.sum():.4f} N/m")


if __name__ == "__main__":
    main()
