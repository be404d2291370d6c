"""Pipe mesh: axial stations x a polar (r, theta) cross-section with wall clustering.

Coordinates (docs/physics.md, conventions): x along the pipe axis, y vertical up, z horizontal;
in the cross-section z = r cos(theta), y = r sin(theta), so theta = 90 deg is the top of the pipe.

Cross-section layout
--------------------
Cells are annular sectors (ring j, sector k).  The innermost ring consists of wedges that
meet at the axis; their zero-length axis faces carry no flux, and the wedges are coupled
to each other through their radial-line faces, so flow crosses the pipe centre without an
axis boundary condition.  The grid is orthogonal: the line joining two neighbouring cell
centres is normal to the face between them (centres lie on the sector mid-rays at the
radial centroid of their ring).  With an even number of sectors the sector edges are
symmetric about the vertical diameter (theta = pi/2) and the horizontal one.

The outermost ring is the wall-function cell.  Its thickness is chosen so that the
centre lies at the requested y+ (``first_cell_yplus``) for the friction velocity that
Colebrook's smooth-pipe friction factor (fluids.friction.Colebrook) predicts; the other
rings grow geometrically from the wall cell toward the axis (or are uniform when the
wall cell is already thicker than a uniform spacing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba

from jitcache import JIT_FLAGS
import numpy as np
from fluids.friction import Colebrook

__all__ = ["MAX_RING_GROWTH", "PipeMesh", "cell_index", "locate_cell", "radial_edges", "radial_growth",
           "ring_centre_radius", "ring_growth_problem", "rings_for_growth"]

#: Largest ratio allowed between the thicknesses of neighbouring rings (``radial_growth``).  The
#: march of a 0.3 m pipe at Re = 10^6 on 5 rings (wall cell at y+ 30, growth 6.4 per ring)
#: diverged in its first station with reversed axial flow; on 6 rings (growth 3.9) it ran.
#: Accurate finite-volume meshes keep the growth near 1.2; beyond 4 the mesh is refused.
MAX_RING_GROWTH = 4.0


def ring_centre_radius(r0, r1):
    """Radial centroid of the annulus r0 <= r <= r1: (2/3)(r1^3 - r0^3)/(r1^2 - r0^2) [m]."""
    r0 = np.asarray(r0, dtype=float)
    r1 = np.asarray(r1, dtype=float)
    return (2.0 / 3.0) * (r1**3 - r0**3) / (r1**2 - r0**2)


def _wall_cell_thickness(radius, y_wall):
    """Thickness of the wall ring whose centre (radial centroid) lies y_wall from the wall [m]."""
    # centre distance from the wall: R - rc(R - d, R) = d/2 - d^2/(6(2R - d)) (exact); Newton on d.
    d = 2.0 * y_wall
    for _ in range(30):
        rc = ring_centre_radius(radius - d, radius)
        f = (radius - rc) - y_wall
        h = 1e-7 * d
        fp = ((radius - ring_centre_radius(radius - d - h, radius)) - (radius - rc)) / h
        step = f / fp
        d -= step
        if abs(step) < 1e-14 * radius:
            break
    return float(d)


def wall_cell_thickness(diameter, first_cell_yplus, bulk_velocity, density, viscosity):
    """(thickness [m], u_tau [m/s]) of the wall ring whose centre sits at ``first_cell_yplus``,
    with the friction velocity of Colebrook's smooth-pipe Darcy factor at Re = rho U D / mu,
    u_tau = U sqrt(f_D / 8) (``PipeMesh.build``; the case check uses it before any mesh is built)."""
    re = density * bulk_velocity * diameter / viscosity
    f_d = Colebrook(re, 0.0)
    u_tau = bulk_velocity * math.sqrt(f_d / 8.0)
    y_wall = first_cell_yplus * viscosity / (density * u_tau)
    return _wall_cell_thickness(0.5 * diameter, y_wall), u_tau


def radial_growth(radius, radial_cells, wall_thickness):
    """Largest thickness ratio of neighbouring rings of :func:`radial_edges` (1 when uniform)."""
    sizes = np.diff(radial_edges(radius, radial_cells, wall_thickness))
    return float(np.max(sizes[:-1] / sizes[1:])) if sizes.size > 1 else 1.0


def rings_for_growth(radius, wall_thickness, limit=MAX_RING_GROWTH, most=400):
    """The fewest rings (>= 2) whose :func:`radial_growth` is at most ``limit`` (``most`` if none)."""
    for n in range(2, most + 1):
        if radial_growth(radius, n, wall_thickness) <= limit:
            return n
    return most


def ring_growth_problem(radius, radial_cells, wall_thickness):
    """What is wrong with ``radial_cells`` rings on this wall cell, as the "allowed" part of a
    one-line message (None when the rings grow at most :data:`MAX_RING_GROWTH` per ring)."""
    growth = radial_growth(radius, radial_cells, wall_thickness)
    if growth <= MAX_RING_GROWTH:
        return None
    return (f"enough rings that each is at most {MAX_RING_GROWTH:g} times as thick as the next one outward "
            f"(here {growth:.3g}, from a wall cell {wall_thickness:.3g} m thick in a pipe of radius {radius:g} m): "
            f"at least {rings_for_growth(radius, wall_thickness)} radial cells, or raise numerics.first_cell_yplus")


def radial_edges(radius, radial_cells, wall_thickness):
    """Ring edges 0 = r_0 < ... < r_n = R with a wall ring of the given thickness [m].

    The remaining rings follow a geometric progression whose ratio q >= 1 makes the
    ring next to the wall ring as thick as the wall ring (smooth transition) and the
    rings grow toward the axis; if the wall ring is thicker than a uniform spacing of
    the rest, the rest is uniform.
    """
    n = int(radial_cells)
    if n < 2:
        raise ValueError(f"radial_cells = {n}: at least 2 rings are needed")
    if not 0.0 < wall_thickness < radius:
        raise ValueError(
            f"wall cell thickness {wall_thickness:.3g} m does not fit in the pipe radius {radius:.3g} m; "
            "lower first_cell_yplus or raise the bulk velocity"
        )
    rest = radius - wall_thickness
    m = n - 1
    if wall_thickness * m >= rest:
        sizes = np.full(m, rest / m)
    else:
        # solve wall_thickness * (q^m - 1)/(q - 1) = rest for q > 1 (bisection, monotone)
        lo, hi = 1.0 + 1e-12, 2.0
        g = lambda q: wall_thickness * (q**m - 1.0) / (q - 1.0) - rest  # noqa: E731
        while g(hi) < 0:
            hi *= 2.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if g(mid) > 0:
                hi = mid
            else:
                lo = mid
        q = 0.5 * (lo + hi)
        sizes = wall_thickness * q ** np.arange(m)  # from the wall inward
        sizes = sizes[::-1] * rest / sizes.sum()  # axis -> wall, exact sum
    edges = np.concatenate([[0.0], np.cumsum(sizes), [radius]])
    edges[-2] = radius - wall_thickness
    return edges


@numba.njit(**JIT_FLAGS)
def cell_index(x, r, th, length, nx, r_edges, nt, ring_hint=-1):
    """Cell indices (i, j, k) of a point at axial x [m], radius r [m] and polar angle
    th in [0, 2 pi) [rad]; i = -1 outside the pipe.  Axial cells are uniform; ring j from a
    binary search of ``r_edges``, or, given a ring near the point (``ring_hint`` >= 0, e.g. a
    particle's ring of its previous step), by stepping from it (the same j for any hint);
    sector k from th (uniform sectors starting at theta = 0)."""
    nr = r_edges.shape[0] - 1
    if x < 0.0 or x > length or r > r_edges[nr]:
        return -1, -1, -1
    i = int(x / length * nx)
    if i >= nx:
        i = nx - 1
    if ring_hint >= 0:
        lo = min(ring_hint, nr - 1)
        while lo > 0 and r_edges[lo] > r:
            lo -= 1
        while lo < nr - 1 and r_edges[lo + 1] <= r:
            lo += 1
    else:
        lo = 0
        hi = nr
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if r_edges[mid] <= r:
                lo = mid
            else:
                hi = mid
    k = int(th / (2.0 * math.pi) * nt)
    if k >= nt:
        k = nt - 1
    return i, lo, k


@numba.njit(**JIT_FLAGS)
def locate_cell(x, y, z, length, nx, r_edges, nt):
    """Cell indices (i, j, k) containing the point (x, y, z) [m], or i = -1 outside.

    O(log nr) per call (see ``cell_index``).
    """
    th = math.atan2(y, z)
    if th < 0.0:
        th += 2.0 * math.pi
    return cell_index(x, math.sqrt(y * y + z * z), th, length, nx, r_edges, nt)


@dataclass(frozen=True, eq=False)
class PipeMesh:
    """Structured pipe mesh: ``nx`` axial cells x ``nr`` rings x ``nt`` sectors.

    Attributes (SI units)
    ---------------------
    diameter, radius, length [m]; mode: "developing" | "periodic".
    x_edges (nx+1,), x (nx,) axial cell faces and centres [m] (periodic: one cell, x = [0]).
    r_edges (nr+1,), r (nr,) ring edges and centre radii [m].
    theta_edges (nt+1,), theta (nt,) sector edges and mid-angles [rad].
    y, z (nr, nt) cell centres [m]; cell_area (nr, nt) exact annular-sector areas [m2];
    volume (nx, nr, nt) [m3]; wall_distance: distance of the wall-ring centre from the wall [m];
    yplus_target: the y+ the wall ring was designed for; friction_velocity_estimate [m/s].
    """

    diameter: float
    length: float
    mode: str
    x_edges: np.ndarray
    r_edges: np.ndarray
    nt: int
    yplus_target: float = float("nan")
    friction_velocity_estimate: float = float("nan")
    _geo: dict = field(default_factory=dict, repr=False)

    # ----------------------------------------------------------------- construction
    @classmethod
    def build(
        cls,
        diameter,
        length,
        mode="developing",
        axial_cells=400,
        radial_cells=20,
        azimuthal_cells=40,
        first_cell_yplus=30.0,
        bulk_velocity=10.0,
        density=1.205,
        viscosity=1.81e-5,
    ):
        """Mesh for a pipe [m] whose wall ring centre sits at ``first_cell_yplus``.

        The friction velocity is estimated from Colebrook's smooth-pipe Darcy factor at
        Re = rho U D / mu: u_tau = U sqrt(f_D / 8).
        """
        if mode not in ("developing", "periodic"):
            raise ValueError(f"mode = {mode!r}: allowed 'developing' or 'periodic'")
        if azimuthal_cells < 4 or azimuthal_cells % 2:
            raise ValueError(f"azimuthal_cells = {azimuthal_cells}: an even number >= 4 is needed")
        radius = 0.5 * diameter
        wall, u_tau = wall_cell_thickness(diameter, first_cell_yplus, bulk_velocity, density, viscosity)
        r_edges = radial_edges(radius, radial_cells, wall)
        nx = 1 if mode == "periodic" else int(axial_cells)
        x_edges = np.linspace(0.0, length, nx + 1)
        return cls(
            diameter=float(diameter),
            length=float(length),
            mode=mode,
            x_edges=x_edges,
            r_edges=r_edges,
            nt=int(azimuthal_cells),
            yplus_target=float(first_cell_yplus),
            friction_velocity_estimate=float(u_tau),
        )

    # ----------------------------------------------------------------- basic sizes
    @property
    def radius(self):
        return 0.5 * self.diameter

    @property
    def nx(self):
        return self.x_edges.size - 1

    @property
    def nr(self):
        return self.r_edges.size - 1

    @property
    def shape(self):
        return (self.nx, self.nr, self.nt)

    @property
    def ncells_section(self):
        return self.nr * self.nt

    @property
    def x(self):
        if self.mode == "periodic":
            return np.zeros(1)
        return 0.5 * (self.x_edges[1:] + self.x_edges[:-1])

    @property
    def dx(self):
        return np.diff(self.x_edges)

    @property
    def r(self):
        return ring_centre_radius(self.r_edges[:-1], self.r_edges[1:])

    @property
    def dtheta(self):
        return 2.0 * math.pi / self.nt

    @property
    def theta_edges(self):
        return np.arange(self.nt + 1) * self.dtheta

    @property
    def theta(self):
        return (np.arange(self.nt) + 0.5) * self.dtheta

    @property
    def z(self):
        return np.outer(self.r, np.cos(self.theta))

    @property
    def y(self):
        return np.outer(self.r, np.sin(self.theta))

    @property
    def cell_area(self):
        ring = 0.5 * (self.r_edges[1:] ** 2 - self.r_edges[:-1] ** 2) * self.dtheta
        return np.repeat(ring[:, None], self.nt, axis=1)

    @property
    def volume(self):
        return self.dx[:, None, None] * self.cell_area[None, :, :]

    @property
    def wall_distance(self):
        return self.radius - self.r[-1]

    # ----------------------------------------------------------------- point location
    def locate(self, x, y, z):
        """Indices (i, j, k) of the cell holding each point; -1 for points outside the pipe."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        y = np.atleast_1d(np.asarray(y, dtype=float))
        z = np.atleast_1d(np.asarray(z, dtype=float))
        return _locate_many(x, y, z, self.length, self.nx, self.r_edges, self.nt)

    # ----------------------------------------------------------------- face geometry
    def geometry(self):
        """Face lists of the cross-section (cached); see :class:`rans.operators.Section`."""
        if "section" not in self._geo:
            from .operators import Section

            self._geo["section"] = Section(self)
        return self._geo["section"]


@numba.njit(**JIT_FLAGS)
def _locate_many(x, y, z, length, nx, r_edges, nt):
    n = x.shape[0]
    out = np.empty((3, n), dtype=np.int64)
    for p in range(n):
        i, j, k = locate_cell(x[p], y[p], z[p], length, nx, r_edges, nt)
        out[0, p] = i
        out[1, p] = j
        out[2, p] = k
    return out[0], out[1], out[2]
