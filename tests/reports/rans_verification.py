"""The gas solver's verification and validation figures quoted in README (report, no pass mark;
the pass marks are in tests/test_rans_pipe_flow.py and tests/test_rans_mms.py).

    python tests/reports/rans_verification.py

Prints the Darcy friction factor against Colebrook (fluids.friction) at Re 2e4, 1e5, 1e6
(periodic mode, 20 x 40 cells, wall cell at y+ 30), the developing centreline against the
OpenFOAM v1912 k-epsilon solution in ../shared/data (400 x 20 x 20 cells, as the test), and
the observed orders of the manufactured cross-section solution on 12x24, 24x48, 48x96.
"""

import sys
from pathlib import Path

import numpy as np
from fluids.friction import Colebrook

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root: tests.*

from rans.profiles import axis_value  # noqa: E402
from tests.conftest import read_reference_csv
from tests.test_rans_mms import GRIDS, _orders, cross_section_errors
from tests.test_rans_pipe_flow import GAS, D, PipeMesh, periodic, solve

for re_ in (2e4, 1e5, 1e6):
    _, f = periodic(re_)
    print(f"friction factor, Re {re_:.0e}: {100 * (f.friction_factor[0] / Colebrook(re_, 0.0) - 1):+.2f} % "
          "of Colebrook")

m = PipeMesh.build(D, 4.0, "developing", axial_cells=400, radial_cells=20, azimuthal_cells=20,
                   bulk_velocity=10.0, density=GAS.density, viscosity=GAS.viscosity)
f = solve(m, GAS, 10.0, inlet_k=1.0)
uc = np.array([axis_value(m, f.ux[i]) for i in range(m.nx)]) / 10.0
rows = [r for r in read_reference_csv("openfoam_v1912_developing_pipe_kepsilon.csv") if r["kind"] == "centreline"]
dev = [np.interp(float(r["x"]), m.x, uc) - float(r["U_over_U0"]) for r in rows]
print(f"developing centreline vs OpenFOAM: max |dev| {100 * np.abs(dev).max():.2f} % of U0 at {len(rows)} "
      f"stations; overshoot {uc.max():.3f} U0 at x = {m.x[uc.argmax()]:.2f} m")

errs = [cross_section_errors(*g) for g in GRIDS]
for name in ("ux", "uy", "uz", "G"):
    for norm, label in ((0, "L2"), (1, "max")):
        if name == "G" and norm == 1:
            continue
        _, order = _orders(errs, name, norm)
        print(f"MMS {name:2s} {label:3s} order on {GRIDS}: {np.round(order, 2)}")
