"""Grain state, cell lists, contact forces and time integration (numba, structure of arrays).

State arrays (N grains, capacity grows in the driver):

    pos, vel, omg      float64[N, 3]   position [m], velocity [m/s], angular velocity [1/s]
    status             int8[N]         FREE, FEED (moved by the feed, not integrated) or GONE
    gid                int64[N]        grain id (counter of the random numbers; never reused)

Coordinates: x along the tube axis (0 ≤ x < L inside the tube, the feed zone x < 0), y, z in the
cross-section, tube wall at sqrt(y² + z²) = R_t.

Neighbours: a Verlet list (pairs closer than (1 + SKIN) d) built from a cell list after the first
drift of every call of :func:`dem_step` and whenever a grain has moved more than half the skin
since; the force kernel reads the list instead of searching the 27 cells every step.

Determinism: the cell list is a counting sort in grain order; the Verlet list is built serially
in a fixed order (cells in a fixed order, grains in each cell by index); the force kernel is a
``prange`` over grains in which grain i sums the forces from its listed neighbours in that order
and writes only row i.  Each pair force is therefore
computed twice (once for each partner) — the price of having no shared ``+=`` — and the two
evaluations are exact negatives of each other (:func:`dem.contacts.contact`).  The result is
the same bit for bit for any number of threads.

Integrator: velocity Verlet (kick–drift–kick): v ← v + (dt/2) a; x ← x + dt v; forces at the
new positions with the half-step velocities; v ← v + (dt/2) a.  The contact forces of the last
step are part of the state (``force``, ``torque``).  Semi-implicit Euler gave e = 0.486 for
e = 0.5 at dt = t_c/25 (first order in dt); the measured restitution here is in
tests/test_dem_contacts.py.
"""

import math

import numpy as np
from numba import njit, prange

from .conf import JIT_FLAGS, PARALLEL_FLAGS
from .contacts import contact

FREE = np.int8(0)
FEED = np.int8(1)
GONE = np.int8(2)
STATUS_NAMES = {0: "free", 1: "feed", 2: "gone"}


@njit(**JIT_FLAGS)
def _cell_x(x, x0, hx, ncx, periodic, length):
    if periodic:
        xx = x - length * math.floor(x / length)
        ix = int(xx / hx)
        if ix >= ncx:
            ix = ncx - 1
        return ix
    ix = int(math.floor((x - x0) / hx))
    if ix < 0:
        ix = 0
    if ix >= ncx:
        ix = ncx - 1
    return ix


@njit(**JIT_FLAGS)
def _cell_t(y, tube_r, h, n):
    i = int(math.floor((y + tube_r) / h))
    if i < 0:
        i = 0
    if i >= n:
        i = n - 1
    return i


@njit(**JIT_FLAGS)
def _separation(a, i, b, j, periodic, length):
    """a_i − b_j (3 components), the axial one the nearest periodic image in a periodic tube."""
    rx = a[i, 0] - b[j, 0]
    if periodic:
        if rx > 0.5 * length:
            rx -= length
        elif rx < -0.5 * length:
            rx += length
    return rx, a[i, 1] - b[j, 1], a[i, 2] - b[j, 2]


@njit(**JIT_FLAGS)
def build_cells(pos, status, x0, hx, ncx, ht, nct, tube_r, periodic, length, cell_start, items):
    """Counting sort of the non-GONE grains into cells (ncx × nct × nct, x fastest-varying last).

    cell_start int64[ncx*nct*nct + 1] receives the offsets into ``items`` (int64[N]); grains of a
    cell appear in ascending index.  Serial: O(N), a few percent of a step.
    """
    nc = ncx * nct * nct
    for c in range(nc + 1):
        cell_start[c] = 0
    n = pos.shape[0]
    cell = np.empty(n, dtype=np.int64)
    for i in range(n):
        if status[i] == GONE:
            cell[i] = -1
            continue
        ix = _cell_x(pos[i, 0], x0, hx, ncx, periodic, length)
        iy = _cell_t(pos[i, 1], tube_r, ht, nct)
        iz = _cell_t(pos[i, 2], tube_r, ht, nct)
        c = (ix * nct + iy) * nct + iz
        cell[i] = c
        cell_start[c + 1] += 1
    for c in range(nc):
        cell_start[c + 1] += cell_start[c]
    cursor = cell_start[:nc].copy()
    for i in range(n):
        c = cell[i]
        if c >= 0:
            items[cursor[c]] = i
            cursor[c] += 1


