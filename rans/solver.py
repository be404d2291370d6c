"""Steady k-epsilon RANS for incompressible air in a straight circular pipe.

Method (docs/numerics.md, "Gas solver")
---------------------------------------
Space marching in the manner of Patankar & Spalding (1972): the pipe flow has no axial
recirculation, so each axial station is a 2-D cross-section problem.  The axial
derivative is a backward difference (second-order BDF2, variable first step), axial
diffusion and the axial gradient of the cross-section pressure are dropped.  Per station:

* axial momentum with the section-mean pressure gradient -dp/dx found so that the mass
  flow is exactly the prescribed one (the axial velocity is linear in dp/dx, so two
  right-hand sides of one LU factorisation give it);
* cross-section momentum (Cartesian components u_y, u_z) and a cross-section pressure p'
  by SIMPLEC with momentum interpolation; cross-section continuity contains -d(u_x)/dx;
  the pressure gradient and the body force (particle momentum source) meet at the faces
  ("balanced force", see rans.operators);
* k and epsilon with upwind convection, linearised implicit sinks and standard wall
  functions (rans.kepsilon), so both stay positive; any non-finite or non-positive value
  stops the solve with :class:`SolverDivergence` naming the variable and the cell.

The outer iterations at a station are repeated until the changes fall below ``tol``.
The fully developed ("periodic") mode is the same operator with d/dx = 0, reached by
pseudo-marching: the previous iterate plays the upstream station, so at convergence the
axial derivative vanishes and the bulk velocity is still imposed exactly.

All cross-section equations are per unit axial length.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from jitcache import JIT_FLAGS
from scipy.sparse.linalg import splu

from . import kepsilon as ke
from .linalg import AndersonMixing, LaggedSparseLU
from .operators import CoupledCrossFlow, _csr_matvec, _dirichlet_gradient, _interp, _transport, face_sums, matvec
from .mesh import PipeMesh

__all__ = ["GasProperties", "Sources", "GasField", "SolverDivergence", "solve"]


class SolverDivergence(RuntimeError):
    """The gas solve failed; the message names the variable and the cell."""


@dataclass(frozen=True)
class GasProperties:
    """Constant gas properties: density [kg m-3], dynamic viscosity [Pa s]."""

    density: float = 1.205
    viscosity: float = 1.81e-5

    @property
    def kinematic_viscosity(self):
        return self.viscosity / self.density


@dataclass
class Sources:
    """Per-cell sources on the gas, filled by the particle phase (zero for single-phase flow).

    momentum (3, nx, nr, nt) [N m-3]: x, y, z components of the momentum added to the gas;
    k (nx, nr, nt) [W m-3]; epsilon (nx, nr, nt) [W m-3 s-1].

    k_reference, epsilon_reference (optional, (nx, nr, nt)): the gas k [m2 s-2] and epsilon
    [m2 s-3] the sources were sampled in.  Particle sinks of turbulence scale with the
    turbulence itself (S_k = -<u'.J> ~ k), so negative parts are applied as the linear sinks
    S_k k/k_reference and S_eps eps/epsilon_reference, which can never drive k or epsilon
    through zero.  Without references they are linearised about the current iterate
    (Patankar), and a sink larger than the flow can sustain stops the solve with a diagnosis.

    drag, velocity_reference (optional, (nx, nr, nt) [kg m-3 s-1] and (3, nx, nr, nt) [m s-1]):
    the momentum source linearised in the gas velocity, S(U) = momentum + drag (U_ref − U)
    (drag = −∂S/∂U of the particle drag, sampled with the source; U_ref the gas velocity it was
    sampled in).  The part −drag U is implicit (on the diagonal of the momentum equations), so a
    dense particle layer brakes the gas with the slip at its new velocity, not the old one; where
    U = U_ref the applied source is ``momentum`` exactly, so the coupled fixed point is that of
    the explicit source (the Rhie-Chow weights leave drag out for the same reason).

    c_eps3 (optional): the particle dissipation source is the closure C_eps3 (eps/k) S_k
    (docs/physics.md, section 2 "Gas phase"), evaluated in the solve with the iterate's eps/k,
    as C_eps1 (eps/k) P_k is: the sink part of S_k (rate -S_k/k_reference) gives the linear
    eps sink of rate C_eps3 (-S_k)/k_reference, a positive S_k the explicit source
    C_eps3 (eps/k) S_k.  It adds to ``epsilon`` (then normally zero).  A source sampled in an
    earlier pass's eps/k and carried through the under-relaxation would not follow eps when the
    turbulence collapses: near the inlet eps/k is ~10^4 times its value downstream of a strong
    particle sink, and a positive S_eps kept from there drives eps to overflow in the axis cell (scenes g, h at 4 eta0).
    """

    momentum: np.ndarray
    k: np.ndarray
    epsilon: np.ndarray
    k_reference: np.ndarray = None
    epsilon_reference: np.ndarray = None
    c_eps3: float | None = None
    drag: np.ndarray = None
    velocity_reference: np.ndarray = None

    @classmethod
    def zeros(cls, mesh):
        s = mesh.shape
        return cls(np.zeros((3,) + s), np.zeros(s), np.zeros(s))

    def applied_momentum(self, ux, uy, uz):
        """The momentum source (3, nx, nr, nt) [N m-3] the solve applies in the gas velocity
        (ux, uy, uz): ``momentum`` + drag (U_ref − U), or ``momentum`` without drag."""
        if self.drag is None:
            return self.momentum.copy()
        u = np.stack([ux, uy, uz])
        return self.momentum + self.drag * (self.velocity_reference - u)

    def applied_epsilon(self, k, epsilon):
        """The dissipation source [W m-3 s-1] the solve applies in the gas field (k, epsilon):
        ``epsilon`` (sinks scaled by epsilon/epsilon_reference) plus, with c_eps3, C_eps3 (eps/k)
        times S_k as applied (sinks scaled by k/k_reference)."""
        out = self.epsilon.copy()
        if self.epsilon_reference is not None:
            out = np.where(out < 0.0, out * epsilon / self.epsilon_reference, out)
        if self.c_eps3 is not None:
            sk = self.k
            if self.k_reference is not None:
                sk = np.where(sk < 0.0, sk * k / self.k_reference, sk)
            out = out + self.c_eps3 * epsilon / k * sk
        return out


@dataclass
class GasField:
    """Converged gas field on a :class:`PipeMesh`; arrays are (nx, nr, nt) unless noted.

    ux, uy, uz [m s-1]; p [Pa] (relative to the outlet, or zero section mean when periodic);
    k [m2 s-2]; epsilon [m2 s-3]; nut [m2 s-1]; pressure_gradient (nx,) section-mean -dp/dx
    [Pa m-1]; wall_shear (nx, nt) [Pa]; wall_yplus (nx, nt) y+ of the wall-cell centres;
    residuals: solver residual history (max normalised change per outer iteration);
    station_iterations (nx,) outer iterations used per station; production_limited (nx,) cells
    per station where the optional production limiter acted in the last iteration; floored
    (nx,) cells per station held at the k/epsilon floors in the last iteration;
    station_relaxation (nx,) the smaller of the implicit k-epsilon and momentum relaxations
    each station was iterated with (below the one asked for where a diverging station was
    retried, see _march_station); station_coupled (nx,) stations of the march retried with the
    coupled cross-flow step; station_converged (nx,) whether each station reached the
    tolerance; station_change (nx, 2) the last outer iteration's largest change of the returned
    state, of the velocity (/ U_b) and of k and epsilon (relative): how far an unconverged
    station is from its tolerance, and in which equations; station_flux (nx, n_faces) the
    cross-section face mass fluxes [kg s-1 m-1] of each station (developing mode; for a warm
    start of a later solve, ``solve(initial=...)``).
    """

    mesh: PipeMesh
    gas: GasProperties
    bulk_velocity: float
    ux: np.ndarray
    uy: np.ndarray
    uz: np.ndarray
    p: np.ndarray
    k: np.ndarray
    epsilon: np.ndarray
    pressure_gradient: np.ndarray
    wall_shear: np.ndarray
    residuals: np.ndarray
    station_iterations: np.ndarray
    converged: bool
    wall_time: float = 0.0
    face_flux: np.ndarray = field(default=None, repr=False)
    production_limited: np.ndarray = field(default=None, repr=False)
    floored: np.ndarray = field(default=None, repr=False)
    station_relaxation: np.ndarray = field(default=None, repr=False)
    station_coupled: np.ndarray = field(default=None, repr=False)
    station_converged: np.ndarray = field(default=None, repr=False)
    station_change: np.ndarray = field(default=None, repr=False)
    station_flux: np.ndarray = field(default=None, repr=False)

    @property
    def nut(self):
        return ke.C_MU * self.k**2 / self.epsilon

    @property
    def iterations(self):
        return int(self.residuals.size)

    @property
    def friction_factor(self):
        """Darcy friction factor from the pressure gradient, f_D = 2 D (-dp/dx) / (rho U_b^2)."""
        return 2.0 * self.mesh.diameter * self.pressure_gradient / (self.gas.density * self.bulk_velocity**2)

    @property
    def wall_yplus(self):
        u_tau = np.sqrt(self.wall_shear / self.gas.density)
        return self.mesh.wall_distance * u_tau / self.gas.kinematic_viscosity


# ---------------------------------------------------------------------- station state
@dataclass
class _State:
    ux: np.ndarray
    uy: np.ndarray
    uz: np.ndarray
    p: np.ndarray
    k: np.ndarray
    eps: np.ndarray
    flux: np.ndarray
    G: float = 0.0  # section-mean -dp/dx [Pa/m]
    tau_w: np.ndarray = None

    def copy(self):
        return _State(*(np.copy(getattr(self, n)) for n in ("ux", "uy", "uz", "p", "k", "eps", "flux")), self.G,
                      None if self.tau_w is None else self.tau_w.copy())


_VARS = ("ux", "uy", "uz", "k", "eps")


PRODUCTION_LIMIT = 10.0  # optional limiter: P_k <= PRODUCTION_LIMIT * rho * eps (solve(production_limit=...))
#: implicit k-eps relaxations a diverging station of the march is retried with (_march_station)
#: and momentum relaxations.  The first keeps the discrete fixed point exactly; with momentum
#: relaxation the momentum-interpolation weights of the SIMPLEC step change with it, so the
#: cross flow of such a station differs at the level of that smoothing term (tests).
STATION_RELAXATION = ((0.5, 1.0), (0.5, 0.7), (0.2, 0.5), (0.05, 0.3))
#: a station still converging when its iterations run out iterates on, a quarter of them at a
#: time, up to this many times its iterations (_march_station)
STATION_EXTENSION = 4
#: how far (in multiples of its iterations) an attempt of _march_station that is still converging
#: (``_still_converging``) may iterate on, and its last resort beyond STATION_EXTENSION, where the
#: caller asks for it (``solve(station_extension=...)``; the coupling loop's final solves, which
#: decide whether a run converged): in near-laminar pockets under strong particle sinks an
#: attempt can contract by only ~0.996 per iteration (scene h's final sources, x = 0.325 m:
#: 6.4e-5 after 500 iterations, projected to reach the tolerance after ~2,000; docs/numerics.md)
FINAL_STATION_EXTENSION = 16
#: how straight log(change) must fall over the last quarter of an attempt's iterations for it to
#: iterate on after an early bump (_still_converging, reading 2)
STEADY_R2 = 0.9
#: solve the cross-section equations with lagged factorisations, refined (rans.linalg.LaggedFactor);
#: False: factorise every matrix (the reference the tests compare with)
REUSE_FACTORISATION = True
#: the same for the coupled cross-flow step's 3n system (rans.linalg.LaggedSparseLU, SuperLU
#: refined); False: a fresh SuperLU factorisation per outer iteration (as with REUSE_FACTORISATION = False)
REUSE_COUPLED_FACTORISATION = True
#: Anderson acceleration of a station's outer iteration in the march (rans.linalg.AndersonMixing,
#: over the whole station state: velocities, cross-section pressure and face fluxes, log k,
#: log eps, -dp/dx): the number of earlier iterations mixed; 0 iterates plainly.  Its attempt
#: comes first; a station it does not converge is iterated again from the upstream state by the
#: plain attempts (_march_station).  The converged state is the same fixed point to the station
#: tolerance; on scene h's sources the march needs about 2.4x fewer outer iterations, counting
#: the attempts dropped (docs/numerics.md, "Gas solver").
ANDERSON_DEPTH = 10
#: plain outer iterations before the mixing starts: most stations of a march converge in a few
#: iterations, where mixing a short history only perturbs the path
ANDERSON_DELAY = 10
#: an attempt whose changes repeat with a period of at most CYCLE_PERIOD_MAX iterations over
#: CYCLE_PERIODS periods, to CYCLE_MATCH relative, ends there (_cycling); 0 lets it run to its cap
CYCLE_PERIODS = 2
CYCLE_PERIOD_MAX = 32
CYCLE_MATCH = 1e-3
#: two consecutive outer iterations (after the fourth) that change the state by more than this
#: (relative) mean a diverging attempt (k up a factor 1e8 and more at the axis, on its way to
#: overflow, where it would stop ~40 iterations later); the first iterations may legitimately
#: lift a cell from the eps floor by as much
DIVERGED_CHANGE = 1e8
#: k-eps solves per outer iteration where the particles dominate the turbulence: the k and eps
#: equations lag each other's ratio eps/k and mu_t (with P_k = mu_t G^2).  Where the section's
#: particle k sink (referenced) exceeds KE_SWEEP_RATIO times its dissipation (scene h, pass 51:
#: 0.6-59 over the stations, median 1.6; the 200 um scenes a and d: 0.21-0.27 at most stations,
#: up to 0.83 at a few) a second solve with the updated eps/k, mu_t and P_k (the velocities held)
#: takes the march on scene h's pass-51 sources from 12,347 to 9,223 outer iterations (31 -> 23 s),
#: and converges its pass-3 march, whose single solve left stations unconverged (46 s), in 19 s;
#: a third solve left stations unconverged there (60 s), and on scene d's sources the second
#: solve everywhere only added its cost (docs/numerics.md, "Gas solver").  A station's
#: converged state is the same discrete fixed point; the marched fields agree with the single
#: solve's to ~1e-6 of their maxima except downstream of stations that need the coupled step,
#: whose state depends on the path (up to 2.4 % of the maximum cross flow there).  The gate is
#: judged every outer iteration; both maps have the same fixed point.  The developing march
#: only: in the periodic mode's pseudo-march the second solve diverged (two tests of
#: tests/test_rans_pipe_flow.py with fixed sinks), and it needs relax_turb = 1 (the Patankar
#: relaxation of a second solve would pull toward the first one's values).
KE_SWEEPS = 2
KE_SWEEP_RATIO = 0.3
#: the accelerated attempt drops its history when an iteration's change exceeds this many times
#: the smallest change it has reached (a mixed step that went astray)
ANDERSON_RESTART = 10.0
#: k >= K_FLOOR U_b^2 and eps >= C_mu k_floor^(3/2) / D after every solve
#: (docs/physics.md, section 2)
K_FLOOR = 1e-10


def turbulence_floors(bulk_velocity, diameter):
    """(k, ε) floors of the solve [m²/s², m²/s³]: k ≥ K_FLOOR U_b², ε ≥ C_μ k_floor^(3/2) / D."""
    k_floor = K_FLOOR * bulk_velocity**2
    return k_floor, ke.C_MU * k_floor**1.5 / diameter


class _StationSolver:
    """Outer iteration of the cross-section equations at one axial station."""

    def __init__(self, mesh, gas, bulk_velocity, momentum_scheme="hybrid", pressure_relaxation=1.0,
                 momentum_relaxation=1.0, production_limit=None):
        self.mesh = mesh
        self.sec = mesh.geometry()
        self.rho = gas.density
        self.mu = gas.viscosity
        self.Ub = bulk_velocity
        self.area_total = self.sec.area.sum()
        self.scheme = momentum_scheme
        self.alpha_p = pressure_relaxation
        self.alpha_u = momentum_relaxation
        self.station = 0
        self.x = 0.0
        self.periodic = mesh.mode == "periodic"
        self.coupled = self.periodic  # the march converges fast with SIMPLEC (strong axial term)
        self.production_limit = production_limit
        self.k_floor, self.eps_floor = turbulence_floors(bulk_velocity, mesh.diameter)
        self.limited = 0
        self.floored = 0
        self.last_change = (math.nan, math.nan)  # (velocity / U_b, k-eps relative) of the last iteration
        self._coupled_system = None  # the coupled cross-flow system's fixed pattern (CoupledCrossFlow)
        # one lagged factorisation per equation, carried across iterations and stations
        # (rans.linalg.LaggedFactor: the direct solution to 1e-10 per cell, relative to the cell's
        # value, with a floor of 1e-3 of the largest for the cross flow and pressure correction
        # that cross zero, and 1e-8 for k and eps, which span decades and stay positive)
        if REUSE_FACTORISATION:
            self._factor = {name: self.sec.lagged_factor(floor=floor).factor
                            for name, floor in (("momentum", 1e-3), ("pressure", 1e-3), ("k", 1e-8), ("eps", 1e-8))}
        else:
            self._factor = dict.fromkeys(("momentum", "pressure", "k", "eps"), self.sec.factor)
        # the coupled cross-flow system (3n: u_z and u_y together, then p), lagged the same way
        self._coupled_factor = splu
        if REUSE_FACTORISATION and REUSE_COUPLED_FACTORISATION:
            self._coupled_factor = LaggedSparseLU((2 * self.sec.n, self.sec.n), floor=1e-3).factor

    # -------------------------------------------------------------------- checks
    def check(self, name, values, positive=False):
        c = _first_bad(np.ascontiguousarray(values, dtype=np.float64), positive)
        if c >= 0:
            sec = self.sec
            j, k = divmod(c, sec.nt)
            th = math.degrees(math.atan2(sec.cy[c], sec.cz[c])) % 360.0
            raise SolverDivergence(
                f"gas solve diverged: {name} = {values[c]:.4g} at x = {self.x:.4g} m, "
                f"r = {math.hypot(sec.cy[c], sec.cz[c]):.4g} m, theta = {th:.1f} deg "
                f"(station {self.station}, ring {j}, sector {k})"
            )

    def _turbulence_terms(self, k, eps, mut, G2, tau_w):
        """P_k = mu_t G^2 and the k equation's dissipation eps, with the wall-function values
        in the wall cells (from the wall cells' k and tau_w)."""
        wall, yP = self.sec.wall, self.sec.wall_distance
        Pk = mut * G2
        # optional production limiter P_k <= c rho eps (docs/physics.md, section 2), off by
        # default:
        # inactive in single-phase pipe flow (P_k/(rho eps) < 3), but under strong particle
        # sinks (C_eps3 > C_eps1 lengthens k/eps) it starves the turbulence and drives k to
        # zero where the particles gather.  Cells where it acts are counted.
        if self.production_limit is not None:
            cap = self.production_limit * self.rho * eps
            over = Pk > cap
            if over.any():
                Pk = np.where(over, cap, Pk)
                self.limited = max(self.limited, int(np.count_nonzero(over)))
        kw = k[wall]
        Pk[wall] = ke.wall_production(tau_w, kw, yP)
        eps_sink = eps.copy()
        eps_sink[wall] = ke.wall_epsilon(kw, yP)
        return Pk, eps_sink

    def _k_eps_sweep(self, k_it, e_it, mut, Pk, eps_sink, Sk, Se, kref, eref, flux, ax, hist, c0, A, wall, yP, src,
                     relax_turb):
        sec, rho, mu = self.sec, self.rho, self.mu
        # k equation (assembled in _k_equation: the transport coefficients of mu + mu_t/sigma_k,
        # upwind, and the sources; the arithmetic of the array form, entry by entry)
        c0k = hist.get("c0_k", c0)
        dk, bk, kPN, kNP = _k_equation(sec.P, sec.N, sec.S, sec.delta, sec.w, sec._om, flux, mu, mut, ke.SIGMA_K,
                                       _cell_array(c0k, A), ax, rho, A, eps_sink, k_it, Sk, kref, hist["k"], Pk,
                                       relax_turb)
        k_new = self._factor["k"](dk, kPN, kNP).solve(bk)
        self.check("k", k_new, positive=True)
        low_k = k_new < self.k_floor
        # epsilon equation (fixed value in the wall cells), assembled in _eps_equation
        c3 = src["c_eps3"]
        de, be, ePN, eNP = _eps_equation(sec.P, sec.N, sec.S, sec.delta, sec.w, sec._om, flux, mu, mut, ke.SIGMA_EPS,
                                         _cell_array(hist.get("c0_eps", c0), A), ax, rho, A, e_it, k_it, Se, eref,
                                         hist["eps"], Pk, Sk, kref, ke.C_EPS1, ke.C_EPS2,
                                         math.nan if c3 is None else float(c3), relax_turb)
        big = 1e12 * de[wall]
        de[wall] += big
        be[wall] += big * ke.wall_epsilon(k_new[wall], yP)
        eps_new = self._factor["eps"](de, ePN, eNP).solve(be)
        self.check("epsilon", eps_new, positive=True)
        return k_new, eps_new, low_k

    # -------------------------------------------------------------------- one outer iteration
    def iterate(self, st, hist, c0, dx, src, laminar=False, relax_turb=1.0):
        try:
            return self._iterate_checked(st, hist, c0, dx, src, laminar, relax_turb)
        except RuntimeError as err:  # scipy's splu: "Factor is exactly singular"
            if isinstance(err, SolverDivergence):
                raise
            raise SolverDivergence(f"gas solve diverged: singular linear system at x = {self.x:.4g} m "
                                   f"(station {self.station}): {err}") from None

    def _iterate_checked(self, st, hist, c0, dx, src, laminar=False, relax_turb=1.0):
        """Update ``st`` in place.  hist: dict of upstream combinations (axial derivative
        (c0 phi - hist)/dx); src: dict with 'mx', 'fz', 'fy' [N m-3], 'k', 'eps' cell arrays."""
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return self._iterate(st, hist, c0, dx, src, laminar, relax_turb)

    def _iterate(self, st, hist, c0, dx, src, laminar, relax_turb):
        self.limited = 0
        self.floored = 0
        sec, rho, mu = self.sec, self.rho, self.mu
        A = sec.area
        wall = sec.wall
        yP = sec.wall_distance

        if laminar:
            mut = np.zeros_like(st.k)
        else:
            mut = rho * ke.C_MU * st.k**2 / st.eps
        # wall function: tau_w = cw * U_t (tangential speed), force per unit length = cw * arc * U
        if laminar:
            cw = np.full(wall.size, mu / yP)
        else:
            cw, _ = ke.wall_shear_coefficient(st.k[wall], yP, rho, mu)
        cwL = cw * sec.wall_arc
        # wall stencil: friction force on the wall cell = -(cwL u_W - bwL u_I) (tangential part),
        # u_I the cell inside it.  Wall functions: bwL = 0.  Laminar: one-sided second-order
        # gradient through the wall value 0, u_W (distance y1) and u_I (distance y2).
        bwL = np.zeros_like(cwL)
        if laminar:
            y1, y2 = yP, sec.wall_inner_distance
            cwL = np.full(wall.size, mu * sec.wall_arc * y2 / (y1 * (y2 - y1)))
            bwL = np.full(wall.size, mu * sec.wall_arc * y1 / (y2 * (y2 - y1)))
        inner = sec.wall_inner

        ux_conv = st.ux
        self.check("u_x (the solver needs positive axial velocity: no reversed flow)", ux_conv, positive=True)
        ax = rho * A * ux_conv / dx  # axial convection coefficient (times c0 below)

        # ---------------- momentum matrix (shared by u_x, u_y, u_z)
        mu_f = sec.interp(mu + mut)
        diag, aPN, aNP = sec.transport(st.flux, mu_f, self.scheme)
        diag_m = diag + c0 * ax
        diag_m[wall] += cwL
        aNP = aNP.copy()
        aNP[sec.wall_inner_faces] -= bwL
        # particle drag linearised in U (Sources.drag): -beta U implicit, beta U_ref explicit
        beta = src["beta"]
        beta_A = 0.0 if beta is None else beta * A
        diag_m = diag_m + beta_A
        # implicit under-relaxation (periodic mode; 1 in the march)
        au = self.alpha_u
        relax_u = (1.0 - au) / au * diag_m
        diag_m = diag_m / au
        lu = self._factor["momentum"](diag_m, aPN, aNP)

        def explicit_drag(c):
            return 0.0 if beta is None else beta_A * src["uref"][c]

        # axial velocity, mass flow fixed through the mean pressure gradient G = -dp/dx
        b = (ax * hist["ux"] + src["mx"] * A + explicit_drag(0) + relax_u * st.ux
             + sec.radial_gradient_correction(st.ux, mu_f))
        u1, u2 = _solve_pair(lu, b, A.copy())
        mdot_target = self.Ub * self.area_total
        G = (mdot_target - A @ u1) / (A @ u2)
        ux_new = u1 + G * u2
        self.check("u_x", ux_new)

        # ---------------- cross-section momentum and continuity (balanced force at the faces)
        fn = sec.interp_mid(src["fz"]) * sec.nz + sec.interp_mid(src["fy"]) * sec.ny
        un = (cwL * (st.uz[wall] * sec.wall_nz + st.uy[wall] * sec.wall_ny)
              - bwL * (st.uz[inner] * sec.wall_nz + st.uy[inner] * sec.wall_ny))
        bz = ax * hist["uz"] + explicit_drag(2) + relax_u * st.uz + sec.radial_gradient_correction(st.uz, mu_f)
        by = ax * hist["uy"] + explicit_drag(1) + relax_u * st.uy + sec.radial_gradient_correction(st.uy, mu_f)
        # wall: shear acts on the tangential velocity only; the normal part of the implicit
        # wall stencil is given back explicitly
        bz[wall] += un * sec.wall_nz
        by[wall] += un * sec.wall_ny
        axial_part = None if self.periodic else rho * A * (c0 * ux_new - hist["ux"]) / dx
        if self.coupled:
            # momentum-interpolation weight without the pseudo-march term, so that the converged
            # periodic solution does not depend on the pseudo step
            d_rc = A / (diag + np.bincount(wall, cwL, minlength=A.size))
            uz, uy, p, flux = self._cross_flow_coupled(st, lu, diag_m, aPN, aNP, bz, by, fn, axial_part, d_rc)
        else:
            uz, uy, p, flux = self._cross_flow_simplec(st, lu, diag_m, aPN, aNP, bz, by, fn, axial_part,
                                                       beta_A / au)
        self.check("u_y", uy)
        self.check("u_z", uz)

        # ---------------- k and epsilon
        if laminar:
            k_new, eps_new = st.k, st.eps
            tau_w = np.abs(cwL * ux_new[wall] - bwL * ux_new[inner]) / sec.wall_arc
        else:
            # G^2 = 2 S_ij S_ij of the cell gradients (Section.gradient, no-slip wall values) and
            # the axial derivative (c0 u_x - hist)/dx (_strain_squared, compiled)
            G2 = _strain_squared(sec.P, sec.N, sec.S, sec.nz, sec.ny, sec.delta, sec.wall, sec.wall_chord,
                                 sec.wall_nz, sec.wall_ny, sec.wall_distance, sec.Tinv, ux_new, uz, uy, hist["ux"],
                                 float(c0), float(dx))
            ut = -uz[wall] * sec.wall_ny + uy[wall] * sec.wall_nz
            Ut = np.sqrt(ux_new[wall] ** 2 + ut**2)
            tau_w = cw * Ut

            Sk = src["k"]
            Se = src["eps"]
            kref = src["k_ref"] if src["k_ref"] is not None else st.k
            eref = src["eps_ref"] if src["eps_ref"] is not None else st.eps
            k_it, e_it, mut_it = st.k, st.eps, mut
            sweeps = 1
            if KE_SWEEPS > 1 and relax_turb >= 1.0 and not self.periodic and src["k_ref"] is not None:
                # particle-dominated turbulence in the march: the section's particle k sink
                # (referenced, linear in k) against its dissipation
                sink = float(np.sum(A * np.maximum(-Sk, 0.0) * st.k / kref))
                if sink > KE_SWEEP_RATIO * float(np.sum(A * rho * st.eps)):
                    sweeps = KE_SWEEPS
            for sweep in range(sweeps):
                if sweep > 0:  # again with eps/k, mu_t and P_k of the last solve (KE_SWEEPS)
                    k_it = np.maximum(k_new, self.k_floor)
                    e_it = np.maximum(eps_new, self.eps_floor)
                    mut_it = rho * ke.C_MU * k_it**2 / e_it
                Pk_it, eps_sink = self._turbulence_terms(k_it, e_it, mut_it, G2, tau_w)
                k_new, eps_new, low_k = self._k_eps_sweep(k_it, e_it, mut_it, Pk_it, eps_sink, Sk, Se, kref, eref,
                                                          flux, ax, hist, c0, A, wall, yP, src, relax_turb)
            # floors (docs/physics.md, section 2) where strong particle sinks laminarise a pocket
            # of the flow; k and eps are positive here already, the floors keep nu_t and k/eps
            # finite.  Counted per station (GasField.floored), never silent.
            # Only with referenced (linear) sinks: a fixed sink the flow cannot sustain still
            # stops the solve (below, at the positivity check, or as a non-converged station).
            low_e = eps_new < self.eps_floor
            if src["k_ref"] is None:
                low_k[:] = False
                low_e[:] = False
            if low_k.any() or low_e.any():
                self.floored = max(self.floored, int(np.count_nonzero(low_k | low_e)))
                k_new = np.maximum(k_new, self.k_floor)
                eps_new = np.maximum(eps_new, self.eps_floor)

        # ---------------- change and update
        ref_u = self.Ub
        ch_u, ch_t = _changes(ux_new, st.ux, uy, st.uy, uz, st.uz, k_new, st.k, eps_new, st.eps)
        ch_u = ch_u / ref_u
        self.last_change = (float(ch_u), float(ch_t))
        ch = max(ch_u, ch_t)
        st.ux, st.uy, st.uz, st.p, st.k, st.eps, st.flux, st.G = ux_new, uy, uz, p, k_new, eps_new, flux, G
        st.tau_w = tau_w
        return ch


    # -------------------------------------------------------------------- cross-flow solvers
    def _cross_flow_simplec(self, st, lu, diag_m, aPN, aNP, bz, by, fn, axial_part, drag_diag=0.0):
        """One SIMPLEC step: momentum predictor, momentum-interpolated fluxes, pressure correction.

        ``drag_diag``: the linearised particle drag's part of ``diag_m``, left out of the
        momentum-interpolation weights so that the fluxes at U = U_ref are those of the
        explicit source (Sources.drag)."""
        sec, rho, A = self.sec, self.rho, self.sec.area
        nwall = sec.wall.size
        g = -sec.normal_difference(st.p) + fn
        Rz, Ry = sec.reconstruct(g, np.zeros(nwall))
        uz, uy = _solve_pair(lu, bz + A * Rz, by + A * Ry)
        # momentum-interpolated face fluxes, their imbalance and the pressure-correction matrix
        # (_simplec_fluxes, compiled; the arithmetic of the array form per entry)
        dP, flux, imbalance, coef, diag_p = _simplec_fluxes(
            sec.P, sec.N, sec.S, sec.delta, sec.w, sec._om, sec.nz, sec.ny, aPN, aNP, diag_m,
            _cell_array(drag_diag, A), A, uz, uy, Rz, Ry, g, rho, sec.div.indptr, sec.div.indices, sec.div.data,
            sec.fsum.indptr, sec.fsum.indices, sec.fsum.data)
        if axial_part is not None:
            imbalance = imbalance + axial_part
        diag_p[sec.wall[0]] += diag_p.max() * 1e3  # pin the level of p' (pure Neumann problem)
        pc = self._factor["pressure"](diag_p, -coef, -coef).solve(-imbalance)
        flux = flux + coef * (pc[sec.P] - pc[sec.N])
        cz, cy = sec.reconstruct(-sec.normal_difference(pc), np.zeros(nwall))
        uz = uz + dP * cz
        uy = uy + dP * cy
        p = st.p + self.alpha_p * pc
        p -= (A @ p) / self.area_total
        return uz, uy, p, flux

    def _cross_flow_coupled(self, st, lu, diag_m, aPN, aNP, bz, by, fn, axial_part, d):
        """Cross-flow momentum and continuity solved together (the 3n system by SuperLU, with the
        factorisation of an earlier outer iteration's matrix, refined: rans.linalg.LaggedSparseLU).

        Momentum:   M u_z - A R_z(g) = b_z,  M u_y - A R_y(g) = b_y,   g = -(p_N - p_P)/delta + f.n
        Continuity: sum_f rho S [ interp(u - d R(g)) . n + d_f g ] = -rho A d(u_x)/dx,  d = A/a_P
        (a_P of the steady operator, without the pseudo-march term).
        """
        sec, rho, A = self.sec, self.rho, self.sec.area
        if self._coupled_system is None:  # the pattern and the blocks that depend on the geometry only
            self._coupled_system = CoupledCrossFlow(sec, rho)
        cs = self._coupled_system
        rz = bz + A * matvec(sec.Rz, fn)
        ry = by + A * matvec(sec.Ry, fn)
        rc = -cs.continuity(cs.interpolated(fn, d))
        if axial_part is not None:
            rc = rc - axial_part
        sol = self._coupled_factor(cs.matrix(diag_m, aPN, aNP, d)).solve(np.concatenate([rz, ry, rc]))
        n = sec.n
        uz, uy, p = sol[:n], sol[n:2 * n], sol[2 * n:]
        p = p - (A @ p) / self.area_total
        g = -matvec(sec.Dn, p) + fn
        flux = rho * sec.S * (sec.nz * sec.interp(uz) + sec.ny * sec.interp(uy) + cs.interpolated(g, d))
        return uz, uy, p, flux


@njit(**JIT_FLAGS)
def _simplec_fluxes(P, N, S, delta, w, om, nz, ny, aPN, aNP, diag_m, drag_diag, A, uz, uy, Rz, Ry, g, rho,
                    div_ptr, div_idx, div_val, fsum_ptr, fsum_idx, fsum_val):
    """The SIMPLEC step's momentum interpolation (_StationSolver._cross_flow_simplec): the
    weights d = A / (a_P - drag - sum |a_nb|) (a_P where that is not above 1e-3 a_P), the face
    mass fluxes rho S [interp(u - d R) . n + interp(d) g], their cell imbalance (sec.div) and
    the pressure-correction coefficients rho interp(d) S / delta with their face sums
    (sec.fsum): (d, flux, imbalance, coef, diag_p), each entry with the array form's arithmetic."""
    n = A.size
    nf = P.size
    offsum = face_sums(P, N, np.abs(aPN), np.abs(aNP), n)
    dP = np.empty(n)
    vz = np.empty(n)
    vy = np.empty(n)
    for i in range(n):
        red = diag_m[i] - drag_diag[i] - offsum[i]
        if not red > 1e-3 * diag_m[i]:
            red = diag_m[i]
        dP[i] = A[i] / red
        vz[i] = uz[i] - dP[i] * Rz[i]
        vy[i] = uy[i] - dP[i] * Ry[i]
    flux = np.empty(nf)
    coef = np.empty(nf)
    for f in range(nf):
        p, q = P[f], N[f]
        d_f = om[f] * dP[p] + w[f] * dP[q]
        Uf = ((om[f] * vz[p] + w[f] * vz[q]) * nz[f] + (om[f] * vy[p] + w[f] * vy[q]) * ny[f]) + d_f * g[f]
        flux[f] = rho * Uf * S[f]
        coef[f] = rho * d_f * S[f] / delta[f]
    imbalance = np.empty(n)
    diag_p = np.empty(n)
    _csr_matvec(div_ptr, div_idx, div_val, flux, imbalance)
    _csr_matvec(fsum_ptr, fsum_idx, fsum_val, coef, diag_p)
    return dP, flux, imbalance, coef, diag_p


@njit(**JIT_FLAGS)
def _strain_squared(P, N, S, nz, ny, delta, wall, wall_chord, wall_nz, wall_ny, wall_distance, Tinv, ux, uz, uy,
                    hist_ux, c0, dx):
    """G^2 = (du_x/dz)^2 + (du_x/dy)^2 + 2 (du_z/dz)^2 + 2 (du_y/dy)^2 + (du_z/dy + du_y/dz)^2
    + 2 (du_x/dx)^2, the gradients as Section.gradient(phi, 0.0) gives them, du_x/dx =
    (c0 u_x - hist)/dx; each entry with the array form's arithmetic."""
    n = ux.size
    geometry = (P, N, S, nz, ny, delta, wall, wall_chord, wall_nz, wall_ny, wall_distance, Tinv)
    ax_z, ax_y = _dirichlet_gradient(*geometry, ux, 0.0)
    zz, zy = _dirichlet_gradient(*geometry, uz, 0.0)
    yz, yy = _dirichlet_gradient(*geometry, uy, 0.0)
    G2 = np.empty(n)
    for i in range(n):
        dudx = (c0 * ux[i] - hist_ux[i]) / dx
        e = zy[i] + yz[i]
        G2[i] = (ax_z[i] * ax_z[i] + ax_y[i] * ax_y[i] + 2.0 * (zz[i] * zz[i]) + 2.0 * (yy[i] * yy[i])
                 + e * e + 2.0 * (dudx * dudx))
    return G2


@njit(**JIT_FLAGS)
def _changes(ux, ux0, uy, uy0, uz, uz0, k, k0, eps, eps0):
    """(largest |velocity change|, largest |k/k0 - 1| or |eps/eps0 - 1|) of an outer iteration."""
    cu = 0.0
    ct = 0.0
    for i in range(ux.size):
        cu = max(cu, abs(ux[i] - ux0[i]), abs(uy[i] - uy0[i]), abs(uz[i] - uz0[i]))
        ct = max(ct, abs(k[i] / k0[i] - 1.0), abs(eps[i] / eps0[i] - 1.0))
    return cu, ct


@njit(**JIT_FLAGS)
def _first_bad(values, positive):
    """The first entry that is not finite (or, with ``positive``, not > 0); -1 if none."""
    for i in range(values.size):
        v = values[i]
        if not np.isfinite(v) or (positive and not v > 0.0):
            return i
    return -1


def _solve_pair(lu, b1, b2):
    """(lu.solve(b1), lu.solve(b2)), in one pass where ``lu`` can (LaggedFactor.solve2)."""
    if hasattr(lu, "solve2"):
        return lu.solve2(b1, b2)
    return lu.solve(b1), lu.solve(b2)


def _cell_array(c, like):
    """``c`` (a scalar or a cell array) as a cell array."""
    return np.full(like.size, float(c)) if np.ndim(c) == 0 else np.ascontiguousarray(c, dtype=np.float64)


@njit(**JIT_FLAGS)
def _upwind_transport(P, N, S, delta, w, om, flux, mu, mut, sigma, n):
    """Section.transport(flux, Section.interp(mu + mut / sigma), "upwind"), with the same
    arithmetic per entry: (diagonal, a_PN, a_NP)."""
    gc = np.empty(n)
    for i in range(n):
        gc[i] = mu + mut[i] / sigma
    return _transport(P, N, S, delta, w, om, flux, _interp(P, N, om, w, gc), n, 0)


@njit(**JIT_FLAGS)
def _relax_implicitly(d, b, x, relax):
    """Patankar's implicit under-relaxation of the rows (d, b) about the iterate x."""
    s = (1.0 - relax) / relax
    for i in range(d.size):
        b[i] += s * d[i] * x[i]
        d[i] = d[i] / relax


@njit(**JIT_FLAGS)
def _k_equation(P, N, S, delta, w, om, flux, mu, mut, sigma, c0, ax, rho, A, eps_sink, k_it, Sk, kref, hist_k, Pk,
                relax):
    """Matrix (diagonal, a_PN, a_NP) and right-hand side of the k equation of an outer
    iteration (_StationSolver._k_eps_sweep), entry by entry in the order of the array form:
    diag + c0 ax + rho A eps/k + A max(-S_k, 0)/k_ref, rhs ax k_hist + A (P_k + max(S_k, 0)),
    then the implicit under-relaxation when ``relax`` < 1."""
    n = A.size
    d, aPN, aNP = _upwind_transport(P, N, S, delta, w, om, flux, mu, mut, sigma, n)
    b = np.empty(n)
    for i in range(n):
        d[i] = d[i] + c0[i] * ax[i] + rho * A[i] * eps_sink[i] / k_it[i] + A[i] * max(-Sk[i], 0.0) / kref[i]
        b[i] = ax[i] * hist_k[i] + A[i] * (Pk[i] + max(Sk[i], 0.0))
    if relax < 1.0:
        _relax_implicitly(d, b, k_it, relax)
    return d, b, aPN, aNP


@njit(**JIT_FLAGS)
def _eps_equation(P, N, S, delta, w, om, flux, mu, mut, sigma, c0, ax, rho, A, e_it, k_it, Se, eref, hist_e, Pk, Sk,
                  kref, c1, c2, c3, relax):
    """As :func:`_k_equation` for epsilon (before its wall values): diag + c0 ax + C2 rho A eps/k +
    A max(-S_eps, 0)/eps_ref, rhs ax eps_hist + A (C1 (eps/k) P_k + max(S_eps, 0)); with C_eps3
    (``c3`` not NaN) the particle term C_eps3 (eps/k) S_k, its sink part implicit."""
    n = A.size
    d, aPN, aNP = _upwind_transport(P, N, S, delta, w, om, flux, mu, mut, sigma, n)
    b = np.empty(n)
    c2rho = c2 * rho
    for i in range(n):
        d[i] = d[i] + c0[i] * ax[i] + c2rho * A[i] * e_it[i] / k_it[i] + A[i] * max(-Se[i], 0.0) / eref[i]
        b[i] = ax[i] * hist_e[i] + A[i] * (c1 * e_it[i] / k_it[i] * Pk[i] + max(Se[i], 0.0))
    if not math.isnan(c3):
        for i in range(n):
            d[i] = d[i] + c3 * A[i] * max(-Sk[i], 0.0) / kref[i]
            b[i] = b[i] + c3 * A[i] * e_it[i] / k_it[i] * max(Sk[i], 0.0)
    if relax < 1.0:
        _relax_implicitly(d, b, e_it, relax)
    return d, b, aPN, aNP


def _source_slices(sources, i, n):
    if sources is None:
        z = np.zeros(n)
        return {"mx": z, "fy": z, "fz": z, "k": z, "eps": z, "k_ref": None, "eps_ref": None, "c_eps3": None,
                "beta": None, "uref": None}
    m = sources.momentum
    return {
        "mx": m[0, i].ravel(),
        "fy": m[1, i].ravel(),
        "fz": m[2, i].ravel(),
        "k": sources.k[i].ravel(),
        "eps": sources.epsilon[i].ravel(),
        "k_ref": None if sources.k_reference is None else sources.k_reference[i].ravel(),
        "eps_ref": None if sources.epsilon_reference is None else sources.epsilon_reference[i].ravel(),
        "c_eps3": sources.c_eps3,
        "beta": None if sources.drag is None else sources.drag[i].ravel(),
        "uref": None if sources.drag is None else [sources.velocity_reference[c, i].ravel() for c in range(3)],
    }


def _pack(st):
    """The station state as one vector for Anderson mixing (k and eps as logarithms, so that a
    mixed state stays positive)."""
    return np.concatenate([st.ux, st.uy, st.uz, st.p, np.log(st.k), np.log(st.eps), st.flux, [st.G]])


def _unpack(st, x, solver):
    """Set ``st`` from a packed (mixed) state; False, leaving ``st`` as it is, where the mixed
    state is not finite (an extrapolation far out: exp of a huge log eps)."""
    n, nf = st.k.size, st.flux.size
    with np.errstate(over="ignore"):
        k, eps = np.exp(x[4 * n:5 * n]), np.exp(x[5 * n:6 * n])
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(k)) and np.all(np.isfinite(eps))):
        return False
    st.ux, st.uy, st.uz, st.p = (x[i * n:(i + 1) * n].copy() for i in range(4))
    # the floors the solve itself applies (turbulence_floors): a mixed log k or log eps far
    # below them would only be floored by the next iteration's k-eps solve
    st.k = np.maximum(k, solver.k_floor)
    st.eps = np.maximum(eps, solver.eps_floor)
    st.flux = x[6 * n:6 * n + nf].copy()
    st.G = float(x[-1])
    return True


