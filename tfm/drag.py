"""Gas–solid drag coefficients β of the two-fluid model.

Convention (one for the whole package): β [kg m-3 s-1] is the interphase momentum
exchange coefficient per unit *mixture* volume, so the force per unit volume on the solids
is F_sg = β (v_g − v_s) (Ding et al. 2024, eq. 11) and the gas feels −F_sg.  With the
"−α_i ∇p" form of the momentum equations, a fixed bed with superficial gas velocity U
has −dp/dx = β U / α_g² (Ergun's packed-bed law), and a single sphere in the dilute limit
feels β |Δv| / α_s per unit particle volume (terminal velocity).  Both are tested.

The three-zone model of Ding et al. (2024, eq. 9) is piecewise: Ergun for α_g < 0.6,
McKeen (Gibilaro's law times a scale factor C) for 0.6 ≤ α_g < 0.9, Wen–Yu above.  It is
discontinuous at both switches; :func:`three_zone_drag` offers a smooth blend
(``blend_width`` > 0, a tanh weight of that half-width in α_g across each switch).

References
----------
Ding, S.; Zhou, H.; Tang, W.; Xiao, R.; Zhou, J. (2024). Influence of Frictional Stress
Models on Simulation Results of High-Pressure Dense-Phase Pneumatic Conveying in Horizontal
Pipe. Appl. Sci. 14, 2031. https://doi.org/10.3390/app14052031
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ERGUN_LIMIT",
    "WEN_YU_LIMIT",
    "ergun_1952",
    "mckeen_pugsley_2003",
    "particle_reynolds",
    "schiller_naumann_cd",
    "three_zone_drag",
    "wen_yu_1966",
]

ERGUN_LIMIT = 0.6
"""Gas volume fraction below which Ding et al. (2024, eq. 9) use Ergun."""
WEN_YU_LIMIT = 0.9
"""Gas volume fraction at and above which Ding et al. (2024, eq. 9) use Wen–Yu."""


def particle_reynolds(alpha_g, rho_g, d_s, slip, mu_g):
    """Solids Reynolds number Re_s = α_g ρ_g d_s |v_s − v_g| / μ_g [-].

    Parameters
    ----------
    alpha_g : gas volume fraction [-]
    rho_g : gas density [kg m-3]
    d_s : particle diameter [m]
    slip : magnitude of the slip velocity |v_s − v_g| [m s-1]
    mu_g : gas dynamic viscosity [Pa s]

    References
    ----------
    Ding et al. (2024), Appl. Sci. 14, 2031, eq. (10).

    Examples
    --------
    >>> round(float(particle_reynolds(1.0, 1.2, 1e-3, 1.0, 1.8e-5)), 3)
    66.667
    """
    return np.asarray(alpha_g) * rho_g * d_s * np.abs(slip) / mu_g


def schiller_naumann_cd(re):
    """Single-sphere drag coefficient C_D = 24/Re (1 + 0.15 Re^0.687) for Re < 1000, else 0.44 [-].

    Parameters
    ----------
    re : particle Reynolds number [-], > 0

    Validity: the Schiller–Naumann fit, within ~5 % of the standard drag curve for
    Re < 800; the constant 0.44 is Newton's regime.

    References
    ----------
    Schiller, L.; Naumann, A. (1933). Über die grundlegenden Berechnungen bei der
    Schwerkraftaufbereitung. Z. Ver. Dtsch. Ing. 77, 318–320.
    Ding et al. (2024), Appl. Sci. 14, 2031, eq. (10).

    Examples
    --------
    >>> round(float(schiller_naumann_cd(1.0)), 3)
    27.6
    >>> float(schiller_naumann_cd(2000.0))
    0.44
    """
    re = np.maximum(np.asarray(re, dtype=float), 1e-30)
    return np.where(re < 1000.0, 24.0 / re * (1.0 + 0.15 * re**0.687), 0.44)


def ergun_1952(alpha_s, rho_g, mu_g, d_s, slip):
    """Ergun drag coefficient β = 150 α_s² μ_g / (α_g d_s²) + 1.75 α_s ρ_g |Δv| / d_s [kg m-3 s-1].

    Written with α_s (1 − α_g) = α_s², as in Ding et al. (2024) eq. (9), first line.

    Parameters
    ----------
    alpha_s : solids volume fraction [-], 0 < α_s < 1
    rho_g : gas density [kg m-3]
    mu_g : gas viscosity [Pa s]
    d_s : particle diameter [m]
    slip : |v_s − v_g| [m s-1]

    Validity: packed and dense beds (α_g < 0.6 in eq. 9; Ergun fitted 0.35 ≲ α_g ≲ 0.6).

    References
    ----------
    Ergun, S. (1952). Fluid flow through packed columns. Chem. Eng. Prog. 48, 89–94.
    Ding et al. (2024), Appl. Sci. 14, 2031, eq. (9).

    Examples
    --------
    >>> round(float(ergun_1952(0.5, 1.0, 1e-5, 1e-4, 0.0)), 6)
    75000.0
    """
    alpha_s = np.asarray(alpha_s, dtype=float)
    alpha_g = 1.0 - alpha_s
    return 150.0 * alpha_s**2 * mu_g / (alpha_g * d_s**2) + 1.75 * alpha_s * rho_g * np.abs(slip) / d_s


def mckeen_pugsley_2003(alpha_s, rho_g, mu_g, d_s, slip, scale=1.0):
    """McKeen drag β = C (17.3/Re_s + 0.336) α_s ρ_g |Δv| α_g^-1.8 / d_s [kg m-3 s-1].

    Gibilaro et al.'s (1985) law multiplied by McKeen & Pugsley's scale factor C, which
    Ding et al. (2024) do not give.  McKeen & Pugsley used C = 0.2–0.3 for cohesive FCC
    clusters; C = 1 (the unscaled Gibilaro law) is this package's default and is a stated
    parameter of every case (``[drag] mckeen_scale``).

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    rho_g : gas density [kg m-3]
    mu_g : gas viscosity [Pa s]
    d_s : particle diameter [m]
    slip : |v_s − v_g| [m s-1]
    scale : McKeen's scale factor C [-]

    Validity: intermediate regime, 0.6 ≤ α_g < 0.9 in Ding et al. (2024) eq. (9).

    References
    ----------
    McKeen, T.; Pugsley, T. (2003). Simulation and experimental validation of a freely
    bubbling bed of FCC catalyst. Powder Technol. 129, 139–152.
    Gibilaro, L.G.; Di Felice, R.; Waldram, S.P.; Foscolo, P.U. (1985). Generalized
    friction factor and drag coefficient correlations for fluid-particle interactions.
    Chem. Eng. Sci. 40, 1817–1823.
    Ding et al. (2024), Appl. Sci. 14, 2031, eq. (9), second line.

    Examples
    --------
    >>> b = mckeen_pugsley_2003(0.2, 1.0, 1e-5, 1e-4, 0.1)
    >>> round(float(b), 1)
    6563.3
    """
    alpha_s = np.asarray(alpha_s, dtype=float)
    alpha_g = 1.0 - alpha_s
    re = np.maximum(particle_reynolds(alpha_g, rho_g, d_s, slip, mu_g), 1e-30)
    return scale * (17.3 / re + 0.336) * alpha_s * rho_g * np.abs(slip) * alpha_g**-1.8 / d_s


def wen_yu_1966(alpha_s, rho_g, mu_g, d_s, slip):
    """Wen–Yu drag β = ¾ C_D α_s α_g ρ_g |Δv| α_g^-2.65 / d_s [kg m-3 s-1].

    C_D from :func:`schiller_naumann_cd` at Re_s = α_g ρ_g d_s |Δv| / μ_g.  The small-slip
    limit (Re_s → 0) is finite: β → 18 μ_g α_s α_g^-2.65 / d_s² (Stokes).

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    rho_g : gas density [kg m-3]
    mu_g : gas viscosity [Pa s]
    d_s : particle diameter [m]
    slip : |v_s − v_g| [m s-1]

    Validity: dilute regime, α_g ≥ 0.9 in Ding et al. (2024) eq. (9).

    References
    ----------
    Wen, C.Y.; Yu, Y.H. (1966). Mechanics of fluidization. Chem. Eng. Prog. Symp. Ser.
    62, 100–111.
    Ding et al. (2024), Appl. Sci. 14, 2031, eqs. (9)–(10).

    Examples
    --------
    >>> round(float(wen_yu_1966(0.01, 1.2, 1.8e-5, 1e-4, 0.0)), 3)
    332.745
    """
    alpha_s = np.asarray(alpha_s, dtype=float)
    alpha_g = 1.0 - alpha_s
    re = np.maximum(particle_reynolds(alpha_g, rho_g, d_s, slip, mu_g), 1e-30)
    # C_D |Δv| written as (24 μ/(α_g ρ_g d)) (1 + 0.15 Re^0.687) below Re 1000: finite at zero slip
    cd_slip = np.where(
        re < 1000.0,
        24.0 * mu_g / (alpha_g * rho_g * d_s) * (1.0 + 0.15 * re**0.687),
        0.44 * np.abs(slip),
    )
    return 0.75 * cd_slip * alpha_s * alpha_g * rho_g * alpha_g**-2.65 / d_s


def three_zone_drag(alpha_s, rho_g, mu_g, d_s, slip, mckeen_scale=1.0, blend_width=0.0):
    """Three-zone drag of Ding et al. (2024, eq. 9) [kg m-3 s-1].

    β = Ergun (α_g < 0.6), McKeen (0.6 ≤ α_g < 0.9), Wen–Yu (α_g ≥ 0.9).

    With ``blend_width`` w > 0 the switches are smoothed: across each switch α_g* the two
    neighbouring laws are mixed with the weight ½(1 + tanh((α_g − α_g*)/w)), which keeps β
    continuous (the printed form jumps by a factor of order 2–5 at α_g = 0.6 for C = 1).

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    rho_g : gas density [kg m-3]
    mu_g : gas viscosity [Pa s]
    d_s : particle diameter [m]
    slip : |v_s − v_g| [m s-1]
    mckeen_scale : McKeen's scale factor C [-] (not given by the paper; default 1)
    blend_width : half-width w of the tanh blend in α_g [-]; 0 gives the printed piecewise law

    References
    ----------
    Ding et al. (2024), Appl. Sci. 14, 2031, eq. (9).

    Examples
    --------
    >>> b = three_zone_drag([0.5, 0.2, 0.01], 32.7, 1.78e-5, 160e-6, 0.5)
    >>> [f"{v:.4g}" for v in b]
    ['1.416e+05', '1.476e+04', '718.7']
    """
    alpha_s = np.asarray(alpha_s, dtype=float)
    alpha_g = 1.0 - alpha_s
    b_er = ergun_1952(alpha_s, rho_g, mu_g, d_s, slip)
    b_mk = mckeen_pugsley_2003(alpha_s, rho_g, mu_g, d_s, slip, mckeen_scale)
    b_wy = wen_yu_1966(alpha_s, rho_g, mu_g, d_s, slip)
    if blend_width <= 0.0:
        return np.where(alpha_g < ERGUN_LIMIT, b_er, np.where(alpha_g < WEN_YU_LIMIT, b_mk, b_wy))
    w1 = 0.5 * (1.0 + np.tanh((alpha_g - ERGUN_LIMIT) / blend_width))
    w2 = 0.5 * (1.0 + np.tanh((alpha_g - WEN_YU_LIMIT) / blend_width))
    return (1.0 - w1) * b_er + w1 * ((1.0 - w2) * b_mk + w2 * b_wy)
