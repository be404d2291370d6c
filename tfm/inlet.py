"""Inlet correlations of Ding et al. (2024, eqs. 20–23) and the inference of the inputs the paper leaves out.

References
----------
Hinkle, B.L. (1953). Acceleration of particles and pressure drops encountered in horizontal
pneumatic conveying. PhD thesis, Georgia Institute of Technology.
Ding et al. (2024), Appl. Sci. 14, 2031, eqs. (20)–(23), Table 1.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["hinkle_1953_solids_velocity", "hinkle_particle_diameter", "inlet_solids_fraction",
           "paper_inlet", "seventh_power_profile"]


def hinkle_1953_solids_velocity(u_g, d_s, rho_s, rho_g, diameter):
    """Hinkle's solids velocity u_s = U_g (1 − 0.68 d_s^0.92 ρ_s^0.5 ρ_g^−0.2 D^−0.54) [m s-1] (eq. 22).

    Parameters
    ----------
    u_g : superficial gas velocity U_g [m s-1]
    d_s : particle diameter [m]
    rho_s : particle density [kg m-3]
    rho_g : gas density [kg m-3]
    diameter : pipe diameter D [m]

    Validity: dimensional correlation in SI units; horizontal dilute to moderately dense
    conveying (Hinkle 1953).

    Examples
    --------
    >>> round(float(hinkle_1953_solids_velocity(6.43, 160e-6, 1650.0, 32.7, 0.01)), 3)
    6.088
    """
    return u_g * (1.0 - 0.68 * d_s**0.92 * rho_s**0.5 * rho_g**-0.2 * diameter**-0.54)


def hinkle_particle_diameter(velocity_ratio, rho_s, rho_g, diameter):
    """Invert eq. (22) for d_s given u_s/U_g [m].

    Parameters
    ----------
    velocity_ratio : u_s,inlet / U_g [-] (Table 1: 0.938–0.953)
    rho_s, rho_g : [kg m-3]; diameter : D [m]

    Examples
    --------
    >>> round(float(hinkle_particle_diameter(6.09 / 6.43, 1650.0, 32.7, 0.01)) * 1e6, 1)
    158.9
    """
    return ((1.0 - velocity_ratio) / (0.68 * rho_s**0.5 * rho_g**-0.2 * diameter**-0.54)) ** (1.0 / 0.92)


def inlet_solids_fraction(m_s, rho_s, u_s, diameter):
    """α_s,inlet = 4 M_s / (ρ_s u_s π D²) [-] (eq. 23).

    Parameters
    ----------
    m_s : solids mass flow [kg s-1]
    rho_s : particle density [kg m-3]
    u_s : solids velocity [m s-1]
    diameter : D [m]

    Examples
    --------
    >>> round(float(inlet_solids_fraction(0.194, 1650.0, 6.09, 0.01)), 4)
    0.2458
    """
    return 4.0 * m_s / (rho_s * u_s * math.pi * diameter**2)


def paper_inlet(u_g, d_s, rho_s, rho_g, diameter, m_s, alpha_max):
    """(u_s, α_s) of the paper's inlet: Hinkle's solids velocity (eq. 22) and the solids fraction
    it gives the mass flow (eq. 23) [m s-1, -].  ValueError (one line) when α_s is not in
    (0, α_max): the mass flow cannot enter at Hinkle's velocity as a packing of these particles.

    Examples
    --------
    >>> [round(v, 3) for v in paper_inlet(6.43, 160e-6, 1650.0, 33.0, 0.01, 0.194, 0.63)]
    [6.088, 0.246]
    """
    u_s = float(hinkle_1953_solids_velocity(u_g, d_s, rho_s, rho_g, diameter))
    a_s = float(inlet_solids_fraction(m_s, rho_s, u_s, diameter)) if u_s > 0.0 else math.inf
    if not 0.0 < a_s < alpha_max:
        raise ValueError(f"inlet solids fraction {a_s:.3g} (eq. 23 with the Hinkle velocity {u_s:.3g} m/s) "
                         f"is outside (0, alpha_max = {alpha_max})")
    return u_s, a_s


def seventh_power_profile(r, diameter, mean):
    """Inlet profile v(r) = (60/49) mean (1 − 2r/D)^(1/7) [m s-1] (eqs. 20–21).

    Examples
    --------
    >>> round(float(seventh_power_profile(0.0, 0.01, 1.0)), 6)
    1.22449
    """
    return 60.0 / 49.0 * mean * np.maximum(1.0 - 2.0 * np.asarray(r) / diameter, 0.0) ** (1.0 / 7.0)
