"""Grain ↔ gas-grid transfer with the tent function (SMH eqs. 7–9).

The gas grid has nx × ny × nz nodes at cell centres: x_i = (i + ½) l_x (0 ≤ x < L), and
y_b = −R_t + (b + ½) l_y, z_c = −R_t + (c + ½) l_z across the tube (l_y = l_z = D_t/ny; with
the paper's 150 × 2 × 2 grid all three are 3.5 mm).  F(x) = f(x/l_x) f(y/l_y) f(z/l_z),
f(s) = 1 − |s| for |s| ≤ 1.

Porosity and grain velocity at node j (eq. 8, normalised by grain and node volume):

    φ_j = 1 − V_p Σ_i W_ij / V_j,      u_j = Σ_i v_i W_ij / Σ_i W_ij

Near the tube wall the cross-section tents of the nodes no longer sum to one (with 2 × 2
nodes, Σ_b f(y − y_b) = 1 only for |y| ≤ R_t/2), so a grain there would deposit less than its
volume.  Two treatments (``weights``):

- ``"grain"`` (default): each grain's cross-section weights are normalised to sum to one,
  W_ij = f_x · [f_y / Σ_b f_y] · [f_z / Σ_c f_z], so every grain deposits exactly V_p (in
  the axial interior), and V_j = l_x · (A_t/A_c) ∫∫_{r < R_c} ŵ_b(y) ŵ_c(z) dy dz (A_t = π R_t²,
  A_c = π R_c², R_c = R_t − R the radius the centres can reach).  With the 2 × 2 grid every
  node is a quadrant, V_j = l_x A_t / 4, and the nodes' porosity is the true one for any radial
  distribution of the centres, also for a real packing whose centres crowd against the wall
  (``tests/test_slug.py``).
- ``"tent"``: W_ij = F(x_i − x_j) and V_j = l_x · (A_t/A_c) ∫∫_{r < R_c} f(y − y_j) f(z − z_j) dy dz.
  A packing whose centres are uniformly distributed in the accessible cylinder then gives its
  true porosity at every node, but a relaxed packing has 38–44 % of its centres within 0.1 d of
  r = R_c, where the tents sum to 0.70–0.875: its nodes' porosity is 0.019–0.026 too high
  (0.546 for a packing at 0.520) and the Carman–Kozeny resistance per grain 0.82–0.86 of its
  value at the true porosity (results/strauss-filled/grain-weights/porosity_check.py).

Along x the feed zone x < 0 holds grains, so the inlet node's tent is full; beyond the outlet
(x ≥ L) the grains are gone, so the outlet node's volume is the part of its tent inside the
tube, V_j · (1 − 1/8) (its tent reaches l_x/2 beyond L and holds 1/8 of its integral there): a
uniform packing up to the outlet gives its true porosity at the outlet node too (test).

Grain values (eq. 9): φ_i = Σ_j φ_j F / Σ_j F and ∇P_i likewise — normalised by the weights,
which do not sum to one near the wall or the tube ends (the same for either treatment: the
per-grain factor cancels), so that the paper's "linear interpolation" returns a uniform field
at every grain.  ``interpolation = "printed"`` takes eq. 9's plain sums instead: a grain whose
weights sum to S < 1 (S = 0.70 on the wall at the bottom of the 2 × 2 grid) sees S ∇P and a
porosity S φ, so its gas force V_p S ∇P/(1 − S φ) is S(1 − φ)/(1 − S φ) of the normalised one
(0.55 in a slug at φ = 0.48, 0.07 for a lone grain at φ = 0.97).  A diagnostic of what the
literal equation would do, not a model choice.
"""

import math

import numpy as np
from numba import njit, prange

from .conf import JIT_FLAGS, PARALLEL_FLAGS
from .engine import GONE


#: Cross-section weights of the grain → node transfer (module docstring).
WEIGHTS = ("grain", "tent")
#: Node → grain interpolation (module docstring): normalised by the weights, or eq. 9's plain sum.
INTERPOLATIONS = ("normalised", "printed")
#: The part of the outlet node's tent (centre l_x/2 before the outlet, half-width l_x) inside the tube.
OUTLET_TENT_FRACTION = 1.0 - 0.125


