"""Fully developed (axially periodic) two-fluid solver on the pipe cross-section.

Unknowns per cell of a :class:`rans.mesh.PipeMesh` cross-section: axial gas and solids
velocities u_g, u_s, the solids fraction α_s, the granular temperature Θ; and the mean
pressure gradient G = −dp/dx and the solids inventory (mean α_s).  G is set by the gas
flow (superficial velocity U_g), the inventory by the solids mass flow M_s.

Equations (Ding et al. 2024, Table 2 and eqs. 1–26, with ∂/∂x = 0 except the mean pressure):

* axial momentum, both phases, drag implicit (one coupled sparse solve):
  0 = α_g G + ∇·(α_g μ_g,eff ∇u_g) − β (u_g − u_s)
  0 = α_s G + ∇·(α_s μ_s ∇u_s) + β (u_g − u_s),   μ_s = μ_kin + μ_col + μ_f (capped)
  gas wall: log-law wall function; solids wall: the modified Schneiderbauer shear (eq. 24),
  linearised as τ = −h u_s with h lagged.  The equations are linear in G for lagged
  coefficients, so G is the factor that makes the gas flow U_g exactly.
* granular temperature (Gidaspow form, steady, no convection):
  0 = ∇·(κ_Θ ∇Θ) + α_s μ_s,kc |∇u_s|² − γ(Θ) − 3 β Θ,  wall flux into the solids −q_w (eq. 25)
* cross-section distribution of α_s, a drift-flux balance: the in-plane solids flux
  F = K (−∇p_s − α_s (ρ_s − ρ_g) g ŷ) − (D_t/α_g) ∇α_s, K = α_g² α_s/β,
  (in-plane inertia and viscous stresses of the solids neglected; the gas carries the
  counter-flow), advanced in pseudo-time to ∇·F = 0 with p_s = p_f(α_s) + p_kin(α_s, Θ)
  implicit in α_s (Newton), the weight upwinded.

* gas turbulence (``turbulence = "k-epsilon"``, default): standard k-ε with eulag's constants and
  log-law wall functions (:mod:`rans.kepsilon`), α_g-weighted, with the dispersed-phase sink
  S_k = −2 α_s ρ_s k/(τ_F + τ_t) (τ_F = α_s ρ_s/β, τ_t = 1.5 C_μ k/ε) and C_ε3 (ε/k) S_k,
  C_ε3 = 1.2; turbulent dispersion of the solids D_t = ν_t/σ_α, σ_α = 1.
  ``turbulence = "mixing-length"``: Nikuradse's ℓ with ν_t = ℓ² |∇u_g|, the dispersion
  damped by (1 − min(α_s/α_min, 1))² (no modulation otherwise).

Stated deviations from the paper (whose realizable k-ε-k_p-ε_p model is garbled in the
extraction, and which solved the 3-D unsteady problem): no secondary flow; the gas k-ε above
in place of the realizable k-ε-k_p-ε_p (no solids turbulent viscosity); in-plane solids
motion drag-limited (drift flux).

A failing solve stops with :class:`SectionDivergence` naming the variable and the cell.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rans import kepsilon as ke
from rans.kepsilon import E_WALL, KAPPA
from rans.mesh import PipeMesh
from rans.operators import Section

from .drag import three_zone_drag
from .friction import cap_viscosity, frictional_stress
from .kinetic import (gidaspow_conductivity, gidaspow_viscosity, lun_dissipation, lun_solids_pressure,
                      savage_radial_distribution)
from .parameters import SolidsParameters
from .wall import schneiderbauer_wall_heat_flux, schneiderbauer_wall_shear

__all__ = ["SectionDivergence", "SectionProblem", "SectionState", "solve_section"]

G_ACC = 9.80665


def _wall_pf(pb, pf_wall):
    """The frictional pressure the solids wall condition sees: p_f of the wall cells (Ding et al.'s
    eqs. 24–25) or zero (``params.wall_law = "schneiderbauer"``, the 2012 condition)."""
    if pb.params.wall_law == "ding":
        return pf_wall
    if pb.params.wall_law == "schneiderbauer":
        return np.zeros_like(pf_wall)
    raise ValueError(f"params.wall_law = {pb.params.wall_law!r}: allowed 'ding', 'schneiderbauer'")


class SectionDivergence(RuntimeError):
    """A cross-section solve produced a non-finite or out-of-range value (message: variable, cell, iteration)."""


@dataclass(frozen=True)
class SectionProblem:
    diameter: float
    rho_g: float
    mu_g: float
    rho_s: float
    d_s: float
    u_g: float                  # superficial gas velocity U_g [m s-1]
    m_s: float                  # solids mass flow [kg s-1]
    friction: str = "berzi"
    params: SolidsParameters = field(default_factory=SolidsParameters)
    mckeen_scale: float = 1.0
    drag_blend: float = 0.02
    radial_cells: int = 16
    azimuthal_cells: int = 32
    first_cell_yplus: float = 30.0
    max_iterations: int = 400
    tolerance: float = 1e-4
    alpha_steps: int = 3
    theta_floor: float = 1e-8
    relax_alpha: float = 0.5
    turbulence: str = "k-epsilon"   # or "mixing-length"
    c_eps3: float = 1.2
    relax_theta: float = 0.3


@dataclass
class SectionState:
    alpha: np.ndarray
    ug: np.ndarray
    us: np.ndarray
    theta: np.ndarray
    G: float
    k: np.ndarray | None = None
    eps: np.ndarray | None = None
    dt: float = 1e-3
    iteration: int = 0
    history: list = field(default_factory=list)

    def as_arrays(self):
        extra = {} if self.k is None else dict(k=self.k, eps=self.eps)
        return dict(alpha=self.alpha, ug=self.ug, us=self.us, theta=self.theta, G=np.array(self.G), **extra,
                    dt=np.array(self.dt), iteration=np.array(self.iteration),
                    history=np.array(self.history, dtype=float).reshape(-1, 4))

    @classmethod
    def from_arrays(cls, d):
        return cls(alpha=d["alpha"].copy(), ug=d["ug"].copy(), us=d["us"].copy(), theta=d["theta"].copy(),
                   G=float(d["G"]), dt=float(d["dt"]), iteration=int(d["iteration"]),
                   k=d["k"].copy() if "k" in d else None, eps=d["eps"].copy() if "eps" in d else None,
                   history=[tuple(r) for r in np.asarray(d["history"])])


def _harmonic(a, b):
    return 2.0 * a * b / np.maximum(a + b, 1e-300)


class _Solver:
    def __init__(self, pb: SectionProblem):
        self.pb = pb
        self.mesh = PipeMesh.build(pb.diameter, 1.0, mode="periodic", radial_cells=pb.radial_cells,
                                   azimuthal_cells=pb.azimuthal_cells, first_cell_yplus=pb.first_cell_yplus,
                                   bulk_velocity=pb.u_g, density=pb.rho_g, viscosity=pb.mu_g)
        self.sec = sec = Section(self.mesh)
        self.n = sec.n
        self.A = sec.area
        self.Atot = float(self.A.sum())
        R = self.mesh.radius
        rc = np.sqrt(sec.cz**2 + sec.cy**2)
        xi = np.clip((R - rc) / R, 0.0, 1.0)
        self.mix_len = R * (0.14 - 0.08 * (1.0 - xi) ** 2 - 0.06 * (1.0 - xi) ** 4)
        self.drho = pb.rho_s - pb.rho_g
        self.capped = 0
        # constant structural pieces
        self.cf = sec.S / sec.delta
        self.face_up_is_N = sec.ny > 0.0   # weight flux comes from the upper cell
        #: axial convection of a marching station (:mod:`tfm.developing`); None: fully developed.
        #: Keys: ``cg``, ``cs`` (ρ_g α_g u_g and ρ_s α_s u_s of the upstream station over Δx
        #: [kg m-3 s-1]), ``ug``, ``us``, ``k``, ``eps``, ``theta`` (upstream values), ``dx`` [m].
        self.conv = None

    # ------------------------------------------------------------ helpers
    def check(self, name, v, it, lo=None):
        bad = ~np.isfinite(v)
        if lo is not None:
            bad |= v < lo
        if np.any(bad):
            c = int(np.flatnonzero(bad)[0])
            j, k = divmod(c, self.sec.nt)
            raise SectionDivergence(f"{name} = {float(v[c])!r} in cell {c} (ring {j}, sector {k}) at iteration {it}")

    def laplacian(self, gamma_f):
        sec = self.sec
        c = gamma_f * self.cf
        n = self.n
        diag = np.bincount(sec.P, c, n) + np.bincount(sec.N, c, n)
        M = sp.coo_matrix((np.concatenate([diag, -c, -c]),
                           (np.concatenate([np.arange(n), sec.P, sec.N]),
                            np.concatenate([np.arange(n), sec.N, sec.P]))), shape=(n, n)).tocsr()
        return M

    def grad_mag2(self, phi, wall_value=None):
        gz, gy = self.sec.gradient(phi, wall_value)
        return gz**2 + gy**2

    def closures(self, st):
        pb, P = self.pb, self.pb.params
        a = np.clip(st.alpha, 1e-10, P.alpha_max - 1e-4)
        g0 = savage_radial_distribution(a, P.alpha_max)
        slip = np.maximum(np.abs(st.ug - st.us), 1e-4)
        beta = three_zone_drag(a, pb.rho_g, pb.mu_g, pb.d_s, slip, pb.mckeen_scale, pb.drag_blend)
        gus2 = self.grad_mag2(st.us)
        ss = 0.5 * gus2
        pf, muf = frictional_stress(pb.friction, a, ss, st.theta, 0.0, pb.d_s, P)
        muf, ncap = cap_viscosity(muf, P.mu_f_max)
        mukc = gidaspow_viscosity(a, pb.rho_s, pb.d_s, st.theta, g0, P.e_ss)
        gug2 = self.grad_mag2(st.ug, 0.0)
        if pb.turbulence == "k-epsilon":
            nut = ke.C_MU * st.k**2 / st.eps
        else:
            nut = self.mix_len**2 * np.sqrt(gug2)
        pkin = lun_solids_pressure(a, pb.rho_s, st.theta, g0, P.e_ss)
        return dict(a=a, g0=g0, beta=beta, pf=pf, muf=muf, ncap=ncap, mukc=mukc, gus2=gus2, gug2=gug2, nut=nut,
                    ss=ss, pkin=pkin)

    # ------------------------------------------------------------ axial momentum
    def momentum(self, st, c):
        pb, sec = self.pb, self.sec
        n, A = self.n, self.A
        a = c["a"]
        ag = 1.0 - a
        mu_g_eff = ag * (pb.mu_g + pb.rho_g * c["nut"])
        mu_s_eff = a * (c["mukc"] + c["muf"])
        Lg = self.laplacian(_harmonic(mu_g_eff[sec.P], mu_g_eff[sec.N]))
        Ls = self.laplacian(_harmonic(mu_s_eff[sec.P], mu_s_eff[sec.N]))
        # gas wall function
        w = sec.wall
        yp = sec.wall_distance
        if pb.turbulence == "k-epsilon":
            hg = ag[w] * ke.wall_shear_coefficient(st.k[w], yp, pb.rho_g, pb.mu_g)[0]
        else:
            up = np.maximum(np.abs(st.ug[w]), 1e-6)
            nu = pb.mu_g / pb.rho_g
            ut = np.sqrt(nu * up / yp)
            for _ in range(30):
                yplus = ut * yp / nu
                ut = np.where(yplus > 11.2, KAPPA * up / np.log(E_WALL * np.maximum(yplus, 11.2)),
                              np.sqrt(nu * up / yp))
            hg = ag[w] * pb.rho_g * ut**2 / up
        # solids wall (eq. 24), linearised
        usw = st.us[w]
        tau = np.abs(schneiderbauer_wall_shear(np.where(usw == 0.0, 1e-6, usw), a[w], pb.rho_s, c["g0"][w],
                                               st.theta[w], _wall_pf(pb, c["pf"][w]), pb.params.e_sw,
                                               pb.params.mu_w, pb.params.beta0))
        hs = tau / np.maximum(np.abs(usw), 1e-2)
        dg = np.zeros(n)
        ds = np.zeros(n)
        dg[w] += hg * sec.wall_arc
        ds[w] += hs * sec.wall_arc
        B = sp.diags(c["beta"] * A)
        rhs = np.concatenate([ag * A, a * A])
        cv = self.conv
        if cv is None:
            M = sp.bmat([[Lg + sp.diags(dg) + B, -B], [-B, Ls + sp.diags(ds) + B]], format="csc")
            u1 = spla.spsolve(M, rhs)
            qg1 = float(np.sum(ag * u1[:n] * A))
            G = pb.u_g * self.Atot / qg1
            u = G * u1
        else:
            # marching station: ρ α u_up (u − u_up)/Δx on the left; u = u_b + G u_1, G from the gas flow
            cg, cs = cv["cg"] * A, cv["cs"] * A
            M = sp.bmat([[Lg + sp.diags(dg + cg) + B, -B], [-B, Ls + sp.diags(ds + cs) + B]], format="csc")
            lu = spla.splu(M)
            u1 = lu.solve(rhs)
            ub = lu.solve(np.concatenate([cg * cv["ug"], cs * cv["us"]]))
            qg1 = float(np.sum(ag * u1[:n] * A))
            G = (pb.u_g * self.Atot - float(np.sum(ag * ub[:n] * A))) / qg1
            u = ub + G * u1
        self.tau_sw = tau
        self.hg, self.hs = hg, hs
        return u[:n], u[n:], G

    # ------------------------------------------------------------ gas k-epsilon
    def turbulence(self, st, c):
        """Standard k-ε of the gas (Launder & Spalding 1974, rans.kepsilon constants and wall functions)
        with the dispersed-phase modulation S_k = −2 α_s ρ_s k / (τ_F + τ_t), τ_F = α_s ρ_s/β,
        τ_t = 1.5 C_μ k/ε, and C_ε3 (ε/k) S_k in the ε equation (no convection: fully developed)."""
        pb, sec = self.pb, self.sec
        A, a = self.A, c["a"]
        ag = 1.0 - a
        k, eps = st.k, st.eps
        mut = pb.rho_g * ke.C_MU * k**2 / eps
        w, yp = sec.wall, sec.wall_distance
        prod = mut * c["gug2"]
        tau_w = ke.wall_shear_coefficient(k[w], yp, pb.rho_g, pb.mu_g)[0] * np.abs(st.ug[w])
        prod = prod.copy()
        prod[w] = ke.wall_production(tau_w, k[w], yp)
        tau_f = a * pb.rho_s / c["beta"]
        tau_t = 1.5 * ke.C_MU * k / eps
        sink_p = 2.0 * a * pb.rho_s / (tau_f + tau_t)           # S_k = −sink_p k
        gk = ag * (pb.mu_g + mut / ke.SIGMA_K)
        Lk = self.laplacian(_harmonic(gk[sec.P], gk[sec.N]))
        dk = (ag * pb.rho_g * eps / k + sink_p) * A
        rk = ag * prod * A
        cv = self.conv
        if cv is not None:
            dk = dk + cv["cg"] * A
            rk = rk + cv["cg"] * A * cv["k"]
        k_new = spla.spsolve((Lk + sp.diags(dk)).tocsc(), rk)
        k_new = np.maximum(k_new, 1e-10)
        ge = ag * (pb.mu_g + mut / ke.SIGMA_EPS)
        Le = self.laplacian(_harmonic(ge[sec.P], ge[sec.N]))
        de = (ke.C_EPS2 * ag * pb.rho_g * eps / k + pb.c_eps3 * sink_p) * A
        rhs = ke.C_EPS1 * ag * eps / k * prod * A
        if cv is not None:
            de = de + cv["cg"] * A
            rhs = rhs + cv["cg"] * A * cv["eps"]
        # ε fixed in the wall cells (wall function): a dominant diagonal
        big = 1e12 * (np.max(de) + np.max(np.abs(Le.diagonal())))
        de = de.copy()
        de[w] += big
        rhs[w] = big * ke.wall_epsilon(k_new[w], yp)
        e_new = np.maximum(spla.spsolve((Le + sp.diags(de)).tocsc(), rhs), 1e-10)
        return k_new, e_new

    # ------------------------------------------------------------ granular temperature
    def granular_temperature(self, st, c):
        pb, sec, P = self.pb, self.sec, self.pb.params
        A, a = self.A, c["a"]
        th = np.maximum(st.theta, pb.theta_floor)
        kap = gidaspow_conductivity(a, pb.rho_s, pb.d_s, th, c["g0"], P.e_ss)
        L = self.laplacian(_harmonic(kap[sec.P], kap[sec.N]))
        gam = lun_dissipation(a, pb.rho_s, pb.d_s, th, c["g0"], P.e_ss) / th     # γ = (γ/Θ*) Θ
        diag = (gam + 3.0 * c["beta"]) * A
        src = a * c["mukc"] * c["gus2"] * A
        w = sec.wall
        qw = schneiderbauer_wall_heat_flux(st.us[w], a[w], pb.rho_s, c["g0"][w], th[w], _wall_pf(pb, c["pf"][w]),
                                           P.e_sw, P.mu_w, P.beta0)
        src_w = -qw * sec.wall_arc
        # implicit part of a negative wall flux (dissipation ∝ Θ^1.5): keep positivity
        neg = src_w < 0.0
        d_w = np.where(neg, -src_w / th[w], 0.0)
        src = src.copy()
        src[w] += np.where(neg, 0.0, src_w)
        dd = diag.copy()
        dd[w] += d_w
        if self.conv is not None:   # (3/2) ρ_s α_s u_s ∂Θ/∂x
            dd += 1.5 * self.conv["cs"] * A
            src = src + 1.5 * self.conv["cs"] * A * self.conv["theta"]
        theta = spla.spsolve((L + sp.diags(dd)).tocsc(), src)
        return np.maximum(theta, pb.theta_floor)

    # ------------------------------------------------------------ solids distribution
    def solids_pressure(self, a, theta, c):
        pb, P = self.pb, self.pb.params
        x = np.clip(a, 0.0, None)
        pf, _ = frictional_stress(pb.friction, x, c["ss"], theta, 0.0, pb.d_s, P)
        # kinetic-collisional part continued along its tangent above α_max − δ (as p_f): finite at packing
        a_lin = P.alpha_max - max(P.linearise_delta, 1e-4)
        xe = np.minimum(x, a_lin)

        def pk(z):
            return lun_solids_pressure(z, pb.rho_s, theta, savage_radial_distribution(z, P.alpha_max), P.e_ss)

        h = 1e-6
        slope = (pk(np.full_like(x, a_lin)) - pk(np.full_like(x, a_lin - h))) / h
        return pf + pk(xe) + np.where(x > a_lin, slope * (x - a_lin), 0.0)

    def distribute(self, st, c, steps):
        with np.errstate(all="ignore"):
            return self._distribute(st, c, steps)

    def _distribute(self, st, c, steps):
        pb, sec, P = self.pb, self.sec, self.pb.params
        n, A = self.n, self.A
        a_f = np.clip(0.5 * (st.alpha[sec.P] + st.alpha[sec.N]), 1e-8, P.alpha_max - 1e-4)
        beta_f = np.sqrt(c["beta"][sec.P] * c["beta"][sec.N])
        bhat = beta_f / a_f
        K = (1.0 - a_f) ** 2 / bhat
        damp = (1.0 - np.minimum(st.alpha / P.alpha_min, 1.0)) ** 2 if pb.turbulence != "k-epsilon" else 1.0
        Dt = c["nut"] * damp / np.maximum(1.0 - st.alpha, 0.3)
        Dt_f = _harmonic(Dt[sec.P], Dt[sec.N])
        up = np.where(self.face_up_is_N, sec.N, sec.P)
        wsign = sec.ny                             # weight flux −K α_up Δρ g n_y
        S, d = sec.S, sec.delta
        alpha = st.alpha.copy()
        total = float(np.sum(alpha * A))
        cv = self.conv
        # marching station: the axial solids flux (α_s u_s − (α_s u_s)_up)/Δx joins the balance
        ax_d = np.zeros(n) if cv is None else np.maximum(st.us, 0.0) * A / cv["dx"]
        ax_b = np.zeros(n) if cv is None else cv["cs"] / pb.rho_s * A   # (α_s u_s)_up / Δx
        for _ in range(steps):
            a_old = alpha.copy()
            x = a_old.copy()
            ok = False
            for _it in range(25):
                p = self.solids_pressure(x, st.theta, c)
                hh = 1e-7
                dp = (self.solids_pressure(x + hh, st.theta, c) - self.solids_pressure(x - hh, st.theta, c)) / (2 * hh)
                # face flux P->N per unit length
                F = S * (K * (-(p[sec.N] - p[sec.P]) / d - np.clip(x[up], 0.0, None) * self.drho * G_ACC * wsign)
                         - Dt_f * (x[sec.N] - x[sec.P]) / d)
                R = (x - a_old) * A / st.dt + ax_d * x - ax_b + np.bincount(sec.P, F, n) - np.bincount(sec.N, F, n)
                dF_dP = S * (K * dp[sec.P] / d + Dt_f / d)
                dF_dN = S * (-K * dp[sec.N] / d - Dt_f / d)
                wgt = -S * K * self.drho * G_ACC * wsign * (x[up] > 0.0)
                dF_dP = dF_dP + np.where(up == sec.P, wgt, 0.0)
                dF_dN = dF_dN + np.where(up == sec.N, wgt, 0.0)
                rows = np.concatenate([np.arange(n), sec.P, sec.P, sec.N, sec.N])
                cols = np.concatenate([np.arange(n), sec.P, sec.N, sec.P, sec.N])
                vals = np.concatenate([A / st.dt + ax_d, dF_dP, dF_dN, -dF_dP, -dF_dN])
                J = sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsc()
                dx = spla.spsolve(J, -R)
                x = x + dx
                if not np.all(np.isfinite(x)):
                    break
                if np.max(np.abs(dx)) < 1e-10:
                    ok = True
                    break
            if ok and x.min() > -1e-6 and x.max() < P.alpha_max + 0.05:
                alpha = np.clip(x, 0.0, None)
                if cv is None:
                    alpha *= total / float(np.sum(alpha * A))
                st.dt = min(st.dt * 1.5, 1e3)
            else:
                st.dt *= 0.3
                if st.dt < 1e-10:
                    self.check("alpha_s", np.where(np.isfinite(x), np.nan, x), st.iteration)
                    raise SectionDivergence(f"alpha_s: Newton failed at iteration {st.iteration} "
                                            f"(cell {int(np.nanargmax(np.abs(x - a_old)))})")
        return alpha

    # ------------------------------------------------------------ outer loop
    def initial_state(self):
        pb = self.pb
        a0 = min(pb.m_s / (pb.rho_s * pb.u_g * self.Atot), 0.3)
        n = self.n
        k0 = (0.05 * pb.u_g) ** 2
        return SectionState(alpha=np.full(n, a0), ug=np.full(n, pb.u_g / (1 - a0)), us=np.full(n, pb.u_g),
                            theta=np.full(n, 1e-4), G=1000.0, k=np.full(n, k0),
                            eps=np.full(n, ke.inlet_epsilon(k0, pb.diameter)))

    def run(self, st, callback=None):
        """Outer iterations.  Where the change stalls in a limit cycle (successive α_s updates point in
        opposite directions, e.g. wall cells at the onset of friction, α_s ≈ α_min), the relaxation of
        α_s and Θ is halved (after 30 iterations without a 10 % improvement of which most oscillated,
        down to 1/16 of the case's value); ``self.relaxation`` reports the last one."""
        pb = self.pb
        converged = False
        self.relaxation = relax = 1.0
        best, since, flips = np.inf, 0, 0
        prev_step = None
        while st.iteration < pb.max_iterations:
            st.iteration += 1
            c = self.closures(st)
            ug, us, G = self.momentum(st, c)
            self.check("gas_ux", ug, st.iteration)
            self.check("solids_ux", us, st.iteration)
            du = float(np.max(np.abs(us - st.us)) / pb.u_g)
            st.ug, st.us = 0.7 * ug + 0.3 * st.ug, 0.7 * us + 0.3 * st.us
            dG = abs(G - st.G) / max(abs(G), 1e-12)
            st.G = 0.7 * G + 0.3 * st.G
            dk = 0.0
            if pb.turbulence == "k-epsilon":
                if st.k is None:
                    ini = self.initial_state()
                    st.k, st.eps = ini.k, ini.eps
                c = self.closures(st)
                k, eps = self.turbulence(st, c)
                self.check("gas_k", k, st.iteration, lo=0.0)
                self.check("gas_epsilon", eps, st.iteration, lo=0.0)
                dk = float(np.max(np.abs(k - st.k)) / np.max(k))
                st.k = np.exp(0.7 * np.log(k) + 0.3 * np.log(st.k))
                st.eps = np.exp(0.7 * np.log(eps) + 0.3 * np.log(st.eps))
            c = self.closures(st)
            th = self.granular_temperature(st, c)
            self.check("theta", th, st.iteration, lo=0.0)
            rt = pb.relax_theta * relax
            st.theta = np.exp(rt * np.log(th) + (1.0 - rt) * np.log(np.maximum(st.theta, pb.theta_floor)))
            c = self.closures(st)
            alpha = self.distribute(st, c, pb.alpha_steps)
            # solids mass flow -> inventory
            if self.conv is None:
                ms = float(np.sum(alpha * pb.rho_s * st.us * self.A))
                ratio = pb.m_s / max(ms, 1e-12)
                alpha = alpha * ratio ** 0.5
            # the inventory update never packs a cell beyond α_max − 0.02 (without friction, "none",
            # the deposit reaches that bound and the solids flow stays short of M_s: reported unconverged)
            over = alpha > pb.params.alpha_max - 0.02
            if np.any(over):
                alpha = np.minimum(alpha, pb.params.alpha_max - 0.02)
            if self.conv is not None:
                # a marching station: the solids flow is carried by the axial flux balance; what the
                # station carries on is checked against what came in (the cap above or a clip of
                # α_s at 0 loses mass: the station then cannot converge)
                ms = float(np.sum(alpha * pb.rho_s * st.us * self.A))
                ratio = float(np.sum(self.conv["cs"] * self.A)) * self.conv["dx"] / max(ms, 1e-12)
            self.check("alpha_s", alpha, st.iteration, lo=0.0)
            da = float(np.max(np.abs(alpha - st.alpha)))
            ra = pb.relax_alpha * relax
            step = alpha - st.alpha
            if prev_step is not None:
                nrm = np.linalg.norm(step) * np.linalg.norm(prev_step)
                flips += int(nrm > 0 and float(step @ prev_step) < 0.0)
            prev_step = step
            st.alpha = ra * alpha + (1.0 - ra) * st.alpha
            res = max(du, dG, da, dk, abs(ratio - 1.0))
            st.history.append((st.iteration, res, st.G, ms))
            self.last = dict(du=du, dG=dG, da=da, dk=dk, dm=abs(ratio - 1.0))
            if callback is not None:
                callback(st)
            if res < pb.tolerance:
                converged = True
                break
            if res < 0.9 * best:
                best, since, flips = res, 0, 0
            else:
                since += 1
                if since >= 30:
                    if flips > 15 and relax > 1.0 / 16.0:
                        relax *= 0.5
                        self.relaxation = relax
                    best, since, flips = res, 0, 0
        c = self.closures(st)
        self.capped = c["ncap"]
        return st, converged, c


def solve_section(pb: SectionProblem, state: SectionState | None = None, callback=None):
    """Solve one fully developed cross-section; returns (solver, state, converged, closures)."""
    s = _Solver(pb)
    st = state if state is not None else s.initial_state()
    st, ok, c = s.run(st, callback)
    return s, st, ok, c
