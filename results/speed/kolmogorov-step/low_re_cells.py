"""Cells of a converged dataset where the k-eps turbulence has died out (k^2/(nu eps) < 39, where
the Kolmogorov time sqrt(nu/eps) exceeds T_L = C_T (2k/3)/eps and the "kolmogorov" step rule
binds), by stretch of the pipe.

    python results/speed/kolmogorov-step/low_re_cells.py RUN.nc
"""
import sys

import numpy as np
import xarray as xr

C_T = 0.24
d = xr.open_dataset(sys.argv[1])
nu = float(d.attrs["case_gas_viscosity"]) / float(d.attrs["case_gas_density"])
k, e, x = d.gas_k.values, d.gas_epsilon.values, d.x.values
c = d.particle_concentration.values
ret = k * k / (nu * e)
t_l = C_T * (2.0 * k / 3.0) / e
tau_eta = np.sqrt(nu / e)
low = ret < 39.0
print(f"{sys.argv[1]}: nu = {nu:.4g} m2/s; cells with k^2/(nu eps) < 39: {low.mean():.3f} of all, "
      f"holding {(c * low).sum() / c.sum():.3f} of the particle mass; k at its floor (<= 1.0001e-8): "
      f"{(k <= 1.0001e-8).mean():.4f} of all")
print(" x range [m]   share of the range's cells   particle mass share   smallest T_L [ms]   median T_L there [ms]")
for a, b in ((0, 0.1), (0.1, 0.5), (0.5, 1.0), (1, 2), (2, 4)):
    m = (x >= a) & (x < b)
    lo = low[m]
    tl = t_l[m]
    print(f" {a:3.1f}-{b:3.1f}      {lo.mean():6.3f}                     {(c[m] * lo).sum() / c[m].sum():6.3f}"
          f"              {tl.min() * 1e3:8.4f}            {np.median(tl[lo]) * 1e3 if lo.any() else float('nan'):8.4f}")
print(f"in those cells: median tau_eta/T_L {np.median(tau_eta[low] / t_l[low]):.2f}; 2k/3 median "
      f"{np.median(2 * k[low] / 3):.4f} m2/s2, particle-mass-weighted {np.sum((2 * k / 3 * c)[low]) / c[low].sum():.4f}")
for v in ("particle_ux_rms", "particle_uy_rms", "particle_uz_rms"):
    a = d[v].values
    m = low & np.isfinite(a) & (c > 0)
    print(f"  {v}: median {np.median(a[m]):.3f} m/s, mass-weighted mean {np.sum(a[m] * c[m]) / c[m].sum():.3f} m/s")