def cross_section_tent_integrals(ny, tube_r, grain_r, samples=1600, weights="grain"):
    """∫∫_{r < R_t − R} w_b(y) w_c(z) dy dz [m²] for the ny × ny cross-section nodes (midpoint rule);
    w = f(y − y_b) (``weights = "tent"``) or f normalised to sum to one over b (``"grain"``)."""
    if weights not in WEIGHTS:
        raise ValueError(f"weights = {weights!r}: allowed {', '.join(WEIGHTS)}")
    rc = tube_r - grain_r
    h = 2 * tube_r / samples
    s = -tube_r + (np.arange(samples) + 0.5) * h
    l = 2 * tube_r / ny
    nodes = -tube_r + (np.arange(ny) + 0.5) * l
    f = np.clip(1.0 - np.abs(s[None, :] - nodes[:, None]) / l, 0.0, None)  # (ny, samples)
    if weights == "grain":
        f = f / f.sum(axis=0)[None, :]
    mask = (s[:, None] ** 2 + s[None, :] ** 2 < rc * rc).astype(float)
    w = f @ mask @ f.T * h * h
    if weights == "grain":  # the normalised weights sum to one: Σ_bc w = π R_c² exactly
        w *= math.pi * rc * rc / w.sum()
    return w


def node_volumes(nx, ny, length, tube_r, grain_r, weights="grain"):
    """V_j [m³] per cross-section node (ny, ny), the same for every axial node (see module docstring)."""
    lx = length / nx
    rc = tube_r - grain_r
    w = cross_section_tent_integrals(ny, tube_r, grain_r, weights=weights)
    return lx * w * (tube_r ** 2 / rc ** 2)


@njit(**JIT_FLAGS)
def _tent(s):
    a = abs(s)
    return 1.0 - a if a < 1.0 else 0.0


@njit(**JIT_FLAGS)
def bin_grains(pos, status, lx, nx, periodic, length, bin_start, items):
    """Counting sort of the non-GONE grains by gas cell in x: bin k = floor(x/l_x) + 1 (0..nx+1);
    x < 0 → bin 0 (only grains with x ≥ −l_x matter), x ≥ L → bin nx+1."""
    nb = nx + 2
    for k in range(nb + 1):
        bin_start[k] = 0
    n = pos.shape[0]
    b = np.empty(n, dtype=np.int64)
    for i in range(n):
        if status[i] == GONE:
            b[i] = -1
            continue
        x = pos[i, 0]
        if periodic:
            x = x - length * math.floor(x / length)
        k = int(math.floor(x / lx)) + 1
        if k < 0:
            k = 0
        if k > nx + 1:
            k = nx + 1
        if periodic and k > nx:
            k = nx
        b[i] = k
        bin_start[k + 1] += 1
    for k in range(nb):
        bin_start[k + 1] += bin_start[k]
    cursor = bin_start[:nb].copy()
    for i in range(n):
        if b[i] >= 0:
            items[cursor[b[i]]] = i
            cursor[b[i]] += 1


def _grains_to_nodes(pos, vel, bin_start, items, lx, nx, ny, tube_r, periodic, length, sum_f, sum_fv,
                     per_grain):
    """Σ_i W_ij and Σ_i v_i W_ij at every node (``per_grain``: the cross-section weights of each
    grain normalised to sum to one; module docstring): a ``prange`` over axial node columns, each
    gathering from the grains of its neighbouring bins in sorted order (race-free, deterministic)."""
    lt = 2.0 * tube_r / ny
    for i in prange(nx):
        for b in range(ny):
            for c in range(ny):
                sum_f[i, b, c] = 0.0
                sum_fv[i, b, c, 0] = 0.0
                sum_fv[i, b, c, 1] = 0.0
                sum_fv[i, b, c, 2] = 0.0
        xj = (i + 0.5) * lx
        for dk in range(3):
            k = i + dk  # bins i, i+1, i+2 are gas cells i-1, i, i+1
            shift = 0.0
            if periodic:
                if k == 0:
                    k = nx
                    shift = -length
                elif k == nx + 1:
                    k = 1
                    shift = length
            for m in range(bin_start[k], bin_start[k + 1]):
                g = items[m]
                x = pos[g, 0]
                if periodic:
                    x = x - length * math.floor(x / length) + shift
                fx = _tent((x - xj) / lx)
                if fx == 0.0:
                    continue
                if per_grain:  # Σ_b f_y Σ_c f_z of this grain: its weights then sum to f_x
                    sy = 0.0
                    sz = 0.0
                    for b in range(ny):
                        sy += _tent((pos[g, 1] - (-tube_r + (b + 0.5) * lt)) / lt)
                        sz += _tent((pos[g, 2] - (-tube_r + (b + 0.5) * lt)) / lt)
                    if sy > 0.0 and sz > 0.0:
                        fx = fx / (sy * sz)
                for b in range(ny):
                    fy = _tent((pos[g, 1] - (-tube_r + (b + 0.5) * lt)) / lt)
                    if fy == 0.0:
                        continue
                    for c in range(ny):
                        fz = _tent((pos[g, 2] - (-tube_r + (c + 0.5) * lt)) / lt)
                        w = fx * fy * fz
                        if w == 0.0:
                            continue
                        sum_f[i, b, c] += w
                        sum_fv[i, b, c, 0] += w * vel[g, 0]
                        sum_fv[i, b, c, 1] += w * vel[g, 1]
                        sum_fv[i, b, c, 2] += w * vel[g, 2]


