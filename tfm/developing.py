"""Developing two-fluid pipe flow: the cross-section solver of :mod:`tfm.section`, marched along x.

The paper's pipe (Ding et al. 2024, §3.5) starts from a uniform suspension: α_s,inlet of eq. 23
at the Hinkle solids velocity of eq. 22, both phases with the 1/7-power profiles of eqs. 20–21.
Its Δp is measured over the whole 2.4 m pipe, of which the first half develops (§4.2.2: the
profiles are stable from L = 120 D on). This module measures what that development does to Δp.

Parabolic marching (the boundary-layer form of the steady equations, as :mod:`rans.solver`
marches the gas): at each station the equations of :mod:`tfm.section` gain the axial
convection of the upstream station, implicit in the station's unknowns,

* momentum:      ρ_i α_i u_i,up (u_i − u_i,up)/Δx   (i = gas, solids),
* solids mass:   (α_s u_s − (α_s u_s)_up)/Δx + ∇·F = 0 (F the in-plane drift flux of
  :mod:`tfm.section`), which carries the solids mass flow from station to station exactly,
* gas k, ε:      ρ_g α_g u_g,up (φ − φ_up)/Δx,  Θ: (3/2) ρ_s α_s u_s,up (Θ − Θ_up)/Δx,

and the station's pressure gradient G(x) = −dp/dx is the value that carries the gas volume
flow U_g A (incompressible gas: α_g u_g integrates to U_g A at every station). The pressure
drop is ∫G dx. Neglected (stated): axial diffusion, in-plane convection of axial momentum by the
drift flux, and the gas's in-plane continuity beyond the section's counter-flow (no secondary
flow, as in the developed section). First order in Δx (backward Euler); the stations grow
geometrically from ``first_step`` so the inlet region is resolved.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .inlet import paper_inlet, seventh_power_profile
from .section import SectionDivergence, SectionProblem, SectionState, _Solver

__all__ = ["MarchResult", "axial_stations", "inlet_state", "march_pipe"]


def axial_stations(length: float, first_step: float, growth: float, max_step: float) -> np.ndarray:
    """Station positions x_1 … x_n = length [m]: steps first_step·growth^i up to max_step, the last
    step shortened to end at ``length``."""
    if not (length > 0 and first_step > 0 and growth >= 1.0 and max_step >= first_step):
        raise ValueError(f"stations: length {length}, first_step {first_step}, growth {growth}, "
                         f"max_step {max_step}: need positive sizes, growth >= 1, max_step >= first_step")
    xs, x, h = [], 0.0, first_step
    while x < length * (1.0 - 1e-12):
        x = min(x + h, length)
        if length - x < 0.25 * h:   # no sliver at the end
            x = length
        xs.append(x)
        h = min(h * growth, max_step)
    return np.asarray(xs)


def inlet_state(solver: _Solver) -> SectionState:
    """The paper's inlet (eqs. 20–23): uniform α_s,inlet, 1/7-power profiles of the gas
    (mean U_g/(1 − α_s,inlet)) and solids (mean u_s,inlet of Hinkle), k and ε of the developed
    section's starting guess; Θ small."""
    pb = solver.pb
    us_in, a_in = paper_inlet(pb.u_g, pb.d_s, pb.rho_s, pb.rho_g, pb.diameter, pb.m_s, pb.params.alpha_max)
    sec = solver.sec
    r = np.sqrt(sec.cz**2 + sec.cy**2)
    prof = seventh_power_profile(r, pb.diameter, 1.0)
    prof = prof / (float(np.sum(prof * solver.A)) / solver.Atot)   # exact mean on this mesh
    st = solver.initial_state()
    st.alpha = np.full(solver.n, a_in)
    st.ug = pb.u_g / (1.0 - a_in) * prof
    st.us = us_in * prof
    st.G = 0.0
    return st


