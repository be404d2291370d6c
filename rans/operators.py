"""Finite-volume operators on the polar cross-section of a :class:`rans.mesh.PipeMesh`.

All cross-section quantities are per unit axial length.  Cell index c = j * nt + k
(ring j, sector k).  Interior faces are listed once, oriented from cell P to cell N;
``n`` is the unit normal from P to N as (n_z, n_y) and ``S`` the length of the face's
integrated normal (the chord for arc faces, so that sum_f S_f n_f = 0 for every cell and
a uniform velocity field carries no net flux).  The grid is orthogonal, so
(phi_N - phi_P)/delta is the face-normal derivative to second order.

Face-normal vectors (pressure gradient, body force, velocity gradients) are turned into
cell vectors by the reconstruction

    R(g)_P = T_P^{-1} sum_f S_f g_f n_f,     T_P = sum_f S_f n_f n_f^T,

which returns G exactly whenever g_f = G . n_f for a uniform vector G.  Pressure gradient
and body force meet at the faces (g_f = -(p_N - p_P)/delta + f_f . n_f) and are
reconstructed together: a body force that is a discrete pressure gradient (e.g. a uniform
weight) is balanced to round-off and drives no spurious cross-flow ("balanced force").
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from numba import njit

from jitcache import JIT_FLAGS

from .linalg import BlockStructure, LaggedFactor

__all__ = ["CoupledCrossFlow", "Section"]


class Section:
    """Face lists, cell metrics and sparse-matrix assembly for one cross-section."""

    def __init__(self, mesh):
        nr, nt = mesh.nr, mesh.nt
        self.nr, self.nt = nr, nt
        self.n = n = nr * nt
        re = mesh.r_edges
        rc = mesh.r
        dth = mesh.dtheta
        th = mesh.theta
        the = mesh.theta_edges
        half = math.sin(0.5 * dth)
        idx = np.arange(n).reshape(nr, nt)

        # radial faces (between ring j and j+1)
        jr = np.repeat(np.arange(nr - 1), nt)
        kr = np.tile(np.arange(nt), nr - 1)
        P_r = idx[jr, kr]
        N_r = idx[jr + 1, kr]
        S_r = 2.0 * re[jr + 1] * half
        d_r = rc[jr + 1] - rc[jr]
        w_r = (re[jr + 1] - rc[jr]) / d_r
        nz_r = np.cos(th[kr])
        ny_r = np.sin(th[kr])
        # azimuthal faces (between sector k and k+1, periodic)
        ja = np.repeat(np.arange(nr), nt)
        ka = np.tile(np.arange(nt), nr)
        P_a = idx[ja, ka]
        N_a = idx[ja, (ka + 1) % nt]
        S_a = re[ja + 1] - re[ja]
        d_a = 2.0 * rc[ja] * half
        w_a = np.full(ja.size, 0.5)
        nz_a = -np.sin(the[ka + 1])
        ny_a = np.cos(the[ka + 1])

        self.P = np.concatenate([P_r, P_a])
        self.N = np.concatenate([N_r, N_a])
        self.S = np.concatenate([S_r, S_a])
        self.delta = np.concatenate([d_r, d_a])
        self.w = np.concatenate([w_r, w_a])
        self.nz = np.concatenate([nz_r, nz_a])
        self.ny = np.concatenate([ny_r, ny_a])
        self.nf = self.P.size
        self.n_radial_faces = P_r.size
        self._om = 1.0 - self.w  # the interpolation's weight on P (interp, transport)

        # wall faces: outer arc of the last ring
        self.wall = idx[nr - 1, :]
        self.wall_chord = 2.0 * re[-1] * half
        self.wall_arc = re[-1] * dth
        self.wall_nz = np.cos(th)
        self.wall_ny = np.sin(th)
        self.wall_distance = re[-1] - rc[-1]
        # the ring inside the wall ring (second-order wall gradient of the laminar mode)
        self.wall_inner = idx[nr - 2, :]
        self.wall_inner_faces = np.arange((nr - 2) * nt, (nr - 1) * nt)  # radial faces P=inner, N=wall
        self.wall_inner_distance = re[-1] - rc[-2]

        # cell metrics
        self.area = mesh.cell_area.ravel().copy()
        self.ring = np.repeat(np.arange(nr), nt)
        self.cz = mesh.z.ravel().copy()
        self.cy = mesh.y.ravel().copy()
        self.radius = mesh.radius

        # reconstruction tensors T_P = sum_f S n n^T (interior faces from both sides + wall)
        T = np.zeros((n, 3))  # (zz, zy, yy)
        for cells in (self.P, self.N):
            np.add.at(T[:, 0], cells, self.S * self.nz * self.nz)
            np.add.at(T[:, 1], cells, self.S * self.nz * self.ny)
            np.add.at(T[:, 2], cells, self.S * self.ny * self.ny)
        T[self.wall, 0] += self.wall_chord * self.wall_nz**2
        T[self.wall, 1] += self.wall_chord * self.wall_nz * self.wall_ny
        T[self.wall, 2] += self.wall_chord * self.wall_ny**2
        det = T[:, 0] * T[:, 2] - T[:, 1] ** 2
        self.Tinv = np.stack([T[:, 2] / det, -T[:, 1] / det, T[:, 0] / det], axis=1)
        self._no_wall = np.zeros(nt)

        # sparse pattern: diagonal + (P,N) + (N,P); permutation COO -> CSC computed once
        rows = np.concatenate([np.arange(n), self.P, self.N])
        cols = np.concatenate([np.arange(n), self.N, self.P])
        probe = sp.csc_matrix((np.arange(1, rows.size + 1, dtype=float), (rows, cols)), shape=(n, n))
        probe.sort_indices()
        self._perm = probe.data.astype(np.int64) - 1
        self._indices = probe.indices.copy()
        self._indptr = probe.indptr.copy()
        self._blocks = BlockStructure(n, nt, self.P, self.N, self.matrix)
        # scatter matrices face -> cell (sum over faces of a cell, signed/unsigned)
        f = np.arange(self.nf)
        self._sum_P = sp.csr_matrix((np.ones(self.nf), (self.P, f)), shape=(n, self.nf))
        self._sum_N = sp.csr_matrix((np.ones(self.nf), (self.N, f)), shape=(n, self.nf))
        self.div = (self._sum_P - self._sum_N).tocsr()  # sum of outward face quantities
        self.fsum = (self._sum_P + self._sum_N).tocsr()
        # linear operators for the coupled cross-flow system
        inv_d = 1.0 / self.delta
        self.Dn = sp.csr_matrix(
            (np.concatenate([-inv_d, inv_d]), (np.concatenate([f, f]), np.concatenate([self.P, self.N]))),
            shape=(self.nf, n))
        self.I = sp.csr_matrix(
            (np.concatenate([1.0 - self.w, self.w]), (np.concatenate([f, f]), np.concatenate([self.P, self.N]))),
            shape=(self.nf, n))
        self.Rz = (sp.diags(self.Tinv[:, 0]) @ self.fsum @ sp.diags(self.S * self.nz)
                   + sp.diags(self.Tinv[:, 1]) @ self.fsum @ sp.diags(self.S * self.ny)).tocsr()
        self.Ry = (sp.diags(self.Tinv[:, 1]) @ self.fsum @ sp.diags(self.S * self.nz)
                   + sp.diags(self.Tinv[:, 2]) @ self.fsum @ sp.diags(self.S * self.ny)).tocsr()

        # deferred correction of the radial-face gradient (see :meth:`radial_gradient_correction`):
        # every radial face but the two next to the wall ring, each with the quadratic through
        # the centres of rings (j, j+1, j+2) on its ray (never the wall ring)
        jc = np.arange(max(nr - 3, 0))
        rows, cols, vals = [], [], []
        for j in jc:
            r0, r1, r2 = rc[j], rc[j + 1], rc[j + 2]
            rf = re[j + 1]
            # derivative at rf of the Lagrange quadratic through r0, r1, r2, minus (phi1 - phi0)/(r1 - r0)
            c = np.array([((rf - r1) + (rf - r2)) / ((r0 - r1) * (r0 - r2)),
                          ((rf - r0) + (rf - r2)) / ((r1 - r0) * (r1 - r2)),
                          ((rf - r0) + (rf - r1)) / ((r2 - r0) * (r2 - r1))])
            c[0] += 1.0 / (r1 - r0)
            c[1] -= 1.0 / (r1 - r0)
            for m, cm in enumerate(c):
                rows.append(j * nt + np.arange(nt))
                cols.append(idx[j + m, :])
                vals.append(np.full(nt, cm))
        self.corrected_faces = np.arange(jc.size * nt)  # radial faces come first, ring by ring
        nfc = self.corrected_faces.size
        cat = (lambda a: np.concatenate(a)) if nfc else (lambda a: np.zeros(0))
        self._corr = sp.csr_matrix((cat(vals), (cat(rows).astype(np.int64), cat(cols).astype(np.int64))),
                                   shape=(nfc, n))
        self._corr_div = self.div[:, :nfc]

    # ------------------------------------------------------------------ matrices
    def matrix(self, diag, a_PN, a_NP):
        """CSC matrix with diagonal ``diag``, entry (P, N) = a_PN and (N, P) = a_NP per face."""
        data = np.concatenate([diag, a_PN, a_NP])[self._perm]
        return sp.csc_matrix((data, self._indices, self._indptr), shape=(self.n, self.n))

    def factor(self, diag, a_PN, a_NP):
        """Direct factorisation of :meth:`matrix` (block-tridiagonal LU over the rings,
        :mod:`rans.linalg`); the result has ``.solve(b)``."""
        return self._blocks.factor(diag, a_PN, a_NP)

    def lagged_factor(self, **kw):
        """A :class:`rans.linalg.LaggedFactor` for matrices of this section (one per equation:
        it solves with the factorisation of that equation's earlier matrix, refined)."""
        return LaggedFactor(self._blocks, **kw)

    def transport(self, flux, gamma_f, scheme="upwind"):
        """Convection-diffusion coefficients for the non-conservative (continuity-subtracted) form.

        flux [kg m-1 s-1]: face mass flux per unit length from P to N; gamma_f [kg m-1 s-1]:
        face diffusivity.  Returns (diag, a_PN, a_NP) with the matrix acting as
        sum_f F_f (phi_f - phi_P) - D_f (phi_N - phi_P) over the faces of each cell.
        scheme: "upwind", "central" or "hybrid" (central where it keeps the coefficients
        non-negative, |F| w < D for uniform spacing |F|/D < 2; upwind without diffusion beyond).
        """
        code = _SCHEMES.get(scheme)
        if code is None:
            raise ValueError(f"scheme = {scheme!r}: allowed upwind, central, hybrid")
        return _transport(self.P, self.N, self.S, self.delta, self.w, self._om,
                          np.ascontiguousarray(flux, dtype=np.float64),
                          np.ascontiguousarray(gamma_f, dtype=np.float64), self.n, code)

    def radial_gradient_correction(self, phi, gamma_f):
        """Explicit (deferred-correction) source per cell [gamma_f * phi per m2, times the
        area per unit length like the matrix rows] that makes the diffusive flux through the
        radial faces second-order at the face.

        (phi_N - phi_P)/delta is the radial derivative at the midpoint between the two ring
        centres, not at the face; the offset is O(h) and, in the wedge ring at the axis (no
        inner face to cancel it) and the rings just outside, it leaves an O(1) truncation error
        in the axisymmetric part of a field and a max-norm order of 1.74-1.84 in the
        manufactured-solution test (1.87-2.14 with the correction; docs/validation.md,
        "Gas solver").  On every radial face but the two next to the wall ring the derivative
        is taken from the quadratic through three ring centres on the ray; the difference from
        the two-point value, times gamma_f S_f, goes to the right-hand side (lagged in the
        outer/station iterations, so the converged solution is that of the corrected scheme).
        The wall region, where wall functions set the near-wall profile, keeps the two-point
        gradient; there the switch leaves ring nr-3 a first-order (but local) truncation error.
        Not corrected: the azimuthal faces of the wedge ring, whose spacing is taken at the
        centroid (2/3 of the ring radius) -- exact for fields linear in y and z, O(1) for the
        r^2 cos 2theta part of a field.  k and epsilon (upwind,
        first order) do not use it: an explicit source of either sign would spoil the
        positivity of their M-matrix solves.
        """
        c, d = self._corr, self._corr_div
        return _radial_correction(c.indptr, c.indices, c.data, d.indptr, d.indices, d.data, self.S,
                                  np.ascontiguousarray(gamma_f, dtype=np.float64),
                                  np.ascontiguousarray(phi, dtype=np.float64))

    # ------------------------------------------------------------------ face/cell maps
    def interp(self, phi):
        """Linear interpolation of a cell field to the interior faces."""
        return _interp(self.P, self.N, self._om, self.w, np.ascontiguousarray(phi, dtype=np.float64))

    def interp_mid(self, phi):
        """Value at the midpoint of the line joining the two cell centres (body forces: with it,
        (phi_N - phi_P)/delta equals the interpolated force for any quadratic potential)."""
        return 0.5 * (phi[self.P] + phi[self.N])

    def normal_difference(self, phi):
        """(phi_N - phi_P)/delta at interior faces [units of phi per m]."""
        return _normal_difference(self.P, self.N, self.delta, np.ascontiguousarray(phi, dtype=np.float64))

    def reconstruct(self, g, g_wall=None):
        """Cell vector (z, y) from face-normal components g (interior) and g_wall (wall faces)."""
        has_wall = g_wall is not None
        gw = np.ascontiguousarray(g_wall, dtype=np.float64) if has_wall else self._no_wall
        return _reconstruct(self.P, self.N, self.S, self.nz, self.ny, np.ascontiguousarray(g, dtype=np.float64),
                            self.n, self.wall, self.wall_chord, gw, self.wall_nz, self.wall_ny, self.Tinv, has_wall)

    def gradient(self, phi, wall_value=None):
        """Cell gradient (d/dz, d/dy) of a cell field.

        wall_value None: zero normal gradient at the wall; otherwise the Dirichlet value at
        the wall (e.g. 0 for a no-slip velocity component).
        """
        phi = np.ascontiguousarray(phi, dtype=np.float64)
        if wall_value is not None and np.ndim(wall_value) == 0:
            return _dirichlet_gradient(self.P, self.N, self.S, self.nz, self.ny, self.delta, self.wall, self.wall_chord,
                                       self.wall_nz, self.wall_ny, self.wall_distance, self.Tinv, phi,
                                       float(wall_value))
        g_wall = None
        if wall_value is not None:
            g_wall = (wall_value - phi[self.wall]) / self.wall_distance
        return self.reconstruct(self.normal_difference(phi), g_wall)


_SCHEMES = {"upwind": 0, "central": 1, "hybrid": 2}


@njit(**JIT_FLAGS)
def _transport(P, N, S, delta, w, om, flux, gamma_f, n, scheme):
    """:meth:`Section.transport` compiled: per face D = gamma_f S / delta and the row
    coefficients cP, cN of the scheme (0 upwind, 1 central, 2 hybrid); returns (the face sums
    of cP over P and cN over N, -cP, -cN), each entry with the arithmetic of the array form."""
    nf = P.size
    cP = np.empty(nf)  # row P: coefficient on (phi_P - phi_N)
    cN = np.empty(nf)  # row N: coefficient on (phi_N - phi_P)
    for f in range(nf):
        D = gamma_f[f] * S[f] / delta[f]
        F = flux[f]
        if scheme == 0:
            cP[f] = D + max(-F, 0.0)
            cN[f] = D + max(F, 0.0)
        else:
            cP[f] = D - F * w[f]
            cN[f] = D + F * om[f]
            if scheme == 2:
                # Spalding's hybrid in Patankar's (1980, §5.2) continuous form: central while it
                # gives non-negative coefficients, pure upwind convection (no diffusion) beyond.
                # (Keeping D in the upwind branch would make the coefficients jump by D at the
                # switch; a face whose Peclet number sits at the switch then flips every outer
                # iteration, a 2-cycle that keeps stations from converging under strong
                # particle sources, as in scene b.)
                cP[f] = max(max(-F, cP[f]), 0.0)
                cN[f] = max(max(F, cN[f]), 0.0)
    return face_sums(P, N, cP, cN, n), -cP, -cN


@njit(**JIT_FLAGS)
def _radial_correction(c_ptr, c_idx, c_val, d_ptr, d_idx, d_val, S, gamma_f, phi):
    """:meth:`Section.radial_gradient_correction` compiled: q_f = gamma_f S_f (corr phi)_f over the
    corrected faces (the first ones), then its cell sums (the two CSR products of the array
    form, each row in stored order)."""
    q = np.empty(c_ptr.size - 1)
    _csr_matvec(c_ptr, c_idx, c_val, phi, q)
    for f in range(q.size):
        q[f] = gamma_f[f] * S[f] * q[f]
    out = np.empty(d_ptr.size - 1)
    _csr_matvec(d_ptr, d_idx, d_val, q, out)
    return out


@njit(**JIT_FLAGS)
def _dirichlet_gradient(P, N, S, nz, ny, delta, wall, wall_chord, wall_nz, wall_ny, wall_distance, Tinv, phi,
                        wall_value):
    """:meth:`Section.gradient` with one wall value for every wall face, compiled: (d/dz, d/dy)."""
    gw = np.empty(wall.size)
    for m in range(wall.size):
        gw[m] = (wall_value - phi[wall[m]]) / wall_distance
    return _reconstruct(P, N, S, nz, ny, _normal_difference(P, N, delta, phi), phi.size, wall, wall_chord, gw,
                        wall_nz, wall_ny, Tinv, True)


@njit(**JIT_FLAGS)
def _interp(P, N, om, w, phi):
    out = np.empty(P.size)
    for f in range(P.size):
        out[f] = om[f] * phi[P[f]] + w[f] * phi[N[f]]
    return out


@njit(**JIT_FLAGS)
def _normal_difference(P, N, delta, phi):
    out = np.empty(P.size)
    for f in range(P.size):
        out[f] = (phi[N[f]] - phi[P[f]]) / delta[f]
    return out


@njit(**JIT_FLAGS)
def _reconstruct(P, N, S, nz, ny, g, n, wall, wall_chord, g_wall, wall_nz, wall_ny, Tinv, has_wall):
    """:meth:`Section.reconstruct` compiled (the face sums by :func:`face_sums`)."""
    sz = np.empty(P.size)
    sy = np.empty(P.size)
    for f in range(P.size):
        t = S[f] * g[f]
        sz[f] = t * nz[f]
        sy[f] = t * ny[f]
    az = face_sums(P, N, sz, sz, n)
    ay = face_sums(P, N, sy, sy, n)
    if has_wall:
        for m in range(wall.size):
            c = wall[m]
            az[c] += wall_chord * g_wall[m] * wall_nz[m]
            ay[c] += wall_chord * g_wall[m] * wall_ny[m]
    Rz = np.empty(n)
    Ry = np.empty(n)
    for i in range(n):
        Rz[i] = Tinv[i, 0] * az[i] + Tinv[i, 1] * ay[i]
        Ry[i] = Tinv[i, 1] * az[i] + Tinv[i, 2] * ay[i]
    return Rz, Ry


class CoupledCrossFlow:
    """The coupled cross-flow system of a section (cross-section momentum and continuity
    together, 3n unknowns u_z, u_y, p), assembled into a pattern fixed at construction.

        [ M    0    G_z ] [u_z]
        [ 0    M    G_y ] [u_y]  =  rhs,      G_z = A R_z D_n,  G_y = A R_y D_n,
        [ C_z  C_y  C_p ] [ p ]               C_z = K n_z I,   C_y = K n_y I,   K = rho div S,

    C_p = pin(−K Q D_n) with the momentum-interpolation operator on face values

        Q = −n_z I D(d) R_z − n_y I D(d) R_y + D(d_f),   d_f = interp(d),

    and the pressure level pinned in the first wall cell (10³ × the largest |diagonal| of
    −K Q D_n added there).  M (the momentum matrix, shared by u_z and u_y) and Q change with
    every outer iteration, the rest is geometry.  C_p is linear in (d, d_f): each of its three
    terms is a sum over j of a column of a constant matrix times a row of another, weighted by
    d_j, so its entries are one sparse product with (d, d_f) (:meth:`matrix`), instead of the
    products of scipy matrices and ``bmat`` of every iteration (0.24 against 2.2 ms for a
    20 × 40 section).  The entries equal those of the products up to the order of summation."""

    def __init__(self, sec, rho):
        self.sec = sec
        self.rho = float(rho)
        n, nf = sec.n, sec.nf
        self.n = n
        D = sp.diags
        nzI = (-D(sec.nz) @ sec.I).tocsr()
        nyI = (D(sec.ny) @ sec.I).tocsr()
        K = (self.rho * sec.div @ D(sec.S)).tocsr()
        KnzI, KnyI = (K @ nzI).tocsc(), (K @ nyI).tocsc()
        RzDn, RyDn = (sec.Rz @ sec.Dn).tocsr(), (sec.Ry @ sec.Dn).tocsr()
        # C_p's entries: (row, column, parameter, coefficient), parameters (d, d_f)
        terms = [_outer_triplets(KnzI, RzDn, -1.0), _outer_triplets(KnyI, RyDn, 1.0),
                 _outer_triplets(K.tocsc(), sec.Dn.tocsr(), -1.0, param_offset=n)]
        cp_r, cp_c, cp_j, cp_v = (np.concatenate(t) for t in zip(*terms))
        cp_r, cp_c = cp_r + 2 * n, cp_c + 2 * n
        # the constant blocks
        const = [(D(sec.area) @ sec.Rz @ sec.Dn).tocoo(), (D(sec.area) @ sec.Ry @ sec.Dn).tocoo(),
                 (K @ D(sec.nz) @ sec.I).tocoo(), (K @ D(sec.ny) @ sec.I).tocoo()]
        offsets = [(0, 2 * n), (n, 2 * n), (2 * n, 0), (2 * n, n)]
        k_r = np.concatenate([c.row + o[0] for c, o in zip(const, offsets)])
        k_c = np.concatenate([c.col + o[1] for c, o in zip(const, offsets)])
        k_v = np.concatenate([c.data for c in const])
        # the momentum blocks: Section.matrix's entries (diagonal, (P, N), (N, P))
        m_r = np.concatenate([np.arange(n), sec.P, sec.N])
        m_c = np.concatenate([np.arange(n), sec.N, sec.P])
        w = int(sec.wall[0])
        rows = np.concatenate([m_r, m_r + n, k_r, cp_r, [2 * n + w]])
        cols = np.concatenate([m_c, m_c + n, k_c, cp_c, [2 * n + w]])
        N3 = 3 * n
        keys = np.unique(cols.astype(np.int64) * N3 + rows)  # CSC order: by column, then row
        self._indices = (keys % N3).astype(np.int32)
        self._indptr = np.searchsorted(keys // N3, np.arange(N3 + 1)).astype(np.int32)
        self.nnz = keys.size

        def where(r, c):
            return np.searchsorted(keys, c.astype(np.int64) * N3 + r)

        self._m_uz = where(m_r, m_c)
        self._m_uy = where(m_r + n, m_c + n)
        if np.unique(self._m_uz).size != self._m_uz.size:
            raise ValueError("the section's momentum pattern has repeated entries")
        self._const = np.zeros(self.nnz)
        np.add.at(self._const, where(k_r, k_c), k_v)
        self._cp_map = sp.csr_matrix((cp_v, (where(cp_r, cp_c), cp_j)), shape=(self.nnz, n + nf))
        self._p_diag = where(np.arange(2 * n, N3), np.arange(2 * n, N3))
        self._pin = where(np.array([2 * n + w]), np.array([2 * n + w]))[0]

    def matrix(self, diag, a_PN, a_NP, d):
        """The system's CSC matrix for the momentum coefficients (those of
        :meth:`Section.matrix`) and the momentum-interpolation weights d per cell."""
        sec = self.sec
        params = np.concatenate([d, sec.interp(d)])
        data = self._const + matvec(self._cp_map, params)
        data[self._pin] += 1e3 * np.abs(data[self._p_diag]).max()
        m = np.concatenate([diag, a_PN, a_NP])
        data[self._m_uz] += m
        data[self._m_uy] += m
        N3 = 3 * self.n
        return sp.csc_matrix((data, self._indices, self._indptr), shape=(N3, N3))

    def interpolated(self, v, d):
        """Q v for face values v."""
        sec = self.sec
        return (-sec.nz * sec.interp(d * matvec(sec.Rz, v)) - sec.ny * sec.interp(d * matvec(sec.Ry, v))
                + sec.interp(d) * v)

    def continuity(self, face_values):
        """K v = rho div(S v): the continuity rows' action on face values."""
        return self.rho * matvec(self.sec.div, self.sec.S * face_values)


def _outer_triplets(L, R, scale, param_offset=0):
    """Entries of sum_j p_j L[:, j] R[j, :] as (row, column, parameter index, coefficient):
    L in CSC, R in CSR, one parameter p_j per column of L (= row of R)."""
    nl, nr = np.diff(L.indptr), np.diff(R.indptr)
    cnt = nl * nr
    j = np.repeat(np.arange(nl.size), cnt)
    local = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    width = np.repeat(nr, cnt)
    li = L.indptr[j] + local // width
    ri = R.indptr[j] + local % width
    return L.indices[li], R.indices[ri], j + param_offset, scale * L.data[li] * R.data[ri]


def matvec(A, x):
    """``A @ x`` for a CSR matrix ``A`` and a vector ``x``, with scipy's summation order (each
    row's entries in stored order, from zero: bit-identical to scipy's ``csr_matvec``) but
    without its per-call dispatch, which costs more than the product at the cross-section's
    size (a few microseconds; the station iteration makes ~50 such products)."""
    y = np.empty(A.shape[0])
    _csr_matvec(A.indptr, A.indices, A.data, np.ascontiguousarray(x, dtype=np.float64), y)
    return y


@njit(**JIT_FLAGS)
def _csr_matvec(indptr, indices, data, x, y):
    for i in range(y.size):
        s = 0.0
        for jj in range(indptr[i], indptr[i + 1]):
            s += data[jj] * x[indices[jj]]
        y[i] = s


@njit(**JIT_FLAGS)
def face_sums(P, N, on_P, on_N, n):
    """Per cell: the sum of ``on_P`` over the faces whose P is the cell, plus the sum of ``on_N``
    over those whose N is (each in face order from zero, then added: bit-identical to the
    products with the scatter matrices ``_sum_P``, ``_sum_N``)."""
    a = np.zeros(n)
    b = np.zeros(n)
    for f in range(P.size):
        a[P[f]] += on_P[f]
        b[N[f]] += on_N[f]
    for i in range(n):
        a[i] += b[i]
    return a
