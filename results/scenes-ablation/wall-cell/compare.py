"""The diagnostics NOTES.md quotes beside the pattern metrics, for each run given:

    python results/scenes-ablation/wall-cell/compare.py RUN.nc [RUN.nc ...]

At the station nearest x = 3.56 m: the axis k (ring 0, mean over θ) [m²/s²], the wall ring's
mean particle concentration against the section mean [kg/m³], the summed wall-collision rate
and the mean wall-impact speed [m/s], the area-mean axial momentum source of the wall ring and
of the interior [N/m³]; and the pipe-mean −dp/dx of the last pass [Pa/m], the passes and the
wall time. The pattern metrics come from ``results/scenes-ablation/section_metrics.py``.
"""

import sys

import numpy as np
import xarray as xr

X = 3.56


def main(paths):
    for path in paths:
        d = xr.open_dataset(path)
        i = int(np.argmin(np.abs(d.x.values - X)))
        a = d.cell_area.values
        k = d.gas_k.isel(x=i).values
        c = d.particle_concentration.isel(x=i).values
        s = d.source_ux.isel(x=i).values
        print(f"{path} (commit {d.attrs.get('eulag_commit')})")
        print(f"  axis k {k[0].mean():.4g} m2/s2; wall-ring concentration {(c[-1] * a[-1]).sum() / a[-1].sum():.3g} "
              f"against the section mean {(c * a).sum() / a.sum():.3g} kg/m3")
        print(f"  wall collision rate (sum) {float(d.wall_collision_rate.isel(x=i).sum()):.3g}, mean impact speed "
              f"{float(d.wall_impact_speed_mean.isel(x=i).mean()):.3g} m/s")
        print(f"  axial momentum source: wall ring {(s[-1] * a[-1]).sum() / a[-1].sum():.3g}, interior "
              f"{(s[:-1] * a[:-1]).sum() / a[:-1].sum():.3g} N/m3")
        print(f"  pipe-mean -dp/dx {float(d.pressure_gradient_history.values[-1]):.5g} Pa/m; "
              f"{int(d.attrs['coupling_passes'])} passes, {float(d.attrs['time_total']):.0f} s")


if __name__ == "__main__":
    main(sys.argv[1:])