@dataclass
class MarchResult:
    """Stations and the section-integrated quantities along the pipe, and the last station."""
    x: np.ndarray                   # station positions [m]
    G: np.ndarray                   # −dp/dx at each station [Pa m-1]
    pressure_drop: np.ndarray       # ∫G dx from the inlet [Pa]
    holdup: np.ndarray              # section-mean α_s
    solids_mass_flow: np.ndarray    # Σ ρ_s α_s u_s A [kg s-1] (carried to the stations' tolerance)
    deposit_peak: np.ndarray        # max α_s
    iterations: np.ndarray          # outer iterations per station
    converged: np.ndarray           # per station
    inlet: dict = field(default_factory=dict)
    state: SectionState | None = None
    closures: dict | None = None
    solver: _Solver | None = None


def march_pipe(pb: SectionProblem, length: float, first_step: float | None = None, growth: float = 1.08,
               max_step: float | None = None, callback=None, start: tuple | None = None,
               solver: _Solver | None = None) -> MarchResult:
    """March the two-fluid pipe from the paper's inlet over ``length`` [m].

    first_step, max_step default to D/4 and 2.5 D.  Each station iterates as the developed section
    does (``pb.max_iterations``, ``pb.tolerance``), warm-started from the upstream station;
    ``callback(i, x, st, row)`` after each station (``row``: that station's scalars, as in
    :class:`MarchResult`).  ``start = (rows, state)`` continues a march whose first ``len(rows)``
    stations are done, ``state`` being the last of them (a checkpoint).  ``solver``: a
    :class:`tfm.section._Solver` of ``pb`` to use (made here when None).  A station that fails raises
    :class:`tfm.section.SectionDivergence` naming the station, the variable and the cell.
    """
    D = pb.diameter
    xs = axial_stations(length, first_step or 0.25 * D, growth, max_step or 2.5 * D)
    solver = _Solver(pb) if solver is None else solver
    st0 = inlet_state(solver)
    A = solver.A
    inlet = dict(alpha_s=float(st0.alpha[0]), solids_velocity=float(np.sum(st0.us * A) / solver.Atot),
                 gas_velocity=float(np.sum(st0.ug * A) / solver.Atot))
    rows, st = ([], st0) if start is None else (list(start[0]), start[1])
    if len(rows) > len(xs):
        raise ValueError(f"a march of {len(rows)} stations cannot continue on {len(xs)} stations")
    try:
        _march(pb, solver, xs, rows, st, callback)
    finally:
        solver.conv = None      # the solver solves the developed section again
    st = solver.last_station
    c = solver.closures(st)
    col = {k: np.array([r[k] for r in rows]) for k in ("x", "G", "holdup", "ms", "peak", "it", "ok")}
    dxs = np.diff(np.concatenate([[0.0], col["x"]]))
    hold = col["holdup"]
    return MarchResult(x=col["x"], G=col["G"], pressure_drop=np.cumsum(col["G"] * dxs), holdup=hold,
                       solids_mass_flow=col["ms"], deposit_peak=col["peak"], iterations=col["it"].astype(int),
                       converged=col["ok"].astype(bool), inlet=inlet, state=st, closures=c, solver=solver)


def _march(pb, solver, xs, rows, st, callback):
    """The stations from ``len(rows)`` on (``rows`` grows; ``solver.last_station``: the last state)."""
    A = solver.A
    solver.last_station = st
    for i in range(len(rows), len(xs)):
        x = float(xs[i])
        dx = x - (float(xs[i - 1]) if i else 0.0)
        up = dict(ug=st.ug.copy(), us=st.us.copy(), k=st.k.copy(), eps=st.eps.copy(), theta=st.theta.copy())
        solver.conv = dict(cg=pb.rho_g * (1.0 - st.alpha) * np.maximum(st.ug, 0.0) / dx,
                           cs=pb.rho_s * st.alpha * np.maximum(st.us, 0.0) / dx, dx=dx, **up)
        st.iteration, st.history = 0, []
        try:
            st, conv_ok, _ = solver.run(st)
        except SectionDivergence as exc:
            raise SectionDivergence(f"station {i + 1} (x = {x:.4g} m): {exc}") from None
        row = dict(x=x, G=float(st.G), holdup=float(np.sum(st.alpha * A) / solver.Atot),
                   ms=float(np.sum(pb.rho_s * st.alpha * st.us * A)), peak=float(st.alpha.max()),
                   it=int(st.iteration), ok=bool(conv_ok))
        rows.append(row)
        solver.last_station = st
        if callback is not None:
            callback(i, x, st, row)
