"""Kinetic theory of granular flow (KTGF): radial distribution, solids pressure, viscosities,
granular conductivity and collisional dissipation.

Conventions.  The solids stress is σ_s = (−p_s + α_s λ_s ∇·v_s) I + 2 α_s μ_s S_s
(Ding et al. 2024, eq. 3), so the viscosities returned here are the *phase* viscosities
that eq. 3 multiplies by α_s (the form of the Fluent theory guide, which the paper used).
Θ is the granular (pseudo-)temperature [m2 s-2]; e is the particle–particle restitution
coefficient e_ss.

References
----------
Lun, C.K.K.; Savage, S.B.; Jeffrey, D.J.; Chepurniy, N. (1984). Kinetic theories for
granular flow. J. Fluid Mech. 140, 223–256. https://doi.org/10.1017/S0022112084000586
Gidaspow, D.; Bezburuah, R.; Ding, J. (1992). Hydrodynamics of circulating fluidized beds:
kinetic theory approach. Fluidization VII, 75–82; Gidaspow, D. (1994). Multiphase Flow and
Fluidization. Academic Press, ch. 9.
Savage, S.B. (1998). Analyses of slow high-concentration flows of granular materials.
J. Fluid Mech. 377, 1–26.
Ding et al. (2024), Appl. Sci. 14, 2031, eq. (12) and Table 3.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "gidaspow_conductivity",
    "gidaspow_viscosity",
    "lun_bulk_viscosity",
    "lun_dissipation",
    "lun_solids_pressure",
    "savage_radial_distribution",
    "strain_rate_invariant",
]


def savage_radial_distribution(alpha_s, alpha_max=0.63):
    """Savage's radial distribution g0 = (1 − 7α_s/16) / (1 − α_s/α_max)² [-].

    Parameters
    ----------
    alpha_s : solids volume fraction [-], 0 ≤ α_s < α_max
    alpha_max : packing limit α_s,max [-] (Table 4: 0.63)

    Validity: diverges as α_s → α_max; callers keep α_s below α_max (the two-fluid solver
    clips at α_max − 1e-4 and reports it).

    References
    ----------
    Ding et al. (2024), Appl. Sci. 14, 2031, eq. (12), after Savage (1998).

    Examples
    --------
    >>> round(float(savage_radial_distribution(0.0)), 6)
    1.0
    >>> round(float(savage_radial_distribution(0.5)), 4)
    18.3478
    """
    a = np.asarray(alpha_s, dtype=float)
    return (1.0 - 7.0 * a / 16.0) / (1.0 - a / alpha_max) ** 2


def lun_solids_pressure(alpha_s, rho_s, theta, g0, e_ss=0.7):
    """Kinetic–collisional solids pressure p_s = α_s ρ_s Θ [1 + 2 (1 + e) α_s g0] [Pa].

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    rho_s : particle density [kg m-3]
    theta : granular temperature Θ [m2 s-2]
    g0 : radial distribution [-]
    e_ss : particle–particle restitution coefficient [-]

    References
    ----------
    Lun et al. (1984), J. Fluid Mech. 140, 223–256, eq. (4.14); Ding et al. (2024) Table 3.

    Examples
    --------
    >>> round(float(lun_solids_pressure(0.3, 1500.0, 0.01, 2.0, 0.7)), 4)
    13.68
    """
    a = np.asarray(alpha_s, dtype=float)
    return a * rho_s * theta * (1.0 + 2.0 * (1.0 + e_ss) * a * g0)


def gidaspow_viscosity(alpha_s, rho_s, d_s, theta, g0, e_ss=0.7):
    """Gidaspow's solids shear viscosity μ_s = μ_col + μ_kin [Pa s].

    μ_col = (4/5) α_s ρ_s d_s g0 (1 + e) sqrt(Θ/π)
    μ_kin = 10 ρ_s d_s sqrt(πΘ) / (96 α_s (1 + e) g0) · [1 + (4/5) g0 α_s (1 + e)]²

    The phase viscosity that eq. (3) multiplies by α_s (Fluent's form of Gidaspow's law).

    Parameters
    ----------
    alpha_s : solids volume fraction [-], > 0
    rho_s : particle density [kg m-3]
    d_s : particle diameter [m]
    theta : granular temperature [m2 s-2]
    g0 : radial distribution [-]
    e_ss : restitution coefficient [-]

    References
    ----------
    Gidaspow, Bezburuah & Ding (1992); Gidaspow (1994) eq. (9.41); Ding et al. (2024) Table 3.

    Examples
    --------
    >>> round(float(gidaspow_viscosity(0.3, 1500.0, 1e-4, 0.01, 2.0, 0.7)), 6)
    0.01586
    """
    a = np.asarray(alpha_s, dtype=float)
    theta = np.maximum(np.asarray(theta, dtype=float), 0.0)
    col = 0.8 * a * rho_s * d_s * g0 * (1.0 + e_ss) * np.sqrt(theta / math.pi)
    kin = (10.0 * rho_s * d_s * np.sqrt(math.pi * theta) / (96.0 * np.maximum(a, 1e-12) * (1.0 + e_ss) * g0)
           * (1.0 + 0.8 * g0 * a * (1.0 + e_ss)) ** 2)
    return col + kin


def lun_bulk_viscosity(alpha_s, rho_s, d_s, theta, g0, e_ss=0.7):
    """Lun's solids bulk viscosity λ_s = (4/3) α_s ρ_s d_s g0 (1 + e) sqrt(Θ/π) [Pa s].

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    rho_s : particle density [kg m-3]
    d_s : particle diameter [m]
    theta : granular temperature [m2 s-2]
    g0 : radial distribution [-]
    e_ss : restitution coefficient [-]

    References
    ----------
    Lun et al. (1984); Ding et al. (2024) eq. (3) and Table 3.

    Examples
    --------
    >>> round(float(lun_bulk_viscosity(0.3, 1500.0, 1e-4, 0.01, 2.0, 0.7)), 6)
    0.011509
    """
    a = np.asarray(alpha_s, dtype=float)
    theta = np.maximum(np.asarray(theta, dtype=float), 0.0)
    return 4.0 / 3.0 * a * rho_s * d_s * g0 * (1.0 + e_ss) * np.sqrt(theta / math.pi)


def gidaspow_conductivity(alpha_s, rho_s, d_s, theta, g0, e_ss=0.7):
    """Gidaspow's granular conductivity κ_Θ [kg m-1 s-1].

    κ_Θ = 150 ρ_s d_s sqrt(πΘ) / (384 (1 + e) g0) · [1 + (6/5) α_s g0 (1 + e)]²
          + 2 ρ_s d_s α_s² g0 (1 + e) sqrt(Θ/π)

    The flux of fluctuation energy is −κ_Θ ∇Θ (κ_Θ already contains the α_s factors).

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    rho_s : particle density [kg m-3]
    d_s : particle diameter [m]
    theta : granular temperature [m2 s-2]
    g0 : radial distribution [-]
    e_ss : restitution coefficient [-]

    References
    ----------
    Gidaspow (1994) eq. (9.42); Ding et al. (2024) Table 3.

    Examples
    --------
    >>> round(float(gidaspow_conductivity(0.3, 1500.0, 1e-4, 0.01, 2.0, 0.7)), 6)
    0.020288
    """
    a = np.asarray(alpha_s, dtype=float)
    theta = np.maximum(np.asarray(theta, dtype=float), 0.0)
    return (150.0 * rho_s * d_s * np.sqrt(math.pi * theta) / (384.0 * (1.0 + e_ss) * g0)
            * (1.0 + 1.2 * a * g0 * (1.0 + e_ss)) ** 2
            + 2.0 * rho_s * d_s * a**2 * g0 * (1.0 + e_ss) * np.sqrt(theta / math.pi))


def lun_dissipation(alpha_s, rho_s, d_s, theta, g0, e_ss=0.7):
    """Collisional dissipation of fluctuation energy γ = 12 (1 − e²) g0 ρ_s α_s² Θ^1.5 / (d_s sqrt(π)) [W m-3].

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    rho_s : particle density [kg m-3]
    d_s : particle diameter [m]
    theta : granular temperature [m2 s-2]
    g0 : radial distribution [-]
    e_ss : restitution coefficient [-]

    References
    ----------
    Lun et al. (1984), eq. (4.22); the form in Gidaspow (1994) eq. (9.43).

    Examples
    --------
    >>> round(float(lun_dissipation(0.3, 1500.0, 1e-4, 0.01, 2.0, 0.7)), 3)
    9322.669
    """
    a = np.asarray(alpha_s, dtype=float)
    theta = np.maximum(np.asarray(theta, dtype=float), 0.0)
    return 12.0 * (1.0 - e_ss**2) * g0 * rho_s * a**2 * theta**1.5 / (d_s * math.sqrt(math.pi))


def strain_rate_invariant(grad):
    """S:S of the deviatoric strain rate S = ½(∇v + ∇vᵀ) − ⅓(∇·v) I [s-2].

    Parameters
    ----------
    grad : velocity gradient tensor(s), shape (..., 3, 3), grad[..., i, j] = ∂v_i/∂x_j [s-1]

    References
    ----------
    Ding et al. (2024), eq. (4).

    Examples
    --------
    Simple shear du_x/dy = 2 s-1 gives S:S = ½ (du_x/dy)²:

    >>> g = np.zeros((3, 3)); g[0, 1] = 2.0
    >>> float(strain_rate_invariant(g))
    2.0
    """
    g = np.asarray(grad, dtype=float)
    s = 0.5 * (g + np.swapaxes(g, -1, -2))
    tr = np.trace(g, axis1=-2, axis2=-1)
    eye = np.eye(3)
    s = s - tr[..., None, None] / 3.0 * eye
    return np.einsum("...ij,...ij->...", s, s)
