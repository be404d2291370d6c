"""Micro-benchmark of the collision kernels: calls per second, warm; first-call time apart.

    python -m collisions.bench [--calls N]

Each kernel is called N times from inside an ``@njit`` driver loop, as the particle
step kernel will call it (inputs reset per call from pre-generated arrays, so the
copy is included).  The first call of every driver (JIT compile of the driver and
compile-or-cache-load of the kernel) is timed and reported apart; the warm figure is
the best of three repeats.  A stand-in particle step (exponential drag update +
three Philox normals (ziggurat) for a Langevin model, no interpolation) gives a lower bound on
the cost of the real step, for scale.  Each benchmark also checks a physical property
(particles inside the pipe; collision fraction close to the kinetic-theory mean
probability, which ignores the curvature of 1 − exp(−fΔt) — exact only for small P).
"""

import argparse
import math
import os
import platform
import time

import numpy as np
from numba import njit

from jitcache import EXPLICIT_FLAGS

from .interparticle import (
    PARTNER_SIZE,
    InterparticleOptions,
    make_interparticle_collision,
    mean_collision_frequency,
    sommerfeld_2001_correlation,
)
from .random import STREAM_COLLISION, STREAM_DISPERSION, STREAM_WALL, next_normal, rng_state
from .wall import WallOptions, make_wall_collision, minimum_bounce_speed

PIPE_RADIUS = 0.0305 / 2  # m (Tsuji & Morikawa 1982 pipe)
D_P = 200e-6  # m


def _make_wall_driver(kernel):
    @njit(**EXPLICIT_FLAGS)
    def drive(pos0, vel0, dgamma, v_min, status_count, n_calls):
        pos = np.empty(3)
        vel = np.empty(3)
        omega = np.zeros(3)
        uf = np.zeros(3)
        dv = np.zeros(3)
        rng = rng_state(1, 0, 0, STREAM_WALL)
        r_p = 0.5 * D_P
        m = pos0.shape[0]
        outside = 0
        for i in range(n_calls):
            k = i % m
            pos[:] = pos0[k]
            vel[:] = vel0[k]
            s = kernel(pos, vel, omega, uf, dv, r_p, PIPE_RADIUS, dgamma, v_min, rng)
            status_count[s] += 1
            if pos[1] ** 2 + pos[2] ** 2 > (PIPE_RADIUS - r_p) ** 2:
                outside += 1
        return outside

    return drive


def _make_interparticle_driver(kernel):
    @njit(**EXPLICIT_FLAGS)
    def drive(vel0, mean, rms, number_density, dt, n_calls):
        vel = np.empty(3)
        omega = np.zeros(3)
        zero = np.zeros(3)
        dv = np.zeros(3)
        partner = np.zeros(PARTNER_SIZE)
        rng = rng_state(1, 0, 0, STREAM_COLLISION)
        m = vel0.shape[0]
        hits = 0
        for i in range(n_calls):
            vel[:] = vel0[i % m]
            s = kernel(vel, omega, D_P, mean, D_P, mean, rms, zero, zero, zero, number_density, 1.0, dt, rng, dv,
                       partner)
            if s != 0:
                hits += 1
        return hits

    return drive


@njit(**EXPLICIT_FLAGS)
def _standin_step(vel0, n_calls):
    """Lower bound of a particle step: exact drag update plus three Langevin normals."""
    vel = np.empty(3)
    uf = np.zeros(3)
    pos = np.zeros(3)
    rng = rng_state(1, 0, 0, STREAM_DISPERSION)
    dt = 1e-4
    tau = 0.1
    a = math.exp(-dt / tau)
    acc = 0.0
    m = vel0.shape[0]
    for i in range(n_calls):
        vel[:] = vel0[i % m]
        for c in range(3):
            uf[c] = 0.8 * uf[c] + 0.6 * 0.5 * next_normal(rng)
            u_f = uf[c] + (10.0 if c == 0 else 0.0)
            vel[c] = u_f + (vel[c] - u_f) * a
            pos[c] += vel[c] * dt
        acc += vel[0]
    return acc + pos[0]


def _time(fn, *args, repeats=3):
    t0 = time.perf_counter()
    fn(*args)
    first = time.perf_counter() - t0
    best = math.inf
    result = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn(*args)
        best = min(best, time.perf_counter() - t0)
    return first, best, result


