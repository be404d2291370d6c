"""Two-fluid model cases (top-level ``model = "two-fluid"``): validation, run, dataset.

The run layer (:mod:`eulag.runs`) calls :func:`validate_two_fluid_case` on the parsed TOML
and :func:`run_two_fluid` to get the dataset.  The solver is :mod:`tfm.section` (fully
developed pipe cross-section); the closures are in :mod:`tfm`.

Case tables and keys (SI; the one exception is ``friction.internal_friction_angle_deg``):

    [pipe]       diameter, length (over which Δp = −dp/dx · length is reported)
    [gas]        density, viscosity, superficial_velocity
    [solids]     density, diameter, mass_flow
    [friction]   model ("dartevelle" | "srivastava-sundaresan" | "berzi" | "none"), alpha_min,
                 alpha_max, internal_friction_angle_deg, fr, r, s, berzi_a,
                 stiffness_over_diameter, linearise_delta, viscosity_cap
    [kinetic]    restitution
    [walls]      restitution, friction, tangential_restitution
    [drag]       mckeen_scale, blend_width
    [numerics]   radial_cells, azimuthal_cells, first_cell_yplus, max_iterations, tolerance,
                 turbulence ("k-epsilon" | "mixing-length")
    [experiment] optional reference values (supplementary_gas, pressure_drop, inlet_alpha_s, ...)
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

__all__ = ["validate_two_fluid_case", "run_two_fluid", "problem_from_case", "resolved_case"]

_FRICTION_MODELS = ("dartevelle", "srivastava-sundaresan", "berzi", "none")


def _num(lo=None, hi=None, lo_open=True, integer=False, even=False):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
            return False
        if not math.isfinite(v):
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
              "tangential_restitution": (0.3, _num(-1, 1, lo_open=False))},
    "drag": {"mckeen_scale": (1.0, _num(0, 100)), "blend_width": (0.02, _num(0, 0.2, lo_open=False))},
    "numerics": {"radial_cells": (16, _num(2, 400, integer=True, lo_open=False)),
                 "azimuthal_cells": (32, _num(4, 800, integer=True, lo_open=False, even=True)),
                 "first_cell_yplus": (30.0, _num(0, 1000)), "max_iterations": (400, _num(0, 1e6, integer=True)),
                 "tolerance": (1e-4, _num(0, 1)),
                 "turbulence": ("k-epsilon", _choice(("k-epsilon", "mixing-length")))},
}
_TOP = ("name", "description", "model")


def _fmt(v):
    return json.dumps(v) if isinstance(v, str) else repr(v)


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
    if "experiment" in case and not isinstance(case["experiment"], dict):
        raise ValueError(f"experiment = {_fmt(case['experiment'])}: allowed a table")


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
                              linearise_delta=f["linearise_delta"], mu_f_max=f["viscosity_cap"])
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


def _dataset(case, solver, st, closures, converged, stop_reason, elapsed):
    import xarray as xr

    import eulag
    from eulag.output import CONVENTIONS, set_converged

    c = resolved_case(case)
    mesh = solver.mesh
    nr, nt = mesh.nr, mesh.nt
    L = c["pipe"]["length"]

    def field(v, units, long_name):
        return xr.Variable(("x", "r", "theta"), np.asarray(v, float).reshape(1, nr, nt), {"units": units,
                                                                                          "long_name": long_name})

    pf, muf = closures["pf"], closures["muf"]
    hist = np.asarray(st.history, dtype=float).reshape(-1, 4)
    data = {
        "gas_ux": field(st.ug, "m s-1", "axial gas velocity"),
        "solids_ux": field(st.us, "m s-1", "axial solids velocity"),
        "solids_fraction": field(st.alpha, "1", "solids volume fraction alpha_s"),
        "granular_temperature": field(st.theta, "m2 s-2", "granular temperature Theta"),
        "frictional_pressure": field(pf, "Pa", "solids frictional pressure p_f"),
        "frictional_viscosity": field(muf, "Pa s", "solids frictional viscosity mu_f (capped)"),
        "drag_coefficient": field(closures["beta"], "kg m-3 s-1", "gas-solid drag coefficient beta"),
        "gas_turbulent_viscosity": field(closures["nut"], "m2 s-1", "gas turbulent kinematic viscosity"),
        "solids_pressure_kinetic": field(closures["pkin"], "Pa", "kinetic-collisional solids pressure (Lun)"),
        "pressure_gradient": xr.Variable(("x",), [st.G], {"units": "Pa m-1", "long_name": "section-mean -dp/dx"}),
        "pressure_drop": xr.Variable((), st.G * L, {"units": "Pa", "long_name": "-dp/dx times pipe.length"}),
        "capped_cells": xr.Variable((), np.int64(solver.capped), {"units": "1",
                                    "long_name": "cells whose frictional viscosity was capped at friction.viscosity_cap"}),
        "solids_holdup": xr.Variable((), float(np.sum(st.alpha * solver.A) / solver.Atot),
                                     {"units": "1", "long_name": "section-mean solids volume fraction"}),
        "solids_mass_flow": xr.Variable((), float(np.sum(st.alpha * c["solids"]["density"] * st.us * solver.A)),
                                        {"units": "kg s-1", "long_name": "solids mass flow of the solution"}),
        "residual": xr.Variable(("iteration",), hist[:, 1], {"units": "1", "long_name": "outer-iteration change"}),
    }
    coords = {
        "x": xr.Variable(("x",), [0.0], {"units": "m", "long_name": "axial position (fully developed)"}),
        "r": xr.Variable(("r",), mesh.r, {"units": "m", "long_name": "ring centre radius"}),
        "theta": xr.Variable(("theta",), mesh.theta, {"units": "rad", "long_name": "sector mid-angle (pi/2 = top)"}),
        "iteration": xr.Variable(("iteration",), hist[:, 0].astype(np.int64), {"units": "1", "long_name": "outer iteration"}),
        "y": xr.Variable(("r", "theta"), mesh.y, {"units": "m", "long_name": "vertical coordinate (up)"}),
        "z": xr.Variable(("r", "theta"), mesh.z, {"units": "m", "long_name": "horizontal coordinate"}),
        "cell_area": xr.Variable(("r", "theta"), mesh.cell_area, {"units": "m2", "long_name": "cell area"}),
    }
    dp_meas = c.get("experiment", {}).get("pressure_drop")
    if isinstance(dp_meas, (int, float)) and dp_meas > 0:
        data["pressure_drop_measured"] = xr.Variable((), float(dp_meas), {
            "units": "Pa", "long_name": "measured pressure drop over the pipe (experiment.pressure_drop)"})
        data["pressure_drop_relative_error"] = xr.Variable((), st.G * L / dp_meas - 1.0, {
            "units": "1", "long_name": "(computed - measured) / measured pressure drop"})
    if st.k is not None:
        data["gas_k"] = field(st.k, "m2 s-2", "gas turbulent kinetic energy")
        data["gas_epsilon"] = field(st.eps, "m2 s-3", "gas turbulent dissipation rate")
    attrs = {"Conventions": CONVENTIONS, "title": f"two-fluid fully developed section: {c.get('name', '')}",
             "model": "two-fluid", "eulag_version": getattr(eulag, "__version__", "unknown"),
             "converged": "true" if converged else "false", "stop_reason": stop_reason,
             "iterations": int(st.iteration), "time_total": float(elapsed)}
    attrs.update({k: v for k, v in _flat_attrs(c).items() if k not in ("model",)})
    ds = xr.Dataset(data, coords=coords, attrs=attrs)
    set_converged(ds, converged)
    return ds


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
        return f"cannot be read ({' '.join(str(exc).split())})"
    return None if key == dataset_key(case) else "checkpoint of a different case"


def same_case(attrs: dict, case: dict) -> bool:
    """Whether a dataset's attributes ``attrs`` are those of a result of ``case``."""
    try:
        return attrs.get("case_json") == dataset_key(case)
    except (ValueError, KeyError, TypeError):
        return False


