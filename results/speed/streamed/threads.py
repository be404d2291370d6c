"""Parallel efficiency of a plain pass of scene h (studies' grid, 30,000 parcels): the same pass
tracked on one and on two numba threads, alternately."""
import time, numba
from eulag.config import Case
from eulag.coupling import CouplingLoop
from particles.tracking import track
case = Case.from_file("cases/scenes/scene_h.toml").replace(
    numerics={"parcels": 6000, "parcels_start": 6000, "max_passes": 4, "average_passes": 1})
loop = CouplingLoop(case, stream=False)
for _ in range(2):
    loop.step()
for r in range(2):
    for th in (2, 1):
        numba.set_num_threads(th)
        t, c = time.perf_counter(), time.process_time()
        s = track(loop.mesh, loop.gas, loop.spec, loop.physics, parcels=30000, seed=1, pass_index=5, stats=loop.stats,
                  settings=loop.settings)
        print(f"{th} threads: {time.perf_counter() - t:.1f} s wall, {time.process_time() - c:.1f} s CPU", flush=True)