def _mixing_weight(st, velocity_scale):
    """Weights that put the packed unknowns on one scale: velocities by U_b, p and the fluxes by
    their largest magnitude, log k and log eps as they are, -dp/dx by its value."""
    n, nf = st.k.size, st.flux.size
    ps = max(float(np.abs(st.p).max()), 1e-30)
    fs = max(float(np.abs(st.flux).max()), 1e-30)
    return np.concatenate([np.full(3 * n, 1.0 / velocity_scale), np.full(n, 1.0 / ps), np.ones(2 * n),
                           np.full(nf, 1.0 / fs), [1.0 / max(abs(st.G), 1e-30)]])


def _initial_state(mesh, bulk_velocity, k0, eps0, profile="uniform"):
    sec = mesh.geometry()
    n = sec.n
    if profile == "power":
        r = np.hypot(sec.cy, sec.cz) / mesh.radius
        ux = np.maximum(1.0 - r, 1e-3) ** (1.0 / 7.0)
        ux *= bulk_velocity * sec.area.sum() / (sec.area @ ux)
    else:
        ux = np.full(n, float(bulk_velocity))
    return _State(ux=ux, uy=np.zeros(n), uz=np.zeros(n), p=np.zeros(n), k=np.full(n, float(k0)),
                  eps=np.full(n, float(eps0)), flux=np.zeros(sec.nf))