def run_two_fluid(case: dict, out: Path | None, resume: bool = False, progress: bool = False):
    """Run a two-fluid case; return its xarray.Dataset (written to ``out`` when given).

    resume : continue from ``out``'s checkpoint (``<out>.checkpoint.npz``, written every 25
    iterations and at an unconverged end) when it belongs to the same case (all keys but
    ``numerics.max_iterations`` and ``[experiment]``); an ``out`` that already holds this finished
    case is returned without recomputing.
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
    solver = _Solver(pb)
    state = None
    ck = checkpoint_path(out) if out is not None else None
    if resume and ck is not None and ck.is_file():
        with np.load(ck) as d:
            if str(d["case_json"]) == key:
                state = SectionState.from_arrays(d)
    if state is None:
        state = solver.initial_state()

    def save(st):
        if ck is not None and st.iteration % 25 == 0:
            np.savez(ck, case_json=np.array(key), **st.as_arrays())
            if progress:
                print(f"two-fluid {c.get('name', '')}: iteration {st.iteration}, change {st.history[-1][1]:.2e}, "
                      f"-dp/dx {st.G:.1f} Pa/m", flush=True)

    t0 = time.perf_counter()
    try:
        st, ok, closures = solver.run(state, save)
    except SectionDivergence as exc:
        raise RuntimeError(f"two-fluid {c.get('name', '')}: {exc}") from None
    reason = ("converged" if ok else
              f"not converged: outer change {st.history[-1][1]:.3g} > numerics.tolerance {pb.tolerance:g} "
              f"after {st.iteration} iterations")
    ds = _dataset(case, solver, st, closures, ok, reason, time.perf_counter() - t0)
    ds.attrs["case_json"] = key
    if out is not None:
        write_dataset(ds, out)
        if ok and ck.is_file():
            ck.unlink()
        elif not ok:
            np.savez(ck, case_json=np.array(key), **st.as_arrays())
    return ds
