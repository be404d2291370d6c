"""Single-particle motion: the exact-exponential step against independent solutions.

- terminal settling velocity vs the root of the Schiller–Naumann force balance (brentq) and
  vs fluids.drag.v_terminal (an independent drag curve);
- stiffness: a 1 µm particle in a linear shear flow with Δt/τ_p = 10^4;
- the fluid impulse J over a step equals m Δu − m g′Δt (not F(u_n)Δt);
- a step with Saffman–Mei and Magnus lift in a shear flow against an ODE solution (solve_ivp)
  with the forces written out from the seed's equations.
"""

import math

import numpy as np
import pytest
from fluids.drag import v_terminal
from scipy.optimize import brentq

from particles import PhysicsOptions, make_motion
from particles.layout import NPRM, P_DP, P_GRAV, P_MU, P_RHO_F, P_RHO_P

RHO, MU, G = 1.205, 1.81e-5, 9.81


def params(d, rho_p, gravity=True):
    prm = np.zeros(NPRM)
    prm[P_RHO_F] = RHO
    prm[P_MU] = MU
    prm[P_RHO_P] = rho_p
    prm[P_DP] = d
    prm[P_GRAV] = G * (1.0 - RHO / rho_p) if gravity else 0.0
    return prm


def schiller_naumann_terminal_velocity(d, rho_p):
    """Root of m g (1 − ρ/ρ_p) = ½ ρ v² C_D(Re) π d²/4 with Schiller–Naumann C_D (written out here)."""
    m = rho_p * math.pi * d**3 / 6.0

    def balance(v):
        re = RHO * d * v / MU
        cd = 24.0 / re * (1.0 + 0.15 * re**0.687) if re <= 1000.0 else 0.44
        return 0.5 * RHO * v * v * cd * math.pi * d * d / 4.0 - m * G * (1.0 - RHO / rho_p)

    return brentq(balance, 1e-12, 100.0, xtol=1e-15, rtol=1e-13)


TRANSLATION_ONLY = PhysicsOptions(saffman_mei_lift=False, magnus_lift=False, rotation=False)


@pytest.mark.parametrize("d", [1e-6, 1e-5, 1e-4, 3e-4, 1e-3, 3e-3])
def test_terminal_velocity_vs_schiller_naumann_balance_and_fluids(d):
    rho_p = 1020.0
    advance = make_motion(TRANSLATION_ONLY)
    prm = params(d, rho_p)
    pos, vel, omega = np.zeros(3), np.zeros(3), np.zeros(3)
    still, vort, imp = np.zeros(3), np.zeros(3), np.zeros(3)
    tau = advance(pos, vel, omega, still, vort, 1e-9, prm, imp)
    for _ in range(400):  # steps of 0.3 tau (drag factor frozen per step): converges to the balance
        tau = advance(pos, vel, omega, still, vort, 0.3 * tau, prm, imp)
    v_sn = schiller_naumann_terminal_velocity(d, rho_p)
    assert -vel[1] == pytest.approx(v_sn, rel=1e-3)
    assert -vel[1] == pytest.approx(v_terminal(d, rho_p, RHO, MU), rel=0.05)
    assert vel[0] == 0.0 and vel[2] == 0.0


def test_stiff_tracer_in_linear_shear_follows_fluid_without_overshoot():
    """1 µm particle, Δt/τ_p = 1e4, U = G y e_x: after one step it moves with the fluid to 0.1 %."""
    d, rho_p, shear = 1e-6, 1000.0, 500.0
    options = PhysicsOptions(magnus_lift=False, rotation=False)  # drag, gravity, Saffman–Mei lift
    advance = make_motion(options)
    prm = params(d, rho_p)
    tau_p = rho_p * d * d / (18.0 * MU)
    dt = 1e4 * tau_p
    pos = np.array([0.0, 0.005, 0.0])
    vel = np.zeros(3)
    omega, imp = np.zeros(3), np.zeros(3)
    vort = np.array([0.0, 0.0, -shear])  # curl of (G y, 0, 0)
    v_settle = tau_p * G * (1.0 - RHO / rho_p)  # Stokes settling velocity
    vy = []
    for n in range(200):
        uf = np.array([shear * pos[1], 0.0, 0.0])
        advance(pos, vel, omega, uf, vort, dt, prm, imp)
        assert np.all(np.isfinite(vel))
        # the particle keeps the fluid velocity it saw during the step, to 0.1 % of it
        assert vel[0] == pytest.approx(uf[0], rel=1e-3)
        assert vel[0] <= uf[0] * (1.0 + 1e-12)  # never overshoots the fluid velocity
        vy.append(vel[1])
    # vertically it settles at a steady speed near the Stokes value (the Saffman lift of the
    # settling slip changes it by a few %) and never oscillates: no sign change, no growth
    vy = np.array(vy)
    assert np.all(vy < 0.0)
    assert np.all(np.abs(vy) < 1.1 * v_settle)
    assert np.ptp(vy[5:]) < 1e-6 * v_settle