def solve(
    mesh,
    gas,
    bulk_velocity,
    inlet_k=1.0,
    inlet_epsilon=None,
    sources=None,
    *,
    tol=1e-6,
    max_iterations=3000,
    station_tol=None,
    station_iterations=(2, 200),
    pseudo_step=None,
    initial=None,
    inlet_profile=None,
    cross_flow_solver=None,
    momentum_scheme="hybrid",
    laminar=False,
    turbulence_relaxation=1.0,
    momentum_relaxation=1.0,
    progress=False,
    require_convergence=True,
    production_limit=None,
    station_retries=True,
    station_extension=STATION_EXTENSION,
    on_station=None,
):
    """Solve the steady gas flow on ``mesh``; returns a :class:`GasField`.

    mesh: :class:`PipeMesh`; gas: :class:`GasProperties`; bulk_velocity [m s-1] (uniform
    inlet velocity when developing, prescribed bulk velocity when periodic);
    inlet_k [m2 s-2], inlet_epsilon [m2 s-3] (None: C_mu^(3/4) k^(3/2)/(0.07 D)); also the
    initial turbulence of the periodic mode.  sources: :class:`Sources` or None.
    tol: convergence on the max normalised change of an outer iteration (periodic mode);
    station_tol (developing; default tol): same, per station; station_iterations: (min, max)
    outer iterations per station.  pseudo_step [m]: pseudo axial step of the periodic mode
    (default 4 D).  initial: a :class:`GasField` on the same mesh to start from: the periodic
    mode iterates from it; the developing mode starts each station's outer iteration from its
    state at that station instead of the upstream station's (a warm start from an earlier solve
    with slightly different sources, e.g. the previous coupling pass; _march_station).
    turbulence_relaxation, momentum_relaxation: implicit under-relaxation of k and epsilon,
    and of the momentum equations (the march uses the first only, and retries a diverging
    station with more of both: _march_station, ``GasField.station_relaxation``).
    station_retries (developing): False returns a station whose first plain attempt stalls
    (its iterations run out without divergence) as it is, unconverged, instead of retrying it
    with the coupled step, more relaxation and the extension of _march_station; a diverging
    attempt is retried either way.  station_extension (developing): how many times its
    iterations an attempt that is still converging, and the last resort of a stalled station,
    may iterate in all (at least STATION_EXTENSION, the default; _march_station).
    cross_flow_solver: "coupled" (direct solve of cross-section momentum and continuity),
    "simplec", or None: coupled in the periodic mode, SIMPLEC in the march (where the strong
    axial term makes it converge in a few iterations at a fraction of the cost).
    inlet_profile: optional callable (y, z) -> (u_x, u_y, u_z) [m s-1] replacing the uniform
    inlet of the developing mode (verification).
    laminar: solve laminar flow (mu_t = 0, no k-epsilon; for verification).
    production_limit: None (default) or c, limiting P_k <= c rho eps (counted per station in
    ``GasField.production_limited``).  k and eps are held above K_FLOOR U_b^2 and
    C_mu k_floor^(3/2)/D (counted per station in ``GasField.floored``).
    momentum_scheme: "hybrid" (default), "upwind" or "central" cross-section convection.
    on_station (developing): called as ``on_station(i, ux, uy, uz, k, eps)`` with station i's
    final cross-section fields (flat, (nr·nt,), in the order of ``GasField.ux[i].ravel()``)
    as soon as the march has them; the march does not touch a station again, so a consumer
    can use the stations upstream while the march goes on (particles.stream).  The periodic
    mode, whose stations are final only at convergence, never calls it.

    Raises :class:`SolverDivergence` on non-finite or non-positive k/epsilon, or when the
    periodic mode does not reach ``tol`` within ``max_iterations`` (message says so) unless
    ``require_convergence`` is False: then the field after ``max_iterations`` is returned with
    ``converged = False`` (a coupling loop's inner iterations; docs/numerics.md, "Coupling loop").
    """
    t0 = time.perf_counter()
    if bulk_velocity <= 0:
        raise ValueError(f"bulk_velocity = {bulk_velocity}: must be > 0")
    if inlet_epsilon is None:
        inlet_epsilon = ke.inlet_epsilon(inlet_k, mesh.diameter)
    if sources is not None:
        _check_sources(mesh, sources)
    solver = _StationSolver(mesh, gas, bulk_velocity, momentum_scheme,
                            momentum_relaxation=momentum_relaxation if mesh.mode == "periodic" else 1.0,
                            production_limit=production_limit)
    if cross_flow_solver is not None:
        if cross_flow_solver not in ("coupled", "simplec"):
            raise ValueError(f"cross_flow_solver = {cross_flow_solver!r}: allowed 'coupled' or 'simplec'")
        solver.coupled = cross_flow_solver == "coupled"
    sec = mesh.geometry()
    n = sec.n
    nx = mesh.nx
    out = {v: np.empty((nx, n)) for v in ("ux", "uy", "uz", "p", "k", "eps")}
    G = np.empty(nx)
    tau = np.empty((nx, sec.nt))
    residuals = []
    iters = np.zeros(nx, dtype=np.int64)
    limited = np.zeros(nx, dtype=np.int64)
    floored = np.zeros(nx, dtype=np.int64)
    station_relax = np.full(nx, float(turbulence_relaxation))
    station_coupled = np.zeros(nx, dtype=bool)
    station_ok = np.ones(nx, dtype=bool)
    station_change = np.full((nx, 2), np.nan)
    converged = True
    bar = _progress(nx if mesh.mode == "developing" else max_iterations, progress)

    if mesh.mode == "periodic":
        st = _initial_state(mesh, bulk_velocity, inlet_k, inlet_epsilon, profile="power")
        if initial is not None:
            st = _state_from_field(initial, 0)
        # pseudo-marching with a switched-evolution step: the pseudo axial step grows while the
        # residual falls and is cut (with a rollback) when an iteration blows up
        dx = pseudo_step if pseudo_step is not None else 1.0 * mesh.diameter
        dx_max = 32.0 * mesh.diameter if pseudo_step is None else pseudo_step
        src = _source_slices(sources, 0, n)
        converged = False
        prev = np.inf
        cuts = 0
        for it in range(max_iterations):
            hist = {"ux": st.ux.copy(), "uy": st.uy.copy(), "uz": st.uz.copy(), "k": st.k.copy(),
                    "eps": st.eps.copy()}
            saved = st.copy()
            try:
                ch = solver.iterate(st, hist, 1.0, dx, src, laminar, turbulence_relaxation)
            except SolverDivergence as err:
                ch, last_err = np.inf, err
            if not np.isfinite(ch) or (ch > 10.0 * prev and ch > 1e-2):
                st = saved
                dx *= 0.25
                cuts += 1
                if dx < 1e-3 * mesh.diameter or cuts > 40:
                    raise SolverDivergence(
                        f"periodic gas solve diverged: pseudo step cut to {dx:.3g} m without recovery"
                        + (f"; last failure: {last_err}" if not np.isfinite(ch) else "")
                    )
                residuals.append(ch if np.isfinite(ch) else np.nan)
                continue
            residuals.append(ch)
            if ch < prev:
                dx = min(dx * 1.5, dx_max)
            prev = ch
            bar.update(1)
            if ch < tol:
                converged = True
                break
        iters[0] = len(residuals)
        station_ok[0] = converged
        station_change[0] = solver.last_change
        bar.close()
        if not converged and require_convergence:
            raise SolverDivergence(
                f"periodic gas solve did not converge: residual {residuals[-1]:.3g} > tol {tol:.3g} "
                f"after {max_iterations} iterations"
            )
        _store(out, G, tau, 0, st)
        limited[0] = solver.limited
        floored[0] = solver.floored
    else:
        stol = tol if station_tol is None else station_tol
        xc = mesh.x
        st = _initial_state(mesh, bulk_velocity, inlet_k, inlet_epsilon)
        if inlet_profile is not None:
            st.ux, st.uy, st.uz = (np.asarray(a, dtype=float).ravel().copy() for a in inlet_profile(sec.cy, sec.cz))
            # the march carries the inlet's discrete mass flow (a mismatch would be an
            # incompatible continuity source at the first station)
            solver.Ub = float(sec.area @ st.ux) / sec.area.sum()
        if initial is not None and tuple(np.shape(initial.ux)) != tuple(mesh.shape):
            raise ValueError(f"initial field has shape {np.shape(initial.ux)}, the mesh needs {mesh.shape}")
        prev1 = st.copy()
        prev2 = None
        fluxes = np.empty((nx, sec.nf))
        x_prev, h_prev = 0.0, None
        for i in range(nx):
            solver.station = i
            solver.x = xc[i]
            h = xc[i] - x_prev
            if prev2 is None:
                c0 = 1.0
                hist = {v: getattr(prev1, v).copy() for v in _VARS}
            else:  # variable-step BDF2
                om = h / h_prev
                c0 = (1.0 + 2.0 * om) / (1.0 + om)
                a1, a2 = 1.0 + om, om * om / (1.0 + om)
                hist = {v: a1 * getattr(prev1, v) - a2 * getattr(prev2, v) for v in _VARS}
                # k and eps: BDF2 is not positivity preserving; where a steep axial drop (strong
                # particle sinks) makes its history small or negative, that cell steps backward Euler
                for v, key in (("k", "c0_k"), ("eps", "c0_eps")):
                    p1 = getattr(prev1, v)
                    be = hist[v] <= 0.1 * p1
                    if be.any():
                        hist[v] = np.where(be, p1, hist[v])
                        hist[key] = np.where(be, 1.0, c0)
            src = _source_slices(sources, i, n)
            start = None if initial is None else _warm_state(initial, i, sec, gas.density)
            st, ok, iters[i], station_relax[i], station_coupled[i], station_change[i] = _march_station(
                solver, prev1, hist, c0, h, src, laminar, turbulence_relaxation, station_iterations, stol,
                residuals, start, retries=station_retries, extension=station_extension)
            station_ok[i] = ok
            converged &= ok
            _store(out, G, tau, i, st)
            if on_station is not None:
                on_station(i, st.ux, st.uy, st.uz, st.k, st.eps)
            fluxes[i] = st.flux
            limited[i] = solver.limited
            floored[i] = solver.floored
            prev2, prev1 = prev1, st
            x_prev, h_prev = xc[i], h
            bar.update(1)
        bar.close()

    shape = mesh.shape
    p = out["p"].copy()
    if mesh.mode == "developing":
        # section-mean pressure relative to the outlet: integrate -dp/dx backward (trapezoidal)
        dxs = mesh.dx
        pbar = np.empty(nx)
        pbar[-1] = G[-1] * 0.5 * dxs[-1]
        for i in range(nx - 2, -1, -1):
            pbar[i] = pbar[i + 1] + 0.5 * (G[i] + G[i + 1]) * 0.5 * (dxs[i] + dxs[i + 1])
        p += pbar[:, None]
    return GasField(
        mesh=mesh,
        gas=gas,
        bulk_velocity=float(bulk_velocity),
        ux=out["ux"].reshape(shape),
        uy=out["uy"].reshape(shape),
        uz=out["uz"].reshape(shape),
        p=p.reshape(shape),
        k=out["k"].reshape(shape),
        epsilon=out["eps"].reshape(shape),
        pressure_gradient=G,
        wall_shear=tau,
        residuals=np.asarray(residuals),
        station_iterations=iters,
        converged=bool(converged),
        wall_time=time.perf_counter() - t0,
        face_flux=st.flux.copy(),  # cross-section face mass fluxes of the last station (restarts)
        production_limited=limited,
        floored=floored,
        station_relaxation=station_relax,
        station_coupled=station_coupled,
        station_converged=station_ok,
        station_change=station_change,
        station_flux=fluxes if mesh.mode == "developing" else None,
    )


