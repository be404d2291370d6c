"""Fluid-dynamic force and torque correlations on a sphere (docs/physics.md, section 3).

One correlation per scalar function, named after its authors; every function is
``@njit`` and takes plain floats, so the tracking kernel calls them directly and the
tests call them from Python.  Reynolds numbers (diameter-based throughout):

    Re_p = ρ_F D_p |u_rel| / μ_F          particle (slip) Reynolds number
    Re_S = ρ_F D_p² |ω_F| / μ_F           shear Reynolds number, ω_F = ∇ × U
    Re_r = ρ_F D_p² |Ω| / μ_F             rotational Reynolds number, Ω = ½ ∇ × U − ω_p

Equation numbers are those of the reference paper of Laín & Sommerfeld (docs/physics.md,
References).

Force assembly (the tracker does it with vectors):

    drag        F_D  = m_p (u_F − u_p) / τ_p,  τ_p = ρ_p D_p² / (18 μ_F f_D),  f_D = C_D Re_p / 24
    slip-shear  F_LS = (ρ_F/2)(π/4) D_p³ C_LS (u_rel × ω_F)
    slip-rot.   F_LR = (ρ_F/2)(π/4) D_p² C_LR |u_rel| (Ω × u_rel) / |Ω|
    torque      T    = (ρ_F/2)(D_p/2)⁵ C_R |Ω| Ω = π μ_F D_p³ f_R Ω,  f_R = C_R Re_r / (64 π)

so that with I_p = m_p D_p²/10 the spin relaxes toward ½ ∇ × U with the time scale
τ_r = ρ_p D_p² / (60 μ_F f_R).
"""

import math

from numba import njit

from collisions.conf import JIT_FLAGS

__all__ = [
    "schiller_naumann_drag_coefficient",
    "schiller_naumann_drag_factor",
    "schiller_naumann_drag_factor_ln",
    "response_time",
    "mei_1992_correction",
    "saffman_mei_lift_coefficient",
    "lun_liu_1997_lift_coefficient",
    "lun_liu_1997_lift_coefficient_ln",
    "oesterle_bui_dinh_1998_lift_coefficient",
    "dennis_1980_torque_coefficient",
    "torque_factor",
    "rotational_response_time",
]

SAFFMAN_CONSTANT = 4.1126  # 2 · 6.46 / π (Saffman 1965/68, in Mei's coefficient form)


@njit(**JIT_FLAGS)
def _log0(x):
    """ln x for x > 0, −∞ at 0, so that exp(a · _log0(x)) = x^a (a > 0) also at x = 0.

    Powers of one Reynolds number are written exp(a ln Re): the tracking step takes one
    logarithm for the drag and the slip-rotation lift (the ``*_ln`` forms) instead of two
    ``pow`` calls.
    """
    return math.log(x) if x > 0.0 else -math.inf


@njit(**JIT_FLAGS)
def schiller_naumann_drag_coefficient(re_p):
    """C_D [-] of Schiller & Naumann (1933): 24/Re (1 + 0.15 Re^0.687) for Re_p ≤ 1000, 0.44 above.

    re_p : particle Reynolds number [-], > 0.  Laín & Sommerfeld, eq. 4.
    """
    if re_p > 1000.0:
        return 0.44
    return 24.0 / re_p * (1.0 + 0.15 * math.exp(0.687 * _log0(re_p)))


@njit(**JIT_FLAGS)
def schiller_naumann_drag_factor(re_p):
    """f_D = C_D Re_p / 24 [-] (1 in the Stokes limit), finite at Re_p = 0.

    re_p : particle Reynolds number [-], ≥ 0.
    """
    return schiller_naumann_drag_factor_ln(re_p, _log0(re_p))


@njit(**JIT_FLAGS)
def schiller_naumann_drag_factor_ln(re_p, ln_re):
    """``schiller_naumann_drag_factor`` given also ln_re = ``_log0(re_p)`` (shared by the step)."""
    if re_p > 1000.0:
        return 0.44 * re_p / 24.0
    return 1.0 + 0.15 * math.exp(0.687 * ln_re)  # Re^0.687


@njit(**JIT_FLAGS)
def response_time(rho_p, d_p, mu, f_d):
    """Drag-corrected particle response time τ_p = ρ_p D_p² / (18 μ_F f_D) [s].

    rho_p [kg m-3], d_p [m], mu [Pa s], f_d [-] (drag factor).
    """
    return rho_p * d_p * d_p / (18.0 * mu * f_d)