def _wall_impacts(m, alpha_max_deg, seed=2):
    """m impacts at random wall points, speed 10 m/s, impact angle uniform in (0, alpha_max]."""
    rs = np.random.default_rng(seed)
    r_p = 0.5 * D_P
    theta = rs.uniform(0, 2 * np.pi, m)
    r = (PIPE_RADIUS - r_p) * (1 + rs.uniform(0, 1e-4, m))
    pos = np.stack([np.zeros(m), r * np.cos(theta), r * np.sin(theta)], axis=1)
    alpha = np.radians(rs.uniform(1e-3, alpha_max_deg, m))
    n0 = -pos[:, 1:] / r[:, None]
    vel = np.zeros((m, 3))
    vel[:, 0] = 10 * np.cos(alpha)
    vel[:, 1:] = -10 * np.sin(alpha)[:, None] * n0
    return pos, vel


def run(n_calls=2_000_000):
    """Run all benchmarks; return a list of (name, first_call_s, calls_per_s, check_text)."""
    rows = []
    pos, vel = _wall_impacts(4096, 90.0)
    pos_g, vel_g = _wall_impacts(4096, 2.0)
    v_min = minimum_bounce_speed(D_P)
    wall = _make_wall_driver(make_wall_collision(WallOptions()))
    for name, p, v, dg in (("wall, rough 5 deg, impact angles 0-90 deg", pos, vel, 5.0),
                           ("wall, rough 5 deg, grazing 0-2 deg", pos_g, vel_g, 5.0),
                           ("wall, smooth, impact angles 0-90 deg", pos, vel, 0.0)):
        counts = np.zeros(4, np.int64)
        first, best, outside = _time(wall, p, v, math.radians(dg), v_min, counts, n_calls)
        frac = counts / counts.sum()
        rows.append((name, first, n_calls / best,
                     f"outside: {outside}; rebound/sliding/rolling fractions "
                     f"{frac[1]:.3f}/{frac[2]:.3f}/{frac[3]:.3f}"))
    rs = np.random.default_rng(3)
    mean = np.array([10.0, 0.0, 0.0])
    rms = np.array([0.5, 0.5, 0.5])
    vel0 = mean + rms * rs.standard_normal((4096, 3))
    ipc = _make_interparticle_driver(make_interparticle_collision(InterparticleOptions()))
    n_p = 1e9  # 1/m3; f ~ pi (2 D_p)^2 n_p <|g|> ~ 100 1/s
    f_mean = mean_collision_frequency(D_P, D_P, n_p, rms[0], rms[0], sommerfeld_2001_correlation(1.0))
    for name, dt in (("inter-particle, P ~ 0.01 (typical step)", 0.01 / f_mean),
                     ("inter-particle, P ~ 0.1 (dense, step limit)", 0.1 / f_mean),
                     ("inter-particle, P ~ 1 (collides)", 100.0 / f_mean)):
        first, best, hits = _time(ipc, vel0, mean, rms, n_p, dt, n_calls)
        rows.append((name, first, n_calls / best,
                     f"collision fraction {hits / n_calls:.4f} (kinetic theory <P> ~ {-math.expm1(-f_mean * dt):.4f})"))
    first, best, _ = _time(_standin_step, vel0, n_calls)
    rows.append(("stand-in particle step (drag + 3 normals)", first, n_calls / best, "for scale"))
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description="Collision kernel micro-benchmark")
    p.add_argument("--calls", type=int, default=2_000_000)
    args = p.parse_args(argv)
    rows = run(args.calls)
    print(f"collision kernels, {args.calls} calls each, warm best of 3; machine: {platform.machine()}, "
          f"{os.cpu_count()} cores, {platform.processor() or platform.platform()}")
    print("first call = JIT compile of the driver + compile or cache load of the kernel; "
          "calls/s and ns/call: warm, per call including the driver's input copy (~10 ns)")
    print(f"{'kernel':45s} {'first call [s]':>15s} {'calls/s':>12s} {'ns/call':>8s}  check")
    for name, first, rate, check in rows:
        print(f"{name:45s} {first:15.2f} {rate:12.3e} {1e9 / rate:8.0f}  {check}")


if __name__ == "__main__":
    main()
