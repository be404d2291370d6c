"""Δp against the Coulomb coefficient μ over long windows: block means (as eta_window.py) and the
slug and regime numbers of the study, for the runs given."""
import sys, json, math
import numpy as np, xarray as xr
sys.path.insert(0, "results/strauss-filled/grain-weights/eta-6s")  # run from the repository root: python results/strauss-filled/grain-weights/mu-15s/mu_window.py RUN.nc ...
from eta_window import block_mean
from eulag.slug import summarize
from eulag.studies.strauss import classify_regime
rows = []
for path in sys.argv[1:]:
    with xr.open_dataset(path) as ds:
        c = json.loads(ds.attrs["case"]); mu = c["grains"]["friction"]
        t = ds["time"].values
        for t0 in (16.25, 19.25):
            dp, se, nb = block_mean(t, ds["pressure_drop"].values, t0, 0.5)
            dp1, se1, _ = block_mean(t, ds["pressure_drop"].values, t0, 1.0)
            n, nse, _ = block_mean(t, ds["grains_in_tube"].values, t0, 0.5)
            s = summarize(ds, t_min=t0); r = classify_regime(ds, t_min=t0)
            print(f"mu {mu:g} t>={t0}: dp {dp:.0f} ± {se:.0f} (1 s blocks ± {se1:.0f}), grains {n:.0f} ± {nse:.0f}, "
                  f"per grain {dp/n:.4f}; regime {r['regime']} (dense {r['dense_share']:.2f}, moving all {r['moving_share_all']:.2f}, "
                  f"outflow/feed {r['outflow_per_feed']:.2f}); slugs {s['slug_records']} records, {s['slug_velocity_m_s']:.3f} m/s, "
                  f"{s['slug_grains']:.0f} grains, {100*s['slug_length_m']:.1f} cm; wall {ds.attrs['wall_time_s']:.0f} s, lost {ds.attrs['grains_lost']}")
        g = ds["grains_in_tube"].values; dpv = ds["pressure_drop"].values
        print("  per second:", [(round(a, 2), round(float(dpv[(t >= a) & (t < a + 1)].mean())), round(float(g[(t >= a) & (t < a + 1)].mean()))) for a in np.arange(13.25, 28.25, 1.0)])
