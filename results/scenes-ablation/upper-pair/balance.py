"""Vertical force balance of the particles over the last metre (2.56-3.56 m), by region:

    python balance.py RUN.nc [...]

their weight, the gas's vertical force on them (minus source_uy, the force they put into the gas)
and the net inter-particle collision force (four-way datasets), each integrated over the region's
cells [N per m of pipe] and as a fraction of the weight. What neither carries, the particles'
own vertical momentum flux (their flights between wall impacts) takes to the walls.
"""
import sys, numpy as np, xarray as xr
for p in sys.argv[1:]:
    ds = xr.open_dataset(p)
    w = ds.sel(x=slice(2.56, 3.56))
    A = ds["cell_area"].transpose("r", "theta").values
    y = ds["y"].values
    def mean(v):
        a = w[v].transpose("x", "r", "theta").values if v in w else None
        return None if a is None else np.nanmean(a, axis=0)
    conc = mean("particle_concentration"); sy = mean("source_uy")
    cy = mean("particle_collision_force_y")
    print(p)
    for name, m in (("upper half", y > 0), ("lower half", y < 0), ("core r<0.6R upper", (y > 0) & (np.hypot(y, ds['z'].values) < 0.6 * 0.01525))):
        W = np.sum((conc * 9.81 * A)[m]); G = np.sum((-sy * A)[m]); C = np.sum((cy * A)[m]) if cy is not None else float('nan')
        print(f"  {name:18s} weight {W:.4f} N/m, gas force on particles (up) {G:+.4f} N/m ({G / W:+.2f} of weight), collision force y {C:+.4f} N/m ({C / W:+.2f})")
