"""Cross-section convection-diffusion coefficients (rans.operators.Section.transport)."""

import numpy as np

from rans import PipeMesh
from rans.operators import Section


def _section():
    return Section(PipeMesh.build(0.0305, 1.0, "periodic", 1, 10, 16))


def test_hybrid_is_central_below_the_switch_and_upwind_without_diffusion_beyond():
    """Spalding's hybrid (Patankar 1980, §5.2): central differencing while its coefficients are
    non-negative, |F| w < D; beyond, upwind convection and no diffusion."""
    s = _section()
    gamma = np.full(s.nf, 1e-3)
    D = gamma * s.S / s.delta
    for pe in (0.5, 1.5, 3.0, 10.0):
        for sign in (1.0, -1.0):
            flux = sign * pe * D
            _, hPN, hNP = s.transport(flux, gamma, "hybrid")
            _, cPN, cNP = s.transport(flux, gamma, "central")
            w = s.w
            centre = np.where(flux > 0, flux * w < D, -flux * (1 - w) < D)
            assert np.allclose(hPN[centre], cPN[centre])
            assert np.allclose(hNP[centre], cNP[centre])
            # beyond the switch: -a_PN = max(-F, 0), -a_NP = max(F, 0) (no D)
            far = ~centre
            assert np.allclose(-hPN[far], np.maximum(-flux[far], 0.0))
            assert np.allclose(-hNP[far], np.maximum(flux[far], 0.0))


def test_hybrid_coefficients_are_continuous_in_the_flux():
    """No jump at the switch: a face whose Peclet number sits there must not flip between two
    different matrices from one outer iteration to the next (that 2-cycle once kept stations
    of a strongly loaded run from converging)."""
    s = _section()
    gamma = np.full(s.nf, 1e-3)
    D = gamma * s.S / s.delta
    pe = np.linspace(-6.0, 6.0, 24001)
    dpe = pe[1] - pe[0]
    prev = None
    worst = 0.0
    for p in pe:
        _, aPN, aNP = s.transport(p * D, gamma, "hybrid")
        cur = np.concatenate([aPN / D, aNP / D])
        assert np.all(cur <= 0.0)
        if prev is not None:
            worst = max(worst, np.abs(cur - prev).max())
        prev = cur
    assert worst <= 1.0001 * dpe  # Lipschitz with constant 1 in F/D


def test_compiled_face_sums_and_csr_products_equal_scipys_bit_for_bit():
    """rans.operators.face_sums and matvec replace scipy's sparse products in the station
    iteration only to drop the per-call dispatch: the sums must be the same floating-point
    operations in the same order, so the march's results do not move by a bit."""
    from rans.operators import face_sums, matvec

    sec = _section()
    rng = np.random.default_rng(7)
    a, b = rng.standard_normal(sec.nf), rng.standard_normal(sec.nf)
    assert np.array_equal(face_sums(sec.P, sec.N, a, b, sec.n), sec._sum_P @ a + sec._sum_N @ b)
    for A, x in ((sec.div, a), (sec.fsum, b), (sec._corr, rng.standard_normal(sec.n))):
        assert np.array_equal(matvec(A, x), A @ x)
