"""A case before it runs: every key resolved, and the numbers that say what the run will meet.

:func:`check_report` lists the resolved case (every key with its value, defaults included,
units in brackets) and derived numbers:

Gas
    Bulk Reynolds number Re = rho U0 D / mu. Darcy friction factor of the smooth pipe by
    Colebrook (``fluids.friction.Colebrook``, the one the mesh is designed with,
    :mod:`rans.mesh`) and by Blasius, f_D = 0.3164 Re^-0.25 (``fluids.friction.Blasius``);
    friction velocity u_tau = U0 sqrt(f_D / 8); the fully developed single-phase
    -dp/dx = f_D rho U0^2 / (2 D) and its pressure drop over the pipe length.
    Wall-cell y+ = y_c u_tau / nu with y_c the distance of the wall ring's centroid from the
    wall, from the mesh the run builds (:class:`rans.PipeMesh`).
Particles (only when the case has ``[particles]``)
    Particle response time tau_p = rho_p d_p^2 / (18 mu f_D) in the Stokes limit (f_D = 1) and
    with the Schiller & Naumann (1933) factor f_D = 1 + 0.15 Re_p^0.687 at the terminal slip
    (Re_p = rho v_t d_p / mu); terminal settling velocity v_t from ``fluids.drag.v_terminal``
    (the drag correlation ``fluids.drag.drag_sphere`` selects by default) and, for
    comparison, from the model's own drag and reduced gravity, v_t = g (1 - rho/rho_p) tau_p(v_t);
    Stokes numbers St = tau_p / (D / U0) and tau_p+ = tau_p u_tau^2 / nu; the mass flows;
    saltation velocities of the gas from ``fluids.saltation`` (:func:`saltation_velocities`).
Numerics
    Cells nx * nr * nt (periodic mode: one axial cell), parcels per pass, and a run-time
    estimate (:func:`runtime_estimate`, with the measured constants it rests on).

:func:`saltation_line` and :func:`total_pressure_drop_line` are the lines the run summary
shares with the report.

References: Colebrook (1939), Blasius (1913); Schiller & Naumann (1933); Rizk (1973),
Matsumoto, Kikuta & Maeda (1977), Weber (1981), Geldart & Ling (1990) as implemented and
referenced in ``fluids.saltation`` (Rabinovich & Kalman 2011 review them).
"""

from __future__ import annotations

import math
from dataclasses import MISSING

from eulag.config import _SECTIONS, Case, _fmt, _public_fields

__all__ = [
    "check_report",
    "saltation_velocities",
    "saltation_line",
    "total_pressure_drop_line",
    "runtime_estimate",
    "SALTATION_MARGIN",
]

#: gravitational acceleration [m s-2] (the model's, ``particles``; fluids uses the same value)
G = 9.80665

#: U0 below this factor times the largest saltation velocity gets a WARNING [1]: the
#: correlations scatter by tens of per cent, and conveying practice keeps 1.2-1.5x above
#: saltation.
SALTATION_MARGIN = 1.2

