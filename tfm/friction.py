"""Frictional stress models: Dartevelle, Srivastava & Sundaresan, modified Berzi, and the
Johnson & Jackson frictional pressure (the comparison curve of Ding et al. 2024, Fig. 7).

Arguments shared by the viscosity functions:
``ss`` = S_s:S_s [s-2] (deviatoric strain rate, see :func:`tfm.kinetic.strain_rate_invariant`),
``theta`` = Θ_s [m2 s-2], ``d_s`` [m], ``div`` = ∇·v_s [s-1], ``phi_i`` [rad].
The frictional viscosity is a phase viscosity, added to μ_s in eq. (3) of the paper (which
multiplies μ_s,eff by α_s).  Volume fractions are [-], pressures [Pa], viscosities [Pa s].

Near packing.  Every pressure function accepts ``delta`` ≥ 0: for α_s ≥ α_max − δ the
pressure continues along its tangent at α_max − δ (value and slope continuous), which keeps
it finite at and beyond α_max.  δ = 0 evaluates the formula as printed (α_s < α_max).

References
----------
Ding, S.; Zhou, H.; Tang, W.; Xiao, R.; Zhou, J. (2024). Appl. Sci. 14, 2031,
https://doi.org/10.3390/app14052031, eqs. (13)–(19), Table 4.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "berzi_2011_pressure",
    "cap_viscosity",
    "dartevelle_2004_pressure",
    "dartevelle_2004_viscosity",
    "frictional_stress",
    "johnson_jackson_1987_pressure",
    "modified_berzi_viscosity",
    "srivastava_sundaresan_2003_n",
    "srivastava_sundaresan_2003_pressure",
    "srivastava_sundaresan_2003_viscosity",
]

MODELS = ("dartevelle", "srivastava-sundaresan", "berzi", "johnson-jackson", "none")


def _with_tangent(alpha_s, alpha_min, alpha_max, delta, value, slope):
    """Evaluate value(α) below α_max − δ and its tangent above; zero at and below α_min."""
    a = np.asarray(alpha_s, dtype=float)
    a_lin = alpha_max - delta if delta > 0.0 else np.inf
    a_eval = np.clip(a, alpha_min + 1e-300, min(a_lin, alpha_max - 1e-12))
    with np.errstate(divide="ignore", invalid="ignore"):
        p = value(a_eval)
        if delta > 0.0:
            p = np.where(a > a_lin, value(a_lin) + slope(a_lin) * (a - a_lin), p)
    return np.where(a > alpha_min, p, 0.0)


def dartevelle_2004_pressure(alpha_s, alpha_min=0.4, alpha_max=0.63, delta=0.0):
    """Dartevelle frictional pressure, as printed in Ding et al. (2024) eq. (13) [Pa].

    p_f = 1000 (α_s − α_min)³ / (α_max − α_s)³ Pa for α_min < α_s < α_max, else 0.

    The 1000 Pa prefactor and the cubic exponents are those of the paper's eq. (13);
    Dartevelle's (2004) own report could not be checked here, so this is the form *as
    printed* by Ding et al.

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    alpha_min, alpha_max : onset of friction and packing limit [-] (Table 4: 0.4, 0.63)
    delta : tangent continuation width below α_max [-] (0: as printed)

    References
    ----------
    Dartevelle, S. (2004). Numerical modeling of geophysical granular flows: 1.
    Geochem. Geophys. Geosyst. 5, Q08003. https://doi.org/10.1029/2003GC000636
    Ding et al. (2024), eq. (13).

    Examples
    --------
    >>> round(float(dartevelle_2004_pressure(0.5)), 3)
    455.166
    >>> float(dartevelle_2004_pressure(0.39))
    0.0
    """
    span = alpha_max - alpha_min

    def value(a):
        return 1000.0 * ((a - alpha_min) / (alpha_max - a)) ** 3

    def slope(a):
        return 3000.0 * ((a - alpha_min) / (alpha_max - a)) ** 2 * span / (alpha_max - a) ** 2

    return _with_tangent(alpha_s, alpha_min, alpha_max, delta, value, slope)


def johnson_jackson_1987_pressure(alpha_s, fr=0.05, r=2.0, s=5.0, alpha_min=0.4, alpha_max=0.63, delta=0.0):
    """Johnson & Jackson frictional pressure p_c = Fr (α_s − α_min)^r / (α_max − α_s)^s [Pa].

    Also the critical-state pressure p_c of the Srivastava & Sundaresan model (Ding et al.
    2024, eq. 15).  Fr, r, s are not given by the paper; Fr = 0.05 Pa, r = 2, s = 5 are the
    values in common use (Johnson, Nott & Jackson 1990; Srivastava & Sundaresan 2003).

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    fr : Fr [Pa]
    r, s : exponents [-]
    alpha_min, alpha_max : [-]
    delta : tangent continuation width below α_max [-]; MFiX's FRICTION_PRINCETON
        linearises within 0.01 of packing

    References
    ----------
    Johnson, P.C.; Jackson, R. (1987). Frictional–collisional constitutive relations for
    granular materials. J. Fluid Mech. 176, 67–93. https://doi.org/10.1017/S0022112087000570
    Ding et al. (2024), eq. (15).

    Examples
    --------
    >>> round(float(johnson_jackson_1987_pressure(0.5)), 4)
    13.4665
    """
    def value(a):
        return fr * (a - alpha_min) ** r / (alpha_max - a) ** s

    def slope(a):
        return value(a) * (r / (a - alpha_min) + s / (alpha_max - a))

    return _with_tangent(alpha_s, alpha_min, alpha_max, delta, value, slope)


def berzi_2011_pressure(alpha_s, stiffness_over_diameter=4.5e6, a=1.8e-6, alpha_min=0.4, alpha_max=0.63, delta=0.0):
    """Modified Berzi frictional pressure p_f = f0 k_n/d_s, f0 = a (α_s − α_min)/(α_max − α_s) [Pa].

    Ding et al. (2024) eq. (18); the extraction of f0 is garbled (it shows ``a`` with
    α_s − α_min both above and below).  Resolution: the text keeps a numerator α_s − α_min
    and the prefactor a; the denominator is read as α_max − α_s, the form of Berzi, di Prisco
    & Vescovi (2011, the rate-independent pressure, linear in the distance from the
    critical fraction and singular at the packing limit), and the form that makes f0 share
    the α_min/α_max structure of eqs. (13) and (15).

    k_n/d_s is not given.  With a = 1.8·10⁻⁶, Fr = 0.05 Pa, r = 2, s = 5, the ordering of
    the paper's Fig. 7 holds for k_n/d_s between about 3 and 6.5 MPa (tested in
    tests/test_tfm_friction.py); 4.5 MPa is the default (for d_s = 160 µm, k_n = 720 Pa m).

    Parameters
    ----------
    alpha_s : solids volume fraction [-]
    stiffness_over_diameter : k_n/d_s [Pa] (k_n in Pa m, d_s in m)
    a : material coefficient [-] (Table 4: 1.8·10⁻⁶)
    alpha_min, alpha_max : [-]
    delta : tangent continuation width below α_max [-]

    References
    ----------
    Berzi, D.; di Prisco, C.G.; Vescovi, D. (2011). Constitutive relations for steady,
    dense granular flows. Phys. Rev. E 84, 031301. https://doi.org/10.1103/PhysRevE.84.031301
    Ding et al. (2024), eq. (18), Table 4.

    Examples
    --------
    >>> round(float(berzi_2011_pressure(0.5, 4.5e6)), 4)
    6.2308
    """
    span = alpha_max - alpha_min
    k = a * stiffness_over_diameter

    def value(x):
        return k * (x - alpha_min) / (alpha_max - x)

    def slope(x):
        return k * span / (alpha_max - x) ** 2

    return _with_tangent(alpha_s, alpha_min, alpha_max, delta, value, slope)


def dartevelle_2004_viscosity(p_f, phi_i, ss, theta, d_s, div):
    """Dartevelle frictional viscosity μ_f = p_f sin²φ_i / sqrt(2 sin²φ_i (S:S + Θ/d_s²) + (∇·v_s)²) [Pa s].

    Parameters
    ----------
    p_f : frictional pressure [Pa]
    phi_i : angle of internal friction [rad]
    ss : S_s:S_s [s-2]
    theta : granular temperature [m2 s-2]
    d_s : particle diameter [m]
    div : ∇·v_s [s-1]

    Validity: the denominator vanishes only for a bed at rest with Θ = 0; callers cap μ_f
    (:func:`cap_viscosity`).

    References
    ----------
    Dartevelle (2004); Ding et al. (2024), eq. (14) (as printed).

    Examples
    --------
    >>> round(float(dartevelle_2004_viscosity(100.0, math.radians(32.0), 2.0, 0.0, 1e-4, 0.0)), 4)
    26.496
    """
    s2 = math.sin(phi_i) ** 2
    den = np.sqrt(2.0 * s2 * (np.asarray(ss) + np.asarray(theta) / d_s**2) + np.asarray(div) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0.0, np.asarray(p_f) * s2 / np.where(den > 0.0, den, 1.0), np.inf * (np.asarray(p_f) > 0))


def modified_berzi_viscosity(p_f, phi_i, ss, theta, d_s, div):
    """Modified Berzi frictional viscosity, Ding et al. (2024) eq. (19) [Pa s].

    Eq. (19) is eq. (14) with the Berzi pressure: μ_f = p_f sin²φ_i / sqrt(2 sin²φ_i
    (S:S + Θ/d_s²) + (∇·v_s)²).  Arguments as :func:`dartevelle_2004_viscosity`.

    References
    ----------
    Ding et al. (2024), eq. (19).

    Examples
    --------
    >>> round(float(modified_berzi_viscosity(10.0, math.radians(32.0), 0.5, 0.0, 1e-4, 0.0)), 4)
    5.2992
    """
    return dartevelle_2004_viscosity(p_f, phi_i, ss, theta, d_s, div)


def srivastava_sundaresan_2003_n(div, phi_i):
    """Exponent n of the Srivastava & Sundaresan model [-]: √3/(2 sin φ_i) if ∇·v_s > 0 (dilation), else 1.03.

    Parameters
    ----------
    div : ∇·v_s [s-1]
    phi_i : angle of internal friction [rad]

    References
    ----------
    Srivastava, A.; Sundaresan, S. (2003). Analysis of a frictional–kinetic model for
    gas–particle flow. Powder Technol. 129, 72–85. https://doi.org/10.1016/S0032-5910(02)00132-8
    Ding et al. (2024), text below eq. (17).

    Examples
    --------
    >>> round(float(srivastava_sundaresan_2003_n(1.0, math.radians(32.0))), 4)
    1.6343
    >>> float(srivastava_sundaresan_2003_n(-1.0, math.radians(32.0)))
    1.03
    """
    return np.where(np.asarray(div) > 0.0, math.sqrt(3.0) / (2.0 * math.sin(phi_i)), 1.03)


def srivastava_sundaresan_2003_pressure(p_c, phi_i, ss, theta, d_s, div):
    """Srivastava & Sundaresan frictional pressure [Pa].

    p_f = p_c [1 − ∇·v_s / (√2 n sin φ_i sqrt(S:S + Θ/d_s²))]^(n−1)     (eq. 16)

    Guards (MFiX FRICTION_PRINCETON, copied as ideas): p_f = 0 when the dilation term
    exceeds 1 (strong dilation); p_f/p_c capped at (n/(n−1))^(n−1) in compression so that
    μ_f of eq. (17) stays ≥ 0; a zero strain-rate scale (bed at rest, Θ = 0) gives p_f = p_c.

    Parameters
    ----------
    p_c : critical-state pressure, :func:`johnson_jackson_1987_pressure` [Pa]
    phi_i : [rad]; ss : S:S [s-2]; theta : Θ [m2 s-2]; d_s : [m]; div : ∇·v_s [s-1]

    References
    ----------
    Srivastava & Sundaresan (2003), eqs. (18)–(20); Ding et al. (2024), eq. (16).

    Examples
    --------
    >>> round(float(srivastava_sundaresan_2003_pressure(10.0, math.radians(32.0), 1.0, 0.0, 1e-4, -0.5)), 4)
    10.151
    """
    n = srivastava_sundaresan_2003_n(div, phi_i)
    scale = math.sqrt(2.0) * n * math.sin(phi_i) * np.sqrt(np.asarray(ss) + np.asarray(theta) / d_s**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(scale > 0.0, np.asarray(div) / np.where(scale > 0.0, scale, 1.0), 0.0)
    base = np.maximum(1.0 - x, 0.0)
    ratio = np.where(x >= 1.0, 0.0, base ** (n - 1.0))
    ratio = np.minimum(ratio, (n / (n - 1.0)) ** (n - 1.0))
    return np.asarray(p_c) * ratio


def srivastava_sundaresan_2003_viscosity(p_f, p_c, phi_i, ss, theta, d_s, div):
    """Srivastava & Sundaresan frictional viscosity [Pa s].

    μ_f = p_f sin φ_i / (√2 sqrt(S:S + Θ/d_s²)) · [n − (n − 1)(p_f/p_c)^(1/(n−1))]   (eq. 17)

    clipped at 0 from below (the guard of :func:`srivastava_sundaresan_2003_pressure`
    makes the bracket ≥ 0 already).

    Parameters
    ----------
    p_f : frictional pressure, eq. (16) [Pa]
    p_c : critical-state pressure, eq. (15) [Pa]
    phi_i : [rad]; ss : S:S [s-2]; theta : Θ [m2 s-2]; d_s : [m]; div : ∇·v_s [s-1]

    References
    ----------
    Srivastava & Sundaresan (2003), eq. (21); Ding et al. (2024), eq. (17).

    Examples
    --------
    Simple shear (div = 0, so p_f = p_c and the bracket is 1):

    >>> round(float(srivastava_sundaresan_2003_viscosity(10.0, 10.0, math.radians(32.0), 2.0, 0.0, 1e-4, 0.0)), 4)
    2.6496
    """
    n = srivastava_sundaresan_2003_n(div, phi_i)
    p_f = np.asarray(p_f, dtype=float)
    p_c = np.asarray(p_c, dtype=float)
    root = np.sqrt(np.asarray(ss) + np.asarray(theta) / d_s**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(p_c > 0.0, p_f / np.where(p_c > 0.0, p_c, 1.0), 0.0)
        bracket = np.maximum(n - (n - 1.0) * ratio ** (1.0 / (n - 1.0)), 0.0)
        mu = np.where(root > 0.0, p_f * math.sin(phi_i) / (math.sqrt(2.0) * np.where(root > 0.0, root, 1.0)),
                      np.inf * (p_f > 0.0))
    return np.where(p_f > 0.0, mu * bracket, 0.0)


def cap_viscosity(mu_f, mu_max):
    """Cap the frictional viscosity at μ_f,max [Pa s]; return (capped array, number of capped cells).

    Parameters
    ----------
    mu_f : frictional viscosity [Pa s]
    mu_max : the cap, an explicit case key (``[friction] viscosity_cap``) [Pa s]

    Examples
    --------
    >>> cap_viscosity(np.array([1.0, 5.0, np.inf]), 2.0)
    (array([1., 2., 2.]), 2)
    """
    mu_f = np.asarray(mu_f, dtype=float)
    capped = mu_f > mu_max
    return np.where(capped, mu_max, mu_f), int(np.count_nonzero(capped))


def frictional_stress(model, alpha_s, ss, theta, div, d_s, params):
    """Frictional pressure and (uncapped) viscosity of a named model.

    Parameters
    ----------
    model : "dartevelle" | "srivastava-sundaresan" | "berzi" | "johnson-jackson" | "none"
        ("johnson-jackson" pairs the JJ pressure with Schaeffer's viscosity
        p sin φ_i / (2 sqrt(S:S/2 + Θ/d_s²)), for comparison only)
    alpha_s : [-]; ss : S:S [s-2]; theta : Θ [m2 s-2]; div : ∇·v_s [s-1]; d_s : [m]
    params : :class:`tfm.parameters.SolidsParameters`

    Returns
    -------
    (p_f [Pa], mu_f [Pa s])

    Examples
    --------
    >>> from tfm.parameters import SolidsParameters
    >>> p, mu = frictional_stress("none", 0.5, 1.0, 0.0, 0.0, 1e-4, SolidsParameters())
    >>> float(p), float(mu)
    (0.0, 0.0)
    """
    P = params
    phi = P.phi_i
    alpha_s = np.asarray(alpha_s, dtype=float)
    if model == "none":
        z = np.zeros_like(alpha_s)
        return z, z.copy()
    if model == "dartevelle":
        p = dartevelle_2004_pressure(alpha_s, P.alpha_min, P.alpha_max, P.linearise_delta)
        return p, dartevelle_2004_viscosity(p, phi, ss, theta, d_s, div)
    if model == "berzi":
        p = berzi_2011_pressure(alpha_s, P.stiffness_over_diameter, P.berzi_a, P.alpha_min, P.alpha_max,
                                P.linearise_delta)
        return p, modified_berzi_viscosity(p, phi, ss, theta, d_s, div)
    if model == "srivastava-sundaresan":
        pc = johnson_jackson_1987_pressure(alpha_s, P.fr, P.r, P.s, P.alpha_min, P.alpha_max, P.linearise_delta)
        p = srivastava_sundaresan_2003_pressure(pc, phi, ss, theta, d_s, div)
        return p, srivastava_sundaresan_2003_viscosity(p, pc, phi, ss, theta, d_s, div)
    if model == "johnson-jackson":
        p = johnson_jackson_1987_pressure(alpha_s, P.fr, P.r, P.s, P.alpha_min, P.alpha_max, P.linearise_delta)
        root = np.sqrt(0.5 * np.asarray(ss) + np.asarray(theta) / d_s**2)
        with np.errstate(divide="ignore", invalid="ignore"):
            mu = np.where(root > 0.0, p * math.sin(phi) / (2.0 * np.where(root > 0.0, root, 1.0)), np.inf * (p > 0))
        return p, mu
    raise ValueError(f"friction.model = {model!r}: allowed {', '.join(MODELS)}")
