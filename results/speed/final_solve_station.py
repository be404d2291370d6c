"""The gas solve on a finished run's averaged final sources, again, with the final solves'
station extension or the plain one: which stations stay unconverged, and how one of them
iterates.

    python final_solve_station.py CHECKPOINT [--extension 4|16] [--watch STATION]

CHECKPOINT: a finished coupling checkpoint (e.g. the scene-h run of bench_scene_h_a5f8c66.log;
not committed).  The checkpoint keeps the final field, not the relaxed iterate the run's own
final solve took as k reference, so the solve is that of the run only up to that reference
(docs/numerics.md, "Gas solver").  Prints the solve's time, the unconverged stations, and for
the watched station each attempt's relaxation, step and iterations with its first and last
change.
"""
import argparse
import time

import numpy as np

import rans
import rans.solver as S
from eulag.config import Case
from eulag.coupling import CouplingLoop, read_checkpoint

ap = argparse.ArgumentParser()
ap.add_argument("checkpoint")
ap.add_argument("--extension", type=int, default=S.FINAL_STATION_EXTENSION)
ap.add_argument("--watch", type=int, default=None)
a = ap.parse_args()

meta, _ = read_checkpoint(a.checkpoint)
case = Case.from_attrs(meta["case"])
loop = CouplingLoop(case, checkpoint=a.checkpoint, resume=True)
avg = loop._computed_sources(loop.sample())
sources = loop._gas_sources({"momentum": avg["momentum"], "k": avg["k"], "k_ref": loop.gas.k,
                             "eps_ref": loop.gas.epsilon})
log = []
iterate = S._StationSolver.iterate


def watched(self, st, *args):
    ch = iterate(self, st, *args)
    if self.station == a.watch:
        log.append(((args[-1], bool(self.coupled), float(self.alpha_u)), ch))
    return ch


S._StationSolver.iterate = watched
n, g = case.numerics, case.gas
t = time.perf_counter()
field = rans.solve(loop.mesh, loop.gas_props, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, sources,
                   tol=n.gas_tolerance, max_iterations=n.gas_max_iterations, station_extension=a.extension)
t = time.perf_counter() - t
bad = np.flatnonzero(~field.station_converged)
print(f"extension {a.extension}: {t:.1f} s, converged {field.converged}, unconverged stations {bad.tolist()} "
      f"(x = {np.round(np.asarray(loop.mesh.x)[bad], 4).tolist()} m)")
if a.watch is not None:
    print(f"station {a.watch}: {len(log)} outer iterations in all")
    start = 0
    for i in range(1, len(log) + 1):
        if i == len(log) or log[i][0] != log[start][0]:
            (r, coupled, m), _ = log[start]
            print(f"  k-eps relaxation {r:g}, momentum {m:g}, {'coupled' if coupled else 'SIMPLEC'} step: "
                  f"{i - start} iterations, change {log[start][1]:.3g} -> {log[i - 1][1]:.3g}")
            start = i