# -- run-time model constants -----------------------------------------------------------
# Measured on the 2-core VM, idle, with the runs of results/speed (python
# tests/benchmarks/bench_speed.py): the base case cases/tsuji_morikawa_200um.toml (200 x 10 x 20
# cells, 30,000 parcels, four-way) converged in 36 passes, 206 s: gas 30 s over 37 solves
# (0.81 s each), particles 172 s for 36 x 30,000 parcels (1.59e-4 s per parcel, about 1,380
# steps each at L/U0 = 0.4 s; the periodic form of the case takes as many, 1,375, in a run of
# 2 passes with 3,000 parcels). The same case on 200 x 20 x 40 cells (`--only paper`; 30,000
# -> 240,000 parcels): 1.80e-4 s per parcel; scenes a and e on 400 x 20 x 40: 2.43e-4 and
# 2.47e-4.
# The same VM type on another host ran the particle kernel 1.5 times slower.
#: gas-solver wall time per cell and coupling pass [s] (developing mode)
GAS_SECONDS_PER_CELL = 0.81 / 40000
#: wall time per cell of a single-phase run's gas solve [s]: cases/single_phase_pipe.toml
#: (400 x 20 x 40 cells, developing, converged to 1e-6) in 2.30 s on the same machine
SINGLE_PHASE_SECONDS_PER_CELL = 2.30 / 320000
#: particle steps per parcel of the measurement [1], at its L/U0 = 0.4 s, step factor 0.5,
#: 10 rings and 50 axial cells per metre
STEPS_PER_PARCEL_MEASURED = 1380
_MEASURED_TRANSIT, _MEASURED_STEP_FACTOR, _MEASURED_RINGS, _MEASURED_AXIAL_DENSITY = 0.4, 0.5, 10, 50.0
#: particle steps per second of wall time, whole machine (two threads) [1/s]
PARTICLE_STEPS_PER_SECOND = STEPS_PER_PARCEL_MEASURED / (172.0 / (36 * 30000))
#: growth of the cost per parcel with the rings, ~ (nr / 10)^0.18 (1.80/1.59 from 10 to 20
#: rings), and with the axial cells per metre, ~ (n_x / L / 50)^0.45 (2.45/1.80 from 50 to 100)
REFINEMENT_EXPONENT, AXIAL_REFINEMENT_EXPONENT = 0.18, 0.45
#: coupling passes of a typical converged run [1]: the base case 36 (converged after 33), the
#: 200 um scenes 17-40, the 50 um ones 27-34 (scene h about 70)
TYPICAL_PASSES = 36
#: compilation of the numba kernels on a cold cache [s] (not in the estimates): about 15 s for
#: a single-phase run, 1-3 min for the particle kernels of one physics-option set
COLD_COMPILE_TEXT = "plus the compilation of the numba kernels on a cold cache (15 s to 3 min, once)"


def _unit(meta: dict, value) -> str:
    """' [unit]' for a number (dimensionless: [1]); '' for strings and booleans."""
    if isinstance(value, bool) or isinstance(value, str) or value is None:
        return ""
    return f" [{meta['unit'] or '1'}]"


def _is_default(section, f) -> bool | None:
    """True/False when the key holds / does not hold its default; None: a required key."""
    value = getattr(section, f.name)
    if f.default is MISSING and f.default_factory is MISSING:
        return None
    default = f.default if f.default is not MISSING else f.default_factory()
    if default is None and not f.metadata["optional"]:
        return None  # an automatic default, resolved from other keys: shown as 'automatic'
    return value == default


_AUTOMATIC = {
    ("pipe", "sections"): lambda c: (c.pipe.length,),
    ("physics", "magnus_lift"): lambda c: c.physics.rotation,
    ("physics", "inter_particle_collisions"): lambda c: c.physics.coupling == "four-way",
    ("numerics", "parcels_start"): lambda c: min(30000, c.numerics.parcels),
}


#: keys that only the particle phase uses: not listed for a single-phase case
PARTICLE_SECTIONS = ("particles", "walls", "physics")
PARTICLE_NUMERICS = ("parcels", "parcels_start", "average_passes", "step_rule", "relaxation",
                     "max_passes", "gas_iterations_per_pass", "step_factor", "batch_size",
                     "batches_per_superbatch", "coupling_tolerance", "residence_cap",
                     "mirror_symmetry", "gas_station_retries", "gas_tolerance_early",
                     "drag_implicit_weight", "residual_noise")


