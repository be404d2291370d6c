"""Standard k-epsilon model constants and log-law wall functions.

Launder, B.E., Spalding, D.B. (1974) The numerical computation of turbulent flows.
Comput. Methods Appl. Mech. Eng. 3, 269-289 (constants, wall functions); see docs/physics.md,
section 2 "Gas phase".
"""

from __future__ import annotations

import math

import numpy as np

C_MU = 0.09  #: [-] eddy-viscosity constant
C_EPS1 = 1.44  #: [-] production constant of the epsilon equation
C_EPS2 = 1.92  #: [-] destruction constant of the epsilon equation
SIGMA_K = 1.0  #: [-] turbulent Prandtl number of k
SIGMA_EPS = 1.3  #: [-] turbulent Prandtl number of epsilon
KAPPA = 0.41  #: [-] von Karman constant
E_WALL = 9.8  #: [-] log-law constant of a smooth wall, u+ = ln(E y+)/kappa


def viscous_edge_yplus(kappa=KAPPA, e_wall=E_WALL):
    """y*_v where the sublayer profile u+ = y+ meets the log law u+ = ln(E y+)/kappa [-] (~11.53)."""
    y = 11.0
    for _ in range(50):  # Newton on f(y) = y - ln(E y)/kappa
        f = y - math.log(e_wall * y) / kappa
        y -= f / (1.0 - 1.0 / (kappa * y))
    return y


#: [-] y* below which the wall cell is treated as viscous sublayer: where the two laws meet,
#: 11.53 for kappa = 0.41, E = 9.8, so that the wall shear coefficient is continuous in k_P.
#: (The often-quoted 11.225 is the crossing for kappa = 0.4187, E = 9.793; with this model's
#: constants it leaves a 2 % jump in tau_w, and a wall cell whose y* sits at the switch cycles
#: between the two laws, so that its gas station does not converge.)
YSTAR_LAMINAR = viscous_edge_yplus()


def inlet_epsilon(k, diameter, length_scale_fraction=0.07):
    """Inlet dissipation from a mixing length l = 0.07 D: eps = C_mu^(3/4) k^(3/2) / l [m2 s-3].

    k [m2 s-2], diameter [m].  The inlet condition of the reference problem (docs/physics.md,
    section 1 "The reference problem").
    """
    return C_MU**0.75 * k**1.5 / (length_scale_fraction * diameter)


def wall_shear_coefficient(k_p, y_p, density, viscosity):
    """Coefficient c [kg m-2 s-1] with tau_w = c U_P (wall function of Launder & Spalding 1974).

    tau_w = rho kappa C_mu^(1/4) k_P^(1/2) U_P / ln(E y*),  y* = rho C_mu^(1/4) k_P^(1/2) y_P / mu,
    and the viscous law tau_w = mu U_P / y_P where y* <= YSTAR_LAMINAR (11.53).
    k_p [m2 s-2], y_p wall distance of the cell centre [m], density [kg m-3], viscosity [Pa s].
    """
    u_star = C_MU**0.25 * np.sqrt(k_p)
    y_star = density * u_star * y_p / viscosity
    log_law = density * KAPPA * u_star / np.log(E_WALL * np.maximum(y_star, YSTAR_LAMINAR))
    return np.where(y_star > YSTAR_LAMINAR, log_law, viscosity / y_p), y_star


def wall_epsilon(k_p, y_p):
    """Dissipation fixed in the wall cell: eps_P = C_mu^(3/4) k_P^(3/2) / (kappa y_P) [m2 s-3]."""
    return C_MU**0.75 * k_p**1.5 / (KAPPA * y_p)


def wall_production(tau_w, k_p, y_p):
    """Production of k in the wall cell: P_k = tau_w C_mu^(1/4) k_P^(1/2) / (kappa y_P) [W m-3]."""
    return tau_w * C_MU**0.25 * np.sqrt(k_p) / (KAPPA * y_p)


def log_law(y_plus):
    """Smooth-wall log law u+ = ln(E y+)/kappa [-]."""
    return np.log(E_WALL * np.asarray(y_plus)) / KAPPA
