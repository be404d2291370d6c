"""Benchmark of a Lagrangian pass: parcel-steps per second per core, warm; compile time apart.

    python -m particles.bench [--parcels N] [--rounds R]
    python -m particles.bench --physics all|minimal [--parcels N]
    python -m particles.bench --switches [--parcels N]
    python -m particles.bench --windows [--parcels N] [--rounds R]

Default (``--physics both``): the kernel's parcel-steps per second per core with the full
physics and with drag, gravity, Langevin and walls only (Saffman and Magnus lift, rotation and
inter-particle collisions off), one numba thread, R interleaved rounds of each, best of each
(the machine may be shared), compile or cache load apart; the full physics once more on the
studies' grid (``studies_grid_rate``: 400 × 20 × 40 cells of a developing 4 m pipe, where a
step also crosses axial faces); then the full-physics pass once more on all threads, which
must give the bit-identical result.

``--windows``: the full physics on the studies' grid swept parcel after parcel and window by
window (``TrackSettings.window_stations``), interleaved rounds, best of each, and whether the
final parcel states agree bit for bit.

``--switches``: the same pass with everything on and with Magnus lift, particle rotation and
inter-particle collisions switched off (a scene that does not need them runs a kernel that
does not contain them); interleaved rounds, best of each, pass time and steps/s ratios.

The fully developed 30.5 mm pipe (20 × 40 cross-section, U0 = 10 m/s, single-phase gas),
Tsuji–Morikawa base particles (200 µm, 1020 kg/m3, η = 2.2, Δγ = 1.5°) with everything on:
drag, both lifts, rotation, Langevin with drift, rough walls, and inter-particle collisions
(statistics from a preliminary pass).  The pass runs once to compile (reported apart), then
with 1 and with 2 numba threads; the figure is parcel-steps (particle time steps) per second,
and per core.  It also checks physical bookkeeping (no parcel lost, the two runs bit-equal).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numba
import numpy as np

from rans import PipeMesh, solve
from rans import kepsilon as ke
from rans.solver import GasProperties

from . import ParticleSpec, PhysicsOptions, track


def run(parcels=20000, physics="all", length=1.0):
    gas_props = GasProperties(1.205, 1.81e-5)
    mesh = PipeMesh.build(0.0305, length, mode="periodic", radial_cells=20, azimuthal_cells=40)
    gas = solve(mesh, gas_props, 10.0, 1.0, ke.inlet_epsilon(1.0, 0.0305))
    spec = ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 1.5)
    if physics == "all":
        options = PhysicsOptions()
    else:
        options = PhysicsOptions(**MINIMAL)
    t0 = time.perf_counter()
    first = track(mesh, gas, spec, options, parcels=parcels, seed=1, pass_index=0)
    t_first = time.perf_counter() - t0
    stats = first.cell_statistics(gas) if options.inter_particle_collisions else None
    results = {}
    for threads in (1, 2):
        if threads > numba.config.NUMBA_NUM_THREADS:
            continue
        numba.set_num_threads(threads)
        best = np.inf
        for _ in range(2):
            t0 = time.perf_counter()
            s = track(mesh, gas, spec, options, parcels=parcels, seed=1, pass_index=1, stats=stats)
            best = min(best, time.perf_counter() - t0)
        results[threads] = (best, s)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return t_first, results


MINIMAL = dict(saffman_mei_lift=False, magnus_lift=False, rotation=False, inter_particle_collisions=False)


def kernel_rates(parcels=20000, rounds=3, length=1.0):
    """Best 1-thread pass time of the full physics and of drag + gravity + Langevin + walls.

    Returns ({name: (seconds, Sample)}, {name: compile-or-load seconds}, all-threads Sample of
    the full physics).  Rounds alternate the two kernels, so both see the same machine load.
    """
    gas_props = GasProperties(1.205, 1.81e-5)
    mesh = PipeMesh.build(0.0305, length, mode="periodic", radial_cells=20, azimuthal_cells=40)
    gas = solve(mesh, gas_props, 10.0, 1.0, ke.inlet_epsilon(1.0, 0.0305))
    spec = ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 1.5)
    variants = {"full physics": PhysicsOptions(),
                "drag, gravity, Langevin, walls": PhysicsOptions(**MINIMAL)}
    first = track(mesh, gas, spec, variants["full physics"], parcels=min(parcels, 5000), seed=1,
                  pass_index=0)
    stats = first.cell_statistics(gas)
    compile_s = {}
    for name, opt in variants.items():
        t0 = time.perf_counter()
        track(mesh, gas, spec, opt, parcels=200, seed=1, pass_index=1, stats=stats)
        compile_s[name] = time.perf_counter() - t0
    threads = numba.get_num_threads()
    best = {name: (np.inf, None) for name in variants}
    try:
        numba.set_num_threads(1)
        for _ in range(rounds):
            for name, opt in variants.items():
                t0 = time.perf_counter()
                s = track(mesh, gas, spec, opt, parcels=parcels, seed=1, pass_index=1, stats=stats)
                t = time.perf_counter() - t0
                if t < best[name][0]:
                    best[name] = (t, s)
    finally:
        numba.set_num_threads(threads)
    many = track(mesh, gas, spec, variants["full physics"], parcels=parcels, seed=1, pass_index=1,
                 stats=stats)
    return best, compile_s, many


def _studies_grid(parcels):
    """The studies' grid (developing 4 m pipe, 400 x 20 x 40 cells, single-phase gas), the base
    particles with the full physics, and collision statistics from a first pass."""
    gas_props = GasProperties(1.205, 1.81e-5)
    mesh = PipeMesh.build(0.0305, 4.0, radial_cells=20, azimuthal_cells=40, axial_cells=400)
    gas = solve(mesh, gas_props, 10.0, 1.0, ke.inlet_epsilon(1.0, 0.0305))
    spec = ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 1.5)
    options = PhysicsOptions()
    stats = track(mesh, gas, spec, options, parcels=min(parcels, 4000), seed=1,
                  pass_index=0).cell_statistics(gas)
    return mesh, gas, spec, options, stats


def studies_grid_rate(parcels=8000, rounds=2):
    """Best 1-thread full-physics pass on the studies' grid: the developing 4 m pipe at 400 axial
    × 20 × 40 cells (320,000 cells, as cases/scenes), single-phase gas, the base particles.

    Each step there crosses about one axial face (split sampling, axial interpolation between
    two stations) and reads from 69 MB of accumulators, so a step costs more than in the
    one-station section of ``kernel_rates``.  Returns (seconds, Sample).
    """
    mesh, gas, spec, options, stats = _studies_grid(parcels)
    threads = numba.get_num_threads()
    best = (np.inf, None)
    try:
        numba.set_num_threads(1)
        for _ in range(rounds):
            t0 = time.perf_counter()
            s = track(mesh, gas, spec, options, parcels=parcels, seed=1, pass_index=1, stats=stats)
            t = time.perf_counter() - t0
            if t < best[0]:
                best = (t, s)
    finally:
        numba.set_num_threads(threads)
    return best


def compare_windows(parcels=6000, rounds=3, windows=(0, 4)):
    """Full-physics passes on the studies' grid swept parcel after parcel (window 0) and window
    by window (``TrackSettings.window_stations``), interleaved rounds, one thread: best seconds
    and Sample per window, and whether the final parcel states agree bit for bit."""
    from .tracking import TrackSettings

    mesh, gas, spec, options, stats = _studies_grid(parcels)
    threads = numba.get_num_threads()
    best = {w: (np.inf, None) for w in windows}
    try:
        numba.set_num_threads(1)
        for _ in range(rounds):
            for w in windows:
                t0 = time.perf_counter()
                s = track(mesh, gas, spec, options, parcels=parcels, seed=1, pass_index=1, stats=stats,
                          settings=TrackSettings(window_stations=w), keep_states=True)
                t = time.perf_counter() - t0
                if t < best[w][0]:
                    best[w] = (t, s)
    finally:
        numba.set_num_threads(threads)
    first = best[windows[0]][1]
    same = all(np.array_equal(first.states, best[w][1].states) for w in windows)
    return best, same


def compare_switches(parcels=20000, rounds=3, length=1.0):
    """Pass wall times with all physics on and with Magnus, rotation and collisions off."""
    gas_props = GasProperties(1.205, 1.81e-5)
    mesh = PipeMesh.build(0.0305, length, mode="periodic", radial_cells=20, azimuthal_cells=40)
    gas = solve(mesh, gas_props, 10.0, 1.0, ke.inlet_epsilon(1.0, 0.0305))
    spec = ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 1.5)
    variants = {"all on": PhysicsOptions(),
                "magnus, rotation, collisions off": PhysicsOptions(magnus_lift=False, rotation=False,
                                                                    inter_particle_collisions=False)}
    first = track(mesh, gas, spec, variants["all on"], parcels=parcels, seed=1, pass_index=0)
    stats = first.cell_statistics(gas)
    compile_s = {}
    for name, opt in variants.items():  # compile (or load from cache) apart
        t0 = time.perf_counter()
        track(mesh, gas, spec, opt, parcels=1000, seed=1, pass_index=1, stats=stats)
        compile_s[name] = time.perf_counter() - t0
    best = {name: (np.inf, None) for name in variants}
    for _ in range(rounds):
        for name, opt in variants.items():
            t0 = time.perf_counter()
            s = track(mesh, gas, spec, opt, parcels=parcels, seed=1, pass_index=1, stats=stats)
            t = time.perf_counter() - t0
            if t < best[name][0]:
                best[name] = (t, s)
    return compile_s, best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parcels", type=int, default=20000)
    ap.add_argument("--physics", choices=("both", "all", "minimal"), default="both")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds (--physics both)")
    ap.add_argument("--switches", action="store_true",
                    help="compare all-on with Magnus, rotation and collisions off")
    ap.add_argument("--windows", action="store_true",
                    help="studies' grid: parcel after parcel against window by window (4 stations)")
    args = ap.parse_args(argv)
    if args.windows:
        parcels = args.parcels if args.parcels != 20000 else 6000
        best, same = compare_windows(parcels, args.rounds)
        print(f"# particles.bench --windows  ({platform.machine()}, {os.cpu_count()} cores, numba "
              f"{numba.__version__}, 1 thread, parcels={parcels}, best of {args.rounds} interleaved rounds, "
              f"400 x 20 x 40 cells)")
        for w, (t, s) in best.items():
            label = "parcel after parcel" if w == 0 else f"windows of {w} stations"
            print(f"{label:24s}: {s.counts['steps'] / t / 1e6:.2f} M parcel-steps/s per core ({t:.2f} s)")
        print(f"final parcel states bit-identical: {'yes' if same else 'NO'}")
        assert same, "the windowed sweep changed a trajectory"
        return
    if args.switches:
        compile_s, best = compare_switches(args.parcels)
        print(f"# particles.bench --switches  ({platform.machine()}, {os.cpu_count()} cores, "
              f"numba {numba.__version__}, {numba.get_num_threads()} threads, parcels={args.parcels})")
        rows = []
        for name, (t, s) in best.items():
            c = s.counts
            assert c["lost"] == 0
            rows.append((name, t, c["steps"]))
            print(f"{name:34s}: pass {t:.3f} s (compile/load {compile_s[name]:.1f} s apart), "
                  f"{c['steps']:,} parcel-steps, {c['steps'] / t / 1e6:.2f} M steps/s")
        (_, t_on, n_on), (_, t_off, n_off) = rows
        print(f"pass time ratio all-on / switched-off: {t_on / t_off:.2f}x; "
              f"per-step cost ratio: {(t_on / n_on) / (t_off / n_off):.2f}x")
        return
    if args.physics == "both":
        best, compile_s, many = kernel_rates(args.parcels, args.rounds)
        print(f"# particles.bench  ({platform.machine()}, {os.cpu_count()} cores, numba {numba.__version__},"
              f" parcels={args.parcels}, 1 thread, best of {args.rounds} interleaved rounds)")
        for name, (t, s) in best.items():
            c = s.counts
            assert c["lost"] == 0 and c["injected"] == c["exited"] + c["stuck"]
            print(f"{name:31s}: {c['steps'] / t / 1e6:.2f} M parcel-steps/s per core  ({t:.3f} s, "
                  f"{c['steps']:,} steps; compile/load {compile_s[name]:.1f} s apart)")
        t, s = studies_grid_rate(max(args.parcels // 2, 1000))
        c = s.counts
        assert c["lost"] == 0
        print(f"{'full physics, studies grid':31s}: {c['steps'] / t / 1e6:.2f} M parcel-steps/s per core  "
              f"({t:.3f} s, {c['steps']:,} steps; 400 x 20 x 40 cells, 4 m developing pipe, "
              f"{max(args.parcels // 2, 1000):,} parcels, best of 2)")
        same = np.array_equal(best["full physics"][1].total, many.total)
        print(f"full physics on {numba.get_num_threads()} threads bit-identical to 1 thread: "
              f"{'yes' if same else 'NO'}")
        assert same, "thread count changed the result"
        return
    t_first, results = run(args.parcels, args.physics)
    print(f"# particles.bench  ({platform.machine()}, {os.cpu_count()} cores, numba {numba.__version__},"
          f" physics={args.physics}, parcels={args.parcels})")
    print(f"first pass (compile or cache load + run, 2 threads): {t_first:.2f} s")
    base = None
    for threads, (t, s) in results.items():
        c = s.counts
        assert c["lost"] == 0 and c["injected"] == c["exited"] + c["stuck"]
        rate = c["steps"] / t
        base = base or rate
        print(f"threads {threads}: {t:.3f} s, {c['steps']:,} parcel-steps, {rate / 1e6:.2f} M steps/s, "
              f"{rate / threads / 1e6:.2f} M steps/s per core, speed-up {rate / base:.2f}x, "
              f"{c['particle_collisions']:,} inter-particle and {c['wall_rebounds']:,} wall collisions")
    if len(results) == 2:
        assert np.array_equal(results[1][1].total, results[2][1].total), "thread count changed the result"
        print("1-thread and 2-thread results bit-identical: yes")


if __name__ == "__main__":
    main()
