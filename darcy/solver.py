"""Linearised pressure equation of the gas in a granular medium (SMH eq. 5), finite volumes.

    φ ∂P′/∂t = (P0/η) ∇·(κ(φ) ∇P′) − P0 ∇·u

P′ [Pa] the pressure relative to P0, φ [-] porosity, κ [m²] permeability (Carman–Kozeny, capped),
η [Pa s] gas viscosity, u [m/s] grain velocity.  The equation is φ/P0 times the linearised gas
mass balance: the Darcy flux q = −(κ/η)∇P′ (eq. 3, q = φ(v_g − u)) plus u is the volume flux of
the mixture, and −(φ/P0) ∂P′/∂t its divergence (gas compressibility).

Grid: the nx × ny × ny cells of :class:`TubeGrid`; cell volumes, x-face areas and side-face areas
are the parts inside the circular tube.  Face permeability: harmonic mean of the two cells.
Face grain velocity: arithmetic mean.  Time: θ-scheme on the linear operator built from the
φ and u handed in (θ = ½, Crank–Nicolson, by default; the diffusivity P0 κ/(ηφ) is ~10 m²/s in
a slug, far beyond any explicit step), one sparse LU solve per step (scipy.sparse).  Crank–
Nicolson is not L-stable: for steps far above a cell's l²/D (≈ 5·10⁻⁹ s in an empty cell at the
capped permeability) its stiff modes flip sign every step; θ = 1 (backward Euler) damps them
and is what the coupled model uses by default (eulag.slug).  The paper
integrates each dimension separately (ADI); a direct solve of the 600 unknowns of the 150 × 2 × 2
grid is as cheap and has no splitting error.

Boundary conditions (``inlet``):
- ``"flux"`` (default): constant gas flux at x = 0, the Darcy flux through the inlet face
  q = v_s − φ u_x (eq. 3 with φ v_g = v_s, the superficial velocity; DENSE.md's "(1 − φ) u" is
  the grains' share of the mixture flux v_s + (1 − φ) u, which is what the inlet face carries
  once the −P0∇·u term's face value u is added).
- ``"source"``: the paper's form: the inlet face is closed and +S = P0 v_s A is added to the
  first layer of cells, −S to the last (SMH §2.1, "S ∝ v_g P0").
Outlet x = L: P′ = 0 at the face.  Periodic tubes (``periodic=True``): P′ periodic plus a mean
gradient G (the pressure drop over the tube is −G L), taken quasi-steady from φ and u: the steady
discrete field P′ = P_u + G P_G (P_u from the u terms, P_G from G, both on the periodic operator)
carries a mixture volume flux j A through every cross-section, and G is the value for which

    j A = v_s A + ⟨(1 − φ) u_x⟩ A,

the superficial gas flux plus the tube-mean solids volume flux (for a 1-D tube of slices this is
G = −η ⟨(j − ū_i)/κ_i⟩, the series resistance).  The discrete steady state then delivers v_s
exactly.  (Solving G as an extra implicit unknown with the constraint "mean gas flux over the
x-faces = v_s" was tried: that differential-algebraic system has a growing mode — the constraint
adds a positive rank-one term to the diffusion operator — so G is taken quasi-steady, from φ and
u alone.  An earlier closed form built from slice-mean permeabilities delivered about 0.987 of
v_s in a slug.)

Mass balance: :meth:`DarcySolver.balance` returns the residual of the discrete gas volume
balance of the last step (storage = boundary fluxes + the u terms), zero to round-off.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .permeability import carman_kozeny, poiseuille_tube_permeability


class TubeGrid:
    """Cells of a circular tube of ``length`` × ``diameter`` [m] on an nx × ny × ny grid.

    Cell centres x_i = (i + ½) l_x, y_b = −R + (b + ½) l_t; ``area`` (ny, ny) [m²] the part of each
    cell's cross-section inside the circle (x-face area); ``side_y`` (ny−1, ny) [m²] the area of
    the face between (b, c) and (b+1, c) inside the circle (``side_z`` its transpose).
    """

    def __init__(self, length, diameter, nx, ny=2, periodic=False, samples=1600):
        if nx < 3:
            raise ValueError(f"nx = {nx}: allowed >= 3")
        self.length, self.diameter, self.nx, self.ny = float(length), float(diameter), int(nx), int(ny)
        self.periodic = bool(periodic)
        r = 0.5 * diameter
        self.lx = self.length / nx
        self.lt = diameter / ny
        k = -(-int(samples) // ny)  # sample points per cell across (at least samples in all)
        samples = k * ny
        h = diameter / samples
        s = -r + (np.arange(samples) + 0.5) * h
        inside = (s[:, None] ** 2 + s[None, :] ** 2) < r * r
        self.area = inside.reshape(ny, k, ny, k).sum(axis=(1, 3)) * h * h
        # face between rows b and b+1 at y = −R + (b+1) l_t: length of that line inside the circle per column c
        side = np.zeros((max(ny - 1, 0), ny))
        for b in range(ny - 1):
            yf = -r + (b + 1) * self.lt
            half = math.sqrt(max(r * r - yf * yf, 0.0))
            for c in range(ny):
                z0, z1 = -r + c * self.lt, -r + (c + 1) * self.lt
                side[b, c] = max(0.0, min(z1, half) - max(z0, -half))
        self.side_y = side * self.lx
        self.side_z = self.side_y.T.copy()  # face between (b, c) and (b, c+1): (ny, ny−1)
        self.volume = self.area * self.lx
        self.x = (np.arange(nx) + 0.5) * self.lx
        self.cross_area = float(self.area.sum())

    @property
    def shape(self):
        return (self.nx, self.ny, self.ny)

    def index(self):
        return np.arange(self.nx * self.ny * self.ny).reshape(self.shape)


class DarcySolver:
    """θ-scheme for eq. 5 on a :class:`TubeGrid`.

    Parameters: p0 [Pa], eta [Pa s], grain diameter d [m] (Carman–Kozeny), kappa_max [m²]
    (default the empty-tube D_t²/32), theta (½ Crank–Nicolson, 1 backward Euler),
    inlet ``"flux"`` | ``"source"``.  State: ``p`` (nx, ny, ny) [Pa], ``grad`` of the mean
    gradient G [Pa/m] for periodic tubes.
    """

    def __init__(self, grid: TubeGrid, p0, eta, d, kappa_max=None, theta=0.5, inlet="flux"):
        if inlet not in ("flux", "source"):
            raise ValueError(f"gas.inlet = {inlet!r}: allowed 'flux', 'source'")
        if not 0.5 <= theta <= 1.0:
            raise ValueError(f"numerics.theta = {theta}: allowed 0.5 <= theta <= 1")
        self.grid, self.p0, self.eta, self.d = grid, float(p0), float(eta), float(d)
        self.kappa_max = poiseuille_tube_permeability(grid.diameter) if kappa_max is None else float(kappa_max)
        self.theta, self.inlet = float(theta), inlet
        self.p = np.zeros(grid.shape)
        self.G = 0.0
        self.last = None

    # ------------------------------------------------------------------ operator
    def _faces(self, phi, u):
        """Face lists (cell a, cell b, conductance T [m³/s · Pa/Pa ≡ P0 κ A/(η h)], face u·n_ab A [m³/s],
        axis) for all internal faces (and the periodic x-faces)."""
        g = self.grid
        kap = carman_kozeny(phi, self.d, self.kappa_max)
        idx = g.index()
        ny = g.ny
        fa, fb, T, U = [], [], [], []
        # x-faces
        if g.periodic:
            a, b = idx, np.roll(idx, -1, axis=0)
            ka, kb = kap, np.roll(kap, -1, axis=0)
            ua, ub = u[..., 0], np.roll(u[..., 0], -1, axis=0)
            A = np.broadcast_to(g.area, kap.shape)
        else:
            a, b = idx[:-1], idx[1:]
            ka, kb = kap[:-1], kap[1:]
            ua, ub = u[:-1, ..., 0], u[1:, ..., 0]
            A = np.broadcast_to(g.area, ka.shape)
        kf = 2 * ka * kb / (ka + kb)
        fa.append(a.ravel()); fb.append(b.ravel())
        T.append((self.p0 / self.eta * kf * A / g.lx).ravel())
        U.append((0.5 * (ua + ub) * A).ravel())
        nx_faces = a.size
        # y-faces (rows b, b+1) and z-faces (columns c, c+1)
        if ny > 1:
            for axis, comp, area in ((1, 1, g.side_y), (2, 2, g.side_z)):
                sl_a = [slice(None)] * 3
                sl_b = [slice(None)] * 3
                sl_a[axis] = slice(0, ny - 1)
                sl_b[axis] = slice(1, ny)
                sl_a, sl_b = tuple(sl_a), tuple(sl_b)
                ka, kb = kap[sl_a], kap[sl_b]
                kf = 2 * ka * kb / (ka + kb)
                Af = np.broadcast_to(area, ka.shape)
                fa.append(idx[sl_a].ravel()); fb.append(idx[sl_b].ravel())
                T.append((self.p0 / self.eta * kf * Af / g.lt).ravel())
                U.append((0.5 * (u[sl_a][..., comp] + u[sl_b][..., comp]) * Af).ravel())
        return (np.concatenate(fa), np.concatenate(fb), np.concatenate(T), np.concatenate(U), kap, nx_faces)

    # ------------------------------------------------------------------ step
    def step(self, phi, u, dt, v_s):
        """Advance P′ by dt [s] with porosity phi (nx, ny, ny) and grain velocity u (nx, ny, ny, 3)
        [m/s] held over the step, superficial gas velocity v_s [m/s].  Returns P′ (nx, ny, ny)."""
        g = self.grid
        phi = np.asarray(phi, float)
        u = np.asarray(u, float)
        n = phi.size
        fa, fb, T, U, kap, nxf = self._faces(phi, u)
        th = self.theta
        C = (phi * g.volume[None]).ravel() / dt
        # Laplacian-type operator L (L P = Σ T (P_nb − P)), as a matrix M = −L (SPD part)
        diag = np.zeros(n)
        np.add.at(diag, fa, T)
        np.add.at(diag, fb, T)
        rhs_src = np.zeros(n)
        # −P0 ∇·u: a face carrying U = (u·n_ab) A from a to b removes P0 U from a, adds to b
        np.add.at(rhs_src, fa, -self.p0 * U)
        np.add.at(rhs_src, fb, self.p0 * U)
        idx = g.index()
        A_col = g.area.ravel()
        first, last = idx[0].ravel(), idx[-1].ravel()
        t_out = None
        if not g.periodic:
            ux0, uxn = u[0, ..., 0].ravel(), u[-1, ..., 0].ravel()
            phi0 = phi[0].ravel()
            if self.inlet == "flux":
                q_in = v_s - phi0 * ux0
                rhs_src[first] += self.p0 * A_col * (q_in + ux0)
            else:
                rhs_src[first] += self.p0 * A_col * v_s
                rhs_src[last] -= self.p0 * A_col * v_s
            rhs_src[last] -= self.p0 * A_col * uxn
            t_out = self.p0 / self.eta * kap[-1].ravel() * A_col / (0.5 * g.lx)
            diag[last] += t_out
        rows = np.concatenate([np.arange(n), fa, fb])
        cols = np.concatenate([np.arange(n), fb, fa])
        vals_M = np.concatenate([diag, -T, -T])
        M = sp.csr_matrix((vals_M, (rows, cols)), shape=(n, n))
        p_old = self.p.ravel()
        rhs = C * p_old - (1 - th) * (M @ p_old) + rhs_src
        G = 0.0
        if g.periodic:  # rhs_src holds the u terms alone (no boundary terms on a periodic tube)
            G, gcol = self._periodic_gradient(M, rhs_src, fa, fb, T, nxf, U, phi, u, v_s)
            rhs = rhs + gcol * G
            rhs_src = rhs_src + gcol * G
        K = (sp.diags(C) + th * M).tocsc()
        p_new = spla.splu(K).solve(rhs)
        pm = th * p_new + (1 - th) * p_old
        self.last = dict(dt=dt, C=C, p_old=p_old, p_new=p_new, pm=pm, M=M, src=rhs_src, t_out=t_out,
                         last=last, G=G, kap=kap, v_s=v_s, phi=phi, u=u)
        self.p = p_new.reshape(g.shape)
        self.G = float(G)
        return self.p

    def _periodic_gradient(self, M, src_u, fa, fb, T, nxf, U, phi, u, v_s):
        """(G, gcol): the mean gradient G [Pa/m] of a periodic tube and its column in the cell
        equations (M P′ = sources + gcol G).

        G is quasi-steady: P′ = P_u + G P_G solves the steady discrete equations, M P_u = src_u
        (the −P0 ∇·u terms) and M P_G = gcol (M is singular on the periodic tube: one cell's P′ is
        pinned), and G is the one value for which the mixture volume flux through the
        x-faces of that steady field, the same through every cross-section, equals
        v_s A + Σ (1 − φ) u_x V / L, the superficial gas flux plus the tube-mean solids flux.
        So the discrete steady state delivers v_s exactly; G depends on φ and u only, not on P′."""
        g = self.grid
        n = phi.size
        xa, xb, xT = fa[:nxf], fb[:nxf], T[:nxf]
        gcol = np.zeros(n)
        np.add.at(gcol, xa, xT * g.lx)
        np.add.at(gcol, xb, -xT * g.lx)
        # P′ is fixed up to a constant: pin the first cell at 0 and solve for the others (both
        # right-hand sides sum to zero, so the first cell's equation holds too)
        lu = spla.splu(M[1:, 1:].tocsc())
        p_u = np.concatenate(([0.0], lu.solve(src_u[1:])))
        p_g = np.concatenate(([0.0], lu.solve(gcol[1:])))
        # mixture volume flux [m³/s] summed over the x-faces (nx cross-sections): Darcy part + u part
        j_u = np.sum(xT * (p_u[xa] - p_u[xb])) / self.p0 + np.sum(U[:nxf])
        j_g = np.sum(xT * (p_g[xa] - p_g[xb] - g.lx)) / self.p0
        solids = np.sum((1.0 - phi) * u[..., 0] * g.area[None])            # Σ (1 − φ) u_x A, all slices
        wanted = g.nx * v_s * g.cross_area + solids
        return (wanted - j_u) / j_g, gcol

    # ------------------------------------------------------------------ diagnostics
    def balance(self):
        """Residual [m³/s] of the gas volume balance of the last step, Σ φV ΔP′/(P0 dt) − (inflow −
        outflow + u terms), and the terms themselves (dict)."""
        L = self.last
        storage = np.sum(L["C"] * (L["p_new"] - L["p_old"])) / self.p0
        sources = np.sum(L["src"]) / self.p0
        outflow = 0.0
        if L["t_out"] is not None:
            outflow = np.sum(L["t_out"] * L["pm"][L["last"]]) / self.p0
        resid = storage - (sources - outflow)
        return resid, dict(storage=storage, sources=sources, outflow=outflow)

    def inlet_pressure(self):
        """P′ [Pa] at the inlet face (area-weighted over the cross-section), from the first cells and
        the inlet flux; for periodic tubes the drop over the tube, −G L."""
        g = self.grid
        if g.periodic:
            return -self.G * g.length
        L = self.last
        p0c = self.p[0].ravel()
        if L is None:
            return float(np.sum(p0c * g.area.ravel()) / g.cross_area)
        if self.inlet == "flux":
            q = L["v_s"] - L["phi"][0].ravel() * L["u"][0, ..., 0].ravel()
            pf = p0c + self.eta * q * (0.5 * g.lx) / L["kap"][0].ravel()
        else:
            pf = p0c
        return float(np.sum(pf * g.area.ravel()) / g.cross_area)

    def gradient(self):
        """∇P′ at the cells (nx, ny, ny, 3) [Pa/m]: the mean of the adjacent face gradients along x
        (boundary faces from the boundary conditions; + G if periodic); across the tube the mean of
        the internal face gradients (wall faces carry no flux and are left out)."""
        g = self.grid
        p = self.p
        grad = np.zeros(g.shape + (3,))
        if g.periodic:
            fx = (np.roll(p, -1, axis=0) - p) / g.lx  # face i+1/2
            grad[..., 0] = 0.5 * (fx + np.roll(fx, 1, axis=0)) + self.G
        else:
            fx = np.empty((g.nx + 1,) + p.shape[1:])
            fx[1:-1] = (p[1:] - p[:-1]) / g.lx
            fx[-1] = (0.0 - p[-1]) / (0.5 * g.lx)
            L = self.last
            if L is not None and self.inlet == "flux":
                q = (L["v_s"] - L["phi"][0] * L["u"][0, ..., 0])
                fx[0] = -self.eta * q / L["kap"][0]
            else:
                fx[0] = 0.0
            grad[..., 0] = 0.5 * (fx[1:] + fx[:-1])
        for axis in (1, 2):
            if g.ny > 1:
                d = np.diff(p, axis=axis) / g.lt
                s = np.zeros(p.shape)
                cnt = np.zeros(p.shape)
                sl_lo = [slice(None)] * 3
                sl_hi = [slice(None)] * 3
                sl_lo[axis] = slice(0, g.ny - 1)
                sl_hi[axis] = slice(1, g.ny)
                s[tuple(sl_lo)] += d
                cnt[tuple(sl_lo)] += 1
                s[tuple(sl_hi)] += d
                cnt[tuple(sl_hi)] += 1
                grad[..., axis] = s / cnt
        return grad

    def state(self):
        return {"p": self.p.copy(), "G": np.array(self.G)}

    def load_state(self, st):
        self.p = np.array(st["p"], float).reshape(self.grid.shape)
        self.G = float(st["G"])
