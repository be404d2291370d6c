"""Model constants of the two-fluid model (Ding et al. 2024, Table 4, and the inputs it leaves out).

Angles enter in degrees (``*_deg``) and are converted to radians once, here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["SolidsParameters"]


@dataclass(frozen=True)
class SolidsParameters:
    """Solids-phase constants.

    Table 4 of Ding et al. (2024): α_s,min 0.4, α_s,max 0.63, e_ss 0.7, φ_i 32°, e_sw 0.5,
    μ_w 0.5, β0 0.3, a 1.8·10⁻⁶.  Not given by the paper (stated choices):
    Fr = 0.05 Pa, r = 2, s = 5 (Johnson & Jackson 1987 / Srivastava & Sundaresan 2003
    values in common use); k_n/d_s of the modified Berzi model (see
    :func:`tfm.friction.berzi_2011_pressure`); the linearisation width δ of p_c below
    α_max (MFiX's FRICTION_PRINCETON uses 0.01); the frictional-viscosity cap μ_f,max.
    """

    alpha_min: float = 0.4
    alpha_max: float = 0.63
    e_ss: float = 0.7
    internal_friction_angle_deg: float = 32.0
    e_sw: float = 0.5
    mu_w: float = 0.5
    beta0: float = 0.3
    berzi_a: float = 1.8e-6
    fr: float = 0.05
    r: float = 2.0
    s: float = 5.0
    stiffness_over_diameter: float = 4.5e6
    linearise_delta: float = 0.01
    mu_f_max: float = 1.0e3
    #: Solids wall condition: "ding" (eqs. 24–26 of Ding et al. 2024: Schneiderbauer et al.'s
    #: with the Coulomb term μ_w p_f in the shear and its work μ_w p_f |u| in the granular energy's
    #: wall flux) or "schneiderbauer" (Schneiderbauer, Schellander & Pirker 2012, without it).
    wall_law: str = "ding"

    @property
    def phi_i(self) -> float:
        """Angle of internal friction [rad]."""
        return math.radians(self.internal_friction_angle_deg)