@njit(**JIT_FLAGS)
def build_neighbours(pos, status, cell_start, items, x0, hx, ncx, ht, nct, periodic, length, tube_r, reach2,
                     nbr_start, nbr):
    """Verlet list: for every non-GONE grain i the grains j ≠ i closer than the reach (d + skin).

    Written as compressed rows: the neighbours of i are ``nbr[nbr_start[i]:nbr_start[i + 1]]``,
    in the order of the cell search (cells in a fixed order, grains of a cell by index).  Needs
    the cells of :func:`build_cells` with sides ≥ the reach.  Returns the number of entries, or
    −1 when ``nbr`` is too short (the caller enlarges it and calls again).
    """
    n = pos.shape[0]
    m = 0
    cap = nbr.shape[0]
    for i in range(n):
        nbr_start[i] = m
        if status[i] == GONE:
            continue
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        cix = _cell_x(xi, x0, hx, ncx, periodic, length)
        ciy = _cell_t(yi, tube_r, ht, nct)
        ciz = _cell_t(zi, tube_r, ht, nct)
        for ddx in range(-1, 2):
            cx = cix + ddx
            if periodic:
                if cx < 0:
                    cx += ncx
                elif cx >= ncx:
                    cx -= ncx
            elif cx < 0 or cx >= ncx:
                continue
            for ddy in range(-1, 2):
                cy = ciy + ddy
                if cy < 0 or cy >= nct:
                    continue
                for ddz in range(-1, 2):
                    cz = ciz + ddz
                    if cz < 0 or cz >= nct:
                        continue
                    c = (cx * nct + cy) * nct + cz
                    for k in range(cell_start[c], cell_start[c + 1]):
                        j = items[k]
                        if j == i:
                            continue
                        rx, ry, rz = _separation(pos, i, pos, j, periodic, length)
                        if rx * rx + ry * ry + rz * rz < reach2:
                            if m >= cap:
                                return -1
                            nbr[m] = j
                            m += 1
    nbr_start[n] = m
    return m


def _contact_forces(pos, vel, omg, status, nbr_start, nbr, periodic, length,
                   radius, tube_r, plate_x, k_n, gn_pp, gt_pp, mu_pp, gn_pw, gt_pw, mu_pw,
                   force, torque, overlap, wall_fn):
    """Contact force and torque on every grain (pairs, cylinder wall, optional plate at x = plate_x).

    Pairs from the Verlet list (:func:`build_neighbours`).  plate_x = NaN: no plate.  Writes force,
    torque [N, N m], overlap (largest overlap of the grain [m]) and wall_fn (sum of the
    cylinder-wall normal forces on the grain [N]).  One row per grain: race-free.
    """
    n = pos.shape[0]
    d = 2.0 * radius
    d2 = d * d
    has_plate = not math.isnan(plate_x)
    for i in prange(n):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        omax = 0.0
        fw = 0.0
        if status[i] != GONE:
            xi = pos[i, 0]
            yi = pos[i, 1]
            zi = pos[i, 2]
            for k in range(nbr_start[i], nbr_start[i + 1]):
                j = nbr[k]
                rx, ry, rz = _separation(pos, i, pos, j, periodic, length)
                r2 = rx * rx + ry * ry + rz * rz
                if r2 >= d2 or r2 == 0.0:
                    continue
                dist = math.sqrt(r2)
                delta = d - dist
                if delta > omax:
                    omax = delta
                a, b, cc, e, f, g, fn = contact(
                    rx / dist, ry / dist, rz / dist, delta,
                    vel[i, 0] - vel[j, 0], vel[i, 1] - vel[j, 1], vel[i, 2] - vel[j, 2],
                    omg[i, 0] + omg[j, 0], omg[i, 1] + omg[j, 1], omg[i, 2] + omg[j, 2],
                    radius, k_n, gn_pp, gt_pp, mu_pp)
                fx += a
                fy += b
                fz += cc
                tx += e
                ty += f
                tz += g
            # cylinder wall
            rr = math.sqrt(yi * yi + zi * zi)
            delta = rr + radius - tube_r
            if delta > 0.0 and rr > 0.0:
                if delta > omax:
                    omax = delta
                a, b, cc, e, f, g, fn = contact(
                    0.0, -yi / rr, -zi / rr, delta, vel[i, 0], vel[i, 1], vel[i, 2],
                    omg[i, 0], omg[i, 1], omg[i, 2], radius, k_n, gn_pw, gt_pw, mu_pw)
                fx += a
                fy += b
                fz += cc
                tx += e
                ty += f
                tz += g
                fw += fn
            if has_plate:
                delta = radius - (xi - plate_x)
                if delta > 0.0:
                    if delta > omax:
                        omax = delta
                    a, b, cc, e, f, g, fn = contact(
                        1.0, 0.0, 0.0, delta, vel[i, 0], vel[i, 1], vel[i, 2],
                        omg[i, 0], omg[i, 1], omg[i, 2], radius, k_n, gn_pw, gt_pw, mu_pw)
                    fx += a
                    fy += b
                    fz += cc
                    tx += e
                    ty += f
                    tz += g
        force[i, 0] = fx
        force[i, 1] = fy
        force[i, 2] = fz
        torque[i, 0] = tx
        torque[i, 1] = ty
        torque[i, 2] = tz
        overlap[i] = omax
        wall_fn[i] = fw