def _march_station(solver, prev, hist, c0, h, src, laminar, relax, station_iterations, stol, residuals,
                   start=None, retries=True, extension=STATION_EXTENSION):
    """Iterate one station of the march to ``stol``: returns (state, converged, iterations,
    relaxation used, whether the coupled cross-flow step was used, the last iteration's
    (velocity, k-eps) change of the state, _StationSolver.last_change).

    The first attempt iterates from ``start`` (a warm start: the station's state in an earlier
    solve, ``solve(initial=...)``) when given, else from the upstream state ``prev``; the
    retries below always from ``prev``.  The convergence test is the same either way, so the
    converged state is the station's discrete fixed point to the tolerance, whichever state the
    iteration starts from, except where the contraction is so slow that a change below the
    tolerance does not bound the error, or where the attempt stalls from one start and not
    from the other and the coupled step's fixed point is taken (strong sinks, scene h:
    docs/numerics.md, "Gas solver").

    The outer iteration lags mu_t, and the march's SIMPLEC cross-flow step is one pressure
    correction per iteration.  Where strong particle sinks have all but laminarised the flow
    (k ~ 1e-3 k_inlet), the cross flow, mu_t and the production of the cross-flow gradients can
    feed each other (k up a factor 100 each second iteration at the axis, scene g at 4 eta0) or
    keep the iteration wandering at a change of 1e-4..1e-3.  Such a station is iterated again
    from the upstream state:

    1. with the coupled cross-flow step (cross-section momentum and continuity solved together,
       as in the periodic mode), when the march uses SIMPLEC: after a divergence, and after
       the iterations ran out without convergence;
    2. with the implicit k-eps and momentum relaxations (r, m) of STATION_RELAXATION below the
       ones given, up to min(1/min(r, m), 4) times the iterations (each attempt may iterate
       on, below), the relaxed change per iteration held to ``stol`` min(r, m); k-eps
       relaxation alone (m as given) with SIMPLEC and then with the coupled step.  After a
       divergence all of them in turn; after iterations that ran out, only those without
       momentum relaxation.  In the near-wall cells of a dense particle layer (scene h at
       4 eta0, final pass) k, eps and u_x can oscillate about the fixed point with a period of
       ~12 iterations, decaying by only ~0.5 % per iteration; k-eps relaxation 0.5 damps it by
       ~1.2 % per iteration, and the four stations of that pass that stall without it converge
       with it (from the stations' upstream states; momentum relaxation 0.7 slows the decay
       instead, and 0.7 alone does not converge; docs/history.md).

    3. when no attempt converged, the first plain attempt (SIMPLEC or the case's step, the
       relaxation given) iterates on from its state at its cap, up to STATION_EXTENSION times
       its iterations in all: a pocket of near-laminar cells can drift slowly for ~300
       iterations before the iteration contracts (scene h's pass 9, x = 0.9 m), a change that
       neither grows nor falls, which no reading of ``_still_converging`` can tell from a
       wandering iteration, and which neither the relaxations nor the coupled step get past;
       with ``extension`` above STATION_EXTENSION, on beyond that while it is still converging.

    An attempt on a limit cycle (its changes repeating with a period of 2-32 iterations:
    ``_cycling``) ends as if its iterations had run out and is not the last resort's to iterate
    on; two changes above DIVERGED_CHANGE end it as a divergence.

    ``retries=False``: a station whose attempt stalls (its iterations run out without
    divergence) is returned as it is, without the further attempts and the extension; one
    that diverges is retried as above.

    An attempt that is still converging when its iterations run out (the largest change of the
    last quarter of them fell from the quarter before, or the last quarter's changes fall on a
    straight line in log(change), at a rate that reaches the tolerance within ``extension``
    (STATION_EXTENSION unless the caller asks for more) times its iterations:
    ``_still_converging``) iterates on, a quarter
    at a time, before any retry; if it diverges while iterating on, it ends as the unconverged
    state where its iterations last ran out.  Where noisy particle sinks leave k at 1e-3 of its level
    in a few cells, k and eps there contract slowly but steadily (0.97-0.99 per iteration with
    tracer-like sinks at alpha = 0.3), and the coupled step, started again from the upstream
    state, only repeats that contraction (the sinks benchmark of docs/numerics.md, "Gas solver").

    The k-eps relaxation keeps the discrete fixed point; the coupled step and the momentum
    relaxation change the momentum-interpolation weights, so the cross flow of that station
    moves by a few % of its maximum (tests).  Only the last attempt's divergence is raised; a
    station still unconverged is returned (the attempt with the smallest last change, relaxed
    changes divided by their relaxation) and reported by GasField.converged and
    GasField.station_converged.
    """
    lo, hi = station_iterations
    extension = max(extension, STATION_EXTENSION)
    alpha_u, coupled = solver.alpha_u, solver.coupled
    attempts = [(relax, alpha_u, coupled, False)]
    if not coupled:
        attempts.append((relax, alpha_u, True, False))
    for r, m in STATION_RELAXATION:
        if r < relax or (r == relax and m < alpha_u):
            attempts.append((r, m, coupled, False))
            if m == alpha_u and not coupled:  # k-eps relaxation alone, with the coupled step
                attempts.append((r, m, True, False))
    if ANDERSON_DEPTH > 0 and not laminar:
        attempts.insert(0, (relax, alpha_u, coupled, True))
    best = None
    resume = None  # the first plain attempt's state where its iterations ran out
    try:
        for a, (r, m, cp, accelerate) in enumerate(attempts):
            if best is not None and m != alpha_u:
                break  # a stalled (not diverged) station is not retried with momentum relaxation
            st = (start if a == 0 and start is not None else prev).copy()
            solver.alpha_u, solver.coupled = m, cp
            tol = stol * min(r, m)
            cap = hi if (r, m) == (relax, alpha_u) else int(hi * min(1.0 / min(r, m), 4.0))
            chunk = max(cap // 4, 1)
            limit, it, changes = cap, 0, []
            at_cap = None  # the unconverged state where the iterations last ran out, if iterated on
            mixing = smallest = None
            cycled = False
            try:
                while it < limit:
                    x_in = _pack(st) if accelerate and it + 1 >= ANDERSON_DELAY else None
                    ch = solver.iterate(st, hist, c0, h, src, laminar, r)
                    residuals.append(ch)
                    changes.append(ch)
                    it += 1
                    if it >= lo and ch < tol:
                        return st, True, it, min(r, m), cp, solver.last_change
                    if it > 4 and not min(changes[-2], ch) <= DIVERGED_CHANGE:
                        raise SolverDivergence(
                            f"gas solve diverged: two outer iterations changed the state by {changes[-2]:.3g} "
                            f"and {ch:.3g} (relative) at x = {solver.x:.4g} m (station {solver.station})")
                    if CYCLE_PERIODS and _cycling(changes, tol):
                        cycled = True
                        break  # a limit cycle: as if its iterations had run out
                    if accelerate and it >= ANDERSON_DELAY:
                        if mixing is None:
                            mixing = AndersonMixing(ANDERSON_DEPTH, _mixing_weight(st, solver.Ub))
                        if smallest is not None and ch > ANDERSON_RESTART * smallest:
                            mixing.reset()
                        smallest = ch if smallest is None else min(smallest, ch)
                        if not _unpack(st, mixing.next(x_in, _pack(st)), solver):
                            mixing.reset()  # a step far out: the plain image stands, the history restarts
                    if (it == limit and not accelerate
                            and _still_converging(changes, chunk, tol, extension * cap - it)):
                        # the state where the iterations ran out, the last time they did
                        at_cap = (ch, st.copy(), it, solver.last_change)
                        limit = min(limit + chunk, extension * cap)
            except SolverDivergence:
                if at_cap is None:
                    if a + 1 == len(attempts) and best is None:
                        raise
                    continue
                # diverged while iterating on: the attempt ends where its iterations last ran out
                ch, st, it, last = at_cap
            else:
                last = solver.last_change
                if resume is None and not accelerate and not cycled and (r, m, cp) == (relax, alpha_u, coupled):
                    resume = (st.copy(), it, cap)  # (a cycle would only repeat itself there)
            if accelerate:
                # an accelerated attempt that did not converge leaves a mixed state, not an iterate:
                # the plain attempts below start again from the upstream state
                continue
            if best is None or ch / min(r, m) < best[0]:  # the relaxed change, scaled back
                best = (ch / min(r, m), st, it, min(r, m), cp, last)
            if not retries:
                break  # stalled, not diverged: kept as it is (a divergence goes on to the retries)
        if retries and resume is not None and resume[1] < STATION_EXTENSION * resume[2]:
            # the last resort: the plain attempt iterates on from where its iterations ran out, up
            # to STATION_EXTENSION times its cap (unless it was extended that far already),
            # through a slow drift that none of the attempts above gets past (scene h,
            # x = 0.9 m: ~300 iterations, then a fast contraction)
            # and, with ``extension`` above STATION_EXTENSION, a quarter of its iterations at a time
            # beyond that while it is still converging (_still_converging)
            st, it, cap = resume
            solver.alpha_u, solver.coupled = alpha_u, coupled
            r = min(relax, alpha_u)
            chunk, limit, tail = max(cap // 4, 1), STATION_EXTENSION * cap, []
            try:
                while it < limit:
                    ch = solver.iterate(st, hist, c0, h, src, laminar, relax)
                    residuals.append(ch)
                    tail.append(ch)
                    it += 1
                    if ch < stol * r:
                        return st, True, it, r, coupled, solver.last_change
                    if (it == limit and limit < extension * cap
                            and _still_converging(tail, chunk, stol * r, extension * cap - it)):
                        limit = min(limit + chunk, extension * cap)
            except SolverDivergence:
                pass
            else:
                if ch / r < best[0]:
                    best = (ch / r, st, it, r, coupled, solver.last_change)
    finally:
        solver.alpha_u, solver.coupled = alpha_u, coupled
    return best[1], False, best[2], best[3], best[4], best[5]


def _cycling(changes, tol):
    """Whether the last outer iterations repeat themselves: for some period 2 <= p <=
    CYCLE_PERIOD_MAX the last max(CYCLE_PERIODS p, 8) changes equal those p iterations earlier
    to CYCLE_MATCH (relative), all above ``tol``, and vary within a period by a factor of 2 or
    more.  The outer iteration is a deterministic map, so such an attempt is on a limit cycle
    (k at the axis up a factor ~30 every second iteration, or the Anderson history's restarts
    repeating every 11-12 iterations, scene h) and would only repeat it until its iterations
    run out.  A change that stays level (a slow drift, which can end in a contraction: the
    last resort of _march_station) is not a cycle."""
    n = len(changes)
    if n < 12:
        return False
    c = np.asarray(changes[-min(n, (CYCLE_PERIODS + 1) * CYCLE_PERIOD_MAX):], dtype=np.float64)
    return _cycling_kernel(c, float(tol), CYCLE_PERIODS, CYCLE_PERIOD_MAX, CYCLE_MATCH)


@njit(**JIT_FLAGS)
def _cycling_kernel(c, tol, periods, period_max, match):
    """:func:`_cycling` on the last changes ``c`` (compiled)."""
    m = c.size
    for i in range(m - 8, m):
        if not (np.isfinite(c[i]) and c[i] > tol):
            return False
    for p in range(2, period_max + 1):
        w = max(periods * p, 8)
        if w + p > m:
            return False
        ok = True
        for i in range(m - w, m):
            if not abs(c[i] - c[i - p]) <= match * c[i]:
                ok = False
                break
        if ok:
            lo = c[m - w]
            hi = c[m - w]
            for i in range(m - w, m):
                lo = min(lo, c[i])
                hi = max(hi, c[i])
            return hi >= 2.0 * lo
    return False


def _still_converging(changes, chunk, tol, left):
    """Whether an outer iteration is still converging toward ``tol`` within ``left`` more
    iterations.  Either of two readings of the last ``chunk`` changes says so:

    1. their largest is below that of the ``chunk`` before, by a rate that reaches ``tol``
       from it in time (a slow contraction; a wandering iteration, whose changes scatter over
       a band, keeps about the same maximum);
    2. they fall along a straight line in log(change) (coefficient of determination
       >= STEADY_R2, negative slope), and the slope of their later half reaches ``tol`` from
       the last change in time.  This one catches a contraction that sets in after a bump: in
       scene g (4 eta0, two-way) the station at x = 0.825 m rises to a change of 0.16 at
       iteration 142 of 200 and then contracts by 0.8-0.92 per iteration to 1.3e-5; the
       first reading projects from the chunk's largest change (6.5e-2) and declines, though
       ~30 more iterations suffice (docs/history.md).  Scattered changes have no such line
       (r2 ~ 0) and an oscillation about the fixed point neither.
    """
    if len(changes) < 2 * chunk or left <= 0:
        return False
    last = np.asarray(changes[-chunk:], dtype=float)
    if not (np.all(np.isfinite(last)) and np.all(last > 0.0)):
        return False
    now, before = last.max(), max(changes[-2 * chunk:-chunk])
    if np.isfinite(before) and now < before:
        if math.log(tol / now) / (math.log(now / before) / chunk) <= left:
            return True
    if last[-1] <= tol or chunk < 8:  # both fits need a few points (the later half >= 4)
        return False
    y = np.log(last)
    n = np.arange(chunk, dtype=float)
    slope, icpt = np.polyfit(n, y, 1)
    r2 = 1.0 - np.sum((y - (slope * n + icpt)) ** 2) / max(np.sum((y - y.mean()) ** 2), 1e-300)
    late = np.polyfit(n[chunk // 2:], y[chunk // 2:], 1)[0]
    if not (slope < 0.0 and late < 0.0 and r2 >= STEADY_R2):
        return False
    return math.log(tol / last[-1]) / late <= left


def _check_sources(mesh, sources):
    arrays = [("momentum", sources.momentum), ("k", sources.k), ("epsilon", sources.epsilon)]
    if sources.drag is not None:
        if sources.velocity_reference is None:
            raise ValueError("a drag source needs its velocity_reference (the gas velocity it was sampled in)")
        arrays += [("drag", sources.drag), ("velocity_reference", sources.velocity_reference)]
        if np.any(sources.drag < 0.0):
            raise ValueError(f"drag coefficient is negative (min {sources.drag.min():g}); it is a sum of m/tau_p >= 0")
    for name, arr in arrays:
        want = (3,) + mesh.shape if name in ("momentum", "velocity_reference") else mesh.shape
        if arr.shape != want:
            raise ValueError(f"{name} source has shape {arr.shape}, the mesh needs {want}")
        bad = ~np.isfinite(arr)
        if bad.any():
            idx = np.argwhere(bad)[0]
            i, j, k = idx[-3:]
            raise ValueError(f"{name} source is not finite ({arr[tuple(idx)]}) at station {i}, ring {j}, sector {k}")


def _store(out, G, tau, i, st):
    out["ux"][i] = st.ux
    out["uy"][i] = st.uy
    out["uz"][i] = st.uz
    out["p"][i] = st.p
    out["k"][i] = st.k
    out["eps"][i] = st.eps
    G[i] = st.G
    tau[i] = st.tau_w


def _state_from_field(f, i):
    sec = f.mesh.geometry()
    return _State(ux=f.ux[i].ravel().copy(), uy=f.uy[i].ravel().copy(), uz=f.uz[i].ravel().copy(),
                  p=f.p[i].ravel().copy(), k=f.k[i].ravel().copy(), eps=f.epsilon[i].ravel().copy(),
                  flux=f.face_flux.copy() if f.face_flux is not None else np.zeros(sec.nf))


def _warm_state(f, i, sec, rho):
    """Station ``i`` of the field ``f`` as the starting state of that station's outer iteration
    (developing mode): velocities, k and epsilon as stored; the cross-section pressure without
    its section mean (GasField.p adds the axial level); the cross-section face mass fluxes of
    the station (GasField.station_flux) or, for a field without them (e.g. one read back from a
    coupling checkpoint, which keeps the last station's only), those of the interpolated
    velocities: the first outer iteration replaces them by the momentum-interpolated ones (from
    the exact field the stations then need ~5-12 iterations instead of 2)."""
    A = sec.area
    p = np.asarray(f.p[i], dtype=float).ravel()
    p = p - (A @ p) / A.sum()
    uz = np.asarray(f.uz[i], dtype=float).ravel().copy()
    uy = np.asarray(f.uy[i], dtype=float).ravel().copy()
    if getattr(f, "station_flux", None) is not None:
        flux = np.asarray(f.station_flux[i], dtype=float).copy()
    else:
        flux = rho * sec.S * (sec.interp(uz) * sec.nz + sec.interp(uy) * sec.ny)
    return _State(ux=np.asarray(f.ux[i], dtype=float).ravel().copy(), uy=uy, uz=uz, p=p,
                  k=np.asarray(f.k[i], dtype=float).ravel().copy(),
                  eps=np.asarray(f.epsilon[i], dtype=float).ravel().copy(), flux=flux)


class _NoBar:
    def update(self, n=1):
        pass

    def close(self):
        pass


def _progress(total, enabled):
    if not enabled:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, desc="gas", unit="it", leave=False)