def _case_lines(case: Case) -> list[str]:
    lines = [f"name = {_fmt(case.name)}", f"description = {_fmt(case.description)}"]
    single = case.particles is None
    for key in _SECTIONS:
        section = getattr(case, key)
        if single and key in PARTICLE_SECTIONS:
            continue
        for f in _public_fields(section):
            if single and key == "numerics" and f.name in PARTICLE_NUMERICS:
                continue
            value = getattr(section, f.name)
            meta = f.metadata
            shown = meta["none_label"] if value is None else _fmt(value)
            note = ""
            auto = _AUTOMATIC.get((key, f.name))
            if auto is not None:
                note = "  (automatic)" if value == auto(case) else ""
            elif _is_default(section, f):
                note = "  (default)"
            extra = ""
            if (key, f.name) == ("gas", "inlet_epsilon") and value is None:
                from rans import kepsilon

                eps = kepsilon.inlet_epsilon(case.gas.inlet_k, case.pipe.diameter)
                extra = f" = {eps:.4g} [m2 s-3]"
            elif (key, f.name) == ("numerics", "residence_cap") and value is None:
                extra = f" = {50.0 * case.pipe.length / case.gas.bulk_velocity:.4g} [s]"
            unit = _unit(meta, value) if value is not None else ""
            lines.append(f"{key}.{f.name} = {shown}{unit}{extra}{note}")
    if single:
        lines.append("(single-phase: no [particles]; the keys of [walls], [physics] and the "
                     "Lagrangian keys of [numerics] are not used and not listed)")
    return lines


def _mesh(case: Case):
    from eulag.coupling import build_mesh

    return build_mesh(case)


def _mass_flows(case: Case) -> tuple[float, float]:
    """Gas and particle mass flow rates [kg s-1]."""
    area = math.pi * case.pipe.diameter ** 2 / 4.0
    m_gas = case.gas.density * case.gas.bulk_velocity * area
    m_p = case.particles.mass_loading * m_gas if case.particles is not None else 0.0
    return m_gas, m_p


def _terminal_velocity(case: Case) -> float:
    from fluids.drag import v_terminal

    p, g = case.particles, case.gas
    return float(v_terminal(p.diameter, p.density, g.density, g.viscosity))


def _schiller_naumann(re_p: float) -> float:
    """Drag factor f_D = C_D Re_p / 24 of Schiller & Naumann (1933), 0.44 Re_p / 24 above 1000
    (the model's, ``particles.forces.schiller_naumann_drag_factor``)."""
    return 0.44 * re_p / 24.0 if re_p > 1000.0 else 1.0 + 0.15 * re_p ** 0.687


def _model_terminal_velocity(case: Case) -> float:
    """Terminal velocity with the model's drag and reduced gravity: v = g (1 - rho/rho_p) tau_p(v)."""
    p, g = case.particles, case.gas
    tau_st = p.density * p.diameter ** 2 / (18.0 * g.viscosity)
    g_red = G * (1.0 - g.density / p.density)
    v = g_red * tau_st
    for _ in range(200):  # contraction: f_D grows with v
        v_new = g_red * tau_st / _schiller_naumann(g.density * v * p.diameter / g.viscosity)
        v_new = 0.5 * (v + v_new)
        if abs(v_new - v) <= 1e-12 * v_new:
            break
        v = v_new
    return v_new


def saltation_velocities(case: Case) -> dict[str, float]:
    """Saltation velocities of the gas [m s-1] by ``fluids.saltation``, for a case with particles.

    Inputs: the particle mass flow m_p = eta rho U0 pi D^2 / 4 [kg s-1], the particle diameter
    and density, the gas density and viscosity, the pipe diameter, and (Matsumoto 1977, Weber)
    the terminal velocity of ``fluids.drag.v_terminal``. Keys: "Rizk" (1973),
    "Matsumoto 1977" (fine- or coarse-particle branch as the correlation selects), "Weber"
    (1981), "Geldart-Ling" (1990). Empty for a case without particles.
    """
    from fluids import saltation as s

    if case.particles is None:
        return {}
    _, m_p = _mass_flows(case)
    p, g, d_pipe = case.particles, case.gas, case.pipe.diameter
    v_t = _terminal_velocity(case)
    return {
        "Rizk": float(s.Rizk(m_p, p.diameter, g.density, d_pipe)),
        "Matsumoto 1977": float(s.Matsumoto_1977(m_p, p.density, p.diameter, g.density, d_pipe, v_t)),
        "Weber": float(s.Weber_saltation(m_p, p.density, p.diameter, g.density, d_pipe, v_t)),
        "Geldart-Ling": float(s.Geldart_Ling(m_p, g.density, d_pipe, g.viscosity)),
    }


