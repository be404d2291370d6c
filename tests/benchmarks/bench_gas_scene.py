"""Gas-solve time per coupling pass on the base case and on scene h's particle sources.

    python tests/benchmarks/bench_gas_scene.py [--scene-checkpoint PATH] [--base-checkpoint PATH]
                         [--passes 2] [--parcels 3000] [--repeat 1] [--direct-coupled]
                         [--warm-from PATH]

Each case's gas solve (``rans.solve`` with the coupling loop's settings, at the case's own grid:
the studies' 400 x 20 x 40 cells for both shipped files) is timed on relaxed particle sources:

* read from a coupling checkpoint (``--scene-checkpoint``, ``--base-checkpoint``: the
  ``<output>.checkpoint`` that ``eulag run CASE.toml`` writes after every pass; its relaxed
  sources, as the loop hands them to the gas solver through ``CouplingLoop._gas_sources``), or
* made here: ``--passes`` coupling passes of the case with ``--parcels`` parcels (scene h:
  about 3 min per pass on 2 cores, most of it the gas solves being measured), the sources
  relaxed after the last of them.

Each solve's time is printed as wall clock (CPU time): the gas solve runs on one thread.

A checkpoint of a late pass is the realistic test (strong, relaxed sinks; e.g. ``eulag run``
of cases/scenes/scene_h.toml with ``numerics.parcels = parcels_start = 6000`` and
``max_passes = 12`` in a copy of the file).  Printed per case: the single-phase solve, then
each repetition of the solve on the sources: wall time, stations that kept the coupled
cross-flow step, outer iterations, -dp/dx, whether it converged, and the factorisations/solves
of the coupled step's lagged SuperLU (``rans.linalg.LaggedSparseLU``).  ``--direct-coupled``
factorises every coupled-step matrix (the former path), and ``--plain`` iterates the stations
without Anderson mixing, for comparison; timings on a shared
machine are noisy: run both, interleaved, several times.

``--warm-from PATH`` (with ``--only`` and that case's checkpoint): the checkpoint of the pass
before.  Its sources are solved first (cold, untimed: the converged field with the face fluxes
of every station, as the loop would hold it), then each repetition times a cold solve and a
solve warm-started from that field (``rans.solve(initial=...)``), and prints both solves'
outer iterations and their largest difference per field, relative to the field's maximum, over
all stations and over the stations upstream of the first one where u_x, k, epsilon or -dp/dx
part by more than 1e-4 of their maximum (which, with its retries, is printed).
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

import rans
from eulag.config import CASES_DIR, Case
from eulag.coupling import CouplingLoop, build_mesh
from rans import linalg, solver

BASE = CASES_DIR / "tsuji_morikawa_200um.toml"
SCENE_H = CASES_DIR / "scenes" / "scene_h.toml"


def _sources_from_checkpoint(path):
    """(case, rans.Sources) of a coupling checkpoint: its relaxed sources as the loop passes them on."""
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files if k.startswith("src_") or k == "meta"}
    meta = json.loads(bytes(data["meta"]).decode())
    case = Case.from_attrs(meta["case"])
    s = {k[4:]: v for k, v in data.items() if k.startswith("src_")}
    if "momentum" not in s:
        raise SystemExit(f"{path}: no particle sources in the checkpoint (pass {meta['pass_index']})")
    src = rans.Sources(momentum=s["momentum"], k=s["k"], epsilon=np.zeros_like(s["k"]), k_reference=s["k_ref"],
                       c_eps3=case.physics.c_eps3, drag=s.get("drag"), velocity_reference=s.get("u_ref"))
    return case, src, f"checkpoint {path} (pass {meta['pass_index']}, relaxation {meta['alpha']:g})"


def _sources_from_passes(path, passes, parcels):
    case = Case.from_toml(path).replace(numerics={"parcels": parcels, "parcels_start": parcels,
                                                  "max_passes": max(passes + 1, 2), "average_passes": 1})
    loop = CouplingLoop(case)
    t = time.perf_counter()
    for _ in range(passes):
        loop.step()
    times = ", ".join(f"{v:.1f}" for v in loop.history.time_gas)
    return case, loop._gas_sources(loop.sources), (
        f"{passes} passes with {parcels} parcels made here ({time.perf_counter() - t:.0f} s; their gas solves "
        f"{times} s), relaxation {loop.alpha:g}")


class _Elapsed:
    """Wall-clock and CPU time of a solve; formats as 'WALL (CPU cpu)'.  The gas solve runs on
    one thread, so its CPU time is the steadier figure on a shared or virtual machine (wall
    clocks of identical solves varied by +-15 % on the 2-core VM on some days)."""

    def __init__(self, wall, cpu):
        self.wall, self.cpu = wall, cpu

    def __format__(self, spec):
        return f"{self.wall:{spec}} (CPU {self.cpu:{spec}})"


def _solve(case, sources, initial=None):
    n, g = case.numerics, case.gas
    mesh = build_mesh(case)
    gas = rans.GasProperties(density=g.density, viscosity=g.viscosity)
    t, c = time.perf_counter(), time.process_time()
    f = rans.solve(mesh, gas, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, sources, tol=n.gas_tolerance,
                   max_iterations=n.gas_max_iterations, initial=initial)
    return f, _Elapsed(time.perf_counter() - t, time.process_time() - c)


def _line(what, f, t):
    return (f"  {what}: {t:.1f} s, converged {f.converged} ({int((~f.station_converged).sum())} stations not), "
            f"coupled step at {int(f.station_coupled.sum())} stations, iterations {int(f.station_iterations.sum())} "
            f"(max {int(f.station_iterations.max())} per station), -dp/dx {f.pressure_gradient.mean():.4f} Pa/m")


def bench_warm(name, case, sources, origin, previous, repeat):
    """Cold against warm-started solves of ``sources``, warm from the converged solve of ``previous``."""
    _, prev_src, prev_origin = _sources_from_checkpoint(previous)
    print(f"{name}: sources from {origin}; warm start from the solve on {prev_origin}")
    start, t0 = _solve(case, prev_src)
    print(_line("previous pass's sources (cold, the warm start)", start, t0))
    for r in range(repeat):
        cold, tc = _solve(case, sources)
        print(_line(f"[{r + 1}/{repeat}] cold", cold, tc))
        warm, tw = _solve(case, sources, initial=start)
        print(_line(f"[{r + 1}/{repeat}] warm", warm, tw))
    _compare(cold, warm)


def _compare(cold, warm):
    """Largest warm - cold difference per field, relative to the field's maximum: over all stations,
    and over those upstream of the first station where u_x, k, epsilon or -dp/dx part by more
    than 1e-4 of their maximum (the cross flow, ~1e-3 U_b, is held to the tolerance on U_b only)."""
    per = {}
    for v in ("ux", "uy", "uz", "p", "k", "epsilon", "pressure_gradient"):
        a, b = np.asarray(getattr(cold, v)), np.asarray(getattr(warm, v))
        per[v] = np.abs(a - b).reshape(a.shape[0], -1).max(axis=1) / np.abs(a).max()
    part = np.flatnonzero(np.max([per[v] for v in ("ux", "k", "epsilon", "pressure_gradient")], axis=0) > 1e-4)
    nx = per["ux"].size
    i0 = int(part[0]) if part.size else nx
    print(f"  warm - cold, max |difference| / max |field|: all stations / stations before {i0}")
    print("   " + ", ".join(f"{v} {d.max():.2g} / {d[:i0].max() if i0 else 0.0:.2g}" for v, d in per.items()))
    if part.size:
        x = cold.mesh.x
        c, w = cold, warm
        print(f"  they part at station {i0} (x = {x[i0]:.3f} m): iterations cold {c.station_iterations[i0]} warm "
              f"{w.station_iterations[i0]}, coupled step {bool(c.station_coupled[i0])}/{bool(w.station_coupled[i0])}, "
              f"converged {bool(c.station_converged[i0])}/{bool(w.station_converged[i0])}; the fields differ by "
              f"more than 1e-4 at {part.size} of {nx} stations, over x = {x[part[0]]:.3f}-{x[part[-1]]:.3f} m")


class _CountedCoupled:
    """Totals of the coupled step's lagged factorisations made while active."""

    def __enter__(self):
        self.made = []
        self._orig = linalg.LaggedSparseLU.__init__
        made, orig = self.made, self._orig

        def init(lu, *a, **kw):
            orig(lu, *a, **kw)
            made.append(lu)

        linalg.LaggedSparseLU.__init__ = init
        return self

    def __exit__(self, *exc):
        linalg.LaggedSparseLU.__init__ = self._orig

    def text(self):
        if not self.made:
            return "coupled step: direct SuperLU"
        return "coupled step: {} factorisations for {} solves".format(
            sum(f.factorisations for f in self.made), sum(f.solves for f in self.made))


