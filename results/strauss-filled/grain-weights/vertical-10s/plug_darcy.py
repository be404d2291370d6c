"""The plug velocity of a slug/plug run against Darcy's law through the plug, and how sharply it
depends on the plug's gas resistance:

    python results/strauss-filled/grain-weights/vertical-10s/plug_darcy.py RUN.nc [--x0 0.05 --x1 0.40] [--windows 2,4,7,10]

Gas and grains together conserve volume (the pressure's storage term neglected): the mixture's
flux j = φ v_g + (1 − φ) u is the same at every x of a steady tube, the gas's v_s plus the
feed's solids flux ṁ/(ρ_s A_t) at the inlet. A plug (slices of porosity < 0.6,
eulag.slug.SLUG_POROSITY, around a catalogued slug centre with ≥ 100 grains) fills the tube, so
the gas flux relative to its grains is q = φ (v_g − u) = j − u, and Darcy's law (eq. 3, with
Carman–Kozeny κ, eq. 4) gives the same flux from the pressure gradient across the plug,
q = κ(φ) G / η. Hence

    u = j − κ(φ) G / η,    d ln u / d ln(κ G) = −q / u.

With q close to j the grains' velocity is a small difference. This prints, per time window: the
plug velocity as the study measures it (the catalogued centres' displacement), Δp and the grains
in the tube (means over the window's records), and the plug-averaged φ, grain velocity u and
G = −∂P'/∂x. It then prints both sides of the flux balance, the amplification q/u, and the change
of κG (and the porosity change alone that gives it) that moves u by 30 %. The inputs are
cross-section means of 3.5 mm slices (the dataset's fields), with κ of the slice-mean porosity.
The solids flux is the feed's (an open tube in a steady state).
"""

import argparse
import json

import numpy as np
import xarray as xr

from darcy.permeability import carman_kozeny
from eulag.slug import SLUG_POROSITY, summarize


def plugs(ds, t0, t1, x0, x1, min_grains=100):
    """Per catalogued plug record in the window: slice-mean φ, grain velocity u, −∂P'/∂x G over
    the run of slices with φ < SLUG_POROSITY that holds its centre."""
    x = ds["x"].values
    t = ds["time"].values
    phi, u, p = ds["porosity"].values, ds["grain_velocity"].values, ds["gas_pressure"].values
    G = -np.gradient(p, x, axis=1)
    st, sx, sg = ds["slug_time"].values, ds["slug_position"].values, ds["slug_grains"].values
    pick = (st >= t0) & (st <= t1) & (sg >= min_grains) & (sx >= x0) & (sx <= x1)
    rows = []
    for i in np.flatnonzero(pick):
        k = int(np.argmin(np.abs(t - st[i])))
        j = int(np.argmin(np.abs(x - sx[i])))
        if phi[k, j] >= SLUG_POROSITY:
            continue
        a = j
        while a > 0 and phi[k, a - 1] < SLUG_POROSITY:
            a -= 1
        b = j
        while b < len(x) - 1 and phi[k, b + 1] < SLUG_POROSITY:
            b += 1
        s = slice(a, b + 1)
        rows.append((phi[k, s].mean(), u[k, s].mean(), G[k, s].mean(), sg[i]))
    return np.array(rows).reshape(-1, 4)


def catalogue_velocity(ds, t0, t1, x0, x1):
    """The plug velocity as the study measures it (eulag.slug.summarize: the catalogued centres'
    displacement), from the records and catalogue entries with t0 <= t <= t1."""
    t, st = ds["time"].values, ds["slug_time"].values
    part = ds.isel(time=(t >= t0) & (t <= t1), slug=(st >= t0) & (st <= t1))
    return summarize(part, x_window=(x0, x1), t_min=t0)["slug_velocity_m_s"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run")
    ap.add_argument("--x0", type=float, default=0.05)
    ap.add_argument("--x1", type=float, default=0.40)
    ap.add_argument("--windows", default="2,4,7,10")
    a = ap.parse_args()
    ds = xr.open_dataset(a.run)
    c = json.loads(ds.attrs["case"])
    vs, eta, d = c["gas"]["superficial_velocity_m_s"], c["gas"]["viscosity_Pa_s"], c["grains"]["diameter_m"]
    area = np.pi * c["tube"]["diameter_m"] ** 2 / 4.0
    solids = c["feed"]["mass_flow_kg_h"] / 3600.0 / (c["grains"]["density_kg_m3"] * area)
    j = vs + solids
    edges = [float(w) for w in a.windows.split(",")]
    print(f"{a.run}: v_s = {vs} m/s, feed solids flux {solids:.4f} m/s, j = {j:.4f} m/s, eta = {eta} Pa s, "
          f"d = {d} m; plugs centred in {a.x0}-{a.x1} m")
    print("window [s] | plug records | plug velocity (catalogue) [m/s] | dp [Pa] | grains in tube | phi | "
          "u [m/s] | G [Pa/m] | q = j - u [m/s] | kappa(phi) G/eta [m/s] | q/u | kappa G change for u -30 % | "
          "same by porosity alone")
    t = ds["time"].values
    for t0, t1 in zip(edges[:-1], edges[1:]):
        sel = (t >= t0) & (t <= t1)
        dp, grains = float(ds["pressure_drop"].values[sel].mean()), float(ds["grains_in_tube"].values[sel].mean())
        r = plugs(ds, t0, t1, a.x0, a.x1)
        if not len(r):
            print(f"{t0:g}-{t1:g} | 0 | | {dp:.0f} | {grains:.0f} |")
            continue
        phi, u, G = r[:, 0].mean(), r[:, 1].mean(), r[:, 2].mean()
        q_kin = j - u
        q_darcy = float(np.mean(carman_kozeny(r[:, 0], d) * r[:, 2] / eta))
        amp = q_kin / u
        dkg = 0.3 / amp  # relative change of kappa G that changes u by -30 %
        dlnk = 3.0 / phi + 2.0 / (1.0 - phi)  # d ln kappa / d phi of Carman-Kozeny
        print(f"{t0:g}-{t1:g} | {len(r)} | {catalogue_velocity(ds, t0, t1, a.x0, a.x1):.3f} | {dp:.0f} | {grains:.0f} | "
              f"{phi:.4f} | {u:.3f} | {G:.0f} | {q_kin:.3f} | {q_darcy:.3f} | {amp:.2f} | +{100 * dkg:.1f} % | "
              f"+{np.log1p(dkg) / dlnk:.4f}")


if __name__ == "__main__":
    main()
