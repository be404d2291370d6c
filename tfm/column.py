"""1-D vertical column: a bed settling through gas to rest, the fast closure test of the solids
pressure (p_f and the kinetic pressure) together with the drag.

Model (closed column, gas and solids at rest at the end).  With the two-fluid momentum
equations of Ding et al. (2024, Table 2) without inertia, and zero net volume flux
(α_s v_s + α_g v_g = 0), the gas equation eliminates ∂p_g/∂y and the solids flux is

    F = α_s v_s = K (−∂p_s/∂y − α_s (ρ_s − ρ_g) g),     K = α_g² / (β/α_s),

(β/α_s is finite as α_s → 0).  ∂α_s/∂t + ∂F/∂y = 0 is advanced by backward Euler in
pseudo-time with Newton iterations, p_s implicit in α_s (p_s = p_f(α_s) + Lun's kinetic–
collisional pressure at a fixed Θ, zero by default), the weight term upwinded from the
cell above, K lagged.  At rest F = 0 on every face: the discrete bed carries its weight
through p_s, p_s,i − p_s,i+1 = α_s,i+1 (ρ_s − ρ_g) g Δy, whose continuum limit is
:func:`analytic_bed`.

References
----------
Ding et al. (2024), Appl. Sci. 14, 2031, Table 2 and eqs. (9)–(19).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad
from scipy.linalg import solve_banded
from scipy.optimize import brentq

from .drag import three_zone_drag
from .friction import berzi_2011_pressure, dartevelle_2004_pressure, johnson_jackson_1987_pressure
from .kinetic import lun_solids_pressure, savage_radial_distribution
from .parameters import SolidsParameters

__all__ = ["ColumnResult", "analytic_bed", "frictional_pressure_curve", "settle_column"]

G = 9.80665


def frictional_pressure_curve(model, params: SolidsParameters):
    """p_f(α_s) at rest (S = 0, ∇·v = 0, Θ = 0) of a named model, as a function of α_s [Pa].

    At rest Srivastava & Sundaresan's p_f equals p_c (eq. 16 with a zero dilation term).
    """
    P = params
    if model == "dartevelle":
        return lambda a: dartevelle_2004_pressure(a, P.alpha_min, P.alpha_max, P.linearise_delta)
    if model == "berzi":
        return lambda a: berzi_2011_pressure(a, P.stiffness_over_diameter, P.berzi_a, P.alpha_min, P.alpha_max,
                                             P.linearise_delta)
    if model in ("srivastava-sundaresan", "johnson-jackson"):
        return lambda a: johnson_jackson_1987_pressure(a, P.fr, P.r, P.s, P.alpha_min, P.alpha_max,
                                                       P.linearise_delta)
    raise ValueError(f"friction.model = {model!r}: allowed dartevelle, srivastava-sundaresan, berzi, johnson-jackson")


@dataclass
class ColumnResult:
    y: np.ndarray            # cell centres above the bottom [m]
    alpha_s: np.ndarray      # solids volume fraction [-]
    p_s: np.ndarray          # solids pressure [Pa]
    steps: int
    residual: float          # max |F| / (K_max Δρ g) at the end [-]
    converged: bool


def settle_column(model, height, inventory, rho_s, d_s, rho_g=32.7, mu_g=1.78e-5, params=None, cells=200,
                  theta=0.0, alpha0=None, max_steps=400, tol=1e-9):
    """Settle a column of solids to rest and return the profile.

    Parameters
    ----------
    model : frictional model name (see :func:`frictional_pressure_curve`)
    height : column height [m]
    inventory : solids volume per unit cross-section area ∫ α_s dy [m]
    rho_s, d_s : particle density [kg m-3] and diameter [m]
    rho_g, mu_g : gas density [kg m-3] and viscosity [Pa s]
    params : :class:`SolidsParameters` (Table 4 defaults)
    cells : number of cells
    theta : uniform granular temperature [m2 s-2] (0: a bed at rest, p_s = p_f)
    alpha0 : initial profile (default uniform inventory/height)

    Returns
    -------
    ColumnResult
    """
    P = params or SolidsParameters()
    pf = frictional_pressure_curve(model, P)
    dy = height / cells
    y = (np.arange(cells) + 0.5) * dy
    drho_g = (rho_s - rho_g) * G
    a = np.full(cells, inventory / height) if alpha0 is None else np.array(alpha0, dtype=float)

    def pressure(x):
        x = np.clip(x, 0.0, None)
        p = pf(x)
        if theta > 0.0:
            g0 = savage_radial_distribution(np.minimum(x, P.alpha_max - 1e-6), P.alpha_max)
            p = p + lun_solids_pressure(x, rho_s, theta, g0, P.e_ss)
        return p

    def dpressure(x):
        h = 1e-7
        return (pressure(x + h) - pressure(x - h)) / (2 * h)

    def mobility(x):
        xf = np.clip(0.5 * (x[:-1] + x[1:]), 1e-8, P.alpha_max)
        slip = 1e-3
        bhat = three_zone_drag(xf, rho_g, mu_g, d_s, slip) / xf
        return (1.0 - xf) ** 2 / bhat

    def fluxes(x, K):
        p = pressure(x)
        return K * (-(p[1:] - p[:-1]) / dy - np.clip(x[1:], 0.0, None) * drho_g)

    dt = 1e-3
    steps = 0
    converged = False
    res = np.inf
    while steps < max_steps:
        steps += 1
        a_old = a.copy()
        K = mobility(a_old)
        ok = False
        x = a_old.copy()
        for _ in range(30):
            F = fluxes(x, K)
            R = (x - a_old) * dy / dt
            R[:-1] += F
            R[1:] -= F
            dp = dpressure(x)
            dFi = K * dp[:-1] / dy                                  # ∂F_{i+½}/∂α_i
            dFj = K * (-dp[1:] / dy - drho_g * (x[1:] > 0.0))       # ∂F_{i+½}/∂α_{i+1}
            ab = np.zeros((3, cells))
            ab[1] = dy / dt
            ab[1, :-1] += dFi
            ab[1, 1:] -= dFj
            ab[0, 1:] = dFj      # row i, column i+1
            ab[2, :-1] = -dFi    # row i+1, column i
            dx = solve_banded((1, 1), ab, -R)
            x = x + dx
            if not np.all(np.isfinite(x)):
                break
            if np.max(np.abs(dx)) < 1e-12:
                ok = True
                break
        if ok and x.min() > -1e-6:
            a = np.clip(x, 0.0, None)
            a *= inventory / (a.sum() * dy)
            change = np.max(np.abs(a - a_old))
            dt = min(dt * 2.0, 1e6)
            F = fluxes(a, mobility(a))
            res = float(np.max(np.abs(F)) / (np.max(mobility(a)) * drho_g))
            if change < tol and res < 1e-8:
                converged = True
                break
        else:
            a = a_old
            dt *= 0.25
            if dt < 1e-9:
                raise RuntimeError(f"column: Newton failed at step {steps} (alpha_s, cell {int(np.argmax(np.abs(x - a_old)))})")
    return ColumnResult(y=y, alpha_s=a, p_s=pressure(a), steps=steps, residual=res, converged=converged)


def analytic_bed(model, inventory, rho_s, rho_g=32.7, params=None):
    """The continuum bed at rest (Θ = 0): dp_f/dy = −α_s (ρ_s − ρ_g) g, p_f = 0 at the top.

    Returns (alpha_bottom, bed_height, alpha_of_height) where alpha_of_height(y) gives α_s at
    height y above the bottom.  From p_f(α_b) = (ρ_s − ρ_g) g · inventory and
    y_top − y(α) = ∫_{α_min}^{α} p_f'(a) / ((ρ_s − ρ_g) g a) da (quadrature).
    """
    P = params or SolidsParameters()
    pf = frictional_pressure_curve(model, P)
    drho_g = (rho_s - rho_g) * G
    target = drho_g * inventory
    hi = P.alpha_max - 1e-9 if P.linearise_delta == 0.0 else 0.99
    a_b = brentq(lambda x: float(pf(x)) - target, P.alpha_min + 1e-12, hi, xtol=1e-14)

    def dpf(x, h=1e-8):
        return (float(pf(x + h)) - float(pf(x - h))) / (2 * h)

    def depth(x):   # distance below the top of the bed where alpha = x
        return quad(lambda s: dpf(s) / (drho_g * s), P.alpha_min + 1e-10, x, limit=200)[0]

    H = depth(a_b)

    def alpha_of_height(yv):
        out = []
        for yy in np.atleast_1d(yv):
            d = H - yy
            if d <= 0.0:
                out.append(np.nan)
            elif yy <= 0.0:
                out.append(a_b)
            else:
                out.append(brentq(lambda x: depth(x) - d, P.alpha_min + 1e-10, a_b, xtol=1e-13))
        return np.array(out)

    return a_b, H, alpha_of_height
