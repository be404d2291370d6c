"""Gas-solve time per coupling pass on the base case and on scene h's particle sources.

    python tests/benchmarks/bench_gas_scene.py [--scene-checkpoint PATH] [--base-checkpoint PATH]
                         [--passes 2] [--parcels 3000] [--repeat 1] [--direct-coupled]

Each case's gas solve (``rans.solve`` with the coupling loop's settings, at the case's own grid:
the studies' 400 x 20 x 40 cells for both shipped files) is timed on relaxed particle sources:

* read from a coupling checkpoint (``--scene-checkpoint``, ``--base-checkpoint``: the
  ``<output>.checkpoint`` that ``eulag run CASE.toml`` writes after every pass; its relaxed
  sources, as the loop hands them to the gas solver through ``CouplingLoop._gas_sources``), or
* made here: ``--passes`` coupling passes of the case with ``--parcels`` parcels (scene h:
  about 3 min per pass on 2 cores, most of it the gas solves being measured), the sources
  relaxed after the last of them.

A checkpoint of a late pass is the realistic test (strong, relaxed sinks; e.g. ``eulag run``
of cases/scenes/scene_h.toml with ``numerics.parcels = parcels_start = 6000`` and
``max_passes = 12`` in a copy of the file).  Printed per case: the single-phase solve, then
each repetition of the solve on the sources: wall time, stations that kept the coupled
cross-flow step, outer iterations, -dp/dx, whether it converged, and the factorisations/solves
of the coupled step's lagged SuperLU (``rans.linalg.LaggedSparseLU``).  ``--direct-coupled``
factorises every coupled-step matrix (the former path), for comparison; timings on a shared
machine are noisy: run both, interleaved, several times.
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


def _solve(case, sources):
    n, g = case.numerics, case.gas
    mesh = build_mesh(case)
    gas = rans.GasProperties(density=g.density, viscosity=g.viscosity)
    t = time.perf_counter()
    f = rans.solve(mesh, gas, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, sources, tol=n.gas_tolerance,
                   max_iterations=n.gas_max_iterations)
    return f, time.perf_counter() - t


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
    ap.add_argument("--only", choices=("base", "scene"), help="one of the two cases")
    ap.add_argument("--save", type=Path, help="write the last solve's fields to SAVE-<base|scene>.npz")
    a = ap.parse_args(argv)
    solver.REUSE_COUPLED_FACTORISATION = not a.direct_coupled
    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}")
    for name, path, ckpt in (("base case", BASE, a.base_checkpoint), ("scene h", SCENE_H, a.scene_checkpoint)):
        if a.only and not name.startswith(a.only):
            continue
        case, src, origin = (_sources_from_checkpoint(ckpt) if ckpt is not None
                             else _sources_from_passes(path, a.passes, a.parcels))
        save = None if a.save is None else a.save.with_name(f"{a.save.stem}-{name.split()[0]}.npz")
        bench(name, case, src, origin, a.repeat, save)


if __name__ == "__main__":
    main()
