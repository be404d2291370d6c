"""Trace of a streamed pass beside the gas march (scene h, studies' grid): when the march
delivered each station, and when each call of the window tracker ran and which windows it swept;
then the same pass tracked after the march, for the parcel-steps per second of the two."""
import sys, time, json
import numpy as np, numba
import rans
from eulag.config import Case
from eulag.coupling import CouplingLoop
import particles.stream as ps
from particles.tracking import track

parcels = int(sys.argv[1]) if len(sys.argv) > 1 else 30000
case = Case.from_file("cases/scenes/scene_h.toml").replace(
    numerics={"parcels": 6000, "parcels_start": 6000, "max_passes": 4, "average_passes": 1})
loop = CouplingLoop(case, stream=False)
for _ in range(2):
    loop.step()
src = loop._gas_sources(loop.sources)
n, g = case.numerics, case.gas
T0 = [0.0]
calls, stations = [], []
orig = ps.make_window_tracker
def traced(physics):
    f = orig(physics)
    def g_(*a):
        t = time.perf_counter(); f(*a); calls.append((a[-2], a[-1], t - T0[0], time.perf_counter() - T0[0], numba.get_num_threads()))
    g_.eulag_variant = f.eulag_variant
    return g_
ps.make_window_tracker = traced
s = ps.StreamedPass(loop.mesh, loop.gas_props, loop.spec, loop.physics, parcels=parcels, seed=1, pass_index=5,
                    stats=loop.stats, settings=loop.settings, partner_stokes=loop.physics.partner_correlation == "cell")
st = s.station
def station(i, *a):
    st(i, *a); stations.append((i, time.perf_counter() - T0[0]))
T0[0] = time.perf_counter()
f = rans.solve(loop.mesh, loop.gas_props, g.bulk_velocity, g.inlet_k, g.inlet_epsilon, src, tol=n.gas_tolerance,
               max_iterations=n.gas_max_iterations, on_station=station)
t_march = time.perf_counter() - T0[0]
s.finish(f)
res = s.result()
t_all = time.perf_counter() - T0[0]
print(f"march {t_march:.1f} s, streamed pass done at {t_all:.1f} s; windows beside the march {s.windows_beside_march}")
for c in calls:
    print("call windows %3d-%3d  %7.2f -> %7.2f s  (%.2f s, %d threads)" % (c[0], c[1], c[2], c[3], c[3] - c[2], c[4]))
idx = [0, 50, 100, 150, 200, 250, 300, 350, 399]
print("stations delivered:", [(stations[i][0], round(stations[i][1], 1)) for i in idx if i < len(stations)])
busy = sum(min(c[3], t_march) - c[2] for c in calls if c[2] < t_march)
print(f"tracker busy beside the march: {busy:.1f} of {t_march:.1f} s")
loop.gas = f
t = time.perf_counter()
r2 = track(loop.mesh, f, loop.spec, loop.physics, parcels=parcels, seed=1, pass_index=5, stats=loop.stats, settings=loop.settings)
print(f"the same pass tracked after the march on {numba.get_num_threads()} threads: {time.perf_counter() - t:.1f} s")
