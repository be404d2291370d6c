"""Rough-wall rebound statistics: mean rebound angle against impact angle for several Δγ.

    python -m collisions.tables [--samples N] [--seed S]

prints, for impact angles 1°–45° and Δγ = 0, 5°, 10°, the mean rebound angle
β̄ = ⟨arcsin(v′·n₀/|v′|)⟩ [deg] of a non-rotating sphere hitting the wall with
the default model (effective-pdf shadow effect, lateral roughness, e_w and μ_w
of Sommerfeld & Huber 1999 at the effective angle).  With Δγ > 0 the mean
rebound angle at small impact angles exceeds the impact angle: the rough wall
throws grazing particles away from it (Sommerfeld & Huber 1999, Fig. 14–16;
Sommerfeld 2003).  Rebounds here are pure collision statistics: no contact
regime (v_min = 0) and a flat local wall (the normal at the impact point).
"""

import argparse
import math
from functools import lru_cache

import numpy as np
from numba import njit

from .conf import JIT_FLAGS
from .random import STREAM_WALL, rng_state  # the impacts' Philox streams (ziggurat normals)
from .wall import WallOptions, make_wall_collision

IMPACT_ANGLES_DEG = (1.0, 2.0, 3.0, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, 45.0)
ROUGHNESS_STD_DEG = (0.0, 5.0, 10.0)


@lru_cache(maxsize=None)
def make_rebound_sampler(options=WallOptions()):
    """Build ``rebound_angles(alpha_deg, dgamma_deg, n, seed, out, speed_ratio)``.

    Fills ``out`` with n rebound angles [deg] and ``speed_ratio`` with |v′|/|v| [-].

    Impacts of a non-rotating sphere (r_p = 100 µm, speed 10 m/s; the angles do not depend
    on either) on the bottom of a pipe of R = 1 m, in the x–y plane at angle α to the wall;
    one rng key (seed, pass 0, parcel i, STREAM_WALL) per impact i.
    """
    kernel = make_wall_collision(options)

    @njit(**JIT_FLAGS)
    def rebound_angles(alpha_deg, dgamma_deg, n, seed, out, speed_ratio):
        r_p = 1e-4
        pipe_radius = 1.0
        a = math.radians(alpha_deg)
        dg = math.radians(dgamma_deg)
        pos = np.zeros(3)
        vel = np.zeros(3)
        omega = np.zeros(3)
        uf = np.zeros(3)
        dv = np.zeros(3)
        for i in range(n):
            pos[0] = 0.0
            pos[1] = -(pipe_radius - r_p)
            pos[2] = 0.0
            vel[0] = 10.0 * math.cos(a)
            vel[1] = -10.0 * math.sin(a)
            vel[2] = 0.0
            omega[:] = 0.0
            rng = rng_state(seed, 0, i, STREAM_WALL)
            kernel(pos, vel, omega, uf, dv, r_p, pipe_radius, dg, 0.0, rng)
            speed = math.sqrt(vel[0] ** 2 + vel[1] ** 2 + vel[2] ** 2)
            out[i] = math.degrees(math.asin(min(1.0, vel[1] / speed)))  # n0 = +e_y at the bottom
            speed_ratio[i] = speed / 10.0
        return out

    return rebound_angles


def rebound_angle_table(impact_angles_deg=IMPACT_ANGLES_DEG, roughness_std_deg=ROUGHNESS_STD_DEG,
                        samples=20000, seed=1, options=WallOptions()):
    """Mean rebound angle [deg], array [len(impact_angles), len(roughness_std)], and its standard error."""
    sampler = make_rebound_sampler(options)
    out = np.empty(samples)
    ratio = np.empty(samples)
    mean = np.empty((len(impact_angles_deg), len(roughness_std_deg)))
    sem = np.empty_like(mean)
    for i, a in enumerate(impact_angles_deg):
        for j, dg in enumerate(roughness_std_deg):
            sampler(float(a), float(dg), samples, seed, out, ratio)
            mean[i, j] = out.mean()
            sem[i, j] = out.std(ddof=1) / math.sqrt(samples) if samples > 1 else 0.0
    return mean, sem


def impact_angle_sensitivity(impact_angles_deg=IMPACT_ANGLES_DEG, dgamma_deg=5.0, samples=20000, seed=1):
    """Sensitivity to evaluating e_w, μ_w at the effective (α + γ₁) or the nominal (α) angle.

    docs/physics.md, sections 5 and 7. Returns {option: (mean rebound angle [deg],
    mean |v′|/|v| [-])}, each an array over ``impact_angles_deg``, for roughness
    ``dgamma_deg`` [deg].
    """
    result = {}
    out = np.empty(samples)
    ratio = np.empty(samples)
    for angle in ("effective", "nominal"):
        sampler = make_rebound_sampler(WallOptions(impact_angle=angle))
        beta = np.empty(len(impact_angles_deg))
        speed = np.empty(len(impact_angles_deg))
        for i, a in enumerate(impact_angles_deg):
            sampler(float(a), float(dgamma_deg), samples, seed, out, ratio)
            beta[i] = out.mean()
            speed[i] = ratio.mean()
        result[angle] = (beta, speed)
    return result


def format_table(impact_angles_deg, roughness_std_deg, mean, sem):
    """Plain-text table of ``rebound_angle_table`` results."""
    head = "impact angle [deg] | " + " | ".join(f"mean rebound, dgamma={dg:g} deg" for dg in roughness_std_deg)
    lines = [head, "-" * len(head)]
    for i, a in enumerate(impact_angles_deg):
        cells = " | ".join(f"{mean[i, j]:8.2f} ± {sem[i, j]:.2f}".rjust(30) for j in range(len(roughness_std_deg)))
        lines.append(f"{a:18.1f} | {cells}")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--samples", type=int, default=100000, help="impacts per table entry")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args(argv)
    mean, sem = rebound_angle_table(samples=args.samples, seed=args.seed)
    print(f"Rough-wall rebound statistics (default WallOptions; non-rotating sphere; "
          f"{args.samples} impacts per entry; ± standard error)")
    print(format_table(IMPACT_ANGLES_DEG, ROUGHNESS_STD_DEG, mean, sem))
    sens = impact_angle_sensitivity(samples=args.samples, seed=args.seed)
    print("\nSensitivity (dgamma = 5 deg): e_w, mu_w at the effective angle alpha + gamma1 (default) "
          "or at the nominal alpha")
    print("impact angle [deg] | rebound [deg] eff. | rebound [deg] nom. | |v'|/|v| eff. | |v'|/|v| nom.")
    for i, a in enumerate(IMPACT_ANGLES_DEG):
        print(f"{a:18.1f} | {sens['effective'][0][i]:18.2f} | {sens['nominal'][0][i]:18.2f} | "
              f"{sens['effective'][1][i]:13.3f} | {sens['nominal'][1][i]:13.3f}")


if __name__ == "__main__":
    main()
