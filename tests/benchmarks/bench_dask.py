"""Lagrangian-pass wall time: local numba threads vs Dask workers (prints figures; not a test).

    python tests/benchmarks/bench_dask.py [--parcels 102400] [--repeats 2]

Fully developed 30.5 mm pipe (20 × 40 cross-section, U0 = 10 m/s, single-phase gas field),
Tsuji–Morikawa base particles (200 µm, 1020 kg/m3, η = 2.2, Δγ = 1.5°), everything on,
including inter-particle collisions (cell statistics from a preliminary pass).  The pass is
split into 32 batches of 3200 parcels, 4 batches per super-batch: 8 super-batches, so two
workers get four each.  Three set-ups:

  local   particles.track in this process, 1 numba thread
  dask-1  DaskTracker on a LocalCluster of 1 worker process × 1 thread
  dask-2  DaskTracker on a LocalCluster of 2 worker processes × 1 thread each

For each, a first pass (numba compile of the super-batch driver in that process, plus the
pass) is reported apart; then ``repeats`` rounds of warm passes are timed, the three set-ups
interleaved in every round (best and mean reported).  All passes must give bit-identical
sums, and no parcel may be lost.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numba
import numpy as np

import particles
from eulag.distributed import DaskTracker, dask_client
from rans import PipeMesh, solve
from rans import kepsilon as ke
from rans.solver import GasProperties


def setup(parcels):
    gas_props = GasProperties(1.205, 1.81e-5)
    mesh = PipeMesh.build(0.0305, 1.0, mode="periodic", radial_cells=20, azimuthal_cells=40)
    gas = solve(mesh, gas_props, 10.0, 1.0, ke.inlet_epsilon(1.0, 0.0305))
    spec = particles.ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 1.5)
    settings = particles.TrackSettings(batch_size=parcels // 32, batches_per_superbatch=4)
    first = particles.track(mesh, gas, spec, parcels=20000, seed=1, pass_index=0)
    stats = first.cell_statistics(gas)
    return mesh, gas, spec, stats, settings


def _cpu(client):
    """CPU seconds used so far by the tracking process(es): this one, or each worker."""
    if client is None:
        return {"local": time.process_time()}
    return client.run(time.process_time)


def _cpu_model():
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "?"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parcels", type=int, default=102400)
    ap.add_argument("--repeats", type=int, default=2)
    opt = ap.parse_args(argv)
    mesh, gas, spec, stats, settings = setup(opt.parcels)
    args = (mesh, gas, spec, particles.PhysicsOptions())
    kw = dict(parcels=opt.parcels, seed=1, pass_index=1, stats=stats, settings=settings)
    _, _, supers = particles.batch_plan(opt.parcels, settings)
    print(f"# bench_dask  ({platform.machine()}, {_cpu_model()}, {os.cpu_count()} cores, "
          f"numba {numba.__version__} ({numba.config.THREADING_LAYER} layer), "
          f"NUMBA_CPU_NAME={os.environ.get('NUMBA_CPU_NAME', '(host)')})")
    print(f"# pass: {opt.parcels} parcels, {len(supers)} super-batches, four-way, periodic 20x40 mesh; "
          f"load average before: {os.getloadavg()[0]:.2f}")

    def local(*a, **k):
        numba.set_num_threads(1)
        try:
            return particles.track(*a, **k)
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

    with dask_client(local_workers=1) as c1, dask_client(local_workers=2) as c2:
        c1.wait_for_workers(1)
        c2.wait_for_workers(2)
        setups = {"local, 1 thread": local, "dask, 1 worker x 1 thread": DaskTracker(c1),
                  "dask, 2 workers x 1 thread": DaskTracker(c2)}
        first, warm, result = {}, {k: [] for k in setups}, {}
        for name, tracker in setups.items():  # compile (the driver is not cacheable) + pass
            t0 = time.perf_counter()
            result[name] = tracker(*args, **kw)
            first[name] = time.perf_counter() - t0
        clients = {"local, 1 thread": None, "dask, 1 worker x 1 thread": c1, "dask, 2 workers x 1 thread": c2}
        cpu = {k: [] for k in setups}
        for _ in range(opt.repeats):  # interleaved, so a change of background load hits all alike
            for name, tracker in setups.items():
                c0 = _cpu(clients[name])
                t0 = time.perf_counter()
                s = tracker(*args, **kw)
                warm[name].append(time.perf_counter() - t0)
                c_1 = _cpu(clients[name])
                cpu[name].append([c_1[w] - c0[w] for w in c0])
                assert np.array_equal(s.total, result[name].total)
    ref = result["local, 1 thread"]
    c = ref.counts
    assert c["lost"] == 0 and c["injected"] == c["exited"] + c["stuck"]
    print(f"# {c['steps']:,} parcel-steps per pass, {c['particle_collisions']:,} inter-particle collisions")
    for name in setups:
        s, times = result[name], warm[name]
        same = all(np.array_equal(getattr(s, f), getattr(ref, f), equal_nan=True) for f in ("total", "var", "cov"))
        best = min(times)
        print(f"{name:28s} first pass {first[name]:6.2f} s (compile ~{max(first[name] - best, 0):5.2f} s);  "
              f"warm best {best:6.2f} s, mean {np.mean(times):6.2f} s;  bit-identical to local: "
              f"{'yes' if same else 'NO'}")
    print("# CPU seconds each tracking process got during the timed passes (wall x 1.0 = a whole core; "
          "less: the core was shared with other processes):")
    for name in setups:
        for t, per in zip(warm[name], cpu[name]):
            print(f"#   {name:28s} wall {t:6.2f} s, CPU per process " + ", ".join(f"{c:6.2f} s" for c in per)
                  + "  (share of a core: " + ", ".join(f"{c / t:.2f}" for c in per) + ")")
    loc = min(warm["local, 1 thread"])
    d1 = min(warm["dask, 1 worker x 1 thread"])
    d2 = min(warm["dask, 2 workers x 1 thread"])
    print(f"speed-up 1 -> 2 workers: {d1 / d2:.2f}x (target >= 1.7x)")
    print(f"Dask overhead on one worker vs local 1 thread: {100 * (d1 / loc - 1):+.1f} % (target <= 15 %)")
    print(f"# load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