def _kick(vel, omg, status, force, torque, gas_force, gx, gy, gz, mass, inertia, h):
    """Half kick of the FREE grains: v ← v + h (F/m + g), ω ← ω + h T/I (F = contacts + gas)."""
    n = vel.shape[0]
    for i in prange(n):
        if status[i] == FREE:
            vel[i, 0] += h * ((force[i, 0] + gas_force[i, 0]) / mass + gx)
            vel[i, 1] += h * ((force[i, 1] + gas_force[i, 1]) / mass + gy)
            vel[i, 2] += h * ((force[i, 2] + gas_force[i, 2]) / mass + gz)
            omg[i, 0] += h * torque[i, 0] / inertia
            omg[i, 1] += h * torque[i, 1] / inertia
            omg[i, 2] += h * torque[i, 2] / inertia


def _drift(pos, vel, omg, status, dt, v_feed):
    """Drift: FREE grains x ← x + dt v; FEED grains move at (v_feed, 0, 0) without rotation."""
    n = pos.shape[0]
    for i in prange(n):
        s = status[i]
        if s == FREE:
            pos[i, 0] += dt * vel[i, 0]
            pos[i, 1] += dt * vel[i, 1]
            pos[i, 2] += dt * vel[i, 2]
        elif s == FEED:
            vel[i, 0] = v_feed
            vel[i, 1] = 0.0
            vel[i, 2] = 0.0
            omg[i, 0] = 0.0
            omg[i, 1] = 0.0
            omg[i, 2] = 0.0
            pos[i, 0] += dt * v_feed


# Two compiled variants of each kernel from the same source: ``prange`` over grains (parallel) and
# a plain loop (serial; ``prange`` is ``range`` without parallel=True).  Measured reason: on a
# loaded 2-core machine (load average 9) a parallel launch costs ~0.6 ms whatever the work, so
# a 322-grain step took 1.7 ms in parallel against ~0.1 ms serial; the serial driver
# :func:`run_steps` also does all DEM steps of a gas step in one call.
contact_forces = njit(**PARALLEL_FLAGS)(_contact_forces)
kick = njit(**PARALLEL_FLAGS)(_kick)
drift = njit(**PARALLEL_FLAGS)(_drift)
contact_forces_serial = njit(**JIT_FLAGS)(_contact_forces)
kick_serial = njit(**JIT_FLAGS)(_kick)
drift_serial = njit(**JIT_FLAGS)(_drift)