def saltation_line(case: Case) -> str:
    """The saltation velocities against U0, for a run summary or the check report.

    One line, ``"  saltation    Rizk 5.94, ... m/s; U0 = 10 m/s is 1.68 x the largest"``, and a
    second line ``"  WARNING: ..."`` when U0 < SALTATION_MARGIN (1.2) x the largest of the four
    (all four are dilute-phase correlations for horizontal conveying and apply to every case
    with a particle mass flow; none is dropped). "" for a single-phase case.
    """
    if case.particles is None:
        return ""
    v = saltation_velocities(case)
    u0 = case.gas.bulk_velocity
    top_name = max(v, key=v.get)
    top = v[top_name]
    text = ("  saltation    " + ", ".join(f"{k} {x:.2f}" for k, x in v.items())
            + f" m/s (fluids.saltation); U0 = {u0:g} m/s is {u0 / top:.2f} x the largest")
    if u0 < SALTATION_MARGIN * top:
        text += (f"\n  WARNING: U0 = {u0:g} m/s is below {SALTATION_MARGIN:g} x the largest "
                 f"saltation velocity ({top_name}, {top:.2f} m/s): particles may settle and form "
                 "a moving or stationary bed, which this dilute-phase model does not represent")
    return text


def _axial_widths(ds):
    """Axial cell widths [m] of a result dataset (from x_edge, or CF bounds of x), or None."""
    import numpy as np

    if "x_edge" in ds.variables:
        return np.diff(np.asarray(ds["x_edge"].values, dtype=float))
    bounds = ds["x"].attrs.get("bounds") if "x" in ds.variables else None
    if bounds and bounds in ds.variables:
        b = np.asarray(ds[bounds].values, dtype=float)
        return b[:, 1] - b[:, 0]
    for key in ("pipe.length", "case_pipe_length"):
        if key in ds.attrs and "x" in ds.sizes:
            return np.full(ds.sizes["x"], float(ds.attrs[key]) / ds.sizes["x"])
    return None


def total_pressure_drop_line(ds) -> str:
    """The pressure drop over the pipe [Pa], Delta p = sum_i (-dp/dx)_i dx_i, from a result dataset.

    Uses ``pressure_gradient(x)`` [Pa m-1] and the axial cell widths (``x_edge``; in periodic
    mode the single cell spans the pipe length); with ``pressure_gradient_single_phase`` the
    single-phase drop and the ratio follow. "" when the dataset has no pressure gradient.
    """
    import numpy as np

    if "pressure_gradient" not in ds.variables:
        return ""
    dx = _axial_widths(ds)
    if dx is None:
        return ""
    length = float(dx.sum())
    dp = float(np.sum(np.asarray(ds["pressure_gradient"].values, dtype=float) * dx))
    text = f"  pressure     Delta p = {dp:.4g} Pa over L = {length:g} m"
    if "pressure_gradient_single_phase" in ds.variables:
        dp0 = float(np.sum(np.asarray(ds["pressure_gradient_single_phase"].values, dtype=float) * dx))
        if dp0 != dp:  # a single-phase dataset holds the same gradient twice
            text += f" (single-phase {dp0:.4g} Pa; ratio {dp / dp0:.3f})"
    return text


