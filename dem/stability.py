"""Stability of the viscous tangential force in the DEM step, for a whole configuration of contacts.

The kick–drift–kick step (``dem.engine``) applies the dashpots at the velocity predicted to the end
of the step.  For one pair contact in the viscous branch of the tangential force it is stable while
f = dt γ_t 7/m < 1 (``eulag.slug.tangential_damping_pair_limit``; 7/m = 2(1/m + R²/I) for two solid
spheres).  A grain with several contacts has less margin: the step is stable while dt λ_max < 1,
λ_max the largest eigenvalue of the tangential damping operator M^-1/2 Jᵀ Γ J M^-1/2 of all contacts
in the viscous branch (J maps the grains' velocities and spins to the contacts' two tangential slip
components, Γ holds the dashpots, M the masses and moments of inertia).  ``damping_factor`` returns
λ_max over a single pair's 7 γ_t/m, so the configuration's limit of γ_t/γ_n is the pair limit
divided by it.  Wall and end-plate dashpots are √2 times the pair's (m_eff = m against m/2).
"""

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.spatial import cKDTree


def damping_factor(pos, diameter, tube_radius, plate_x=None):
    """λ_max of the tangential damping of the grains at ``pos`` (n, 3) [m] in a tube of radius
    ``tube_radius`` [m] along x (and an end plate at x = ``plate_x``, grains at x > plate_x), every
    contact sticking, over a single pair's 7 γ_t/m [-]."""
    pos = np.asarray(pos, dtype=float)
    r = 0.5 * diameter
    inertia = 0.4 * r * r  # per unit mass
    rows, cols, vals, gam = [], [], [], []

    def add(i, j, nv, g):
        a = np.array([1.0, 0.0, 0.0]) if abs(nv[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = np.cross(nv, a)
        t1 /= np.linalg.norm(t1)
        for t in (t1, np.cross(nv, t1)):
            nt = np.cross(nv, t)
            row = len(gam)
            for gi, sgn in ((i, 1.0), (j, -1.0)):
                if gi is None:
                    continue
                for k in range(3):
                    rows.extend((row, row))
                    cols.extend((6 * gi + k, 6 * gi + 3 + k))
                    vals.extend((sgn * t[k], -r * nt[k] / math.sqrt(inertia)))
            gam.append(g)

    n = len(pos)
    for i, j in sorted(cKDTree(pos).query_pairs(diameter)):
        rv = pos[i] - pos[j]
        add(i, j, rv / np.linalg.norm(rv), 1.0)
    for i in range(n):
        rr = math.hypot(pos[i, 1], pos[i, 2])
        if rr > 0.0 and rr + r > tube_radius:
            add(i, None, np.array([0.0, -pos[i, 1] / rr, -pos[i, 2] / rr]), math.sqrt(2.0))
        if plate_x is not None and pos[i, 0] - plate_x < r:
            add(i, None, np.array([1.0, 0.0, 0.0]), math.sqrt(2.0))
    if not gam:
        return 0.0
    jac = sp.csr_matrix((vals, (rows, cols)), shape=(len(gam), 6 * n))
    b = sp.diags(np.sqrt(gam)) @ jac
    a = b @ b.T
    if a.shape[0] <= 8:
        lam = np.linalg.eigvalsh(a.toarray()).max()
    else:
        lam = sla.eigsh(a.tocsc(), k=1, which="LA")[0][0]
    return float(lam) / 7.0
