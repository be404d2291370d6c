"""Why the gas march slows beside a streamed pass: the march's wall and thread-CPU time on one
set of scene-h sources, alone / with the row-building callback only / beside a streamed pass /
beside a plain pass tracked in another thread / beside particles.bench in another process."""
import sys, time, threading, subprocess, json
import numpy as np, numba
import rans
from eulag.config import Case
from eulag.coupling import CouplingLoop
from particles import stream as pstream
from particles.stream import StreamedPass
from particles.tracking import track

case = Case.from_file("cases/scenes/scene_h.toml").replace(
    numerics={"parcels": 6000, "parcels_start": 6000, "max_passes": 4, "average_passes": 1})
loop = CouplingLoop(case, stream=False)
for _ in range(2):
    st = loop.step()
    print("pass", st.index, "gas", round(st.times["gas_solve"], 1), "lagr", round(st.times["lagrangian"], 1), flush=True)
src = loop._gas_sources(loop.sources)
n, g = case.numerics, case.gas
stats = loop.stats

def solve(on_station=None):
    t, c = time.perf_counter(), time.thread_time()
    f = rans.solve(loop.mesh, loop.gas_props, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, src, tol=n.gas_tolerance,
                   max_iterations=n.gas_max_iterations, on_station=on_station)
    return f, time.perf_counter() - t, time.thread_time() - c

def mk_stream(track_it=True):
    saved = StreamedPass._run
    if not track_it:
        StreamedPass._run = lambda self: None
    try:
        return StreamedPass(loop.mesh, loop.gas_props, loop.spec, loop.physics, parcels=30000, seed=1, pass_index=5,
                            stats=stats, settings=loop.settings, partner_stokes=loop.physics.partner_correlation == "cell")
    finally:
        StreamedPass._run = saved

def run(kind):
    if kind == "alone":
        f, w, c = solve()
    elif kind == "rows-only":
        s = mk_stream(False); f, w, c = solve(s.station); s.cancel()
    elif kind == "streamed":
        s = mk_stream(True); f, w, c = solve(s.station); s.cancel(wait=True)
    elif kind == "thread-track":
        stop = []
        def bg():
            numba.set_num_threads(1)
            track(loop.mesh, loop.gas, loop.spec, loop.physics, parcels=30000, seed=1, pass_index=5, stats=stats,
                  settings=loop.settings)
        th = threading.Thread(target=bg, daemon=True); th.start(); time.sleep(1.0)
        f, w, c = solve(); th.join()
    elif kind == "process-bench":
        p = subprocess.Popen([sys.executable, "-c", "import sys; sys.argv=['x','--rounds','12']; import runpy; runpy.run_module('particles.bench', run_name='__main__')"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(25)  # its compile
        f, w, c = solve(); p.kill(); p.wait()
    print(f"{kind:14s} wall {w:6.1f} s  march-thread CPU {c:6.1f} s  iterations {int(f.station_iterations.sum())}  -dp/dx {f.pressure_gradient.mean():.4f}", flush=True)

kinds = sys.argv[1].split(",") if len(sys.argv) > 1 else ["alone", "rows-only", "streamed", "thread-track", "process-bench"]
for r in range(int(sys.argv[2]) if len(sys.argv) > 2 else 2):
    for k in kinds:
        run(k)
