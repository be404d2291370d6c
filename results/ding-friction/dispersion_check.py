"""Does the turbulent dispersion of the solids hold the deposit up? Q_s = 0.8 m3/h, modified Berzi, 16 x 32.

    python results/ding-friction/dispersion_check.py [FACTOR ...]   (default: 1 10 100)

The solids' turbulent dispersion D_t = ν_t/σ_α (σ_α = 1, tfm.section) multiplied by FACTOR in the
in-plane solids balance only (the gas k-ε untouched), for this process only: a diagnostic
(docs/two-fluid.md, "Measured reasons where it differs"), not an option.  Prints Δp over 2.4 m,
the largest α_s and the holdup, and where the gas turbulence is: the share of cells with
ν_t < 1e-9 m2/s and the median ν_t in the suspension (α_s < 0.05) and the deposit (α_s > 0.4).
"""

import sys
import tomllib
from pathlib import Path

import numpy as np

import tfm.section as S
from eulag.two_fluid import run_two_fluid

CASE = Path(__file__).resolve().parents[2] / "cases" / "two_fluid" / "ding_qs0.8.toml"


def main(factors):
    orig = S._Solver._distribute
    for f in factors:
        def scaled(self, st, c, steps, f=f):
            return orig(self, st, {**c, "nut": c["nut"] * f}, steps)

        S._Solver._distribute = scaled
        try:
            with open(CASE, "rb") as fh:
                ds = run_two_fluid(tomllib.load(fh), None)
        finally:
            S._Solver._distribute = orig
        a, nut = ds.solids_fraction.values, ds.gas_turbulent_viscosity.values
        print(f"D_t x {f:g}: dp = {float(ds.pressure_drop) / 1e3:.3f} kPa, largest alpha_s {a.max():.3f}, "
              f"holdup {float(ds.solids_holdup):.4f}, converged {bool(ds.converged)}; "
              f"cells with nu_t < 1e-9 m2/s: {(nut < 1e-9).mean():.2f}; median nu_t "
              f"{np.median(nut[a < 0.05]):.2e} (alpha_s < 0.05), {np.median(nut[a > 0.4]):.2e} m2/s (alpha_s > 0.4)")


if __name__ == "__main__":
    main([float(v) for v in sys.argv[1:]] or [1.0, 10.0, 100.0])