def test_step_impulse_is_momentum_change_minus_weight_not_force_times_dt():
    d, rho_p = 200e-6, 1020.0
    advance = make_motion(TRANSLATION_ONLY)
    prm = params(d, rho_p)
    m = rho_p * math.pi * d**3 / 6.0
    vel0 = np.array([5.0, 0.3, -0.2])
    uf = np.array([10.0, 0.0, 0.0])
    vel, pos, omega, imp, vort = vel0.copy(), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
    dt = 0.5  # about 15 tau_p
    tau = advance(pos, vel, omega, uf, vort, dt, prm, imp)
    g_red = np.array([0.0, -prm[P_GRAV], 0.0])
    assert imp == pytest.approx(m * ((vel - vel0) - g_red * dt), rel=1e-12, abs=1e-18)
    # F(u_n) dt overshoots the exact impulse when dt >> tau_p
    assert np.linalg.norm(m * (uf - vel0) / tau * dt) > 2.0 * np.linalg.norm(imp)
    # exact solution of du/dt = (u_F - u)/tau + g' with frozen tau (no lift)
    exact = uf + g_red * tau + (vel0 - uf - g_red * tau) * math.exp(-dt / tau)
    assert vel == pytest.approx(exact, rel=1e-12)


def test_spin_relaxes_to_half_the_vorticity_with_the_stokes_time_scale():
    d, rho_p = 50e-6, 1020.0
    advance = make_motion(PhysicsOptions(saffman_mei_lift=False, magnus_lift=False))
    prm = params(d, rho_p, gravity=False)
    vort = np.array([0.0, 0.0, -200.0])
    omega = np.zeros(3)
    tau_r = rho_p * d * d / (60.0 * MU)  # I_p/(pi mu d^3) in the Stokes regime (Re_r << 32)
    advance(np.zeros(3), np.zeros(3), omega, np.zeros(3), vort, tau_r, prm, np.zeros(3))
    assert omega[2] == pytest.approx(-100.0 * (1.0 - math.exp(-1.0)), rel=1e-12)


@pytest.mark.parametrize("lift", ["saffman", "magnus", "both"])
def test_lifted_step_vs_an_ode_solution_with_the_forces_written_out(lift):
    """One step with Saffman–Mei and/or Magnus lift and gravity in a shear flow U = G y e_x
    against scipy's solve_ivp of du/dt = (u_F − u)/τ_p + F_LS/m + F_LR/m + g′, dx/dt = u, the
    forces written out here (Schiller–Naumann drag, Saffman's 4.1126/√Re_S with Mei's f, Lun &
    Liu's C_LR; seed eqs. 3–9) with their coefficients taken at the step's start, as the step
    takes them: velocity and position to 1e-9.  The lift moves the step by far more than that,
    and a lagging particle's Saffman lift points to the faster fluid (+y)."""
    from scipy.integrate import solve_ivp

    from .test_particles_forces import lun_liu, mei_f, sn_cd

    d, rho_p, shear = 200e-6, 1020.0, 500.0
    saffman, magnus = lift != "magnus", lift != "saffman"
    advance = make_motion(PhysicsOptions(saffman_mei_lift=saffman, magnus_lift=magnus, rotation=True))
    prm = params(d, rho_p)
    uf, vort = np.array([10.0, 0.0, 0.0]), np.array([0.0, 0.0, -shear])  # ∇×(G y e_x) = −G e_z
    u0, w0 = np.array([9.4, 0.15, -0.05]), np.array([0.0, 0.0, 120.0])
    m = rho_p * math.pi * d**3 / 6.0
    slip = float(np.linalg.norm(uf - u0))
    re_p, re_s = RHO * d * slip / MU, RHO * d * d * shear / MU
    tau = rho_p * d * d / (18.0 * MU) / (sn_cd(re_p) * re_p / 24.0)
    k_s = 0.5 * RHO * math.pi / 4 * d**3 * 4.1126 / math.sqrt(re_s) * mei_f(re_p, re_s) / m if saffman else 0.0
    big_omega = 0.5 * vort - w0
    re_r = RHO * d * d * float(np.linalg.norm(big_omega)) / MU
    k_m = (0.5 * RHO * math.pi / 4 * d * d * lun_liu(re_p, re_r) * slip / (float(np.linalg.norm(big_omega)) * m)
           if magnus else 0.0)
    g_red = np.array([0.0, -prm[P_GRAV], 0.0])

    def rhs(t, y):
        r = uf - y[3:]
        return np.concatenate([y[3:], r / tau + k_s * np.cross(r, vort) + k_m * np.cross(big_omega, r) + g_red])

    dt = 0.25 * tau
    sol = solve_ivp(rhs, (0.0, dt), np.concatenate([np.zeros(3), u0]), method="DOP853", rtol=1e-13, atol=1e-16)
    pos, vel, omega, imp = np.zeros(3), u0.copy(), w0.copy(), np.zeros(3)
    advance(pos, vel, omega, uf, vort, dt, prm, imp)
    assert vel == pytest.approx(sol.y[3:, -1], rel=1e-9, abs=1e-9 * slip)
    assert pos == pytest.approx(sol.y[:3, -1], rel=1e-9, abs=1e-9 * slip * dt)
    plain_pos, plain_vel = np.zeros(3), u0.copy()
    make_motion(TRANSLATION_ONLY)(plain_pos, plain_vel, np.zeros(3), uf, vort, dt, prm, np.zeros(3))
    assert np.abs(vel - plain_vel).max() > 1e-5 * slip
    if lift == "saffman":
        assert vel[1] > plain_vel[1]
