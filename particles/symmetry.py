"""Mirror symmetry of a horizontal pipe: the sampled fields averaged with their mirror image.

A horizontal pipe with gravity along −y, particles injected uniformly over the section and a
statistically isotropic rough wall is symmetric under the mirror z → −z (the vertical plane
through the axis).  On the polar mesh (uniform sectors from θ = 0, θ measured from +z toward
+y, ``rans.mesh``) the mirror maps θ → π − θ, i.e. sector k → (nt/2 − 1 − k) mod nt; the
mesh is mirror-symmetric for even nt.

Under the mirror a scalar is even, the z component of a polar vector (velocity, impulse,
force) is odd, and the x and y components of an axial vector (spin, vorticity) are odd.
Averaging each cell accumulator of a Lagrangian pass with its mirror image (with its parity,
``layout.ACC_PARITY``) is exact in the mean — the expectation is mirror-symmetric — halves the
variance of every cell quantity (the two mirror cells are sampled by different parcels) and
removes the modes of the wrong parity, which in a mirror-symmetric problem are noise by
construction.  ``a + b`` and ``b + a`` are the same floating-point number, so the averaged
fields are mirror-symmetric to the last bit.
"""

from __future__ import annotations

import numpy as np

from .layout import (ACC_PARITY, B_INLET, B_J, B_MOM_IN, B_MOM_OUT, B_PP, B_WALL, B_WEIGHT, NACC, NWALL,
                     Layout)

__all__ = ["mirror_sectors", "mirror_cell_array", "mirror_average_vector"]


def mirror_sectors(nt: int) -> np.ndarray:
    """Index of the mirror image of each sector: k → (nt/2 − 1 − k) mod nt (nt even)."""
    nt = int(nt)
    if nt < 2 or nt % 2:
        raise ValueError(f"mirror symmetry needs an even number of azimuthal sectors, got {nt}")
    return (nt // 2 - 1 - np.arange(nt)) % nt


def mirror_cell_array(a: np.ndarray, parity: int = 1, axis: int = -1) -> np.ndarray:
    """(a + parity · a∘mirror)/2 of an array whose ``axis`` runs over the nt sectors."""
    a = np.asarray(a)
    m = mirror_sectors(a.shape[axis])
    img = np.take(a, m, axis=axis)
    return 0.5 * (a + img) if parity > 0 else 0.5 * (a - img)


def mirror_average_vector(vec: np.ndarray, shape: tuple[int, int, int], kind: str = "total") -> np.ndarray:
    """A pass's flat result vector (``layout.Layout``) averaged with its mirror image.

    shape : (nx, nr, nt) of the mesh.  kind : "total" (the batch sums: parity-weighted mean
    of the two mirror cells), "var" (their variance: (v + v∘mirror)/4, the two cells taken
    as independent samples) or "cov" (the covariance with the cell mass weight, which is even:
    (c + parity · c∘mirror)/4).  The wall-face accumulators (x, θ) are mirrored like the
    cells; the budget's impulse vectors keep x and y and lose z (odd, so its
    section total is exactly zero); histograms and counters stay as they are.
    """
    if kind not in ("total", "var", "cov"):
        raise ValueError(f"kind = {kind!r}: allowed total, var, cov")
    nx, nr, nt = shape
    lay = Layout(nx * nr * nt, nx * nt)
    out = np.array(vec, dtype=float, copy=True)
    m = mirror_sectors(nt)
    par = np.asarray(ACC_PARITY, dtype=float)
    cells = out[: lay.wall].reshape(nx, nr, nt, NACC)
    img = cells[:, :, m, :]
    if kind == "total":
        cells[...] = 0.5 * (cells + par * img)
    elif kind == "var":
        cells[...] = 0.25 * (cells + img)
    else:
        cells[...] = 0.25 * (cells + par * img)
    if out.size > lay.wall:
        wall = out[lay.wall: lay.angle].reshape(nx, nt, NWALL)
        wimg = wall[:, m, :]
        wall[...] = 0.5 * (wall + wimg) if kind == "total" else 0.25 * (wall + wimg)
    if out.size > lay.budget:
        # The budget's impulse vectors are section totals: the mirror leaves their x and y
        # components as they are and reverses z, so the average's z component is exactly zero
        # (as the sum over the averaged cells is), in the total and in its spread.
        for b in (B_MOM_IN, B_MOM_OUT, B_WEIGHT, B_WALL, B_PP, B_INLET, B_J):
            out[lay.budget + b + 2] = 0.0
    return out
