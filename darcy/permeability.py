"""Permeability of a packing of monodisperse spheres."""

import numpy as np


def carman_kozeny(phi, d, kappa_max=np.inf):
    """Carman–Kozeny permeability κ [m²] = d² φ³ / (180 (1 − φ)²), capped at ``kappa_max`` [m²].

    phi [-] porosity (0 < φ ≤ 1), d [m] grain diameter.  κ diverges as φ → 1; the cap (by
    default in :class:`darcy.DarcySolver` the empty-tube value D_t²/32 of
    :func:`poiseuille_tube_permeability`) keeps the gas equation bounded in nearly empty cells.
    Valid for packed beds, φ ≈ 0.35–0.6 (SMH eq. 4).

    References: Carman, P. C. (1937) Trans. Inst. Chem. Eng. 15:150–166.

    Examples
    --------
    >>> float(carman_kozeny(0.5, 1.4e-3)) * 1e9   # doctest: +ELLIPSIS
    5.444...
    """
    phi = np.asarray(phi, dtype=float)
    s = np.clip(1.0 - phi, 1e-6, None)  # φ = 1 would divide by zero; the cap applies long before
    return np.minimum(d * d * phi ** 3 / (180.0 * s * s), kappa_max)


def poiseuille_tube_permeability(diameter):
    """Permeability [m²] of an empty tube of the given diameter [m]: D²/32 (Hagen–Poiseuille,
    mean velocity = −(D²/32η) dP/dx)."""
    return diameter * diameter / 32.0
