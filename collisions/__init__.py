"""Collision kernels (numba): rough-wall particle–wall and stochastic particle–particle collisions.

Pure kernels on plain float arrays and scalars; no dependency on rans/ or particles/.

- ``collisions.random``: counter-based generator (Philox-4x32-10) keyed by
  (seed, pass, parcel, stream, draw); streams STREAM_INJECTION, STREAM_DISPERSION,
  STREAM_WALL, STREAM_COLLISION.
- ``collisions.wall``: rough-wall collision (Sommerfeld & Huber 1999, shadow effect of
  Sommerfeld 2003), ``make_wall_collision(WallOptions(...))`` → kernel.
- ``collisions.interparticle``: binary hard-sphere kernel and the stochastic collision
  model of Sommerfeld (2001), ``make_interparticle_collision(InterparticleOptions(...))``.
- ``python -m collisions.bench``: kernel calls per second;
  ``python -m collisions.tables``: rough-wall rebound-angle statistics.
"""

from .interparticle import (
    COLLISION_NONE,
    COLLISION_SLIDING,
    COLLISION_STICKING,
    PARTNER_SIZE,
    InterparticleOptions,
    collision_probability,
    hard_sphere_pair,
    interparticle_collision,
    kinetic_collision_frequency,
    make_interparticle_collision,
    mean_collision_frequency,
    sample_size_class,
    sommerfeld_2001_correlation,
)
from .random import (
    N_STREAMS,
    RNG_STATE_SIZE,
    STREAM_COLLISION,
    STREAM_DISPERSION,
    STREAM_INJECTION,
    STREAM_WALL,
    next_normal,
    next_normal_pair,
    next_uniform,
    next_uniform_pair,
    normal,
    rng_state,
    uniform,
)
from .wall import (
    WALL_NO_IMPACT,
    WALL_REBOUND,
    WALL_ROLLING,
    WALL_SLIDING,
    WallOptions,
    make_wall_collision,
    minimum_bounce_speed,
    sommerfeld_huber_1999_friction,
    sommerfeld_huber_1999_restitution,
    time_to_wall,
    wall_collision,
)

__all__ = [
    "COLLISION_NONE", "COLLISION_SLIDING", "COLLISION_STICKING", "PARTNER_SIZE",
    "InterparticleOptions", "collision_probability", "hard_sphere_pair", "interparticle_collision",
    "kinetic_collision_frequency", "make_interparticle_collision", "mean_collision_frequency",
    "sample_size_class", "sommerfeld_2001_correlation",
    "N_STREAMS", "RNG_STATE_SIZE", "STREAM_COLLISION", "STREAM_DISPERSION", "STREAM_INJECTION",
    "STREAM_WALL", "next_normal", "next_normal_pair", "next_uniform", "next_uniform_pair",
    "normal", "rng_state", "uniform",
    "WALL_NO_IMPACT", "WALL_REBOUND", "WALL_ROLLING", "WALL_SLIDING", "WallOptions",
    "make_wall_collision", "minimum_bounce_speed", "sommerfeld_huber_1999_friction",
    "sommerfeld_huber_1999_restitution", "time_to_wall", "wall_collision",
]
