"""Grid-sequencing trial for scene h: converge the proxy grid, inject its relaxed sources and
collision statistics into the studies' grid, and continue there.  Trial code, not the product.
    python seq.py COARSE_MAXPASSES FINE_MAXPASSES"""
import sys, time, math
import numpy as np
from eulag.config import Case, CASES_DIR
import eulag.coupling as C

t_all = time.perf_counter()
fine_case = Case.from_toml(CASES_DIR / "scenes" / "scene_h.toml").replace(
    numerics={"parcels": 30000, "parcels_start": 30000, "max_passes": int(sys.argv[2])})
coarse_case = fine_case.replace(numerics={"axial_cells": 40, "radial_cells": 10, "azimuthal_cells": 20,
                                          "parcels": 4000, "parcels_start": 4000, "batch_size": 250,
                                          "max_passes": int(sys.argv[1]), "average_passes": 1})


def line(tag, loop, s, t0):
    crit = {c.name: c.value for c in loop.criteria} if loop.criteria else {}
    print(f"{tag} pass {s.index:3d} a={s.relaxation:.3g} res={s.residual:.3g} dp={s.pressure_gradient:.3f} "
          f"cm={loop.history.collision_momentum[-1]:+.4f} " + " ".join(f"{k[:10]}={v:.3g}" for k, v in crit.items())
          + f" tg={s.times['gas_solve']:.0f} tp={s.times['lagrangian']:.0f} t={time.perf_counter()-t0:.0f}", flush=True)


coarse = C.CouplingLoop(coarse_case, notify=lambda t: print("  NOTE", t, flush=True))
t0 = time.perf_counter()
for s in coarse:
    line("coarse", coarse, s, t0)
print("coarse converged", coarse.converged, "after", coarse.converged_at, "passes", coarse.pass_index,
      f"{time.perf_counter()-t0:.0f} s", flush=True)

cm, fm = coarse.mesh, C.build_mesh(fine_case)
ix = np.clip(np.searchsorted(cm.x_edges, fm.x) - 1, 0, cm.nx - 1)
ir = np.clip(np.searchsorted(cm.r_edges, fm.r) - 1, 0, cm.nr - 1)
it = np.clip((fm.theta // cm.dtheta).astype(int), 0, cm.nt - 1)
I, R, T = np.meshgrid(ix, ir, it, indexing="ij")
flat = (I * cm.nr + R) * cm.nt + T  # coarse cell of each fine cell, fine shape


def inj(a):  # a: coarse shape (..., nx, nr, nt) -> fine
    a = np.asarray(a)
    lead = a.shape[:-3]
    return a.reshape(lead + (-1,))[..., flat]


src = coarse.sources
gk = coarse.gas_relaxed if coarse.gas_relaxed is not None else coarse.gas
transferred = {"momentum": inj(src["momentum"]), "k": inj(src["k"]), "k_ref": inj(src["k_ref"]),
               "eps_ref": inj(src["eps_ref"])}
fine = C.CouplingLoop(fine_case, notify=lambda t: print("  NOTE", t, flush=True))
t0 = time.perf_counter()
fine.gas0, _, _ = fine._solve_gas(None)
fine.gas, tg, _ = fine._solve_gas(fine._gas_sources(transferred))
print(f"fine: first gas solve on the transferred sources {tg:.0f} s, -dp/dx {np.mean(fine.gas.pressure_gradient):.3f}",
      flush=True)
fine.sources = transferred
fine.sources["k_ref"] = fine.gas.k.copy()  # the sinks as rates were referred to the coarse k; now applied
st = coarse.stats
fine.stats = st[flat.ravel()].copy()
fine.stats_n_ref = coarse.stats_n_ref[flat.ravel()].copy()
fine.stats_n_count = coarse.stats_n_count[flat.ravel()].copy()
# pass_index starts past 2 so that the statistics blend rather than being replaced
fine.pass_index = 2
fine.alpha = coarse.alpha if len(sys.argv) < 4 else float(sys.argv[3])
print("fine alpha", fine.alpha, flush=True)
for s in fine:
    line("fine", fine, s, t0)
print("fine converged", fine.converged, "after", fine.converged_at, "passes", fine.pass_index,
      f"{time.perf_counter()-t0:.0f} s; all {time.perf_counter()-t_all:.0f} s", flush=True)
