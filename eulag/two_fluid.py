"""Two-fluid model cases (top-level ``model = "two-fluid"``): validation, run, dataset.

The run layer (:mod:`eulag.runs`) calls :func:`validate_two_fluid_case` on the parsed TOML
and :func:`run_two_fluid` to get the dataset.  The solver is :mod:`tfm.section` (fully
developed pipe cross-section) or, with ``numerics.mode = "developing"``, :mod:`tfm.developing`
(the same section marched along the pipe from the paper's inlet); the closures are in :mod:`tfm`.

Case tables and keys (SI; the one exception is ``friction.internal_friction_angle_deg``):

    [pipe]       diameter, length (fully developed: Δp = −dp/dx · length; developing: the
                 marched length, Δp = ∫ −dp/dx dx)
    [gas]        density, viscosity, superficial_velocity
    [solids]     density, diameter, mass_flow
    [friction]   model ("dartevelle" | "srivastava-sundaresan" | "berzi" | "none"), alpha_min,
                 alpha_max, internal_friction_angle_deg, fr, r, s, berzi_a,
                 stiffness_over_diameter, linearise_delta, viscosity_cap
    [kinetic]    restitution
    [walls]      restitution, friction, tangential_restitution
    [drag]       mckeen_scale, blend_width
    [numerics]   radial_cells, azimuthal_cells, first_cell_yplus, max_iterations, tolerance,
                 turbulence ("k-epsilon" | "mixing-length"), mode ("fully-developed" |
                 "developing"), first_step_diameters, step_growth, max_step_diameters
                 (the marching stations of the developing mode, in pipe diameters)
    [experiment] optional reference values (supplementary_gas, pressure_drop, inlet_alpha_s, ...)
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from eulag.files import savez_atomic

__all__ = ["validate_two_fluid_case", "run_two_fluid", "problem_from_case", "resolved_case", "check_report"]

_FRICTION_MODELS = ("dartevelle", "srivastava-sundaresan", "berzi", "none")


def _num(lo=None, hi=None, lo_open=True, integer=False, even=False):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
            return False
        try:
            if not math.isfinite(v):
                return False
        except OverflowError:  # an integer beyond the range of a double
            return False
        if lo is not None and (v <= lo if lo_open else v < lo):
            return False
        if hi is not None and v > hi:
            return False
        return not (even and v % 2)
    kind = "an even integer" if even else ("an integer" if integer else "a number")
    rng = []
    if lo is not None:
        rng.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        rng.append(f"<= {hi:g}")
    return check, kind + (" " + " and ".join(rng) if rng else "")


def _choice(options):
    return (lambda v: v in options), "one of " + ", ".join(options)


def _text():
    return (lambda v: isinstance(v, str)), "a string"


#: numerics.mode: one fully developed section (tfm.section) or the pipe marched from the paper's
#: inlet (tfm.developing)
MODES = ("fully-developed", "developing")

#: section -> key -> (default or None if required, (check, allowed))
SCHEMA = {
    "pipe": {"diameter": (None, _num(0, 1)), "length": (2.4, _num(0, 1e4))},
    "gas": {"density": (None, _num(0, 1e4)), "viscosity": (None, _num(0, 1)),
            "superficial_velocity": (None, _num(0, 200))},
    "solids": {"density": (None, _num(0, 3e4)), "diameter": (None, _num(0, 0.05)),
               "mass_flow": (None, _num(0, 1e3))},
    "friction": {"model": ("berzi", _choice(_FRICTION_MODELS)), "alpha_min": (0.4, _num(0, 1)),
                 "alpha_max": (0.63, _num(0, 1)), "internal_friction_angle_deg": (32.0, _num(0, 90)),
                 "fr": (0.05, _num(0, 1e9)), "r": (2.0, _num(0, 100)), "s": (5.0, _num(0, 100)),
                 "berzi_a": (1.8e-6, _num(0, 1)), "stiffness_over_diameter": (4.5e6, _num(0, 1e15)),
                 "linearise_delta": (0.01, _num(0, 0.2, lo_open=False)),
                 "viscosity_cap": (1.0e3, _num(0, 1e12))},
    "kinetic": {"restitution": (0.7, _num(0, 1))},
    "walls": {"restitution": (0.5, _num(0, 1)), "friction": (0.5, _num(0, 10, lo_open=False)),
              "tangential_restitution": (0.3, _num(-1, 1, lo_open=False)),
              "law": ("ding", _choice(("ding", "schneiderbauer")))},
    "drag": {"mckeen_scale": (1.0, _num(0, 100)), "blend_width": (0.02, _num(0, 0.2, lo_open=False))},
    "numerics": {"radial_cells": (16, _num(2, 400, integer=True, lo_open=False)),
                 "azimuthal_cells": (32, _num(4, 800, integer=True, lo_open=False, even=True)),
                 "first_cell_yplus": (30.0, _num(0, 1000)), "max_iterations": (400, _num(0, 1e6, integer=True)),
                 "tolerance": (1e-4, _num(0, 1)),
                 "turbulence": ("k-epsilon", _choice(("k-epsilon", "mixing-length"))),
                 "mode": ("fully-developed", _choice(MODES)),
                 "first_step_diameters": (0.25, _num(0, 1000)), "step_growth": (1.08, _num(1, 2, lo_open=False)),
                 "max_step_diameters": (2.5, _num(0, 1000))},
}
_TOP = ("name", "description", "model")

#: [experiment]: the measurements beside a case (Table 1 of Ding et al.; not used by the solver),
#: key -> (check, allowed): supplementary gas [m3 h-1], inlet solids fraction [-] and velocity
#: [m s-1], outlet pressure [Pa], measured pressure drop over the pipe [Pa]
EXPERIMENT = {"supplementary_gas": _num(0, 1e6), "inlet_alpha_s": _num(0, 1),
              "inlet_solids_velocity": _num(0, 200), "outlet_pressure": _num(0, 1e9),
              "pressure_drop": _num(0, 1e9)}


def _fmt(v):
    text = json.dumps(v) if isinstance(v, str) else repr(v)
    return text if len(text) <= 60 else f"{text[:24]}...({len(text)} characters)"


def resolved_case(case: dict) -> dict:
    """The case with every default filled in (validated first)."""
    validate_two_fluid_case(case)
    out = {k: case[k] for k in _TOP if k in case}
    for sec, keys in SCHEMA.items():
        given = case.get(sec, {})
        out[sec] = {k: given.get(k, default) for k, (default, _) in keys.items()}
    if "experiment" in case:
        out["experiment"] = dict(case["experiment"])
    return out


def validate_two_fluid_case(case: dict) -> None:
    """Check a parsed two-fluid case; raise ValueError with one line "section.key = value: allowed ..."."""
    if case.get("model") != "two-fluid":
        raise ValueError(f"model = {_fmt(case.get('model'))}: allowed \"two-fluid\" for this module")
    for k in case:
        if k not in _TOP and k not in SCHEMA and k != "experiment":
            raise ValueError(f"{k} = {_fmt(case[k]) if not isinstance(case[k], dict) else '[table]'}: "
                             f"allowed top-level keys {', '.join(_TOP)} and tables {', '.join(SCHEMA)}, experiment")
    for k in ("name", "description"):
        if k in case and not isinstance(case[k], str):
            raise ValueError(f"{k} = {_fmt(case[k])}: allowed a string")
    for sec, keys in SCHEMA.items():
        given = case.get(sec, {})
        if not isinstance(given, dict):
            raise ValueError(f"{sec} = {_fmt(given)}: allowed a table")
        for k, v in given.items():
            if k not in keys:
                raise ValueError(f"{sec}.{k} = {_fmt(v)}: allowed keys of [{sec}]: {', '.join(keys)}")
            check, allowed = keys[k][1]
            if not check(v):
                raise ValueError(f"{sec}.{k} = {_fmt(v)}: allowed {allowed}")
        for k, (default, _) in keys.items():
            if default is None and k not in given:
                raise ValueError(f"{sec}.{k} = (missing): allowed {keys[k][1][1]} (required)")
    fr = case.get("friction", {})
    amin, amax = fr.get("alpha_min", 0.4), fr.get("alpha_max", 0.63)
    if not amin < amax:
        raise ValueError(f"friction.alpha_min = {amin!r}: allowed a number < friction.alpha_max ({amax!r})")
    num = case.get("numerics", {})
    first, most = num.get("first_step_diameters", 0.25), num.get("max_step_diameters", 2.5)
    if most < first:
        raise ValueError(f"numerics.max_step_diameters = {most!r}: allowed a number >= "
                         f"numerics.first_step_diameters ({first!r})")
    if "experiment" in case and not isinstance(case["experiment"], dict):
        raise ValueError(f"experiment = {_fmt(case['experiment'])}: allowed a table")
    for k, v in case.get("experiment", {}).items():
        if k not in EXPERIMENT:
            raise ValueError(f"experiment.{k} = {_fmt(v)}: allowed keys of [experiment]: {', '.join(EXPERIMENT)}")
        check, allowed = EXPERIMENT[k]
        if not check(v):
            raise ValueError(f"experiment.{k} = {_fmt(v)}: allowed {allowed}")
    # values each within their own range that clash (as the Euler-Lagrange cases check them)
    gas, solids, pipe = case["gas"], case["solids"], case["pipe"]
    if not solids["density"] > gas["density"]:
        raise ValueError(f"solids.density = {_fmt(solids['density'])}: allowed a number > gas.density "
                         f"({_fmt(gas['density'])}): particles heavier than the gas")
    yplus = case.get("numerics", {}).get("first_cell_yplus", SCHEMA["numerics"]["first_cell_yplus"][0])
    thickness = wall_ring_thickness(case, yplus)
    if not 0.0 < thickness < 0.5 * pipe["diameter"]:
        raise ValueError(f"numerics.first_cell_yplus = {_fmt(yplus)}: allowed a y+ whose wall cell fits the pipe "
                         f"(here {thickness:.3g} m thick in a pipe of radius {0.5 * pipe['diameter']:g} m)")
    from rans.mesh import ring_growth_problem

    rings = case.get("numerics", {}).get("radial_cells", SCHEMA["numerics"]["radial_cells"][0])
    problem = ring_growth_problem(0.5 * pipe["diameter"], rings, thickness)
    if problem is not None:
        raise ValueError(f"numerics.radial_cells = {_fmt(rings)}: allowed {problem} (the wall ring at y+ = "
                         f"{_fmt(yplus)})")
    if not solids["diameter"] < 0.2 * pipe["diameter"]:
        raise ValueError(f"solids.diameter = {_fmt(solids['diameter'])}: allowed a number < pipe.diameter / 5 "
                         f"({0.2 * pipe['diameter']:g}): a continuum of particles much smaller than the pipe")
    if case.get("numerics", {}).get("mode", SCHEMA["numerics"]["mode"][0]) == "developing":
        from tfm.inlet import paper_inlet

        try:  # the marched pipe starts from the paper's inlet (eqs. 20-23)
            paper_inlet(gas["superficial_velocity"], solids["diameter"], solids["density"], gas["density"],
                        pipe["diameter"], solids["mass_flow"], amax)
        except ValueError as exc:
            raise ValueError(f"solids.mass_flow = {_fmt(solids['mass_flow'])}: allowed a mass flow that enters the "
                             f"developing pipe (numerics.mode) at the paper's inlet: {exc}") from None


_CHECK_UNITS = {("pipe", "diameter"): "m", ("pipe", "length"): "m", ("gas", "density"): "kg m-3",
                ("gas", "viscosity"): "Pa s", ("gas", "superficial_velocity"): "m s-1",
                ("solids", "density"): "kg m-3", ("solids", "diameter"): "m", ("solids", "mass_flow"): "kg s-1",
                ("friction", "internal_friction_angle_deg"): "degrees", ("friction", "fr"): "Pa",
                ("friction", "stiffness_over_diameter"): "Pa", ("friction", "viscosity_cap"): "Pa s",
                ("numerics", "first_step_diameters"): "D", ("numerics", "max_step_diameters"): "D"}


def check_report(case: dict, source=None) -> str:
    """``eulag check`` of a two-fluid case: every key resolved (defaults marked) and the numbers
    the run will meet — the gas Reynolds number and single-phase pressure gradient (Colebrook),
    the particles' terminal velocity, response time, Stokes and Archimedes numbers, the mass
    loading, the paper's inlet (Hinkle's solids velocity, eq. 22, and α_s, eq. 23), the mesh and,
    for a marched pipe, its stations. Raises ValueError as :func:`validate_two_fluid_case`."""
    from fluids.drag import v_terminal
    from fluids.friction import Colebrook

    from tfm.developing import axial_stations
    from tfm.inlet import hinkle_1953_solids_velocity, inlet_solids_fraction

    from eulag.config import resolved_case_lines

    c = resolved_case(case)
    rows = [(f"{sec}.{k}", c[sec][k], _CHECK_UNITS.get((sec, k), ""), k in case.get(sec, {}))
            for sec, keys in SCHEMA.items() for k in keys]
    rows += [(f"experiment.{k}", v, "", True) for k, v in c.get("experiment", {}).items()]
    lines = resolved_case_lines(c, "two-fluid", source, rows)
    p, g, s, n = c["pipe"], c["gas"], c["solids"], c["numerics"]
    D, L, rho, mu, U = p["diameter"], p["length"], g["density"], g["viscosity"], g["superficial_velocity"]
    rho_s, d_s, m_s = s["density"], s["diameter"], s["mass_flow"]
    area = math.pi * D * D / 4.0
    re = rho * U * D / mu
    f_d = Colebrook(re, 0.0)
    dpdx = f_d * rho * U * U / (2.0 * D)
    v_t = float(v_terminal(D=d_s, rhop=rho_s, rho=rho, mu=mu))
    tau = rho_s * d_s * d_s / (18.0 * mu)
    ar = rho * (rho_s - rho) * 9.80665 * d_s ** 3 / mu ** 2
    u_in = float(hinkle_1953_solids_velocity(U, d_s, rho_s, rho, D))
    lines += ["", "Gas",
              f"  Reynolds     Re = rho U_g D / mu = {re:.4g} [1]",
              f"  single phase f_D = {f_d:.4g} [1] (Colebrook, smooth): -dp/dx = {dpdx:.4g} [Pa m-1], "
              f"Delta p = {dpdx * L / 1e3:.4g} [kPa] over L = {L:g} [m]",
              "", "Solids",
              f"  terminal     v_t = {v_t:.4g} [m s-1] (fluids.drag.v_terminal); Re_p = {rho * v_t * d_s / mu:.3g} [1] "
              f"at v_t; Archimedes Ar = {ar:.4g} [1]",
              f"  tau_p        {tau:.4g} [s] (Stokes); St = tau_p U_g / D = {tau * U / D:.4g} [1]",
              f"  loading      M_s / (rho U_g A) = {m_s / (rho * U * area):.4g} [1] "
              f"(gas {rho * U * area:.4g} [kg s-1], solids {m_s:g} [kg s-1])",
              f"  inlet        Hinkle's u_s = {u_in:.4g} [m s-1] (eq. 22), alpha_s = "
              f"{float(inlet_solids_fraction(m_s, rho_s, u_in, D)):.4g} [1] (eq. 23)"]
    if "pressure_drop" in c.get("experiment", {}):
        dp = float(c["experiment"]["pressure_drop"])
        lines.append(f"  measured     Delta p = {dp / 1e3:.4g} [kPa] over the pipe ({dp / L:.4g} [Pa m-1]; "
                     f"{dp / (dpdx * L):.3g} x the gas alone)")
    wall = wall_ring_thickness(c, n["first_cell_yplus"])
    lines += ["", "Numerics",
              f"  section      {n['radial_cells']} x {n['azimuthal_cells']} cells, wall ring at y+ = "
              f"{n['first_cell_yplus']:g} "
              f"({1e3 * wall:.3g} mm thick, {wall / c['solids']['diameter']:.2f} particle diameters: Delta p depends "
              f"on it, docs/two-fluid.md); "
              f"{n['turbulence']}; at most {n['max_iterations']} outer iterations to a change of {n['tolerance']:g}"]
    if n["mode"] == "developing":
        xs = axial_stations(L, n["first_step_diameters"] * D, n["step_growth"], n["max_step_diameters"] * D)
        lines.append(f"  march        {len(xs)} stations over {L:g} m (first step {1e3 * xs[0]:.3g} mm, growth "
                     f"{n['step_growth']:g}, at most {n['max_step_diameters']:g} D), from the paper's inlet")
    else:
        lines.append(f"  mode         fully developed (the pressure gradient times L = {L:g} m gives Delta p)")
    return "\n".join(lines)


def wall_ring_thickness(case: dict, yplus: float) -> float:
    """Thickness [m] of the section's wall ring whose centre sits at ``yplus`` of the case's gas
    flow (``rans.mesh.wall_cell_thickness``, as the mesh is built)."""
    from rans.mesh import wall_cell_thickness

    pipe, gas = case["pipe"], case["gas"]
    return wall_cell_thickness(pipe["diameter"], yplus, gas["superficial_velocity"], gas["density"],
                               gas["viscosity"])[0]


def problem_from_case(case: dict):
    """A :class:`tfm.section.SectionProblem` from a (validated) case."""
    from tfm.parameters import SolidsParameters
    from tfm.section import SectionProblem

    c = resolved_case(case)
    f, w = c["friction"], c["walls"]
    params = SolidsParameters(alpha_min=f["alpha_min"], alpha_max=f["alpha_max"], e_ss=c["kinetic"]["restitution"],
                              internal_friction_angle_deg=f["internal_friction_angle_deg"], e_sw=w["restitution"],
                              mu_w=w["friction"], beta0=w["tangential_restitution"], berzi_a=f["berzi_a"],
                              fr=f["fr"], r=f["r"], s=f["s"], stiffness_over_diameter=f["stiffness_over_diameter"],
                              linearise_delta=f["linearise_delta"], mu_f_max=f["viscosity_cap"],
                              wall_law=w["law"])
    n = c["numerics"]
    return SectionProblem(diameter=c["pipe"]["diameter"], rho_g=c["gas"]["density"], mu_g=c["gas"]["viscosity"],
                          rho_s=c["solids"]["density"], d_s=c["solids"]["diameter"],
                          u_g=c["gas"]["superficial_velocity"], m_s=c["solids"]["mass_flow"], friction=f["model"],
                          params=params, mckeen_scale=c["drag"]["mckeen_scale"], drag_blend=c["drag"]["blend_width"],
                          radial_cells=n["radial_cells"], azimuthal_cells=n["azimuthal_cells"],
                          first_cell_yplus=float(n["first_cell_yplus"]), max_iterations=n["max_iterations"],
                          tolerance=n["tolerance"], turbulence=n["turbulence"])


def _flat_attrs(c: dict) -> dict:
    out = {}
    for k, v in c.items():
        if isinstance(v, dict):
            for kk, vv in v.items():
                out[f"{k}.{kk}"] = vv if not isinstance(vv, bool) else str(vv).lower()
        else:
            out[k] = v
    return out


#: the per-cell fields of a two-fluid dataset: name -> (state or closure key, units, long_name)
_FIELDS = {
    "gas_ux": ("ug", "m s-1", "axial gas velocity"),
    "solids_ux": ("us", "m s-1", "axial solids velocity"),
    "solids_fraction": ("alpha", "1", "solids volume fraction alpha_s"),
    "granular_temperature": ("theta", "m2 s-2", "granular temperature Theta"),
    "frictional_pressure": ("pf", "Pa", "solids frictional pressure p_f"),
    "frictional_viscosity": ("muf", "Pa s", "solids frictional viscosity mu_f (capped)"),
    "drag_coefficient": ("beta", "kg m-3 s-1", "gas-solid drag coefficient beta"),
    "gas_turbulent_viscosity": ("nut", "m2 s-1", "gas turbulent kinematic viscosity"),
    "solids_pressure_kinetic": ("pkin", "Pa", "kinetic-collisional solids pressure (Lun)"),
    "gas_k": ("k", "m2 s-2", "gas turbulent kinetic energy"),
    "gas_epsilon": ("eps", "m2 s-3", "gas turbulent dissipation rate"),
}


def _station_fields(st, closures) -> dict:
    """The per-cell fields of one solved section (state ``st`` and its ``closures``)."""
    src = {"ug": st.ug, "us": st.us, "alpha": st.alpha, "theta": st.theta, "k": st.k, "eps": st.eps,
           **{k: closures[k] for k in ("pf", "muf", "beta", "nut", "pkin")}}
    return {name: np.asarray(src[key], float).copy() for name, (key, _, _) in _FIELDS.items()
            if src[key] is not None}


def _dataset(case, solver, st, closures, converged, stop_reason, elapsed, march=None):
    """The dataset of a solved case.  ``march``: None for a fully developed section (one station
    at x = 0), else ``(rows, fields)`` of a developing run: per-station scalars (``x``, ``G``, …)
    and per-station cell fields (lists over the stations, as :func:`_station_fields`)."""
    import xarray as xr

    import eulag
    from eulag.output import CONVENTIONS, set_converged

    c = resolved_case(case)
    mesh = solver.mesh
    nr, nt = mesh.nr, mesh.nt
    L = c["pipe"]["length"]
    if march is None:
        xs, G, stations = np.array([0.0]), np.array([st.G]), [_station_fields(st, closures)]
        dp, dp_name = st.G * L, "-dp/dx times pipe.length"
    else:
        rows, stations = march
        xs, G = np.array([r["x"] for r in rows]), np.array([r["G"] for r in rows])
        dp, dp_name = float(np.sum(G * np.diff(np.concatenate([[0.0], xs])))), "integral of -dp/dx over the pipe"
    nx = len(xs)

    def field(name):
        _, units, long_name = _FIELDS[name]
        v = np.stack([s[name] for s in stations]).reshape(nx, nr, nt)
        return xr.Variable(("x", "r", "theta"), v, {"units": units, "long_name": long_name})

    alpha_end = stations[-1]["solids_fraction"]
    hist = np.asarray(st.history, dtype=float).reshape(-1, 4)
    data = {name: field(name) for name in _FIELDS if name in stations[0]}
    data.update({
        "pressure_gradient": xr.Variable(("x",), G, {"units": "Pa m-1", "long_name": "section-mean -dp/dx"}),
        "pressure_drop": xr.Variable((), dp, {"units": "Pa", "long_name": dp_name}),
        "capped_cells": xr.Variable((), np.int64(solver.capped), {"units": "1",
                                    "long_name": "cells whose frictional viscosity was capped at friction.viscosity_cap"}),
        "solids_holdup": xr.Variable((), float(np.sum(alpha_end * solver.A) / solver.Atot),
                                     {"units": "1", "long_name": "section-mean solids volume fraction"}),
        "solids_mass_flow": xr.Variable((), float(np.sum(alpha_end * c["solids"]["density"]
                                                        * stations[-1]["solids_ux"] * solver.A)),
                                        {"units": "kg s-1", "long_name": "solids mass flow of the solution"}),
        "residual": xr.Variable(("iteration",), hist[:, 1], {"units": "1", "long_name": "outer-iteration change"}),
    })
    if march is not None:
        rows = march[0]
        data["pressure"] = xr.Variable(("x",), -np.cumsum(G * np.diff(np.concatenate([[0.0], xs]))), {
            "units": "Pa", "long_name": "section-mean pressure relative to the inlet"})
        data["solids_holdup_x"] = xr.Variable(("x",), [r["holdup"] for r in rows], {
            "units": "1", "long_name": "section-mean solids volume fraction at each station"})
        data["solids_mass_flow_x"] = xr.Variable(("x",), [r["ms"] for r in rows], {
            "units": "kg s-1", "long_name": "solids mass flow at each station"})
        data["station_iterations"] = xr.Variable(("x",), np.array([r["it"] for r in rows], np.int64), {
            "units": "1", "long_name": "outer iterations of each station"})
        data["station_converged"] = xr.Variable(("x",), np.array([r["ok"] for r in rows], np.int8), {
            "units": "1", "long_name": "1 where the station's iterations converged"})
    coords = {
        "x": xr.Variable(("x",), xs, {"units": "m", "long_name": "axial position (fully developed)" if march is None
                                      else "axial position of the station from the inlet"}),
        "r": xr.Variable(("r",), mesh.r, {"units": "m", "long_name": "ring centre radius"}),
        "theta": xr.Variable(("theta",), mesh.theta, {"units": "rad", "long_name": "sector mid-angle (pi/2 = top)"}),
        "iteration": xr.Variable(("iteration",), hist[:, 0].astype(np.int64), {"units": "1", "long_name": "outer iteration"}),
        "y": xr.Variable(("r", "theta"), mesh.y, {"units": "m", "long_name": "vertical coordinate (up)"}),
        "z": xr.Variable(("r", "theta"), mesh.z, {"units": "m", "long_name": "horizontal coordinate"}),
        "cell_area": xr.Variable(("r", "theta"), mesh.cell_area, {"units": "m2", "long_name": "cell area"}),
        # the cell faces (eulag export): a marched station holds the step that ends at it
        "x_edge": xr.Variable(("x_edge",), np.concatenate([[0.0], xs]) if march is not None else np.array([0.0, L]),
                              {"units": "m", "long_name": "axial position of the cell faces"}),
        "r_edge": xr.Variable(("r_edge",), np.asarray(mesh.r_edges, float),
                              {"units": "m", "long_name": "radius of the ring faces (last: the wall)"}),
        "theta_edge": xr.Variable(("theta_edge",), np.asarray(mesh.theta_edges, float),
                                  {"units": "rad", "long_name": "azimuthal angle of the sector faces"}),
    }
    dp_meas = c.get("experiment", {}).get("pressure_drop")
    if isinstance(dp_meas, (int, float)) and dp_meas > 0:
        data["pressure_drop_measured"] = xr.Variable((), float(dp_meas), {
            "units": "Pa", "long_name": "measured pressure drop over the pipe (experiment.pressure_drop)"})
        data["pressure_drop_relative_error"] = xr.Variable((), dp / dp_meas - 1.0, {
            "units": "1", "long_name": "(computed - measured) / measured pressure drop"})
    title = "fully developed section" if march is None else "developing pipe"
    attrs = {"Conventions": CONVENTIONS, "title": f"two-fluid {title}: {c.get('name', '')}",
             "model": "two-fluid", "eulag_version": getattr(eulag, "__version__", "unknown"),
             "converged": "true" if converged else "false", "stop_reason": stop_reason,
             "iterations": int(st.iteration), "time_total": float(elapsed)}
    attrs.update({k: v for k, v in _flat_attrs(c).items() if k not in ("model",)})
    ds = xr.Dataset(data, coords=coords, attrs=attrs)
    set_converged(ds, converged)
    return ds




def _read_checkpoint(ck: Path, key: str):
    """The arrays of checkpoint ``ck`` when it belongs to the case ``key``, else None (an
    unreadable checkpoint counts as none: the run starts afresh and overwrites it)."""
    try:
        with np.load(ck) as d:
            if str(d["case_json"]) != key:
                return None
            return {k: d[k] for k in d.files}
    except Exception:  # noqa: BLE001 - a torn or foreign file is no checkpoint
        return None


def checkpoint_path(out: Path) -> Path:
    """The checkpoint beside the output ``out``: ``<out>.checkpoint.npz``."""
    out = Path(out)
    return out.with_name(out.name + ".checkpoint.npz")


def dataset_key(case: dict) -> str:
    """The identity of a two-fluid case's result (the dataset's ``case_json`` attribute): the
    resolved case without ``numerics.max_iterations`` (the iteration budget does not change the
    answer) and without ``[experiment]`` (reference data, not model input)."""
    c = resolved_case(case)
    same = {k: (dict(v, max_iterations=None) if k == "numerics" else v) for k, v in c.items() if k != "experiment"}
    return json.dumps(same, sort_keys=True, default=str)


def checkpoint_problem(ckpt, case: dict):
    """Why the checkpoint ``ckpt`` cannot be resumed as ``case`` (None: it can)."""
    try:
        with np.load(Path(ckpt)) as d:
            key = str(d["case_json"])
    except Exception as exc:  # noqa: BLE001 - unreadable for whatever reason
        from eulag.arguments import unreadable_archive_reason

        return f"cannot be read ({unreadable_archive_reason(exc)})"
    mine = dataset_key(case)
    if key == mine:
        return None
    from eulag.config import case_differences

    try:
        what = case_differences(json.loads(key), json.loads(mine), there="in the checkpoint")
    except (ValueError, TypeError):
        what = ""
    return "checkpoint of a different case" + (f" ({what})" if what else "")


def budget_raised(attrs: dict, case: dict) -> bool:
    """Whether ``case`` allows more outer iterations than the run stored in a dataset's attributes
    ``attrs`` had (``numerics.max_iterations`` is not part of :func:`dataset_key`): its unconverged
    result is then not the final answer of ``case``.  A fully developed run is compared by the
    iterations it did (a resumed run may have done more than its own limit), a marched pipe by
    the limit its stations had."""
    try:
        developing = attrs.get("numerics.mode") == "developing"
        stored = int(attrs["numerics.max_iterations"] if developing else attrs["iterations"])
    except (KeyError, TypeError, ValueError):
        return False
    return int(resolved_case(case)["numerics"]["max_iterations"]) > stored


def compared_cases(attrs: dict, case: dict) -> tuple[dict, dict]:
    """The stored case of a dataset's attributes ``attrs`` (``case_json``) and ``case`` as
    :func:`same_case` compares them (:func:`dataset_key`)."""
    return json.loads(attrs.get("case_json", "null")), json.loads(dataset_key(case))


def same_case(attrs: dict, case: dict) -> bool:
    """Whether a dataset's attributes ``attrs`` are those of a result of ``case`` (the cases
    :func:`compared_cases` gives are equal)."""
    try:
        stored, mine = compared_cases(attrs, case)
    except (ValueError, KeyError, TypeError):
        return False
    return stored == mine


def run_two_fluid(case: dict, out: Path | None, resume: bool = False, progress: bool = False):
    """Run a two-fluid case; return its xarray.Dataset (written to ``out`` when given).

    resume : continue from ``out``'s checkpoint (``<out>.checkpoint.npz``; fully developed: written
    every 25 iterations and at an unconverged end; developing: every
    :data:`CHECKPOINT_STATIONS` stations and at a failure or interruption) when it belongs to the
    same case (all keys but ``numerics.max_iterations`` and ``[experiment]``; a developing
    checkpoint also needs the same ``max_iterations``, so that its stations were solved alike);
    an ``out`` that already holds this finished case is returned without recomputing.
    """
    import xarray as xr

    from eulag.output import write_dataset
    from tfm.section import SectionDivergence, SectionState, _Solver

    validate_two_fluid_case(case)
    c = resolved_case(case)
    key = dataset_key(case)  # "the same case" for resume
    out = Path(out) if out is not None else None
    if resume and out is not None and out.is_file():
        with xr.open_dataset(out) as old:
            if old.attrs.get("case_json") == key and old.attrs.get("converged") == "true":
                return old.load()
    pb = problem_from_case(case)
    ck = checkpoint_path(out) if out is not None else None
    if c["numerics"]["mode"] == "developing":
        return _run_developing(case, c, pb, key, out, ck, resume, progress)
    t0 = time.perf_counter()
    solver = _Solver(pb)
    state = None
    before = 0.0  # wall time of the sessions before a resume [s]
    if resume and ck is not None and ck.is_file():
        d = _read_checkpoint(ck, key)
        if d is not None:
            state = SectionState.from_arrays(d)
            before = float(d.get("time_total", 0.0))
            if progress:
                print(f"two-fluid {c.get('name', '')}: resuming from {ck} after iteration {state.iteration}", flush=True)
    if state is None:
        state = solver.initial_state()

    def elapsed():
        return np.array(before + (time.perf_counter() - t0))

    def save(st):
        if ck is not None and st.iteration % 25 == 0:
            savez_atomic(ck, {"case_json": np.array(key), "time_total": elapsed(), **st.as_arrays()})
            if progress:
                print(f"two-fluid {c.get('name', '')}: iteration {st.iteration}, change {st.history[-1][1]:.2e}, "
                      f"-dp/dx {st.G:.1f} Pa/m", flush=True)

    try:
        st, ok, closures = solver.run(state, save)
    except SectionDivergence as exc:
        raise RuntimeError(f"two-fluid {c.get('name', '')}: {exc}") from None
    reason = ("converged" if ok else
              f"not converged: outer change {st.history[-1][1]:.3g} > numerics.tolerance {pb.tolerance:g} "
              f"after {st.iteration} iterations")
    ds = _dataset(case, solver, st, closures, ok, reason, float(elapsed()))
    ds.attrs["case_json"] = key
    if out is not None:
        write_dataset(ds, out)
        if ok and ck.is_file():
            ck.unlink()
        elif not ok:
            savez_atomic(ck, {"case_json": np.array(key), "time_total": elapsed(), **st.as_arrays()})
    return ds


#: a developing run writes its checkpoint every this many stations
CHECKPOINT_STATIONS = 10


def _run_developing(case, c, pb, key, out, ck, resume, progress):
    """``numerics.mode = "developing"``: march the pipe (:func:`tfm.developing.march_pipe`) from the
    paper's inlet over ``pipe.length``; checkpoint every :data:`CHECKPOINT_STATIONS` stations
    (the stations done, their fields and the last state) and at a failure or interruption."""
    from eulag.output import write_dataset
    from tfm.developing import march_pipe
    from tfm.section import SectionDivergence, SectionState, _Solver

    t0 = time.perf_counter()
    D, n = c["pipe"]["diameter"], c["numerics"]
    rows, fields, start = [], [], None
    before = 0.0  # wall time of the sessions before a resume [s]
    if resume and ck is not None and ck.is_file():
        d = _read_checkpoint(ck, key)
        if d is not None and "station_x" in d and int(d.get("max_iterations", -1)) == pb.max_iterations:
            before = float(d.get("time_total", 0.0))
            cols = ("x", "G", "holdup", "ms", "peak", "it", "ok")
            rows = [{k: d[f"station_{k}"][i].item() for k in cols} for i in range(len(d["station_x"]))]
            names = [str(v) for v in d["field_names"]]
            fields = [{nm: d[f"field_{nm}"][i] for nm in names} for i in range(len(rows))]
            start = (list(rows), SectionState.from_arrays(d))
            if progress:
                print(f"two-fluid {c.get('name', '')}: resuming from {ck} after station {len(rows)}", flush=True)

    def save(st):
        cols = {f"station_{k}": np.array([r[k] for r in rows]) for k in rows[0]}
        names = list(fields[0])
        arrays = {f"field_{nm}": np.stack([f[nm] for f in fields]) for nm in names}
        savez_atomic(ck, {"case_json": np.array(key), "max_iterations": np.array(pb.max_iterations),
                          "time_total": np.array(before + (time.perf_counter() - t0)),
                          "field_names": np.array(names), **cols, **arrays, **st.as_arrays()})

    done = []   # the last completed station's state (for the checkpoint of a failure)

    def station(i, x, st, row):
        rows.append(row)
        fields.append(_station_fields(st, solver.closures(st)))
        done[:] = [SectionState.from_arrays(st.as_arrays())]
        if ck is not None and len(rows) % CHECKPOINT_STATIONS == 0:
            save(st)
        if progress and len(rows) % CHECKPOINT_STATIONS == 0:
            print(f"two-fluid {c.get('name', '')}: station {len(rows)}, x = {x:.3f} m, -dp/dx {st.G:.1f} Pa/m, "
                  f"{row['it']} iterations", flush=True)

    solver = _Solver(pb)
    try:
        res = march_pipe(pb, c["pipe"]["length"], first_step=n["first_step_diameters"] * D, growth=n["step_growth"],
                         max_step=n["max_step_diameters"] * D, callback=station, start=start, solver=solver)
    except BaseException as exc:
        # a failure or an interruption: keep every completed station for --resume
        if ck is not None and done and len(fields) == len(rows):
            save(done[-1])
        if isinstance(exc, SectionDivergence):
            raise RuntimeError(f"two-fluid {c.get('name', '')}: {exc}") from None
        raise
    ok = bool(res.converged.all())
    bad = [i + 1 for i, r in enumerate(rows) if not r["ok"]]
    reason = ("converged" if ok else f"not converged: {len(bad)} of {len(rows)} stations reached "
              f"numerics.max_iterations = {pb.max_iterations} (first: station {bad[0]}, x = {rows[bad[0] - 1]['x']:.4g} m)")
    res.solver.capped = int(res.closures["ncap"])
    ds = _dataset(case, res.solver, res.state, res.closures, ok, reason, before + (time.perf_counter() - t0),
                  march=(rows, fields))
    ds.attrs["case_json"] = key
    for k, v in res.inlet.items():
        ds.attrs[f"inlet_{k}"] = v
    if out is not None:
        write_dataset(ds, out)
        if ck.is_file():
            ck.unlink()
    return ds