def _nodes_to_grains(pos, status, field, lx, nx, ny, tube_r, periodic, length, normalise, out):
    """Tent interpolation of a node field (nx, ny, ny, k) to the grains (eq. 9), normalised by Σ F
    (``normalise``) or the plain sum of eq. 9 as printed."""
    lt = 2.0 * tube_r / ny
    ncomp = field.shape[3]
    n = pos.shape[0]
    for g in prange(n):
        for q in range(ncomp):
            out[g, q] = 0.0
        if status[g] == GONE:
            continue
        x = pos[g, 0]
        if periodic:
            x = x - length * math.floor(x / length)
        i0 = int(math.floor(x / lx - 0.5))
        wsum = 0.0
        for i in range(i0, i0 + 2):
            ii = i
            xj = (i + 0.5) * lx
            if periodic:
                if ii < 0:
                    ii += nx
                elif ii >= nx:
                    ii -= nx
            elif ii < 0 or ii >= nx:
                continue
            fx = _tent((x - xj) / lx)
            if fx == 0.0:
                continue
            for b in range(ny):
                fy = _tent((pos[g, 1] - (-tube_r + (b + 0.5) * lt)) / lt)
                if fy == 0.0:
                    continue
                for c in range(ny):
                    fz = _tent((pos[g, 2] - (-tube_r + (c + 0.5) * lt)) / lt)
                    w = fx * fy * fz
                    if w == 0.0:
                        continue
                    wsum += w
                    for q in range(ncomp):
                        out[g, q] += w * field[ii, b, c, q]
        if normalise and wsum > 0.0:
            for q in range(ncomp):
                out[g, q] /= wsum


# parallel (prange) and serial variants from one source (see dem.engine for the measured reason)
grains_to_nodes = njit(**PARALLEL_FLAGS)(_grains_to_nodes)
nodes_to_grains = njit(**PARALLEL_FLAGS)(_nodes_to_grains)
grains_to_nodes_serial = njit(**JIT_FLAGS)(_grains_to_nodes)
nodes_to_grains_serial = njit(**JIT_FLAGS)(_nodes_to_grains)


class TentTransfer:
    """Tent transfer between the grains and an nx × ny × ny gas grid over a tube of length L."""

    def __init__(self, nx, ny, length, tube_r, grain_r, periodic=False, parallel=False, weights="grain",
                 interpolation="normalised"):
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation = {interpolation!r}: allowed {', '.join(INTERPOLATIONS)}")
        self.normalise = interpolation == "normalised"
        self.parallel = bool(parallel)
        self.nx, self.ny, self.length, self.tube_r = nx, ny, length, tube_r
        self.lx = length / nx
        self.periodic = bool(periodic)
        self.weights = weights
        self.v_grain = 4.0 / 3.0 * math.pi * grain_r ** 3
        self.vol = np.broadcast_to(node_volumes(nx, ny, length, tube_r, grain_r, weights=weights),
                                   (nx, ny, ny)).copy()
        if not self.periodic:  # the outlet node's tent inside the tube (module docstring)
            self.vol[-1] *= OUTLET_TENT_FRACTION
        self.bin_start = np.zeros(nx + 3, dtype=np.int64)
        self.sum_f = np.zeros((nx, ny, ny))
        self.sum_fv = np.zeros((nx, ny, ny, 3))

    def porosity_velocity(self, pos, vel, status):
        """(φ [nx, ny, ny], u [nx, ny, ny, 3]) from the grains (FREE and FEED grains count)."""
        items = np.zeros(len(status), dtype=np.int64)
        bin_grains(pos, status, self.lx, self.nx, self.periodic, self.length, self.bin_start, items)
        (grains_to_nodes if self.parallel else grains_to_nodes_serial)(pos, vel, self.bin_start, items, self.lx, self.nx, self.ny, self.tube_r, self.periodic,
                        self.length, self.sum_f, self.sum_fv, self.weights == "grain")
        phi = 1.0 - self.v_grain * self.sum_f / self.vol
        u = np.zeros_like(self.sum_fv)
        ok = self.sum_f > 0
        u[ok] = self.sum_fv[ok] / self.sum_f[ok][:, None]
        return phi, u

    def to_grains(self, pos, status, field):
        """Node field (nx, ny, ny, k) → grain values (N, k)."""
        out = np.zeros((len(status), field.shape[3]))
        (nodes_to_grains if self.parallel else nodes_to_grains_serial)(pos, status, np.ascontiguousarray(field), self.lx, self.nx, self.ny, self.tube_r,
                        self.periodic, self.length, self.normalise, out)
        return out