def _make_run_steps(cf, kk, dr):
    def run_steps(nsteps, pos, vel, omg, force, torque, status, gas_force, vp, wp, items, overlap, wall_fn,
                  pos_ref, cell_start, x0, hx, ncx, ht, nct, periodic, length, radius, tube_r, skin, plate_x,
                  k_n, gn_pp, gt_pp, mu_pp, gn_pw, gt_pw, mu_pw, gx, gy, gz, mass, inertia, dt, v_feed):
        """``nsteps`` velocity-Verlet steps (see :func:`dem_step`); returns the largest overlap [m].

        The Verlet list is built after the first drift and again whenever a grain has moved more
        than skin/2 since (two grains then cannot have closed more than the skin: no contact is
        missed)."""
        h = 0.5 * dt
        omax = 0.0
        n = pos.shape[0]
        reach = 2.0 * radius + skin
        reach2 = reach * reach
        lim2 = 0.25 * skin * skin
        nbr_start = np.zeros(n + 1, dtype=np.int64)
        nbr = np.empty(16 * n + 64, dtype=np.int64)
        stale = True
        for _ in range(nsteps):
            kk(vel, omg, status, force, torque, gas_force, gx, gy, gz, mass, inertia, h)
            dr(pos, vel, omg, status, dt, v_feed)
            if periodic:
                for i in range(n):
                    pos[i, 0] -= length * math.floor(pos[i, 0] / length)
            for i in range(n):
                for q in range(3):
                    vp[i, q] = vel[i, q]
                    wp[i, q] = omg[i, q]
            kk(vp, wp, status, force, torque, gas_force, gx, gy, gz, mass, inertia, h)
            if not stale:
                for i in range(n):
                    ex, ey, ez = _separation(pos, i, pos_ref, i, periodic, length)
                    if ex * ex + ey * ey + ez * ez > lim2:
                        stale = True
                        break
            if stale:
                build_cells(pos, status, x0, hx, ncx, ht, nct, tube_r, periodic, length, cell_start, items)
                while build_neighbours(pos, status, cell_start, items, x0, hx, ncx, ht, nct, periodic, length,
                                       tube_r, reach2, nbr_start, nbr) < 0:
                    nbr = np.empty(2 * nbr.shape[0], dtype=np.int64)
                for i in range(n):
                    for q in range(3):
                        pos_ref[i, q] = pos[i, q]
                stale = False
            cf(pos, vp, wp, status, nbr_start, nbr, periodic, length, radius, tube_r,
               plate_x, k_n, gn_pp, gt_pp, mu_pp, gn_pw, gt_pw, mu_pw, force, torque, overlap, wall_fn)
            kk(vel, omg, status, force, torque, gas_force, gx, gy, gz, mass, inertia, h)
            for i in range(n):
                if overlap[i] > omax:
                    omax = overlap[i]
        return omax
    return run_steps


run_steps_serial = njit(**JIT_FLAGS)(_make_run_steps(contact_forces_serial, kick_serial, drift_serial))
run_steps_parallel = njit(**JIT_FLAGS)(_make_run_steps(contact_forces, kick, drift))


class Grains:
    """Structure of arrays of the grains with spare capacity; the driver appends and compacts."""

    def __init__(self, capacity=1024):
        self.n = 0
        self._alloc(capacity)

    def _alloc(self, cap):
        self.pos = np.zeros((cap, 3))
        self.vel = np.zeros((cap, 3))
        self.omg = np.zeros((cap, 3))
        self.force = np.zeros((cap, 3))
        self.torque = np.zeros((cap, 3))
        self.status = np.full(cap, GONE, dtype=np.int8)
        self.gid = np.full(cap, -1, dtype=np.int64)

    ARRAYS = ("pos", "vel", "omg", "force", "torque", "status", "gid")

    def view(self, name):
        return getattr(self, name)[: self.n]

    def append(self, pos, vel, status, gid):
        m = len(pos)
        if self.n + m > len(self.status):
            cap = max(2 * len(self.status), self.n + m)
            old = {k: getattr(self, k)[: self.n].copy() for k in self.ARRAYS}
            self._alloc(cap)
            for k, v in old.items():
                getattr(self, k)[: self.n] = v
        s = slice(self.n, self.n + m)
        self.pos[s] = pos
        self.vel[s] = vel
        self.omg[s] = 0.0
        self.force[s] = 0.0
        self.torque[s] = 0.0
        self.status[s] = status
        self.gid[s] = gid
        self.n += m

    def compact(self):
        """Drop GONE grains, keeping the order of the others (deterministic)."""
        keep = np.flatnonzero(self.status[: self.n] != GONE)
        for k in self.ARRAYS:
            a = getattr(self, k)
            a[: len(keep)] = a[keep]
            a[len(keep): self.n] = GONE if k == "status" else 0
        self.n = len(keep)

    def state(self):
        return {k: self.view(k).copy() for k in self.ARRAYS}

    @classmethod
    def from_state(cls, st):
        g = cls(max(1024, 2 * len(st["status"])))
        g.append(st["pos"], st["vel"], st["status"], st["gid"])
        for k in ("omg", "force", "torque"):
            getattr(g, k)[: g.n] = st[k]
        return g