def bench(name, case, sources, origin, repeat, save=None):
    print(f"{name}: {case.numerics.axial_cells} x {case.numerics.radial_cells} x "
          f"{case.numerics.azimuthal_cells} cells; sources from {origin}")
    single, t1 = _solve(case, None)
    print(f"  single phase: {t1:.1f} s, {int(single.station_iterations.sum())} iterations, "
          f"-dp/dx {single.pressure_gradient.mean():.3f} Pa/m")
    out = None
    for r in range(repeat):
        with _CountedCoupled() as counted:
            f, t = _solve(case, sources)
        print(f"  with the particle sources [{r + 1}/{repeat}]: {t:.1f} s per gas solve, converged {f.converged}, "
              f"stations with the coupled step {int(f.station_coupled.sum())}, iterations "
              f"{int(f.station_iterations.sum())}, -dp/dx {f.pressure_gradient.mean():.4f} Pa/m; {counted.text()}")
        out = f
    if save is not None:
        np.savez(save, **{v: getattr(out, v) for v in ("ux", "uy", "uz", "p", "k", "epsilon", "pressure_gradient",
                                                       "station_coupled", "station_iterations")})
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python tests/benchmarks/bench_gas_scene.py",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--scene-checkpoint", type=Path, help="coupling checkpoint of scene h (its relaxed sources)")
    ap.add_argument("--base-checkpoint", type=Path, help="coupling checkpoint of the base case")
    ap.add_argument("--passes", type=int, default=2, help="passes run here for a case without a checkpoint")
    ap.add_argument("--parcels", type=int, default=3000, help="parcels per pass of those passes")
    ap.add_argument("--repeat", type=int, default=1, help="gas solves timed per case")
    ap.add_argument("--direct-coupled", action="store_true",
                    help="factorise every coupled-step matrix (no lagged SuperLU), for comparison")
    ap.add_argument("--plain", action="store_true",
                    help="iterate the stations without Anderson mixing (rans.solver.ANDERSON_DEPTH = 0), for comparison")
    ap.add_argument("--only", choices=("base", "scene"), help="one of the two cases")
    ap.add_argument("--save", type=Path, help="write the last solve's fields to SAVE-<base|scene>.npz")
    ap.add_argument("--warm-from", type=Path,
                    help="checkpoint of the pass before (with --only and that case's checkpoint): cold against "
                         "warm-started solves")
    a = ap.parse_args(argv)
    solver.REUSE_COUPLED_FACTORISATION = not a.direct_coupled
    if a.plain:
        solver.ANDERSON_DEPTH = 0
    if a.warm_from is not None and (a.only is None or (a.scene_checkpoint if a.only == "scene" else a.base_checkpoint)
                                    is None):
        ap.error("--warm-from needs --only and that case's checkpoint")
    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}")
    for name, path, ckpt in (("base case", BASE, a.base_checkpoint), ("scene h", SCENE_H, a.scene_checkpoint)):
        if a.only and not name.startswith(a.only):
            continue
        case, src, origin = (_sources_from_checkpoint(ckpt) if ckpt is not None
                             else _sources_from_passes(path, a.passes, a.parcels))
        if a.warm_from is not None:
            bench_warm(name, case, src, origin, a.warm_from, a.repeat)
            continue
        save = None if a.save is None else a.save.with_name(f"{a.save.stem}-{name.split()[0]}.npz")
        bench(name, case, src, origin, a.repeat, save)


if __name__ == "__main__":
    main()
