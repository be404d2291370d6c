"""Solids wall boundary condition: the modified Schneiderbauer model of Ding et al. (2024, eqs. 24–26).

Schneiderbauer et al.'s (2012) sliding/non-sliding collision model with a Coulomb
frictional term −μ_w p_f added to the wall shear stress.  The extraction of eq. (25) shows
"√(2πμ0²)"; it is read as √(2π) μ0² (the form of Schneiderbauer et al. 2012, eq. 41, and of
Soleimani et al. 2015).

References
----------
Schneiderbauer, S.; Schellander, D.; Löderer, A.; Pirker, S. (2012). Non-steady state
boundary conditions for collisional granular flows at flat frictional moving walls.
Int. J. Multiphase Flow 43, 149–156. https://doi.org/10.1016/j.ijmultiphaseflow.2012.03.007
Ding et al. (2024), Appl. Sci. 14, 2031, eqs. (24)–(26), Table 4.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import erf

__all__ = ["schneiderbauer_mu0", "schneiderbauer_slip_ratio", "schneiderbauer_wall_heat_flux",
           "schneiderbauer_wall_shear"]


def schneiderbauer_mu0(e_sw=0.5, mu_w=0.5, beta0=0.3):
    """μ0 = (7/2)(1 + e_sw)/(1 + β0) μ_w [-] (eq. 26).

    Parameters
    ----------
    e_sw : particle–wall restitution coefficient [-]
    mu_w : particle–wall friction coefficient [-]
    beta0 : tangential restitution coefficient β0 [-]

    Examples
    --------
    >>> round(schneiderbauer_mu0(0.5, 0.5, 0.3), 6)
    2.019231
    """
    return 3.5 * (1.0 + e_sw) / (1.0 + beta0) * mu_w


def schneiderbauer_slip_ratio(u_sw, theta, mu0):
    """ū_sw = |u_sw| / (sqrt(2Θ) μ0) [-] (eq. 26); large where Θ → 0 (pure sliding).

    Parameters
    ----------
    u_sw : solids slip velocity at the wall [m s-1]
    theta : granular temperature at the wall [m2 s-2]
    mu0 : :func:`schneiderbauer_mu0` [-]

    Examples
    --------
    >>> round(float(schneiderbauer_slip_ratio(1.0, 0.02, 2.0)), 6)
    2.5
    """
    den = np.sqrt(2.0 * np.maximum(np.asarray(theta, dtype=float), 0.0)) * mu0
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0.0, np.abs(u_sw) / np.where(den > 0.0, den, 1.0), np.inf)


def schneiderbauer_wall_shear(u_sw, alpha_s, rho_s, g0, theta, p_f, e_sw=0.5, mu_w=0.5, beta0=0.3):
    """Wall shear stress on the solids along the slip direction [Pa] (eq. 24).

    τ_sw = −η_w μ_w α_s ρ_s g0 Θ erf(ū_sw) û − μ_w p_f û,   η_w = (1 + e_sw)/2,

    returned as the signed component along u_sw (negative: it opposes the slip; 0 at zero slip).

    Parameters
    ----------
    u_sw : solids slip velocity (signed component) [m s-1]
    alpha_s : solids volume fraction at the wall [-]
    rho_s : particle density [kg m-3]
    g0 : radial distribution [-]
    theta : granular temperature [m2 s-2]
    p_f : frictional pressure at the wall [Pa]
    e_sw, mu_w, beta0 : wall restitution, friction and tangential restitution [-]

    Examples
    --------
    Pure friction (Θ = 0): the Coulomb term alone.

    >>> float(schneiderbauer_wall_shear(1.0, 0.5, 1500.0, 10.0, 0.0, 80.0))
    -40.0
    """
    eta = 0.5 * (1.0 + e_sw)
    mu0 = schneiderbauer_mu0(e_sw, mu_w, beta0)
    ubar = schneiderbauer_slip_ratio(u_sw, theta, mu0)
    sign = np.sign(u_sw)
    return -(eta * mu_w * np.asarray(alpha_s) * rho_s * g0 * np.asarray(theta) * erf(ubar) + mu_w * np.asarray(p_f)) * sign


def schneiderbauer_wall_heat_flux(u_sw, alpha_s, rho_s, g0, theta, p_f, e_sw=0.5, mu_w=0.5, beta0=0.3):
    """Flux of fluctuation energy at the wall q_w [W m-2] (eq. 25, with √(2π) μ0²).

    q_w = τ_sw·u_sw − α_s ρ_s g0 η_w sqrt(Θ) / (√(2π) μ0²) · exp(−ū²) ·
          { μ_w [2 μ_w |u|² (2η_w − μ0) + Θ (14 μ_w η_w − 4 μ0 (1 + μ_w) − 6 μ_w μ0² η_w)]
            + μ0² sqrt(Θ) exp(ū²) [sqrt(Θ) (4(η_w − 1) + 6 μ_w² η_w) − √(2π) μ_w |u| erf(ū)] }

    Parameters as :func:`schneiderbauer_wall_shear`.

    Examples
    --------
    >>> round(float(schneiderbauer_wall_heat_flux(0.0, 0.5, 1500.0, 10.0, 0.01, 0.0)), 4)
    4.1333
    """
    eta = 0.5 * (1.0 + e_sw)
    mu0 = schneiderbauer_mu0(e_sw, mu_w, beta0)
    theta = np.maximum(np.asarray(theta, dtype=float), 0.0)
    u = np.abs(np.asarray(u_sw, dtype=float))
    ubar = np.minimum(schneiderbauer_slip_ratio(u, theta, mu0), 25.0)
    tau = schneiderbauer_wall_shear(u, alpha_s, rho_s, g0, theta, p_f, e_sw, mu_w, beta0)
    sq = np.sqrt(theta)
    pre = np.asarray(alpha_s) * rho_s * g0 * eta * sq / (math.sqrt(2.0 * math.pi) * mu0**2)
    first = mu_w * (2.0 * mu_w * u**2 * (2.0 * eta - mu0) + theta * (14.0 * mu_w * eta - 4.0 * mu0 * (1.0 + mu_w)
                                                                   - 6.0 * mu_w * mu0**2 * eta))
    second = mu0**2 * sq * (sq * (4.0 * (eta - 1.0) + 6.0 * mu_w**2 * eta)
                            - math.sqrt(2.0 * math.pi) * mu_w * u * erf(ubar))
    return tau * u - pre * (np.exp(-ubar**2) * first + second)