class ContactModel:
    """Contact constants from the material: mass, inertia, dashpots for pairs and wall."""

    def __init__(self, diameter, density, stiffness, restitution, friction, wall_friction=None,
                 wall_restitution=None, tangential_ratio=1.0):
        from .contacts import contact_time, dashpot_coefficient

        self.radius = 0.5 * diameter
        self.volume = math.pi / 6.0 * diameter ** 3
        self.mass = density * self.volume
        self.inertia = 0.4 * self.mass * self.radius ** 2
        self.k_n = stiffness
        ew = restitution if wall_restitution is None else wall_restitution
        self.gn_pp = dashpot_coefficient(restitution, stiffness, 0.5 * self.mass)
        self.gn_pw = dashpot_coefficient(ew, stiffness, self.mass)
        self.gt_pp = tangential_ratio * self.gn_pp
        self.gt_pw = tangential_ratio * self.gn_pw
        self.mu_pp = friction
        self.mu_pw = friction if wall_friction is None else wall_friction
        self.t_contact = contact_time(restitution, stiffness, 0.5 * self.mass)


#: Skin of the Verlet list [grain diameters]: pairs closer than (1 + SKIN) d are listed.
SKIN = 0.2


class CellGrid:
    """Cell-list geometry: cells ≥ the Verlet reach (1 + skin) d on a side covering [x0, x1) × the tube."""

    def __init__(self, x0, x1, tube_r, diameter, periodic=False, skin=SKIN):
        self.periodic = bool(periodic)
        self.length = x1 - x0
        self.x0 = x0
        if not skin >= 0.0:
            raise ValueError(f"skin = {skin!r}: allowed a number >= 0 (grain diameters)")
        self.skin = skin * diameter
        reach = diameter + self.skin
        self.ncx = max(1, int(math.floor(self.length / reach)))
        if periodic and self.ncx < 3:
            raise ValueError(f"tube.length_m = {self.length}: allowed >= {3 * reach:.4g} m (three cells of the "
                             f"neighbour search, 3 (1 + skin) grain diameters) for a periodic tube")
        self.hx = self.length / self.ncx
        self.tube_r = tube_r
        self.nct = max(1, int(math.floor(2 * tube_r / reach)))
        self.ht = 2 * tube_r / self.nct
        self.cell_start = np.zeros(self.ncx * self.nct * self.nct + 1, dtype=np.int64)


def dem_step(g, model, grid, gas_force, gravity, dt, v_feed, plate_x, work, nsteps=1, parallel=False):
    """``nsteps`` velocity-Verlet DEM steps of the grains ``g`` (a :class:`Grains`); ``work`` holds scratch.

    Kick–drift–kick: v ← v + (dt/2) a; x ← x + dt v; contact forces at the new positions with the
    velocities predicted to the end of the step (v + (dt/2) a_old, for the dashpots); v ← v + (dt/2) a.
    ``gas_force`` [N] (N, 3) is held constant.  Returns the largest overlap [m] found.
    ``parallel`` picks the ``prange`` kernels (bit-identical results, see module docstring).
    """
    n = g.n
    if work.get("n", -1) < n:
        cap = len(g.status)
        work.update(items=np.zeros(cap, dtype=np.int64), overlap=np.zeros(cap), wall_fn=np.zeros(cap),
                    vp=np.zeros((cap, 3)), wp=np.zeros((cap, 3)), pos_ref=np.zeros((cap, 3)), n=cap)
    if n == 0:
        return 0.0
    run = run_steps_parallel if parallel else run_steps_serial
    return run(nsteps, g.pos[:n], g.vel[:n], g.omg[:n], g.force[:n], g.torque[:n], g.status[:n], gas_force[:n],
               work["vp"][:n], work["wp"][:n], work["items"][:n], work["overlap"][:n], work["wall_fn"][:n],
               work["pos_ref"][:n], grid.cell_start, grid.x0, grid.hx, grid.ncx, grid.ht, grid.nct, grid.periodic,
               grid.length, model.radius, grid.tube_r, grid.skin, plate_x, model.k_n, model.gn_pp, model.gt_pp, model.mu_pp, model.gn_pw,
               model.gt_pw, model.mu_pw, float(gravity[0]), float(gravity[1]), float(gravity[2]), model.mass,
               model.inertia, dt, v_feed)