@njit(**JIT_FLAGS)
def mei_1992_correction(re_p, re_s):
    """Mei's (1992) finite-Re correction f of the Saffman lift [-].

    β = 0.5 Re_S / Re_p;  f = (1 − 0.3314 β^0.5) exp(−Re_p/10) + 0.3314 β^0.5 for Re_p ≤ 40,
    f = 0.0524 (β Re_p)^0.5 for Re_p > 40.  re_p > 0, re_s ≥ 0.  Laín & Sommerfeld, eq. 7.
    """
    beta = 0.5 * re_s / re_p
    if re_p <= 40.0:
        sb = 0.3314 * math.sqrt(beta)
        return (1.0 - sb) * math.exp(-0.1 * re_p) + sb
    return 0.0524 * math.sqrt(beta * re_p)


@njit(**JIT_FLAGS)
def saffman_mei_lift_coefficient(re_p, re_s):
    """C_LS = 4.1126 / Re_S^0.5 · f(Re_p, Re_S) [-] (Saffman 1965/68 with Mei 1992).

    re_p > 0, re_s > 0 [-].  With f = 1 the force equals Saffman's 1.615 μ D |u_rel| Re_S^0.5.
    Laín & Sommerfeld, eqs. 6–7.
    """
    return SAFFMAN_CONSTANT / math.sqrt(re_s) * mei_1992_correction(re_p, re_s)


@njit(**JIT_FLAGS)
def lun_liu_1997_lift_coefficient(re_p, re_r):
    """Slip-rotation lift coefficient C_LR [-] of Lun & Liu (1997).

    C_LR = Re_r/Re_p for Re_p ≤ 1 (Rubinow & Keller 1961), (Re_r/Re_p)(0.178 + 0.822 Re_p^−0.522)
    for Re_p > 1 (published for Re_p < 1000; used unchanged above).  re_p > 0, re_r ≥ 0
    (diameter-based).  Laín & Sommerfeld, eqs. 8–9.
    """
    return lun_liu_1997_lift_coefficient_ln(re_p, re_r, _log0(re_p))


@njit(**JIT_FLAGS)
def lun_liu_1997_lift_coefficient_ln(re_p, re_r, ln_re):
    """``lun_liu_1997_lift_coefficient`` given also ln_re = ``_log0(re_p)`` (shared by the step)."""
    c = re_r / re_p
    if re_p <= 1.0:
        return c
    return c * (0.178 + 0.822 * math.exp(-0.522 * ln_re))  # Re^-0.522


@njit(**JIT_FLAGS)
def oesterle_bui_dinh_1998_lift_coefficient(re_p, re_r):
    """Slip-rotation lift coefficient C_LR [-] of Oesterlé & Bui Dinh (1998), Re_p < 140.

    C_LR = 0.45 + (Re_r/Re_p − 0.45) exp(−0.05684 Re_r^0.4 Re_p^0.3), diameter-based Re_r,
    so that C_LR → Re_r/Re_p as Re_p → 0.
    """
    return 0.45 + (re_r / re_p - 0.45) * math.exp(-0.05684 * re_r**0.4 * re_p**0.3)


@njit(**JIT_FLAGS)
def dennis_1980_torque_coefficient(re_r):
    """Rotational (torque) coefficient C_R [-] with the diameter-based Re_r > 0.

    C_R = 64π/Re_r for Re_r ≤ 32 (Rubinow & Keller 1961, Stokes torque π μ D³ Ω);
    C_R = 12.9/Re_r^0.5 + 128.4/Re_r for 32 < Re_r (Dennis, Singh & Ingham 1980; valid to
    about 1000).  The constants 12.9/128.4 are the diameter-based form of the 6.45/32.1 quoted
    with the radius-based Re_r (docs/physics.md, section 3).  Laín & Sommerfeld, eqs. 10–11.
    """
    if re_r <= 32.0:
        return 64.0 * math.pi / re_r
    return 12.9 / math.sqrt(re_r) + 128.4 / re_r


@njit(**JIT_FLAGS)
def torque_factor(re_r):
    """f_R = C_R Re_r / (64π) [-]: the torque relative to the Stokes torque π μ D³ Ω.

    1 for Re_r ≤ 32; (12.9 Re_r^0.5 + 128.4)/(64π) above.  Finite at Re_r = 0.
    """
    if re_r <= 32.0:
        return 1.0
    return (12.9 * math.sqrt(re_r) + 128.4) / (64.0 * math.pi)


@njit(**JIT_FLAGS)
def rotational_response_time(rho_p, d_p, mu, f_r):
    """Spin relaxation time τ_r = I_p / (π μ D_p³ f_R) = ρ_p D_p² / (60 μ_F f_R) [s].

    rho_p [kg m-3], d_p [m], mu [Pa s], f_r [-] (``torque_factor``); I_p = m_p D_p²/10.
    """
    return rho_p * d_p * d_p / (60.0 * mu * f_r)