def runtime_estimate(case: Case) -> tuple[float, float, str]:
    """Estimated wall time [s] of ``eulag run`` on a 2-core machine: (typical, at max_passes, basis).

    Model: each pass costs a gas solve, GAS_SECONDS_PER_CELL x cells, and a Lagrangian pass,
    parcels x steps per parcel / PARTICLE_STEPS_PER_SECOND, with steps per parcel =
    STEPS_PER_PARCEL_MEASURED x (L/U0) / 0.4 s x 0.5 / step_factor x (nr / 10)^0.18 x
    (n_x / L / 50 m⁻¹)^0.45 (1 for a periodic pipe, whose one axial cell does not limit the
    step). A coupled
    run: one single-phase solve, then TYPICAL_PASSES passes (at most max_passes), the last
    average_passes of them with numerics.parcels and the others with numerics.parcels_start;
    one-way coupling: one gas solve and the average_passes passes. Single-phase: one gas solve
    at SINGLE_PHASE_SECONDS_PER_CELL.
    Good to a factor of about 1.5 on an idle 2-core machine for dilute 200 um cases; the dense
    50 um scenes take more steps per parcel (their collisions shorten the step) and more passes,
    and a loaded machine is slower. Compilation on a cold numba cache is not included.
    """
    n = case.numerics
    nx = 1 if case.pipe.mode == "periodic" else n.axial_cells
    cells = nx * n.radial_cells * n.azimuthal_cells
    if case.particles is None:
        t = SINGLE_PHASE_SECONDS_PER_CELL * cells
        basis = (f"one gas solve at {SINGLE_PHASE_SECONDS_PER_CELL * 1e6:.3g} us per cell (measured on "
                 "2 cores, see eulag.check)")
        return t, t, basis
    gas = GAS_SECONDS_PER_CELL * cells
    transit = case.pipe.length / case.gas.bulk_velocity
    # a periodic pipe's parcels take the developing pipe's steps (its one axial cell does not
    # limit the step): the axial factor applies to developing pipes only
    axial = 1.0 if case.pipe.mode == "periodic" else \
        (nx / case.pipe.length / _MEASURED_AXIAL_DENSITY) ** AXIAL_REFINEMENT_EXPONENT
    steps = (STEPS_PER_PARCEL_MEASURED * transit / _MEASURED_TRANSIT * _MEASURED_STEP_FACTOR
             / n.step_factor * (n.radial_cells / _MEASURED_RINGS) ** REFINEMENT_EXPONENT * axial)
    per_parcel = steps / PARTICLE_STEPS_PER_SECOND

    def total(passes):
        final = min(n.average_passes, passes)
        early = passes - final
        return (gas * (1 + passes) + per_parcel * (early * n.parcels_start + final * n.parcels))

    if case.physics.coupling == "one-way":
        t = gas + per_parcel * n.average_passes * n.parcels
        return t, t, (f"one gas solve and {n.average_passes} passes of {n.parcels} parcels, "
                      f"~{steps:.0f} steps each at {PARTICLE_STEPS_PER_SECOND:.3g} steps/s")
    typical = min(TYPICAL_PASSES, n.max_passes)
    basis = (f"{typical} passes (typical; {n.max_passes} at most), each a gas solve "
             f"({gas:.2g} s at {GAS_SECONDS_PER_CELL * 1e6:.3g} us per cell) and a Lagrangian pass "
             f"(~{steps:.0f} steps per parcel at {PARTICLE_STEPS_PER_SECOND:.3g} steps/s); constants "
             "measured on 2 cores with the base case, see eulag.check")
    return total(typical), total(n.max_passes), basis


