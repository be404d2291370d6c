"""Grid-sequencing trial for scene h: converge the case on a grid coarser by 2 in every
direction (200 x 10 x 20), carry its relaxed sources and collision statistics to the studies'
400 x 20 x 40 grid by linear interpolation between cell centres (convex weights: no new
extrema, no negative densities), and continue there.  Trial code, not the product.

    python seq_smooth.py COARSE_MAXPASSES FINE_MAXPASSES [OUT.npz]
"""
import sys
import time

import numpy as np

import eulag.coupling as C
from eulag.config import CASES_DIR, Case
from particles.layout import CS_OK

t_all = time.perf_counter()
fine_case = Case.from_toml(CASES_DIR / "scenes" / "scene_h.toml").replace(
    numerics={"max_passes": int(sys.argv[2])})
coarse_case = fine_case.replace(numerics={"axial_cells": 200, "radial_cells": 10, "azimuthal_cells": 20,
                                          "parcels": 30000, "average_passes": 1,
                                          "max_passes": int(sys.argv[1])})


def line(tag, loop, s, t0):
    crit = {c.name: c.value for c in loop.criteria} if loop.criteria else {}
    print(f"{tag} pass {s.index:3d} a={s.relaxation:.3g} res={s.residual:.3g} dp={s.pressure_gradient:.3f} "
          f"cm={loop.history.collision_momentum[-1]:+.4f} " + " ".join(f"{k[:10]}={v:.3g}" for k, v in crit.items())
          + f" tg={s.times['gas_solve']:.0f} tp={s.times['lagrangian']:.0f} t={time.perf_counter()-t0:.0f}", flush=True)


def weights_1d(src, dst, periodic_period=None):
    """(i0, i1, w1) so that value(dst) = (1 - w1) v[i0] + w1 v[i1]: linear between the source
    centres, constant beyond the end centres (or periodic)."""
    n = src.size
    if periodic_period is not None:
        s = np.concatenate([src[-1:] - periodic_period, src, src[:1] + periodic_period])
        j = np.clip(np.searchsorted(s, dst) - 1, 0, n)
        w = (dst - s[j]) / (s[j + 1] - s[j])
        return (j - 1) % n, j % n, w
    j = np.clip(np.searchsorted(src, dst) - 1, 0, n - 2)
    w = np.clip((dst - src[j]) / (src[j + 1] - src[j]), 0.0, 1.0)
    return j, j + 1, w


def make_transfer(cm, fm):
    wx = weights_1d(cm.x, fm.x)
    wr = weights_1d(cm.r, fm.r)
    wt = weights_1d(cm.theta, fm.theta, 2 * np.pi)

    def along(a, axis, w):
        i0, i1, w1 = w
        shape = [1] * a.ndim
        shape[axis] = w1.size
        w1 = w1.reshape(shape)
        return (1.0 - w1) * np.take(a, i0, axis=axis) + w1 * np.take(a, i1, axis=axis)

    def transfer(a):  # (..., nx, nr, nt) coarse -> fine
        a = np.asarray(a, dtype=float)
        nd = a.ndim
        a = along(a, nd - 3, wx)
        a = along(a, nd - 2, wr)
        return along(a, nd - 1, wt)

    def transfer_cells(a):  # (ncell, m) flat coarse cells -> fine
        a = np.asarray(a, dtype=float)
        m = a.shape[1]
        b = a.reshape(cm.shape + (m,)).transpose(3, 0, 1, 2)
        return np.ascontiguousarray(transfer(b).reshape(m, -1).T)

    return transfer, transfer_cells


coarse = C.CouplingLoop(coarse_case, notify=lambda t: print("  NOTE", t, flush=True))
t0 = time.perf_counter()
for s in coarse:
    line("coarse", coarse, s, t0)
t_coarse = time.perf_counter() - t0
print("coarse converged", coarse.converged, "after", coarse.converged_at, "passes", coarse.pass_index,
      f"{t_coarse:.0f} s (gas {coarse.timings['gas_solve']:.0f}, particles {coarse.timings['lagrangian']:.0f})",
      flush=True)

cm, fm = coarse.mesh, C.build_mesh(fine_case)
transfer, transfer_cells = make_transfer(cm, fm)
src = coarse.sources
moved = {"momentum": transfer(src["momentum"]), "k": transfer(src["k"]), "k_ref": transfer(src["k_ref"]),
         "eps_ref": transfer(src["eps_ref"])}
fine = C.CouplingLoop(fine_case, notify=lambda t: print("  NOTE", t, flush=True))
t0 = time.perf_counter()
fine.gas0, _, _ = fine._solve_gas(None)
fine.gas, tg, _ = fine._solve_gas(fine._gas_sources(moved))
print(f"fine: gas solve on the moved sources {tg:.0f} s, -dp/dx {np.mean(fine.gas.pressure_gradient):.3f} "
      f"(coarse {np.mean(coarse.gas.pressure_gradient):.3f})", flush=True)
fine.sources = moved
st = transfer_cells(coarse.stats)
st[:, CS_OK] = (st[:, CS_OK] > 0.5).astype(float)
fine.stats = st
fine.stats_n_ref = transfer_cells(coarse.stats_n_ref[:, None])[:, 0]
fine.stats_n_count = np.round(transfer_cells(coarse.stats_n_count[:, None])[:, 0])
fine.pass_index = 2  # the statistics blend rather than being replaced
print("fine alpha", fine.alpha, flush=True)
for s in fine:
    line("fine", fine, s, t0)
t_fine = time.perf_counter() - t0
print("fine converged", fine.converged, "after", fine.converged_at, "passes", fine.pass_index,
      f"{t_fine:.0f} s (gas {fine.timings['gas_solve']:.0f}, particles {fine.timings['lagrangian']:.0f}); "
      f"all {time.perf_counter()-t_all:.0f} s", flush=True)
if len(sys.argv) > 3:
    from eulag import runs  # noqa: F401  (dataset writing is the product's; here the loop's state)
    fine._save() if fine.checkpoint is not None else None
    np.savez(sys.argv[3], history_dp=np.asarray(fine.history.pressure_gradient),
             replicas=np.asarray(fine.replicas), rep_dp=np.asarray(fine.replica_pressure_gradients),
             ux=np.asarray(fine.gas.ux), uy=np.asarray(fine.gas.uy), uz=np.asarray(fine.gas.uz))
