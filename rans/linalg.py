"""Direct solver for the cross-section matrices: block-tridiagonal LU over the rings.

The cross-section operators (:meth:`rans.operators.CrossSection.matrix`) couple a cell with
its two azimuthal neighbours in the same ring (a periodic tridiagonal block, nt × nt) and with
the cell of the same sector in the rings inside and outside it (diagonal blocks).  Ordering
the cells ring by ring (cell = ring · nt + sector, the mesh's ordering) makes the matrix block
tridiagonal, and block LU without pivoting between blocks

    D'_0 = D_0,   D'_j = D_j − L_j D'_{j−1}⁻¹ U_{j−1}

is exact and stable for the diagonally dominant matrices of the finite-volume equations.
The inner rings need no pivoting either, but each D'_j is inverted with LAPACK (pivoted).
For a 20 × 40 section this is 4–8× faster than a general sparse LU (scipy's SuperLU), which
dominates the cost of the axial march.  :class:`BlockStructure` falls back to SuperLU for a
section that is not block tridiagonal in this ordering.

:class:`LaggedFactor` saves most factorisations of the march: the matrices of a station's
outer iterations (and of the next station) change little from one iteration to the next, so
it solves with the factorisation of an earlier matrix and refines (x += LU⁻¹ (b − A x)) until
the error estimated in every cell is below ``rtol`` of its value (with a floor for fields
that cross zero), factorising afresh only when a few sweeps do not get there.  The solution
is the direct one to that tolerance (1e-10 by default, far below the outer iteration's).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from jitcache import JIT_FLAGS
from scipy.sparse.linalg import splu

__all__ = ["AndersonMixing", "BlockStructure", "BlockLU", "LaggedFactor", "LaggedSparseLU"]


class BlockStructure:
    """Where each diagonal and face coefficient of a cross-section matrix goes in the blocks.

    n cells ordered ring-major with ``nt`` cells per ring; ``P``, ``N`` the two cells of each
    interior face (as in :meth:`CrossSection.matrix`: entry (P, N) = a_PN, (N, P) = a_NP).
    """

    def __init__(self, n, nt, P, N, sparse_matrix=None):
        self.n, self.nt = int(n), int(nt)
        self.nr = self.n // self.nt
        P = np.asarray(P)
        N = np.asarray(N)
        jP, kP = np.divmod(P, nt)
        jN, kN = np.divmod(N, nt)
        same = jP == jN
        out = jN == jP + 1
        inw = jN == jP - 1
        self.ok = self.n == self.nr * self.nt and bool(np.all(same | out | inw)) and bool(
            np.all(kP[~same] == kN[~same]))
        self._sparse_matrix = sparse_matrix
        self._P, self._N = P, N
        if not self.ok:
            return
        nt = self.nt
        # flat indices into D (nr, nt, nt) for the same-ring entries
        self.f_same = np.flatnonzero(same)
        self.d_PN = (jP[same] * nt + kP[same]) * nt + kN[same]
        self.d_NP = (jN[same] * nt + kN[same]) * nt + kP[same]
        # ring couplings: U_j[k] = entry (j·nt+k, (j+1)·nt+k), L_j[k] = entry (j·nt+k, (j−1)·nt+k)
        self.f_out = np.flatnonzero(out)  # P inside, N outside: a_PN -> U_jP, a_NP -> L_jN
        self.f_in = np.flatnonzero(inw)  # P outside, N inside: a_PN -> L_jP, a_NP -> U_jN
        self.u_out = P[out]
        self.l_out = N[out]
        self.l_in = P[inw]
        self.u_in = N[inw]
        self.diag_index = (np.arange(self.n) // nt * nt + np.arange(self.n) % nt) * nt + np.arange(self.n) % nt

    def factor(self, diag, a_PN, a_NP):
        """LU of the matrix with diagonal ``diag`` and face coefficients; has ``.solve(b)``.

        Block LU does not pivot between blocks: a matrix that is not diagonally dominant
        (e.g. central convection at cell Péclet numbers above 2) goes to SuperLU instead."""
        if not self.ok:
            return splu(self._sparse_matrix(diag, a_PN, a_NP))
        diag = np.ascontiguousarray(diag, dtype=np.float64)
        a_PN = np.ascontiguousarray(a_PN, dtype=np.float64)
        a_NP = np.ascontiguousarray(a_NP, dtype=np.float64)
        if not _row_dominant(diag, a_PN, a_NP, self._P, self._N):
            return splu(self._sparse_matrix(diag, a_PN, a_NP))
        nr, nt = self.nr, self.nt
        D, L, U = _blocks(nr, nt, diag, a_PN, a_NP, self.diag_index, self.d_PN, self.d_NP, self.f_same, self.u_out,
                          self.l_out, self.f_out, self.l_in, self.u_in, self.f_in)
        return BlockLU(D.reshape(nr, nt, nt), L.reshape(nr, nt), U.reshape(nr, nt))


@njit(**JIT_FLAGS)
def _blocks(nr, nt, diag, a_PN, a_NP, diag_index, d_PN, d_NP, f_same, u_out, l_out, f_out, l_in, u_in, f_in):
    """The blocks of :meth:`BlockStructure.factor` (flat): each entry summed in the order of
    ``np.add.at`` over the same index lists (entries of faces that share a cell pair add up, as
    in the sparse assembly)."""
    n = nr * nt
    D = np.zeros(n * nt)
    for i in range(diag_index.size):
        D[diag_index[i]] += diag[i]
    for i in range(d_PN.size):
        D[d_PN[i]] += a_PN[f_same[i]]
    for i in range(d_NP.size):
        D[d_NP[i]] += a_NP[f_same[i]]
    U = np.zeros(n)
    L = np.zeros(n)
    for i in range(u_out.size):
        U[u_out[i]] += a_PN[f_out[i]]
    for i in range(l_out.size):
        L[l_out[i]] += a_NP[f_out[i]]
    for i in range(l_in.size):
        L[l_in[i]] += a_PN[f_in[i]]
    for i in range(u_in.size):
        U[u_in[i]] += a_NP[f_in[i]]
    return D, L, U


@njit(**JIT_FLAGS)
def _row_dominant(diag, a_PN, a_NP, P, N):
    """Whether |diag| >= (the row's sum of |off-diagonal| entries)(1 - 1e-12) in every row (the
    sums over P and over N taken apart and then added, as two ``np.bincount`` would)."""
    n = diag.size
    a = np.zeros(n)
    b = np.zeros(n)
    for f in range(P.size):
        a[P[f]] += abs(a_PN[f])
        b[N[f]] += abs(a_NP[f])
    for i in range(n):
        if not abs(diag[i]) >= (a[i] + b[i]) * (1.0 - 1e-12):
            return False
    return True


class BlockLU:
    """Block LU of a block-tridiagonal matrix with dense diagonal blocks D (nr, nt, nt) and
    diagonal off-diagonal blocks: L[j] couples ring j to ring j−1, U[j] ring j to ring j+1.

    The inverses D'_j⁻¹ are stored transposed (``inv_t[j, c, a]`` = (D'_j⁻¹)[a, c]), so that the
    products D'_j⁻¹ y of :func:`_solve` run over contiguous columns: each entry is still summed
    over c in the same order (bit-identical to the row-by-row product), but the loop over a
    vectorises."""

    def __init__(self, D, L, U):
        self.L, self.U = L, U
        self.inv_t = np.empty_like(D)
        bad = _factor(D, L, U, self.inv_t)
        if bad >= 0:
            # the same exception type scipy's splu raises for a singular matrix
            raise RuntimeError(f"Factor is exactly singular (block LU, ring {bad})")

    def solve(self, b):
        x = np.empty(self.L.size)
        _solve(self.inv_t, self.L, self.U, np.ascontiguousarray(b, dtype=np.float64), x)
        return x


@njit(**JIT_FLAGS)
def _factor(D, L, U, inv_t):
    """inv_t[j] = (D'_j⁻¹)ᵀ with D'_j = D_j − diag(L_j) D'_{j−1}⁻¹ diag(U_{j−1}); returns the first
    ring whose block is singular or not finite, −1 if none."""
    nr, nt, _ = D.shape
    M = np.empty((nt, nt))
    for j in range(nr):
        for a in range(nt):
            for c in range(nt):
                M[a, c] = D[j, a, c]
                if j > 0:
                    M[a, c] -= L[j, a] * inv_t[j - 1, c, a] * U[j - 1, c]
        if not np.all(np.isfinite(M)):
            return j
        try:
            inv = np.linalg.inv(M)
        except Exception:  # numpy.linalg.LinAlgError: singular block
            return j
        if not np.all(np.isfinite(inv)):
            return j
        inv_t[j] = inv.T
    return -1


@njit(**JIT_FLAGS)
def _solve(inv_t, L, U, b, x):
    nr, nt, _ = inv_t.shape
    y = np.empty(nt)
    acc = np.empty(nt)
    # forward: z_j = D'_j⁻¹ (b_j − L_j z_{j−1})
    for j in range(nr):
        for a in range(nt):
            y[a] = b[j * nt + a] - (L[j, a] * x[(j - 1) * nt + a] if j > 0 else 0.0)
        acc[:] = 0.0
        for c in range(nt):
            yc = y[c]
            for a in range(nt):
                acc[a] += inv_t[j, c, a] * yc
        for a in range(nt):
            x[j * nt + a] = acc[a]
    # backward: x_j = z_j − D'_j⁻¹ U_j x_{j+1}
    for j in range(nr - 2, -1, -1):
        for c in range(nt):
            y[c] = U[j, c] * x[(j + 1) * nt + c]
        acc[:] = 0.0
        for c in range(nt):
            yc = y[c]
            for a in range(nt):
                acc[a] += inv_t[j, c, a] * yc
        for a in range(nt):
            x[j * nt + a] -= acc[a]


@njit(**JIT_FLAGS)
def _block_products(inv_t, j, y1, y2, acc1, acc2):
    """acc = D'_j⁻¹ y for two vectors at once (the order of :func:`_solve`'s sums)."""
    nt = y1.size
    acc1[:] = 0.0
    acc2[:] = 0.0
    for c in range(nt):
        yc1 = y1[c]
        yc2 = y2[c]
        for a in range(nt):
            m = inv_t[j, c, a]
            acc1[a] += m * yc1
            acc2[a] += m * yc2


@njit(**JIT_FLAGS)
def _solve2(inv_t, L, U, b1, b2, x1, x2):
    """:func:`_solve` for two right-hand sides in one pass over the factorisation (each
    solution with the arithmetic of :func:`_solve`)."""
    nr, nt, _ = inv_t.shape
    y1 = np.empty(nt)
    y2 = np.empty(nt)
    acc1 = np.empty(nt)
    acc2 = np.empty(nt)
    for j in range(nr):
        for a in range(nt):
            y1[a] = b1[j * nt + a] - (L[j, a] * x1[(j - 1) * nt + a] if j > 0 else 0.0)
            y2[a] = b2[j * nt + a] - (L[j, a] * x2[(j - 1) * nt + a] if j > 0 else 0.0)
        _block_products(inv_t, j, y1, y2, acc1, acc2)
        for a in range(nt):
            x1[j * nt + a] = acc1[a]
            x2[j * nt + a] = acc2[a]
    for j in range(nr - 2, -1, -1):
        for c in range(nt):
            y1[c] = U[j, c] * x1[(j + 1) * nt + c]
            y2[c] = U[j, c] * x2[(j + 1) * nt + c]
        _block_products(inv_t, j, y1, y2, acc1, acc2)
        for a in range(nt):
            x1[j * nt + a] -= acc1[a]
            x2[j * nt + a] -= acc2[a]


class LaggedFactor:
    """Solves with matrices of one structure through the factorisation of an earlier one.

    ``factor(diag, a_PN, a_NP)`` records the matrix and returns ``self``; ``solve(b)`` starts
    from the held factorisation (of an earlier matrix) and refines with it,
    x ← x + LU⁻¹ (b − A x), until the error it leaves in any cell is estimated below ``rtol``
    of that cell's |x| + ``floor`` · max|x| (the floor, a fraction of the largest value, for
    fields that cross zero: cross flow, pressure correction; k and ε take a small one, so a
    cell whose k is 10⁻⁶ of the core's is solved almost as exactly as the core).  The
    refinement contracts geometrically (by ~10⁻² per sweep for matrices 0.1 % apart): the
    error sweep m leaves is estimated as δ_m ρ/(1 − ρ), δ_m its step and ρ the largest ratio
    δ_i/δ_{i−1} of its sweeps so far (per-cell maxima relative to the scale above), at least
    10⁻² (the first ratio is often not yet the asymptotic one, and with more sweeps the last
    ratio alone left errors of 23 rtol under the sinks benchmark's matrices).  When ``max_sweeps``
    refinements will not get there (the contraction so far says so), the current matrix is
    factorised and solved directly, and so are the next 1, 3, 7, … (up to 32) matrices while
    the refinement keeps failing; when the last solve needed more than ``refactor_after``
    sweeps, the next matrix is factorised at once (the matrices drift away from the held
    one).  A factorisation of a 20 × 40 section costs about 40 solves (0.31 ms against 8 µs),
    a compiled refinement sweep (a solve and a residual) about 1.3 of them: on scene h's
    sources 8 sweeps, refactorising after a solve that needed more than 4, take the march
    from 25.1–25.6 s (4 and 2: 34,000 factorisations) to 21.9 s (18,300; 12 and 6: 22.6 s).
    GMRES with the held factorisation as preconditioner instead of the plain refinement
    needed ~6 iterations per solve and was no faster.
    ``factorisations``, ``solves``, ``refined`` (solves accepted after refinement) and
    ``sweeps`` count what was done (for benchmarks and tests)."""

    def __init__(self, blocks, rtol=1e-10, floor=1e-3, max_sweeps=8, refactor_after=4):
        if not (rtol > 0.0 and floor >= 0.0 and max_sweeps >= 1 and refactor_after >= 0):
            raise ValueError("LaggedFactor needs rtol > 0, floor >= 0, max_sweeps >= 1, refactor_after >= 0")
        self._blocks = blocks
        self.rtol = float(rtol)
        self.floor = float(floor)
        self.max_sweeps = int(max_sweeps)
        self.refactor_after = int(refactor_after)
        self._lu = None
        self._fresh = False
        self._coef = None
        self._last_sweeps = 0
        self._skip = 0  # matrices still to factorise directly after a failed refinement
        self._backoff = 0
        self.factorisations = 0
        self.solves = 0
        self.refined = 0
        self.sweeps = 0

    def factor(self, diag, a_PN, a_NP):
        self._coef = (np.ascontiguousarray(diag, dtype=np.float64), np.ascontiguousarray(a_PN, dtype=np.float64),
                      np.ascontiguousarray(a_NP, dtype=np.float64))
        self._fresh = False
        if self._lu is None or self._last_sweeps > self.refactor_after or self._skip > 0:
            self._skip = max(self._skip - 1, 0)
            self._refactor()
        return self

    def _refactor(self):
        self._lu = None  # a singular matrix leaves no factorisation behind
        self._lu = self._blocks.factor(*self._coef)
        self._fresh = True
        self._last_sweeps = 0
        self.factorisations += 1

    def solve(self, b):
        b = np.ascontiguousarray(b, dtype=np.float64)
        self.solves += 1
        if self._lu is None:  # the last factorisation raised: try the current matrix again
            self._refactor()
        if self._fresh:
            return self._lu.solve(b)
        if isinstance(self._lu, BlockLU):  # the loop below, compiled (the same arithmetic)
            x = np.empty_like(b)
            lu, (diag, a_PN, a_NP) = self._lu, self._coef
            sweep = _refine(lu.inv_t, lu.L, lu.U, diag, a_PN, a_NP, self._blocks._P, self._blocks._N, b, x,
                            self.floor, self.rtol, self.max_sweeps)
            if sweep > 0:
                return self._accept(x, sweep)
            return self._refinement_failed(-sweep, b)
        x = self._lu.solve(b)
        r = np.empty_like(b)
        last = np.inf
        slowest = 1e-2
        for sweep in range(1, self.max_sweeps + 1):
            self._residual(x, b, r)
            dx = self._lu.solve(r)
            x += dx
            step = self._step(dx, x)
            if not step <= 1e300:
                break
            if step <= self.rtol * 1e-2:  # so small a step leaves < rtol even at slow contraction
                return self._accept(x, sweep)
            if sweep > 1:
                rho = step / last  # contraction per sweep
                slowest = max(slowest, rho)
                if slowest < 1.0 and step * slowest / (1.0 - slowest) <= self.rtol:
                    return self._accept(x, sweep)
                if rho >= 1.0 or step * rho ** (self.max_sweeps - sweep + 1) > self.rtol:
                    break  # will not get there within max_sweeps
            last = step
        return self._refinement_failed(sweep, b)

    def solve2(self, b1, b2):
        """``(solve(b1), solve(b2))`` with the same results and bookkeeping, the two refinements
        made together in one pass over the held block factorisation per sweep (the solve of a
        20 × 40 section is bound by reading the factorisation's 256 kB: two right-hand sides
        cost little more than one)."""
        if not isinstance(self._lu, BlockLU) or self._fresh:
            return self.solve(b1), self.solve(b2)
        b1 = np.ascontiguousarray(b1, dtype=np.float64)
        b2 = np.ascontiguousarray(b2, dtype=np.float64)
        x1 = np.empty_like(b1)
        x2 = np.empty_like(b2)
        lu, (diag, a_PN, a_NP) = self._lu, self._coef
        s1, s2 = _refine2(lu.inv_t, lu.L, lu.U, diag, a_PN, a_NP, self._blocks._P, self._blocks._N, b1, b2, x1, x2,
                          self.floor, self.rtol, self.max_sweeps)
        self.solves += 1
        if s1 <= 0:  # b1 brings a fresh factorisation, which solves b2 directly (as solve would)
            x1 = self._refinement_failed(-s1, b1)
            self.solves += 1
            return x1, self._lu.solve(b2)
        x1 = self._accept(x1, s1)
        self.solves += 1
        if s2 > 0:
            return x1, self._accept(x2, s2)
        return x1, self._refinement_failed(-s2, b2)

    def _refinement_failed(self, sweep, b):
        # factorise afresh, and the next matrices too, for a stretch that doubles while the
        # refinement keeps failing (stiff stations, whose matrices change fast)
        self.sweeps += sweep
        self._backoff = min(2 * self._backoff + 1, 32)
        self._skip = self._backoff
        self._refactor()
        return self._lu.solve(b)

    def _residual(self, x, b, r):
        diag, a_PN, a_NP = self._coef
        _residual(diag, a_PN, a_NP, self._blocks._P, self._blocks._N, x, b, r)

    def _step(self, dx, x):
        return _relative_step(dx, x, self.floor)

    def _direct_solve(self, b):
        """The solution with a fresh factorisation of the current matrix (tests)."""
        return self._blocks.factor(*self._coef).solve(np.ascontiguousarray(b, dtype=np.float64))

    def _accept(self, x, sweeps):
        self.sweeps += sweeps
        self.refined += 1
        self._last_sweeps = sweeps
        self._backoff = 0
        return x


class LaggedSparseLU(LaggedFactor):
    """:class:`LaggedFactor` for a general sparse matrix (SuperLU): the coupled cross-flow
    system of a station (cross-section momentum and continuity, 3n unknowns), whose matrices
    change little from one outer iteration to the next, as the single equations' do.

    ``factor(A)`` records the CSC matrix ``A`` and returns ``self``; ``solve(b)`` solves with the
    held SuperLU factorisation of an earlier matrix as preconditioner of GMRES (:meth:`solve`),
    or, with ``krylov = 0``, refines with it exactly as :class:`LaggedFactor` does.  The solution
    vector is made of ``segments``, consecutive lengths (e.g. (2n, n): the two cross-flow
    velocity components together, then the pressure); the error is estimated per entry relative
    to its |x| + ``floor`` · max|x| of its segment (fields of different units).  A SuperLU
    factorisation of the 20 × 40 section's system costs 30–50 solves (its fill is large).  Under
    scene h's sinks the plain refinement fails at the stations that need the coupled step often
    enough to factorise every second matrix (736 factorisations for 1,446 solves on the pass-12
    sources of ``tests/benchmarks/bench_gas_scene.py``, 6 sweeps, afresh after a solve that
    needed more than 3); GMRES with the same held factorisation makes 82 for the same solves,
    ~10 iterations each, and the fields agree to 3·10⁻¹² of their maxima.  The matrix is
    factorised afresh after a solve that needed more than ``refactor_after`` preconditioner
    solves (default 12 with GMRES, 3 sweeps of the plain refinement with ``krylov = 0``).
    ``krylov_iterations`` counts the GMRES iterations."""

    def __init__(self, segments, rtol=1e-10, floor=1e-3, max_sweeps=6, refactor_after=None, permc_spec="COLAMD",
                 krylov=30):
        if krylov < 0:
            raise ValueError("LaggedSparseLU needs krylov >= 0")
        if refactor_after is None:  # preconditioner solves per GMRES solve; sweeps of the plain refinement
            refactor_after = 12 if krylov else 3
        super().__init__(None, rtol=rtol, floor=floor, max_sweeps=max_sweeps, refactor_after=refactor_after)
        self._bounds = np.cumsum([0] + [int(m) for m in segments])
        self.permc_spec = permc_spec
        self.krylov = int(krylov)
        self.krylov_iterations = 0

    def solve(self, b):
        """With ``krylov`` > 0: GMRES right-preconditioned by the held factorisation (at most
        ``krylov`` iterations, to a residual of 10⁻¹⁴ |b|), then one refinement sweep, whose step
        LU⁻¹ (b − A x) estimates the error left; accepted when that is below ``rtol`` per entry
        (relative to the entry's segment as in :class:`LaggedFactor`), else the matrix is
        factorised afresh as after a failed refinement.  A Krylov method tolerates a held
        factorisation whose plain refinement contracts too slowly or not at all (a few
        eigenvalues of LU⁻¹A far from 1), so one SuperLU factorisation serves many more outer
        iterations.  ``krylov`` = 0: the plain refinement of :class:`LaggedFactor`."""
        if self.krylov == 0:
            return super().solve(b)
        b = np.ascontiguousarray(b, dtype=np.float64)
        self.solves += 1
        if self._lu is None:
            self._refactor()
        if self._fresh:
            return self._lu.solve(b)
        x, its = _gmres(self._coef, self._lu.solve, b, self._lu.solve(b), self.krylov,
                        1e-14 * float(np.linalg.norm(b)))
        self.krylov_iterations += its
        dx = self._lu.solve(b - self._coef @ x)
        x += dx
        if self._step(dx, x) <= self.rtol:
            return self._accept(x, its + 1)
        return self._refinement_failed(its + 1, b)

    def factor(self, A):
        if A.shape[0] != self._bounds[-1]:
            raise ValueError(f"matrix of {A.shape[0]} rows for segments of {self._bounds[-1]} unknowns")
        self._coef = A
        self._fresh = False
        if self._lu is None or self._last_sweeps > self.refactor_after or self._skip > 0:
            self._skip = max(self._skip - 1, 0)
            self._refactor()
        return self

    def _refactor(self):
        self._lu = None
        self._lu = splu(self._coef, permc_spec=self.permc_spec)
        self._fresh = True
        self._last_sweeps = 0
        self.factorisations += 1

    def _residual(self, x, b, r):
        r[:] = b - self._coef @ x

    def _direct_solve(self, b):
        return splu(self._coef, permc_spec=self.permc_spec).solve(np.ascontiguousarray(b, dtype=np.float64))

    def _step(self, dx, x):
        worst = 0.0
        for lo, hi in zip(self._bounds[:-1], self._bounds[1:]):
            worst = max(worst, _relative_step(dx[lo:hi], x[lo:hi], self.floor))
        return worst


def _gmres(A, precondition, b, x0, m, target):
    """Right-preconditioned GMRES (Saad 2003, Alg. 9.5; modified Gram–Schmidt, Givens rotations)
    for A x = b from x0: at most ``m`` iterations, until the residual estimate is at most
    ``target``.  ``precondition(v)`` applies M⁻¹ ≈ A⁻¹.  Returns (x, iterations)."""
    r = b - A @ x0
    beta = float(np.linalg.norm(r))
    if not beta > target:
        return x0, 0
    n = b.size
    V = np.empty((m + 1, n))
    Z = np.empty((m, n))
    H = np.zeros((m + 1, m))
    cs = np.zeros(m)
    sn = np.zeros(m)
    g = np.zeros(m + 1)
    g[0] = beta
    V[0] = r / beta
    k = 0
    for j in range(m):
        Z[j] = precondition(V[j])
        w = A @ Z[j]
        for i in range(j + 1):
            H[i, j] = w @ V[i]
            w -= H[i, j] * V[i]
        h = float(np.linalg.norm(w))
        H[j + 1, j] = h
        for i in range(j):  # the earlier rotations on the new column
            H[i, j], H[i + 1, j] = cs[i] * H[i, j] + sn[i] * H[i + 1, j], -sn[i] * H[i, j] + cs[i] * H[i + 1, j]
        den = float(np.hypot(H[j, j], H[j + 1, j]))
        if not den > 0.0:
            break  # a singular least-squares column: keep the iterations before it
        cs[j], sn[j] = H[j, j] / den, H[j + 1, j] / den
        H[j, j], H[j + 1, j] = den, 0.0
        g[j + 1], g[j] = -sn[j] * g[j], cs[j] * g[j]
        k = j + 1
        if abs(g[k]) <= target or not h > 0.0:  # converged, or the Krylov space holds the solution
            break
        if k < m:
            V[k] = w / h
    if k == 0:
        return x0, 0
    y = np.linalg.solve(np.triu(H[:k, :k]), g[:k])
    return x0 + y @ Z[:k], k


@njit(**JIT_FLAGS)
def _refine(inv_t, L, U, diag, a_PN, a_NP, P, N, b, x, floor, rtol, max_sweeps):
    """:meth:`LaggedFactor.solve`'s refinement with a block LU, compiled: x (out) = the solution
    with the held factorisation, refined; returns the sweeps it took, negated when the
    refinement will not reach ``rtol`` (x is then to be discarded)."""
    n = b.size
    r = np.empty(n)
    dx = np.empty(n)
    _solve(inv_t, L, U, b, x)
    last = np.inf
    slowest = 1e-2  # the slowest contraction so far, at least 1e-2
    for sweep in range(1, max_sweeps + 1):
        _residual(diag, a_PN, a_NP, P, N, x, b, r)
        _solve(inv_t, L, U, r, dx)
        verdict, last, slowest = _sweep(x, dx, last, slowest, sweep, floor, rtol, max_sweeps)
        if verdict != 0:
            return verdict
    return -max_sweeps


@njit(**JIT_FLAGS)
def _sweep(x, dx, last, slowest, sweep, floor, rtol, max_sweeps):
    """x += dx, and the refinement's verdict after sweep ``sweep`` (one rule for :func:`_refine`
    and :func:`_refine2`): (verdict, this step, the slowest contraction so far); verdict
    ``sweep`` when the error left is below ``rtol`` (a step below rtol/100, or the step times
    slowest/(1 − slowest)), ``-sweep`` when it will not get there within ``max_sweeps`` (the
    step not finite, not contracting, or too slow), 0 to go on."""
    for i in range(x.size):
        x[i] += dx[i]
    step = _relative_step(dx, x, floor)
    if not step <= 1e300:
        return -sweep, step, slowest
    if step <= rtol * 1e-2:  # so small a step leaves < rtol even at slow contraction
        return sweep, step, slowest
    if sweep > 1:
        rho = step / last  # contraction per sweep
        slowest = max(slowest, rho)
        if slowest < 1.0 and step * slowest / (1.0 - slowest) <= rtol:
            return sweep, step, slowest
        if rho >= 1.0 or step * rho ** float(max_sweeps - sweep + 1) > rtol:
            return -sweep, step, slowest  # will not get there within max_sweeps
    if sweep == max_sweeps:
        return -sweep, step, slowest
    return 0, step, slowest


@njit(**JIT_FLAGS)
def _refine2(inv_t, L, U, diag, a_PN, a_NP, P, N, b1, b2, x1, x2, floor, rtol, max_sweeps):
    """:func:`_refine` for two right-hand sides: each with its own sweeps, stopping rule and
    arithmetic exactly as :func:`_refine` alone; their block solves share one pass over the
    factorisation while both refine.  Returns the two sweep counts (negated: failed)."""
    n = b1.size
    r1 = np.empty(n)
    r2 = np.empty(n)
    dx1 = np.empty(n)
    dx2 = np.empty(n)
    _solve2(inv_t, L, U, b1, b2, x1, x2)
    last1 = last2 = np.inf
    slowest1 = slowest2 = 1e-2
    res1 = res2 = 0  # 0: still refining; > 0 accepted after that many sweeps; < 0 failed
    for sweep in range(1, max_sweeps + 1):
        if res1 == 0:
            _residual(diag, a_PN, a_NP, P, N, x1, b1, r1)
        if res2 == 0:
            _residual(diag, a_PN, a_NP, P, N, x2, b2, r2)
        if res1 == 0 and res2 == 0:
            _solve2(inv_t, L, U, r1, r2, dx1, dx2)
        elif res1 == 0:
            _solve(inv_t, L, U, r1, dx1)
        else:
            _solve(inv_t, L, U, r2, dx2)
        if res1 == 0:
            res1, last1, slowest1 = _sweep(x1, dx1, last1, slowest1, sweep, floor, rtol, max_sweeps)
        if res2 == 0:
            res2, last2, slowest2 = _sweep(x2, dx2, last2, slowest2, sweep, floor, rtol, max_sweeps)
        if res1 != 0 and res2 != 0:
            break
    return res1, res2


@njit(**JIT_FLAGS)
def _residual(diag, a_PN, a_NP, P, N, x, b, r):
    """r = b − A x."""
    for i in range(x.size):
        r[i] = b[i] - diag[i] * x[i]
    for f in range(P.size):
        r[P[f]] -= a_PN[f] * x[N[f]]
        r[N[f]] -= a_NP[f] * x[P[f]]


@njit(**JIT_FLAGS)
def _relative_step(dx, x, floor):
    """max_i |dx_i| / (|x_i| + floor · max_j |x_j|): the relative change of the last
    refinement, per cell; inf if not finite."""
    big = 0.0
    for i in range(x.size):
        big = max(big, abs(x[i]))
    lo = floor * big
    worst = 0.0
    for i in range(x.size):
        a = abs(dx[i])
        if not a <= 1e300:
            return np.inf
        if a > 0.0:
            s = abs(x[i]) + lo
            if s > 0.0:
                worst = max(worst, a / s)
            else:
                return np.inf
    return worst


class AndersonMixing:
    """Anderson acceleration of a fixed-point iteration x ← g(x) (Anderson 1965; the form of
    Walker & Ni 2011, "Anderson acceleration for fixed-point iterations", SIAM J. Numer.
    Anal. 49, 1715–1735, with mixing parameter 1).

    After each evaluation g(x_n), :meth:`next` returns the next iterate

        x_{n+1} = g(x_n) − Σ_j γ_j (Δg)_j,   γ = argmin ‖W (f_n − ΔF γ)‖₂,

    f = g(x) − x the fixed-point residual, ΔF and Δg the differences of the last ``depth``
    residuals and images, W a diagonal weight that puts the unknowns on one scale.  The small
    least-squares problem is solved through its normal equations with a relative Tikhonov
    term (``regularisation`` of their trace), which keeps a nearly dependent history harmless.
    A fixed point of g is a fixed point of the mixed iteration, so the converged state is the
    unaccelerated one to the tolerance of the convergence test; only the path changes.
    :meth:`reset` drops the history (after a rejected step)."""

    def __init__(self, depth, weight=None, regularisation=1e-10):
        if depth < 1:
            raise ValueError(f"depth = {depth}: must be >= 1")
        self.depth = int(depth)
        self.weight = weight
        self.regularisation = regularisation
        self.reset()

    def reset(self):
        self._g = None
        self._f = None
        self._dg = None  # ring buffers of the last ``depth`` differences, (depth, n)
        self._df = None
        self._gram = np.zeros((self.depth, self.depth))  # ΔF ΔFᵀ, updated a row at a time
        self._count = 0
        self._slot = 0

    def next(self, x, g):
        """The next iterate from the last input ``x`` and its image ``g``."""
        f = g - x
        wf = f if self.weight is None else self.weight * f
        if self._f is not None:
            if self._dg is None:
                self._dg = np.empty((self.depth, g.size))
                self._df = np.empty((self.depth, g.size))
            s = self._slot
            np.subtract(g, self._g, out=self._dg[s])
            np.subtract(wf, self._f, out=self._df[s])
            self._count = min(self._count + 1, self.depth)
            self._slot = (s + 1) % self.depth
            row = self._df[:self._count] @ self._df[s]
            self._gram[s, :self._count] = row
            self._gram[:self._count, s] = row
        self._g, self._f = g, wf
        m = self._count
        if m == 0:
            return g
        a = self._gram[:m, :m].copy()
        a[np.diag_indices_from(a)] += self.regularisation * max(np.trace(a), 1e-300)
        try:
            gamma = np.linalg.solve(a, self._df[:m] @ wf)
        except np.linalg.LinAlgError:
            self.reset()
            return g
        return g - gamma @ self._dg[:m]