def _minutes(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def check_report(case: Case) -> str:
    """The resolved case (one line per key: ``section.key = value [units]``) and derived numbers.

    See the module docstring for what is derived and from which correlations. Particle numbers
    only for a case with ``[particles]``.
    """
    from fluids.friction import Blasius, Colebrook

    g, pipe, n = case.gas, case.pipe, case.numerics
    nu = g.kinematic_viscosity
    re = case.reynolds_number
    f_c = float(Colebrook(re, 0.0))
    f_b = float(Blasius(re))
    ut_c = g.bulk_velocity * math.sqrt(f_c / 8.0)
    ut_b = g.bulk_velocity * math.sqrt(f_b / 8.0)
    dpdx = f_c * g.density * g.bulk_velocity ** 2 / (2.0 * pipe.diameter)
    mesh = _mesh(case)
    y_c = float(mesh.wall_distance)
    wall_ring = float(mesh.r_edges[-1] - mesh.r_edges[-2])
    nx, nr, nt = mesh.shape

    out = [f"case {case.name}" + (f" ({case.source})" if case.source else ""), ""]
    out.append("Case (every key; '(default)': the key's default, '(automatic)': derived from others)")
    out += ["  " + line for line in _case_lines(case)]
    out += ["", "Gas"]
    out.append(f"  Reynolds     Re = rho U0 D / mu = {re:.4g} [1]")
    out.append(f"  friction     f_D = {f_c:.5f} [1] (Colebrook, smooth), {f_b:.5f} [1] (Blasius); "
               f"u_tau = {ut_c:.4g} [m s-1] (Colebrook), {ut_b:.4g} [m s-1] (Blasius)")
    out.append(f"  -dp/dx       {dpdx:.4g} [Pa m-1] fully developed (Colebrook); "
               f"Delta p = {dpdx * pipe.length:.4g} [Pa] over L = {pipe.length:g} [m]")
    out.append(f"  wall cell    ring thickness {wall_ring * 1e3:.4g} [mm], centroid "
               f"{y_c * 1e3:.4g} [mm] from the wall: y+ = {y_c * ut_c / nu:.1f} [1] (Colebrook), {y_c * ut_b / nu:.1f} [1] "
               f"(Blasius); target numerics.first_cell_yplus = {n.first_cell_yplus:g} [1]")
    from rans.mesh import MAX_RING_GROWTH, radial_growth

    out.append(f"  rings        {nr}; largest thickness ratio of a ring to the next one outward "
               f"{radial_growth(0.5 * pipe.diameter, nr, wall_ring):.3g} [1] (allowed: at most {MAX_RING_GROWTH:g})")

    p = case.particles
    if p is not None:
        m_gas, m_p = _mass_flows(case)
        tau_st = p.density * p.diameter ** 2 / (18.0 * g.viscosity)
        v_t = _terminal_velocity(case)
        re_t = g.density * v_t * p.diameter / g.viscosity
        tau_sn = tau_st / _schiller_naumann(re_t)
        t_flow = pipe.diameter / g.bulk_velocity
        out += ["", "Particles"]
        out.append(f"  terminal     v_t = {v_t:.4g} [m s-1] (fluids.drag.v_terminal), "
                   f"{_model_terminal_velocity(case):.4g} [m s-1] (the model's Schiller-Naumann drag); "
                   f"Re_p = {re_t:.3g} [1] at v_t")
        out.append(f"  tau_p        {tau_st:.4g} [s] (Stokes), {tau_sn:.4g} [s] (Schiller-Naumann "
                   "at the terminal slip)")
        out.append(f"  Stokes       St = tau_p U0 / D = {tau_st / t_flow:.3g} [1] (Stokes), "
                   f"{tau_sn / t_flow:.3g} [1] (Schiller-Naumann); tau_p+ = tau_p u_tau^2 / nu = "
                   f"{tau_st * ut_c ** 2 / nu:.3g} [1], {tau_sn * ut_c ** 2 / nu:.3g} [1]")
        out.append(f"  mass flows   gas {m_gas * 1e3:.4g} [g s-1], particles {m_p * 1e3:.4g} [g s-1] "
                   f"(eta = {p.mass_loading:g} [1])")
        sline = saltation_line(case)
        if sline:
            out += sline.split("\n")

    typical, worst, basis = runtime_estimate(case)
    out += ["", "Numerics"]
    where = " (periodic: one axial cell)" if pipe.mode == "periodic" else ""
    out.append(f"  cells        {nx} x {nr} x {nt} = {nx * nr * nt} [1]{where}")
    if p is not None:
        if case.physics.coupling == "one-way":
            out.append(f"  parcels      {n.parcels} [1] per pass, {n.average_passes} [1] passes")
        else:
            out.append(f"  parcels      {n.parcels_start} [1] per early pass, {n.parcels} [1] per final "
                       f"pass ({n.average_passes} [1] final passes averaged), at most "
                       f"{n.max_passes} [1] passes")
    if typical == worst:
        out.append(f"  run time     about {_minutes(typical)} ({typical:.3g} [s]): {basis}; {COLD_COMPILE_TEXT}")
    else:
        out.append(f"  run time     about {_minutes(typical)} ({typical:.3g} [s]), up to "
                   f"{_minutes(worst)} ({worst:.3g} [s]): {basis}; {COLD_COMPILE_TEXT}")
    return "\n".join(out)
