"""The weak pair along the vertical diameter of a scene's secondary flow: solenoidal or divergent?

    python upper_pair.py RUN.nc [RUN.nc ...]

For each dataset, at the analysis station (x = 3.555 m for the scenes), prints:

* the cells of the mirror-symmetrised stream function psi_s (the solenoidal in-plane flow;
  ``eulag.analysis``) at count thresholds of 10 % (the study's), 5, 2 and 1 % of max|psi_s|, with
  each cell's sign, peak fraction, area fraction and centre, no minimum area;
* along the vertical diameter, from the bottom wall to the top wall: the mirror-even raw u_y
  (what the study's u_y sign pattern reads), the u_y of the solenoidal flow curl(psi_s e_x), and
  their difference, the divergent (irrotational) part that the axial development drives
  (div u_in-plane = -du_x/dx), each with the spread of the dataset's replicas (the gas solved on
  each final pass's own sources) where it has them.

A four-cell flow has a solenoidal u_y that changes sign on the vertical diameter; a two-cell flow
with a divergent part can show a sign change of the raw u_y only.
"""
import sys

import numpy as np
import xarray as xr

from eulag import analysis as A


def _solenoidal_uy(geo, uy, uz):
    psi_s = A.mirror_symmetrise_psi(A._stream_function(geo, uy, uz), geo.theta)
    ur, ut = A._psi_velocity(geo, psi_s)
    th = geo.theta[None, :]
    return psi_s, ur * np.sin(th) + ut * np.cos(th)


def lines(geo, uy, uz):
    psi_s, uy_sol = _solenoidal_uy(geo, uy, uz)
    y, raw = A._vertical_line(geo, A.mirror_average(uy, 1))
    _, sol = A._vertical_line(geo, A.mirror_average(uy_sol, 1))
    return psi_s, y, raw, sol


def report(path):
    ds = xr.open_dataset(path)
    x = 3.555
    geo = A.polar_section(ds)
    u_b = A.bulk_velocity(ds)
    uy, uz = A._field(ds, "gas_uy", x), A._field(ds, "gas_uz", x)
    psi_s, y, raw, sol = lines(geo, uy, uz)
    print(f"== {path}: x = {x} m, U_b = {u_b:.3g} m/s, max|psi_s| = {np.abs(psi_s).max():.3e} m2/s")
    total = geo.area.sum()
    for thr in (0.10, 0.05, 0.02, 0.01):
        cells = A.count_cells(psi_s, thr, geo.area, geo.y, geo.z)
        txt = "; ".join(f"{'+' if c['sign'] > 0 else '-'}{c['peak_fraction']:.3f} "
                        f"(area {c['area'] / total:.3f}, y/R {c['y'] / geo.radius:+.2f}, z/R {c['z'] / geo.radius:+.2f})"
                        for c in cells)
        print(f"  cells above {thr:.0%} of max|psi_s|: {len(cells)}: {txt}")
    reps = A.dataset_replicas(ds)
    rep_lines = [lines(geo, ry, rz) for ry, rz in reps]
    print(f"  vertical diameter (u_y in % of U_b; replicas: {len(reps)}, min..max)")
    print("   y/R     raw u_y            solenoidal u_y     divergent")
    for i in range(y.size):
        def span(j):
            if not rep_lines:
                return ""
            v = [100 * rl[j][i] / u_b for rl in rep_lines]
            return f" [{min(v):+.3f}..{max(v):+.3f}]"
        print(f"  {y[i] / geo.radius:+.3f} {100 * raw[i] / u_b:+.3f}{span(2)} {100 * sol[i] / u_b:+.3f}{span(3)} "
              f"{100 * (raw[i] - sol[i]) / u_b:+.3f}")
    m = A.pattern_metrics(ds, x)
    print(f"  study metrics: cells {m['count_symmetrised']}, index {m['mode_index']:.2f}, "
          f"u_y signs {A.sign_text(m['uy_sign_pattern'])} (solenoidal {A.sign_text(m['uy_solenoidal_sign_pattern'])}), "
          f"{m['main_pair_sense']}; second pair {100 * m['second_pair_fraction']:.1f} % at y/R {m['second_pair_y']:+.2f}")
    if reps:
        rm = A.replica_pattern_metrics(reps, x, template=ds)
        for i, r in enumerate(rm["replicas"]):
            print(f"  replica {i + 1}: cells {r['count_symmetrised']}, index {r['mode_index']:.2f}, u_y signs "
                  f"{A.sign_text(r['uy_sign_pattern'])} (solenoidal {A.sign_text(r['uy_solenoidal_sign_pattern'])}), "
                  f"second pair {100 * r['second_pair_fraction']:.1f} % at y/R {r['second_pair_y']:+.2f}")


if __name__ == "__main__":
    for p in sys.argv[1:]:
        report(p)
