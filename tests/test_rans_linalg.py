"""The block-tridiagonal direct solver against scipy's sparse LU on the mesh's own matrices."""

import numpy as np
import pytest
from scipy.sparse.linalg import splu

from rans.linalg import BlockStructure
from rans.mesh import PipeMesh


@pytest.mark.parametrize("nr, nt, scheme", [(6, 12, "upwind"), (10, 16, "hybrid"), (20, 40, "central")])
def test_block_lu_matches_sparse_lu(nr, nt, scheme):
    m = PipeMesh.build(0.0305, 1.0, "periodic", radial_cells=nr, azimuthal_cells=nt, bulk_velocity=10.0,
                       density=1.205, viscosity=1.81e-5)
    sec = m.geometry()
    rng = np.random.default_rng(nr)
    flux = rng.normal(size=sec.P.size) * 1e-4
    diag, aPN, aNP = sec.transport(flux, sec.interp(np.full(sec.n, 1e-3)), scheme)
    diag = diag + sec.area * rng.uniform(1.0, 100.0, sec.n)  # axial/implicit terms: dominance
    b = rng.normal(size=sec.n)
    x_ref = splu(sec.matrix(diag, aPN, aNP)).solve(b)
    x = sec.factor(diag, aPN, aNP).solve(b)
    np.testing.assert_allclose(x, x_ref, rtol=1e-10, atol=1e-12 * np.abs(x_ref).max())


def test_singular_matrix_raises_like_splu():
    m = PipeMesh.build(0.0305, 1.0, "periodic", radial_cells=4, azimuthal_cells=8, bulk_velocity=10.0,
                       density=1.205, viscosity=1.81e-5)
    sec = m.geometry()
    coef = np.ones(sec.P.size)
    diag = sec.fsum @ coef
    diag[sec.nt:2 * sec.nt] = 0.0
    coef[:] = 0.0  # ring 1 is a zero block: exactly singular
    with pytest.raises(RuntimeError, match="singular.*ring 1"):
        sec.factor(diag, -coef, -coef)


def test_structure_that_is_not_block_tridiagonal_falls_back_to_sparse_lu():
    # a 2 x 3 "mesh" with one face that skips a ring
    P = np.array([0, 0, 1])
    N = np.array([1, 5, 2])

    def matrix(diag, a_PN, a_NP):
        import scipy.sparse as sp
        rows = np.concatenate([np.arange(6), P, N])
        cols = np.concatenate([np.arange(6), N, P])
        return sp.csc_matrix((np.concatenate([diag, a_PN, a_NP]), (rows, cols)), shape=(6, 6))

    bs = BlockStructure(6, 3, P, N, matrix)
    assert not bs.ok
    diag = np.full(6, 4.0)
    a = -np.ones(3)
    b = np.arange(6.0)
    np.testing.assert_allclose(bs.factor(diag, a, a).solve(b), splu(matrix(diag, a, a)).solve(b))


def test_matrix_that_is_not_diagonally_dominant_goes_to_sparse_lu():
    m = PipeMesh.build(0.0305, 1.0, "periodic", radial_cells=6, azimuthal_cells=12, bulk_velocity=10.0,
                       density=1.205, viscosity=1.81e-5)
    sec = m.geometry()
    rng = np.random.default_rng(7)
    flux = rng.normal(size=sec.P.size)  # strong convection, tiny diffusion: central is not dominant
    diag, aPN, aNP = sec.transport(flux, sec.interp(np.full(sec.n, 1e-6)), "central")
    diag = diag + 1e-3
    lu = sec.factor(diag, aPN, aNP)
    assert not hasattr(lu, "inv")  # SuperLU, not the block LU
    b = rng.normal(size=sec.n)
    np.testing.assert_allclose(sec.matrix(diag, aPN, aNP) @ lu.solve(b), b, atol=1e-8)
