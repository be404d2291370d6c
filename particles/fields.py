"""Gas fields seen by the particles: a per-cell table and its interpolation to a point.

``FieldTable.from_gas(mesh, gas)`` packs, per cell, the mean velocity U (3), k, ε, the
mean-flow vorticity ∇ × U (3) into one contiguous array ``values[nx, nr, nt, NT]``
(gradients: axial by central differences, cross-section by the finite-volume gradient of
``rans.operators.Section``); ``axis[nx, NF]`` holds the ring-0 means, the value on the axis.

``interpolate`` (numba) evaluates the fields at a point (x, y, z):

* axially linear between station centres (constant beyond the first and last);
* in the cross-section bilinear in (r, θ) between the four surrounding cell centres;
* inside the innermost ring (r below the ring-0 centre) linear in r between the axis value
  and the ring values, so the fields are single-valued and continuous through the axis;
* ∇k (for the Langevin drift correction) is the exact gradient of the interpolated k, so
  the drift is consistent with the σ² = 2k/3 the dispersion model actually sees;
* inside the wall-function cell (beyond the wall-ring centre, distance y from the wall less
  than y_P) the log-law reconstruction (docs/physics.md, section 3; ``wall_law``, case key
  ``physics.wall_cell_fields``), with the wall-ring values at the particle's (x, θ):

      U_t(y) = U_t,P g(y*)/g(y*_P),   g(y*) = ln(E y*)/κ  (y* ≥ y*_v),  g = y*  (y* < y*_v)
      u_n(y) = u_n,P y / y_P           (wall-normal component, zero at the wall)
      ∇ × U  = n₀ × dU_t/dy            (n₀ the inward wall normal)
      k = k_P,   ε = ε_P y_P / max(y, y_v),   ∇k = 0

  with y* = C_μ^¼ k_P^½ y/ν and y*_v ≈ 11.53 the point where the linear and logarithmic
  profiles meet (continuous profile); ε ∝ 1/y holds in the log layer and is held at its
  sublayer-edge value below y_v, where the log law does not apply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from collisions.conf import JIT_FLAGS, KERNEL_FLAGS
from rans import kepsilon as ke
from rans.mesh import cell_index

__all__ = ["FieldTable", "interpolate", "NF", "F_UX", "F_UY", "F_UZ", "F_K", "F_EPS",
           "F_WX", "F_WY", "F_WZ", "F_DKX", "F_DKY", "F_DKZ", "NT"]

# field indices of the table (last axis)
F_UX, F_UY, F_UZ = 0, 1, 2  # mean gas velocity [m s-1]
F_K, F_EPS = 3, 4  # k [m2 s-2], epsilon [m2 s-3]
F_WX, F_WY, F_WZ = 5, 6, 7  # vorticity of the mean flow, curl U [s-1]
F_DKX, F_DKY, F_DKZ = 8, 9, 10  # grad k [m s-2] (of the interpolated k; not stored in the table)
NT = 8  # fields stored per cell in the table
NF = 11  # fields returned by ``interpolate``


YSTAR_VISCOUS = ke.YSTAR_LAMINAR  # where u+ = y+ meets the log law (rans.kepsilon), ~11.53


@dataclass(frozen=True, eq=False)
class FieldTable:
    """Per-cell gas data for the tracker (arrays in SI units, see the module docstring).

    values (nx, nr, nt, NF); axis (nx, NF); x_centres (nx,); r_centres (nr,); r_edges (nr+1,);
    x_edges (nx+1,); nt; length, radius [m]; nu [m2 s-1] kinematic viscosity; rho [kg m-3].
    """

    values: np.ndarray
    axis: np.ndarray
    x_centres: np.ndarray
    x_edges: np.ndarray
    r_centres: np.ndarray
    r_edges: np.ndarray
    nt: int
    length: float
    radius: float
    rho: float
    nu: float

    @classmethod
    def from_gas(cls, mesh, gas):
        """Table of a converged :class:`rans.GasField` ``gas`` on ``mesh``."""
        nx, nr, nt = mesh.shape
        ux, uy, uz, k, eps = (np.asarray(getattr(gas, n), dtype=np.float64).reshape(nx, nr, nt)
                              for n in ("ux", "uy", "uz", "k", "epsilon"))
        tab = np.empty((nx, nr, nt, NT))
        axis = np.empty((nx, NT))
        table_rows(mesh.geometry(), mesh.x, ux, uy, uz, k, eps, 0, nx, tab, axis)
        problem = table_problem(tab, k, eps)
        if problem:
            raise ValueError(problem)
        return cls.on_mesh(mesh, gas.gas, tab, axis)

    @classmethod
    def on_mesh(cls, mesh, gas_props, values, axis):
        """The table of ``values`` (nx, nr, nt, NT) and ``axis`` (nx, NT) on ``mesh`` for the gas
        properties ``gas_props`` (``rans.GasProperties``); the arrays are used, not copied."""
        return cls(values=values, axis=axis,
                   x_centres=np.asarray(mesh.x, dtype=np.float64).copy(),
                   x_edges=np.asarray(mesh.x_edges, dtype=np.float64).copy(),
                   r_centres=np.asarray(mesh.r, dtype=np.float64).copy(),
                   r_edges=np.asarray(mesh.r_edges, dtype=np.float64).copy(),
                   nt=int(mesh.nt), length=float(mesh.length), radius=float(mesh.radius),
                   rho=float(gas_props.density), nu=float(gas_props.kinematic_viscosity))

    @property
    def shape(self):
        return self.values.shape[:3]

    def at(self, x, y, z, wall_law=True):
        """Fields (NF,) at one point (Python convenience around ``interpolate``)."""
        out = np.empty(NF)
        interpolate(float(x), float(y), float(z), self.values, self.axis, self.x_centres,
                    self.r_centres, self.r_edges, self.length, self.radius, self.nu, out, -1,
                    bool(wall_law))
        return out


def axial_gradient(phi, x, j0, j1):
    """Rows j0 … j1−1 of ``np.gradient(phi, x, axis=0)`` (first-order edges), bit for bit:
    central differences on non-uniform spacing inside, one-sided at the ends, and numpy's
    scalar form when the spacing is uniform to the last bit.  Rows need only their two
    neighbours, so a table can be built station by station as a march produces them
    (particles.stream) and still equal the table of the whole field."""
    nx = phi.shape[0]
    out = np.empty((j1 - j0,) + phi.shape[1:])
    if nx == 1:
        out[...] = 0.0
        return out
    diffx = np.diff(np.asarray(x, dtype=np.float64))
    uniform = bool((diffx == diffx[0]).all())
    lo, hi = max(j0, 1), min(j1, nx - 1)  # interior rows
    if hi > lo:
        if uniform:
            out[lo - j0:hi - j0] = (phi[lo + 1:hi + 1] - phi[lo - 1:hi - 1]) / (2.0 * diffx[0])
        else:
            dx1 = diffx[lo - 1:hi - 1]
            dx2 = diffx[lo:hi]
            shape = (-1,) + (1,) * (phi.ndim - 1)
            a = (-(dx2) / (dx1 * (dx1 + dx2))).reshape(shape)
            b = ((dx2 - dx1) / (dx1 * dx2)).reshape(shape)
            c = (dx1 / (dx2 * (dx1 + dx2))).reshape(shape)
            out[lo - j0:hi - j0] = a * phi[lo - 1:hi - 1] + b * phi[lo:hi] + c * phi[lo + 1:hi + 1]
    if j0 == 0:
        out[0] = (phi[1] - phi[0]) / diffx[0]
    if j1 == nx:
        out[nx - 1 - j0] = (phi[nx - 1] - phi[nx - 2]) / diffx[-1]
    return out


def table_rows(sec, x, ux, uy, uz, k, eps, j0, j1, tab, axis):
    """Fill rows j0 … j1−1 of a field table ``tab`` (nx, nr, nt, NT) and of its axis values
    ``axis`` (nx, NT) from the gas fields ux … eps (nx, nr, nt), of which rows j0−1 … j1 (those
    that exist) must hold the gas: the vorticity takes the cross-section gradients of
    ``sec`` (``rans.operators.Section``; velocities vanish at the wall) and the axial ones of
    :func:`axial_gradient`.  The same rows come out however the range is split."""
    nr, nt = ux.shape[1:]
    n = j1 - j0
    g = {}
    for name, phi in (("ux", ux), ("uy", uy), ("uz", uz)):
        dz = np.empty((n, nr, nt))
        dy = np.empty((n, nr, nt))
        for i in range(j0, j1):
            a, b = sec.gradient(phi[i].ravel(), 0.0)
            dz[i - j0] = a.reshape(nr, nt)
            dy[i - j0] = b.reshape(nr, nt)
        g[name] = (axial_gradient(phi, x, j0, j1), dy, dz)
    rows = tab[j0:j1]
    rows[..., F_UX] = ux[j0:j1]
    rows[..., F_UY] = uy[j0:j1]
    rows[..., F_UZ] = uz[j0:j1]
    rows[..., F_K] = k[j0:j1]
    rows[..., F_EPS] = eps[j0:j1]
    rows[..., F_WX] = g["uz"][1] - g["uy"][2]  # d uz/dy - d uy/dz
    rows[..., F_WY] = g["ux"][2] - g["uz"][0]  # d ux/dz - d uz/dx
    rows[..., F_WZ] = g["uy"][0] - g["ux"][1]  # d uy/dx - d ux/dy
    axis[j0:j1] = rows[:, 0, :, :].mean(axis=1)


def table_problem(tab, k, eps):
    """Why particles cannot be tracked in these table rows and gas k, ε ('' if they can)."""
    if not np.all(np.isfinite(tab)):
        return "gas field has non-finite values; cannot track particles in it"
    if np.any(k <= 0.0) or np.any(eps <= 0.0):
        return "gas field has k <= 0 or epsilon <= 0; cannot track particles in it"
    return ""


_C_MU_QUARTER = ke.C_MU**0.25
_KAPPA = ke.KAPPA
_E_WALL = ke.E_WALL


@njit(**JIT_FLAGS)
def wall_profile(ystar):
    """u+ of the continuous sublayer/log-law profile at y* [-] (y* < y*_v: y*, else ln(E y*)/κ)."""
    if ystar < YSTAR_VISCOUS:
        return ystar
    return math.log(_E_WALL * ystar) / _KAPPA


@njit(**JIT_FLAGS)
def wall_profile_slope(ystar):
    """d u+/d y* of ``wall_profile`` [-]."""
    if ystar < YSTAR_VISCOUS:
        return 1.0
    return 1.0 / (_KAPPA * ystar)


@njit(**KERNEL_FLAGS)
def _blend_section(tab, i, j, k0, k1, wt, f, out, scale):
    """out[f] += scale * ((1 - wt) tab[i, j, k0, f] + wt tab[i, j, k1, f]) for all fields."""
    for q in range(f):
        out[q] += scale * ((1.0 - wt) * tab[i, j, k0, q] + wt * tab[i, j, k1, q])


@njit(**KERNEL_FLAGS)
def interpolate(x, y, z, tab, axis, xc, rc, r_edges, length, radius, nu, out, ring_hint=-1, wall_law=True):
    """Gas fields at the point (x, y, z) [m] into ``out`` (NF,); see the module docstring.

    tab (nx, nr, nt, NT), axis (nx, NT), xc (nx,) station centres (uniform), rc (nr,) ring
    centres, r_edges (nr+1,), length [m], radius [m], nu [m2 s-1].  Points beyond r = R are
    treated as on the wall ring.  Returns the indices (i, j, k) of the cell holding the point,
    as ``rans.locate_cell`` computes them (i = -1 outside the pipe).  ``ring_hint``: a ring
    near the point (the tracker passes the ring of the previous position), from which
    ``rans.mesh.cell_index`` steps to the ring instead of a binary search; the result is the
    same for any hint (-1: binary search).  ``wall_law``: inside the wall-function cell the
    log-law reconstruction (default); False: the wall-ring values at (x, θ) held out to the
    wall (U, k, ε and the table's ∇ × U of the ring centre; ∇k = 0), the fields a tracker
    without a wall model would see (``physics.wall_cell_fields = "wall-ring"``).
    """
    nx = tab.shape[0]
    nr = tab.shape[1]
    nt = tab.shape[2]
    for q in range(NF):
        out[q] = 0.0
    # axial weights
    if nx == 1:
        i0 = 0
        i1 = 0
        wx = 0.0
    else:
        s = (x - xc[0]) / (xc[1] - xc[0])
        if s <= 0.0:
            i0 = 0
            wx = 0.0
        elif s >= nx - 1:
            i0 = nx - 2
            wx = 1.0
        else:
            i0 = int(s)
            wx = s - i0
        i1 = i0 + 1
    # azimuthal weights (sector centres at (k + 1/2) dtheta)
    th = math.atan2(y, z)
    if th < 0.0:
        th += 2.0 * math.pi
    s = th * nt / (2.0 * math.pi) - 0.5
    kf = math.floor(s)
    wt = s - kf
    k0 = int(kf)  # -1 <= k0 < nt for 0 <= th <= 2 pi: wrap without an integer division
    if k0 < 0 or k0 >= nt:
        k0 = k0 % nt
    k1 = k0 + 1
    if k1 == nt:
        k1 = 0
    r = math.sqrt(y * y + z * z)
    ci, cj, ck = cell_index(x, r, th, length, nx, r_edges, nt, ring_hint)
    dwx = 0.0 if (nx == 1 or wx <= 0.0 or wx >= 1.0) else 1.0 / (xc[1] - xc[0])
    dwt = nt / (2.0 * math.pi)  # d wt / d theta
    if r < rc[nr - 1]:
        if r < rc[0]:  # between the axis and the ring-0 centres
            wr = r / rc[0]
            dwr = 1.0 / rc[0]
            for q in range(NT):
                out[q] = (1.0 - wr) * ((1.0 - wx) * axis[i0, q] + wx * axis[i1, q])
            _blend_section(tab, i0, 0, k0, k1, wt, NT, out, wr * (1.0 - wx))
            if wx > 0.0:
                _blend_section(tab, i1, 0, k0, k1, wt, NT, out, wr * wx)
            ka0 = axis[i0, F_K]
            ka1 = axis[i1, F_K]
            jlo = 0
            k_lo0 = ka0
            k_lo1 = ka1
            klo_t0 = 0.0  # theta derivative of the inner values (the axis value has none)
            klo_t1 = 0.0
            wr_for_t = wr
        else:
            if cj >= 0:  # rc[cj - 1] < r_edges[cj] <= r < r_edges[cj + 1] < rc[cj + 1]
                lo = cj if rc[cj] <= r else cj - 1
            else:
                lo = 0
                hi = nr - 1
                while hi - lo > 1:
                    mid = (lo + hi) >> 1
                    if rc[mid] <= r:
                        lo = mid
                    else:
                        hi = mid
            wr = (r - rc[lo]) / (rc[lo + 1] - rc[lo])
            dwr = 1.0 / (rc[lo + 1] - rc[lo])
            _blend_section(tab, i0, lo, k0, k1, wt, NT, out, (1.0 - wr) * (1.0 - wx))
            _blend_section(tab, i0, lo + 1, k0, k1, wt, NT, out, wr * (1.0 - wx))
            if wx > 0.0:
                _blend_section(tab, i1, lo, k0, k1, wt, NT, out, (1.0 - wr) * wx)
                _blend_section(tab, i1, lo + 1, k0, k1, wt, NT, out, wr * wx)
            k_lo0 = (1.0 - wt) * tab[i0, lo, k0, F_K] + wt * tab[i0, lo, k1, F_K]
            k_lo1 = (1.0 - wt) * tab[i1, lo, k0, F_K] + wt * tab[i1, lo, k1, F_K]
            klo_t0 = (tab[i0, lo, k1, F_K] - tab[i0, lo, k0, F_K]) * dwt
            klo_t1 = (tab[i1, lo, k1, F_K] - tab[i1, lo, k0, F_K]) * dwt
            jlo = lo + 1
            wr_for_t = -1.0
        # the outer ring of the radial interval (ring 0 for the axis region, else lo + 1)
        k_hi0 = (1.0 - wt) * tab[i0, jlo, k0, F_K] + wt * tab[i0, jlo, k1, F_K]
        k_hi1 = (1.0 - wt) * tab[i1, jlo, k0, F_K] + wt * tab[i1, jlo, k1, F_K]
        khi_t0 = (tab[i0, jlo, k1, F_K] - tab[i0, jlo, k0, F_K]) * dwt
        khi_t1 = (tab[i1, jlo, k1, F_K] - tab[i1, jlo, k0, F_K]) * dwt
        kr = ((1.0 - wx) * (k_hi0 - k_lo0) + wx * (k_hi1 - k_lo1)) * dwr
        kx = (((1.0 - wr) * k_lo1 + wr * k_hi1) - ((1.0 - wr) * k_lo0 + wr * k_hi0)) * dwx
        kt = (1.0 - wx) * ((1.0 - wr) * klo_t0 + wr * khi_t0) + wx * ((1.0 - wr) * klo_t1 + wr * khi_t1)
        if wr_for_t >= 0.0:  # axis region: (1/r) dk/dtheta = (1/rc0) d k_ring0/dtheta, finite at r = 0
            kt_over_r = ((1.0 - wx) * khi_t0 + wx * khi_t1) / rc[0]
        else:
            kt_over_r = kt / r
        if r > 0.0:
            st = y / r
            ct = z / r
        else:
            st = 0.0
            ct = 1.0
        out[F_DKX] = kx
        out[F_DKY] = st * kr + ct * kt_over_r
        out[F_DKZ] = ct * kr - st * kt_over_r
        return ci, cj, ck
    # wall-function cell: wall-ring values at (x, theta), then the log-law reconstruction
    j = nr - 1
    if not wall_law:
        _blend_section(tab, i0, j, k0, k1, wt, NT, out, 1.0 - wx)
        if wx > 0.0:
            _blend_section(tab, i1, j, k0, k1, wt, NT, out, wx)
        out[F_DKX] = 0.0
        out[F_DKY] = 0.0
        out[F_DKZ] = 0.0
        return ci, cj, ck
    _blend_section(tab, i0, j, k0, k1, wt, F_EPS + 1, out, 1.0 - wx)
    if wx > 0.0:
        _blend_section(tab, i1, j, k0, k1, wt, F_EPS + 1, out, wx)
    kp = out[F_K]
    epsp = out[F_EPS]
    y_p = radius - rc[nr - 1]
    y_w = radius - r
    if y_w < 1e-9 * radius:
        y_w = 1e-9 * radius
    if r > 0.0:
        ery = y / r
        erz = z / r
    else:
        ery = 0.0
        erz = 1.0
    un = out[F_UY] * ery + out[F_UZ] * erz  # outward radial component at the wall-ring centre
    tx = out[F_UX]
    ty = out[F_UY] - un * ery
    tz = out[F_UZ] - un * erz
    ustar = _C_MU_QUARTER * math.sqrt(kp)
    ys_p = ustar * y_p / nu
    ys = ustar * y_w / nu
    gp = wall_profile(ys_p)
    ratio = wall_profile(ys) / gp
    slope = wall_profile_slope(ys) * ustar / (nu * gp)  # d(U_t/U_t,P)/dy [1/m]
    fn = y_w / y_p
    out[F_UX] = tx * ratio
    out[F_UY] = ty * ratio + un * fn * ery
    out[F_UZ] = tz * ratio + un * fn * erz
    # curl U = n0 x dU_t/dy with the inward normal n0 = (0, -ery, -erz)
    dtx = tx * slope
    dty = ty * slope
    dtz = tz * slope
    out[F_WX] = -ery * dtz + erz * dty
    out[F_WY] = -erz * dtx
    out[F_WZ] = ery * dtx
    y_v = YSTAR_VISCOUS * nu / ustar
    out[F_EPS] = epsp * y_p / max(y_w, y_v)
    out[F_DKX] = 0.0
    out[F_DKY] = 0.0
    out[F_DKZ] = 0.0
    return ci, cj, ck
