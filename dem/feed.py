"""Grains entering the tube: a relaxed random packing of porosity φ_f pushed in at constant speed.

SMH §3 insert the grains at the inlet at 0.04 m/s and porosity 0.57.  Here a block of the tube
of length L_b is filled with N = (1 − φ_f) A_t L_b / V_p grains at random positions (Philox
random numbers of ``collisions.random``, stream STREAM_INJECTION), periodic in x, and relaxed
without gravity and with strong damping until the largest overlap is below 0.2 % of d: the
template.  Copies of it are stacked behind the inlet (x < 0) and moved rigidly at the feed
speed v_f = ṁ / (ρ_s (1 − φ_f) A_t) (FEED grains); a grain becomes free when its centre
crosses x = 0.  The copies are identical (the template is periodic in x, so they join
without overlap); the randomness that follows comes from the dynamics in the tube.
"""

import math

import numpy as np

from collisions.random import STREAM_INJECTION, uniform

from .engine import FREE, CellGrid, ContactModel, Grains, dem_step


def feed_speed(mass_flow, density, porosity, tube_diameter):
    """v_f [m/s] = ṁ [kg/s] / (ρ_s (1 − φ_f) π D_t²/4)."""
    return mass_flow / (density * (1.0 - porosity) * math.pi * tube_diameter ** 2 / 4.0)


def relaxed_packing(n, length, tube_r, diameter, density, stiffness, seed, max_steps=40000, tol=2e-3):
    """(n, 3) positions of a relaxed random packing in a periodic tube segment of ``length`` [m].

    Random start (uniform in the accessible cylinder), then damped soft-sphere relaxation
    (restitution 0.05, no friction, velocities halved every step) until the largest overlap is
    below ``tol`` · d.  Deterministic for a given seed.
    """
    r = 0.5 * diameter
    rc = tube_r - r
    pos = np.empty((n, 3))
    for i in range(n):
        u1, u2 = uniform(seed, 0, i, STREAM_INJECTION, 0), uniform(seed, 0, i, STREAM_INJECTION, 1)
        u3 = uniform(seed, 0, i, STREAM_INJECTION, 2)
        rr, th = rc * math.sqrt(u1), 2 * math.pi * u2
        pos[i] = (length * u3, rr * math.cos(th), rr * math.sin(th))
    g = Grains(n)
    g.append(pos, np.zeros_like(pos), np.full(n, FREE, dtype=np.int8), np.arange(n))
    m = ContactModel(diameter, density, stiffness, 0.05, 0.0)
    grid = CellGrid(0.0, length, tube_r, diameter, periodic=True)
    dt = m.t_contact / 30
    work, gas, zero = {}, np.zeros((n, 3)), np.zeros(3)
    for it in range(max_steps):
        om = dem_step(g, m, grid, gas, zero, dt, 0.0, np.nan, work)
        g.vel[:n] *= 0.5
        g.omg[:n] = 0.0
        if it > 50 and om < tol * diameter:
            break
    else:
        raise RuntimeError(f"feed packing did not relax: overlap {om / diameter:.3g} d after {max_steps} steps")
    return g.pos[:n].copy()


class Feed:
    """Stacks copies of the template behind the inlet and releases them (see module docstring)."""

    def __init__(self, template, block_length, speed):
        self.template = np.asarray(template)
        self.block_length = float(block_length)
        self.speed = float(speed)
        self.next_block = 0

    def blocks_due(self, s):
        """Positions of the blocks to add now that the feed has advanced by s = v_f t [m]."""
        out = []
        while s >= (self.next_block - 1) * self.block_length:
            k = self.next_block
            p = self.template.copy()
            p[:, 0] += s - (k + 1) * self.block_length
            out.append(p)
            self.next_block += 1
        return out
