"""Deviation of the fully developed k-epsilon profile from the pipe DNS (report, no pass mark).

    python tests/reports/dns_deviation.py

DNS: El Khoury et al. (2013), Re_tau = 550 (Re_b = 19,000) and 1000 (Re_b = 37,700), in
../shared/data.  The solver runs at the DNS bulk Reynolds number (periodic mode, 20 x 40
cells, wall cell at y+ 30) and the mean velocity U/U_b is compared at the DNS points with
y+ >= 30 (the wall-function model says nothing closer to the wall).
"""

import csv
import math
from pathlib import Path

import numpy as np

from rans import GasProperties, PipeMesh, solve
from rans.profiles import axis_value, radial_profile

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
RHO, MU, D = 1.205, 1.81e-5, 0.0305


def read(name):
    with open(DATA / name) as fh:
        lines = [ln for ln in fh if not ln.startswith("#")]
    return list(csv.DictReader(lines))


for name, re_b in (("pipe_dns_elkhoury2013_Retau550.csv", 19000.0), ("pipe_dns_elkhoury2013_Retau1000.csv", 37700.0)):
    rows = read(name)
    one_minus_r = np.array([float(r["one_minus_r"]) for r in rows])
    yplus = np.array([float(r["y_plus"]) for r in rows])
    u_dns = np.array([float(r["Uz_over_Ub"]) for r in rows])
    U = re_b * MU / (RHO * D)
    m = PipeMesh.build(D, 1.0, "periodic", radial_cells=20, azimuthal_cells=40, bulk_velocity=U, density=RHO, viscosity=MU)
    f = solve(m, GasProperties(RHO, MU), U, tol=1e-8)
    col = f.ux[0].mean(axis=1)
    sel = yplus >= 30.0
    u = radial_profile(m, col, (1.0 - one_minus_r[sel]) * m.radius) / U
    dev = u - u_dns[sel]
    uc = axis_value(m, f.ux[0]) / U
    print(f"{name}: Re_b = {re_b:.0f}; U_c/U_b k-eps {uc:.3f}, DNS {u_dns[-1]:.3f}; "
          f"deviation (y+ >= 30) mean {dev.mean():+.3f}, max |.| {np.abs(dev).max():.3f} of U_b "
          f"at 1 - r/R = {one_minus_r[sel][np.abs(dev).argmax()]:.3f}; friction factor {f.friction_factor[0]:.5f}")
