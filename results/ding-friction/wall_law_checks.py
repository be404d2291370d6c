"""The solids wall law (eq. 24-25 of Ding et al. 2024, modified Schneiderbauer) at Q_s = 0.8 m3/h,
modified Berzi, 16 x 32: what the wall shear is made of, and two physically motivated variants.

    python results/ding-friction/wall_law_checks.py [base|pkin|noqf|notau|original]

base  the case as shipped (cases/two_fluid/ding_qs0.8.toml);
pkin  the normal stress of eq. 24 replaced by the wall's full solids pressure, Lun's p_kin
      (times erf(u-bar)) + p_f;
noqf  the Coulomb work mu_w p_f |u| left out of the granular-energy wall flux of eq. 25;
notau the Coulomb term mu_w p_f left out of the wall shear of eq. 24 only;
original  both left out: the wall condition of Schneiderbauer, Schellander & Pirker (2012)
      before Ding et al.'s modification (the case key walls.law = "schneiderbauer").
The variants replace ``tfm.wall`` functions inside ``tfm.section`` for this process only; they
are diagnostics (docs/two-fluid.md, "Measured reasons where it differs"), not options.
Prints Delta p over 2.4 m, the force balance and the wall integrals over the submerged solids
weight per unit length W.
"""

import dataclasses
import math
import sys
import tomllib
from pathlib import Path

import numpy as np
from scipy.special import erf

import tfm.section as S
import tfm.wall as W
from eulag.two_fluid import problem_from_case
from tfm.kinetic import lun_solids_pressure

CASE = Path(__file__).resolve().parents[2] / "cases" / "two_fluid" / "ding_qs0.8.toml"


def main(variant="base"):
    with open(CASE, "rb") as fh:
        pb = problem_from_case(tomllib.load(fh))
    orig_q = W.schneiderbauer_wall_heat_flux
    if variant == "pkin":
        e_ss = pb.params.e_ss

        def shear(u, a, rho, g0, th, pf, e_sw=0.5, mu_w=0.5, beta0=0.3):
            mu0 = W.schneiderbauer_mu0(e_sw, mu_w, beta0)
            ub = W.schneiderbauer_slip_ratio(u, th, mu0)
            pk = lun_solids_pressure(a, rho, np.maximum(th, 0.0), g0, e_ss)
            return -(mu_w * pk * erf(ub) + mu_w * np.asarray(pf)) * np.sign(u)

        S.schneiderbauer_wall_shear = shear
    elif variant == "noqf":
        def heat_flux(u, a, rho, g0, th, pf, *args):
            return orig_q(u, a, rho, g0, th, 0.0 * np.asarray(pf), *args)

        S.schneiderbauer_wall_heat_flux = heat_flux
    elif variant == "notau":
        orig_shear = W.schneiderbauer_wall_shear

        def shear_no_pf(u, a, rho, g0, th, pf, *args):
            return orig_shear(u, a, rho, g0, th, 0.0 * np.asarray(pf), *args)

        S.schneiderbauer_wall_shear = shear_no_pf
    elif variant == "original":  # the case key walls.law = "schneiderbauer"
        pb = dataclasses.replace(pb, params=dataclasses.replace(pb.params, wall_law="schneiderbauer"))
    elif variant != "base":
        raise SystemExit(f"variant {variant!r}: allowed base, pkin, noqf, notau, original")
    s, st, ok, c = S.solve_section(pb)
    w, arc, A, a = s.sec.wall, s.sec.wall_arc, s.A, c["a"]
    P = pb.params
    eta_w = 0.5 * (1.0 + P.e_sw)
    ub = W.schneiderbauer_slip_ratio(st.us[w], st.theta[w], W.schneiderbauer_mu0(P.e_sw, P.mu_w, P.beta0))
    f_gas = np.sum(s.hg * st.ug[w] * arc)
    f_sol = np.sum(s.hs * st.us[w] * arc)
    weight = np.sum(a * A) * (pb.rho_s - pb.rho_g) * S.G_ACC  # submerged weight per unit length [N/m]
    coll_stress = eta_w * a[w] * pb.rho_s * c["g0"][w] * st.theta[w]
    print(f"{variant}: converged {ok} after {st.iteration} iterations; dp over 2.4 m {st.G * 2.4 / 1e3:.3f} kPa; "
          f"G A {st.G * s.Atot:.4f} N/m = gas wall {f_gas:.4f} + solids wall {f_sol:.4f}")
    print(f"  solids wall force / W {f_sol / weight:.3f}: collisional {np.sum(P.mu_w * coll_stress * erf(ub) * arc) / weight:.3f}"
          f" + frictional {np.sum(P.mu_w * c['pf'][w] * arc) / weight:.3f}"
          f"{' (not applied: mu_w p_f left out of the shear)' if variant in ('notau', 'original') else ''}; "
          f"holdup {np.sum(a * A) / s.Atot:.4f}")
    print(f"  over the wall / W: eta_w a rho g0 Theta {np.sum(coll_stress * arc) / weight:.3f}, "
          f"p_kin + p_f {np.sum((c['pkin'][w] + c['pf'][w]) * arc) / weight:.3f}; erf(u-bar) min {erf(ub).min():.4f}; "
          f"wall u_s {st.us[w].min():.2f}-{st.us[w].max():.2f} m/s, Theta {st.theta[w].min():.2g}-{st.theta[w].max():.2g} m2/s2")


if __name__ == "__main__":
    main(*sys.argv[1:2])
