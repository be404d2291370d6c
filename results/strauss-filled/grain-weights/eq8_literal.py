"""Strauß et al.'s eqs. 8–9 read literally on the 2 × 2 cross-section grid, against eulag's transfer:
the porosity a packing gets and the gas force per grain, in a resting slug and on resting beds.

    python results/strauss-filled/grain-weights/eq8_literal.py      (output: eq8_literal.txt)

A frozen relaxed packing (porosity 0.48, `dem.feed.relaxed_packing`) fills a 14 cm tube section
of 40 gas cells (3.5 mm, the paper's grid constant), whole ("full slug", gas at v_s = 1 m/s) or cut
to the grains below a height z_c (resting beds, gas at v_s = 4 m/s). The quasi-steady Darcy
pressure field is solved for each porosity field (grains at rest), and each grain gets
F = −V_p ∇P/(1 − φ), ∇P and φ interpolated to the grain (eq. 6 as the docs resolve it).
Variants of the grain → node porosity (eq. 8) and node → grain interpolation (eq. 9):

* ``eulag``: the shipped transfer (`dem.TentTransfer`, each grain's cross-section weights
  normalised, node volume l_x A/4, normalised interpolation);
* ``quad``: plain tent sums over the node volume l_x A/4 (a quarter of the tube's section);
* ``l3``: plain tent sums over a cubic node volume l_x l_t² (l_t = R, the node spacing across);
  each with the interpolation normalised (``/norm``) or as printed (``/printed``, plain sums),
  and with the permeability capped at the empty tube's (D²/32, eulag) or not.

Printed per variant: the mean node porosity in the bottom and top node rows, −dP/dx in the
middle of the section, the mean gas force per grain in units of μ m g (μ = 0.5; what must be
overcome to slide a grain resting on the bottom) and r = Σ F / (A (−dP/dx) L): the grains' share of the
pressure drop.  A diagnostic for docs/slug.md ("Measured against the paper").
"""

import math

import numpy as np

from darcy import DarcySolver, TubeGrid
from dem import FREE, TentTransfer
from dem.feed import relaxed_packing

D, R, RHO = 1.4e-3, 3.5e-3, 937.0
ETA, P0 = 6.73e-5, 101325.0
AREA = math.pi * R * R
VP = math.pi / 6.0 * D ** 3
MU_M_G = 0.5 * RHO * VP * 9.81


def _tent(s):
    return np.clip(1.0 - np.abs(s), 0.0, None)


def _weights(pos, lx):
    """Plain tent weights (N, 2, 2, 2) to the two axial nodes around each grain and the 2 × 2
    nodes across (cell centres, spacing R), and the lower axial node's index."""
    x = pos[:, 0]
    i0 = np.floor(x / lx - 0.5).astype(int)
    wx = np.stack([_tent((x - (i0 + 0.5) * lx) / lx), _tent((x - (i0 + 1.5) * lx) / lx)], 1)
    nodes = np.array([-0.5 * R, 0.5 * R])
    wy = _tent((pos[:, 1:2] - nodes[None]) / R)
    wz = _tent((pos[:, 2:3] - nodes[None]) / R)
    return i0, wx[:, :, None, None] * wy[:, None, :, None] * wz[:, None, None, :]


def _plain_porosity(pos, nx, lx, node_volume):
    i0, w = _weights(pos, lx)
    s = np.zeros((nx + 2, 2, 2))
    for a in range(2):
        np.add.at(s, np.clip(i0 + a, -1, nx) + 1, w[:, a])
    return 1.0 - VP * s[1:-1] / node_volume


def _interpolate(pos, field, nx, lx, normalise):
    i0, w = _weights(pos, lx)
    out = np.zeros((len(pos), field.shape[-1]))
    ws = np.zeros(len(pos))
    for a in range(2):
        i = i0 + a
        wa = w[:, a] * ((i >= 0) & (i < nx))[:, None, None]
        out += np.einsum("nbc,nbcq->nq", wa, field[np.clip(i, 0, nx - 1)])
        ws += wa.sum(axis=(1, 2))
    return out / ws[:, None] if normalise else out


def force(pos, measured, length, nx, vs, variant, kappa_max):
    """(node porosity, −dP/dx in the middle, F per grain [N] of the measured grains, r)."""
    lx = length / nx
    if variant == "eulag":
        tr = TentTransfer(nx, 2, length, R, D / 2)
        phi, u = tr.porosity_velocity(pos, np.zeros_like(pos), np.full(len(pos), FREE, np.int8))
    else:
        phi = _plain_porosity(pos, nx, lx, {"l3": lx * R * R, "quad": lx * AREA / 4}[variant.split("/")[0]])
        u = np.zeros(phi.shape + (3,))
    phi = np.clip(phi, 0.2, 1.0)
    gas = DarcySolver(TubeGrid(length, 2 * R, nx, 2), P0, ETA, D, theta=1.0, kappa_max=kappa_max)
    for _ in range(4):
        gas.step(phi, u, 10.0, vs)  # steps far beyond the gas's relaxation time: quasi-steady
    grad = gas.gradient()
    field = np.concatenate([grad, phi[..., None]], 3)
    v = _interpolate(pos[measured], field, nx, lx, variant == "eulag" or variant.endswith("norm"))
    f = -VP * v[:, 0] / np.maximum(1.0 - v[:, 3], 0.05)
    mid = slice(8, -8)
    g = -grad[mid, :, :, 0].mean()
    return phi[mid], g, f.mean(), f.sum() / (AREA * g * (length - 0.04))


def main():
    block = 0.014
    n = int(round((1 - 0.48) * AREA * block / VP))
    template = relaxed_packing(n, block, R, D, RHO, 1500.0, 1)
    nx = 40
    length = nx * 3.5e-3
    full = np.concatenate([template + np.array([k * block, 0, 0]) for k in range(-1, int(length / block) + 1)])
    full = full[(full[:, 0] < length) & (full[:, 0] >= -block)]
    print(f"mu m g = {MU_M_G:.3e} N; {len(full)} grains in the packing")
    for label, zc, vs in (("full slug", 1.0, 1.0), ("bed z < 0", 0.0, 4.0), ("bed z < -1.4 mm", -1.4e-3, 4.0),
                          ("bed z < -2.1 mm", -2.1e-3, 4.0)):
        pos = full[full[:, 2] < zc]
        measured = (pos[:, 0] >= 0.02) & (pos[:, 0] < length - 0.02)
        for variant in ("eulag", "quad/norm", "quad/printed", "l3/norm", "l3/printed"):
            for cap, cap_label in ((None, "D2/32"), (1e3, "none ")):
                phi, g, f, r = force(pos, measured, length, nx, vs, variant, cap)
                print(f"{label:16s} v_s {vs:.0f} m/s {variant:13s} cap {cap_label} porosity bottom "
                      f"{phi[:, :, 0].mean():.3f} top {phi[:, :, 1].mean():.3f}  -dP/dx {g:9.1f} Pa/m  "
                      f"F per grain {f / MU_M_G:6.3f} mu m g  r {r:.3f}")
        print()


if __name__ == "__main__":
    main()
