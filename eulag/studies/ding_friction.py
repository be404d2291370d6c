"""The frictional-stress study of the dense-phase two-fluid model (``eulag study ding-friction``).

Ding, Zhou, Tang, Xiao & Zhou (2024), "Influence of Frictional Stress Models on Simulation
Results of High-Pressure Dense-Phase Pneumatic Conveying in Horizontal Pipe", Appl. Sci. 14,
2031 (https://doi.org/10.3390/app14052031), ran the five operating points of their Table 1
with three frictional-stress models.  This study runs the same matrix through the run layer
(:func:`eulag.runs.execute` on the cases ``cases/two_fluid/ding_qs{0.4,...,1.2}.toml``, the
friction model changed in the case data) with the fully developed cross-section solver
(:mod:`tfm.section`), and writes:

* the table: Q_s, U_g, M_s, model, Δp over the 2.4 m pipe, the measured Δp where the case has
  it, the deposit's peak α_s and area, the capped cells, the solids wall force over the solids
  weight, convergence and run time;
* the paper's statements (Figs. 3, 6, 8; Table 5) checked against the rows;
* a grid-convergence table after the paper's Table 5 (Q_s = 0.8, each model, three meshes);
* the sensitivity of Δp to the inputs the paper does not give (full mode: Berzi, Q_s = 0.8);
* the force balance of the section (G A = gas wall force + solids wall force, the latter
  split into the collisional and the frictional term of the wall condition, eq. 24);
* the developing pipe (``numerics.mode = "developing"``, :mod:`tfm.developing`): every rate and
  model marched over the 2.4 m from the paper's inlet (eqs. 20–23), beside the developed section
  (quick mode: Berzi at Q_s = 0.8 only);
* figures after Fig. 3 (Δp against Q_s and U_g), Figs. 5-6 (α_s sections and vertical
  profiles), Fig. 7 (p_f(α_s) of the three models and Johnson-Jackson, from the closures),
  Figs. 8-9 (p_f and τ_f = μ_f |∇u_s| along the vertical diameter) and Fig. 10 (u_g, u_s, k_g,
  Θ, α_s along the vertical diameter at Q_s = 0.8).

Runs follow the studies' habits (:mod:`eulag.studies.runner`): one dataset ``<run>.nc`` per run
and a run record ``<run>.record.json`` (what the table and figures take from the dataset, so
that ``--resume`` / ``--report`` work from records alone); ``--resume`` reuses a dataset of the
same case data, a record of the same case data and record version, or a failed record
(``<run>.failed.json``); a failing run is one line in the table and never stops the study.

``--quick``: Q_s = 0.8 only, the three models on an 8 x 16 mesh and a grid table on 6 x 12,
8 x 16 and 10 x 20 (no sensitivity runs); seconds, not results.
"""

from __future__ import annotations

import copy
import math
import time
from pathlib import Path

import numpy as np

from eulag.config import CASES_DIR

from .report import Column, _figure, draw_figures, machine_info, markdown_table, write_csv
from .runner import RunRecord, _BadInput, _finish, _log, refuse_report_of_nothing, run_case

STUDY = "ding-friction"
MODELS = ("dartevelle", "srivastava-sundaresan", "berzi")
LABELS = {"dartevelle": "Dartevelle", "srivastava-sundaresan": "Srivastava-Sundaresan", "berzi": "modified Berzi"}
SHORT = {"dartevelle": "D", "srivastava-sundaresan": "S", "berzi": "B"}
RATES = ("0.4", "0.6", "0.8", "1.0", "1.2")
CASE_DIR = CASES_DIR / "two_fluid"
#: mesh of the matrix (radial x azimuthal cells; the cases' own), and the three meshes of the grid table
GRID = (16, 32)
GRIDS = ((16, 32), (24, 48), (32, 64))
QUICK_GRID = (8, 16)
QUICK_GRIDS = ((6, 12), (8, 16), (10, 20))
#: The paper's Table 5 (modified Berzi, Q_s = 0.8 m3/h, 3-D meshes): name, inlet cells, axial size [mm],
#: total cells, simulated Δp [kPa]; measured 4.26 kPa.
PAPER_TABLE5 = (("A", 180, 2.0, 216_000, 3.77), ("B", 288, 1.5, 460_800, 3.91),
                ("C", 420, 1.25, 806_400, 4.06), ("D", 576, 1.0, 1_382_400, 4.09))
PAPER_DP_MEASURED = 4.26  # kPa, Q_s = 0.8 (Table 5)

#: Inputs the paper leaves out (and two it gives), Berzi at Q_s = 0.8: (label, section, key, values, note)
SENSITIVITY = (
    ("pipe diameter D [mm]", "pipe", "diameter", (0.0092, 0.011), 1e3, "inferred: 10 mm"),
    ("coal size d_s [µm]", "solids", "diameter", (140e-6, 190e-6), 1e6, "inferred: 160 µm (Hinkle, eq. 22)"),
    ("coal density ρ_s [kg/m³]", "solids", "density", (1400.0, 1900.0), 1.0, "inferred: 1650 kg/m³ (eq. 23)"),
    ("k_n/d_s [MPa]", "friction", "stiffness_over_diameter", (3.0e6, 6.5e6), 1e-6,
     "not given: 4.5 MPa (Fig. 7 ordering holds for 3-6.5)"),
    ("McKeen C [-]", "drag", "mckeen_scale", (0.5, 2.0), 1.0, "not given: 1"),
    ("gas turbulence", "numerics", "turbulence", ("mixing-length",), None, "stated deviation: k-ε"),
    ("wall friction μ_w [-]", "walls", "friction", (0.3,), 1.0,
     "Table 4: 0.5 (shown to locate the Δp gap; not used)"),
    ("wall cell: y+ of its centre (its thickness in d_s)", "numerics", "first_cell_yplus", (60.0, 100.0, 170.0),
     1.0, "not given: y+ 30 (0.68 d_s); the paper's Mesh C cells average ≈ 0.43 mm (inferred D), "
          "a wall cell that thick ≈ y+ 115"),
)

PROFILE_FIELDS = ("solids_fraction", "gas_ux", "solids_ux", "gas_k", "granular_temperature",
                  "frictional_pressure", "frictional_shear")


# ---------------------------------------------------------------------------- cases
def _load(rate: str):
    from eulag import runs

    try:
        return runs.load_case(CASE_DIR / f"ding_qs{rate}.toml")
    except runs.RunError as exc:
        raise _BadInput(str(exc)) from None


def _variant(base, name: str, *, model: str | None = None, grid=None, changes=()):
    """``base`` (a :class:`eulag.runs.ModelCase`) as run ``name``: friction ``model``, mesh ``grid``
    (radial, azimuthal cells), further ``changes`` ((section, key, value), ...); validated."""
    from eulag.runs import ModelCase
    from eulag.two_fluid import validate_two_fluid_case

    data = copy.deepcopy(base.data)
    data["name"] = name
    if model is not None:
        data.setdefault("friction", {})["model"] = model
    if grid is not None:
        data.setdefault("numerics", {}).update(radial_cells=grid[0], azimuthal_cells=grid[1])
    for sec, key, value in changes:
        data.setdefault(sec, {})[key] = value
    try:
        validate_two_fluid_case(data)
    except ValueError as exc:
        raise _BadInput(" ".join(str(exc).split())) from None
    return ModelCase(base.model, name, data, base.source)


def _grid_text(grid) -> str:
    return f"{grid[0]}x{grid[1]}"


def study_cases(quick: bool, models=MODELS, rates=None, sensitivity: bool | None = None, developing: bool = True):
    """The study's runs: a dict name -> (kind, info, ModelCase), kind "matrix" | "grid" |
    "sensitivity" | "developing".

    matrix: every rate x model on the matrix mesh; grid: Q_s = 0.8, each model, three meshes (the
    matrix run where the mesh is the same); ``rates`` None: Q_s = 0.8 in quick mode, all five
    otherwise; sensitivity (full mode): Berzi at Q_s = 0.8 with one
    input changed at a time; developing: the matrix runs marched from the paper's inlet (quick
    mode: Berzi at Q_s = 0.8).
    """
    grid, grids = (QUICK_GRID, QUICK_GRIDS) if quick else (GRID, GRIDS)
    rates = tuple(rates) if rates else (("0.8",) if quick else RATES)
    sensitivity = (not quick) if sensitivity is None else sensitivity
    out: dict = {}
    bases = {r: _load(r) for r in sorted(set(rates) | {"0.8"})}
    for r in rates:
        for m in models:
            name = f"ding_qs{r}__{m}__{_grid_text(grid)}"
            out[name] = ("matrix", {"rate": r, "model": m, "grid": grid},
                         _variant(bases[r], name, model=m, grid=grid))
    for m in models:
        for g in grids:
            name = f"ding_qs0.8__{m}__{_grid_text(g)}"
            if name not in out:
                out[name] = ("grid", {"rate": "0.8", "model": m, "grid": g},
                             _variant(bases["0.8"], name, model=m, grid=g))
    if sensitivity:
        for label, sec, key, values, scale, _ in SENSITIVITY:
            for v in values:
                tag = f"{key}-{v:g}" if isinstance(v, float) else f"{key}-{v}"
                name = f"ding_qs0.8__berzi__{_grid_text(grid)}__{tag}"
                out[name] = ("sensitivity", {"rate": "0.8", "model": "berzi", "grid": grid, "label": label,
                                             "section": sec, "key": key, "value": v, "scale": scale},
                             _variant(bases["0.8"], name, model="berzi", grid=grid, changes=[(sec, key, v)]))
    if developing:
        for r in rates:
            for m in models:
                if quick and (m != "berzi" or r != "0.8"):
                    continue
                name = f"ding_qs{r}__{m}__{_grid_text(grid)}__developing"
                out[name] = ("developing", {"rate": r, "model": m, "grid": grid},
                             _variant(bases[r], name, model=m, grid=grid, changes=[("numerics", "mode", "developing")]))
    return out


# ---------------------------------------------------------------------------- running one case
def _extractor(args, label: str, case):
    """The study's metrics of a finished two-fluid dataset (:func:`extract_metrics`), for
    :func:`eulag.studies.runner.run_case`; a metric that fails is recorded, never loses the row."""
    def extract(ds, rec: RunRecord) -> dict:
        try:
            metrics = extract_metrics(ds, case)
        except Exception as exc:  # noqa: BLE001 - a metric must not lose the row
            metrics = {"extract_error": f"{type(exc).__name__}: {exc}"}
        _log(args, f"  {label}: Δp {metrics.get('dp', math.nan) / 1e3:.3f} kPa")
        return metrics
    return extract


# ---------------------------------------------------------------------------- metrics
def _vertical(field2d: np.ndarray, r: np.ndarray, theta: np.ndarray, radius: float):
    """Values along the vertical diameter (interpolated in θ between the sectors beside it):
    (height above the bottom / D, values), bottom to top."""
    th = np.concatenate([theta - 2 * np.pi, theta, theta + 2 * np.pi])
    f3 = np.concatenate([field2d, field2d, field2d], axis=1)

    def at(angle):
        return np.array([np.interp(angle, th, f3[j]) for j in range(len(r))])

    h = np.concatenate([(radius - r[::-1]), radius + r]) / (2 * radius)
    return h, np.concatenate([at(1.5 * np.pi)[::-1], at(0.5 * np.pi)])


def _reconstruct(ds, case):
    """The solver's closures and wall forces at the dataset's (converged) state."""
    from tfm.section import SectionState, _Solver
    from eulag.two_fluid import problem_from_case

    pb = problem_from_case(case.data)
    s = _Solver(pb)

    def flat(v):
        return np.asarray(ds[v].values, float).reshape(-1)

    st = SectionState(alpha=flat("solids_fraction"), ug=flat("gas_ux"), us=flat("solids_ux"),
                      theta=flat("granular_temperature"), G=float(ds["pressure_gradient"].values[0]),
                      k=flat("gas_k") if "gas_k" in ds else None, eps=flat("gas_epsilon") if "gas_epsilon" in ds else None)
    c = s.closures(st)
    s.momentum(st, c)
    return s, st, c


def extract_metrics(ds, case) -> dict:
    """What the table and figures take from a finished two-fluid dataset."""
    from tfm.wall import schneiderbauer_wall_shear

    d = case.data
    # the section at the end of the pipe (a developed run has one station)
    alpha = np.asarray(ds["solids_fraction"].values, float)[-1]
    area = np.asarray(ds["cell_area"].values, float)
    amin = float(d.get("friction", {}).get("alpha_min", 0.4))
    dp = float(ds["pressure_drop"].values)
    developing = ds.attrs.get("numerics.mode") == "developing"
    m = {"dp": dp, "dpdx": float(ds["pressure_gradient"].values[-1]),
         "peak_alpha": float(alpha.max()), "deposit_area": float(area[alpha > amin].sum() / area.sum()),
         "holdup": float(ds["solids_holdup"].values), "capped": int(ds["capped_cells"].values),
         "mass_flow_solution": float(ds["solids_mass_flow"].values)}
    r, theta = np.asarray(ds["r"].values), np.asarray(ds["theta"].values)
    R = 0.5 * float(d["pipe"]["diameter"])
    fields = {k: np.asarray(ds[k].values, float)[-1] for k in PROFILE_FIELDS if k in ds}
    if developing:
        m.update(_development_metrics(ds, d))
    # force balance and τ_f from the solver's closures at this state (a fully developed section)
    try:
        if developing:
            raise _NotDeveloped

        s, st, c = _reconstruct(ds, case)
        w, arc = s.sec.wall, s.sec.wall_arc
        gas_wall = float(np.sum(s.hg * st.ug[w] * arc))
        sol_wall = float(np.sum(s.hs * st.us[w] * arc))
        P, pb = s.pb.params, s.pb
        usw = np.where(st.us[w] == 0.0, 1e-6, st.us[w])
        coll = float(np.sum(np.abs(schneiderbauer_wall_shear(usw, c["a"][w], pb.rho_s, c["g0"][w], st.theta[w],
                                                             0.0, P.e_sw, P.mu_w, P.beta0)) * arc))
        fric = float(np.sum(P.mu_w * c["pf"][w] * arc))
        weight = float(np.sum(st.alpha * (pb.rho_s - pb.rho_g) * 9.80665 * s.A))
        GA = st.G * s.Atot
        m.update(gas_wall_share=gas_wall / GA, solids_wall_share=sol_wall / GA, solids_wall_over_weight=sol_wall / weight,
                 collisional_wall_over_weight=coll / weight, frictional_wall_over_weight=fric / weight)
        nr, nt = len(r), len(theta)
        fields["frictional_shear"] = (c["muf"] * np.sqrt(c["gus2"])).reshape(nr, nt)
    except _NotDeveloped:
        pass
    except Exception as exc:  # noqa: BLE001 - the force balance is a diagnostic; keep the row
        m["force_balance_error"] = f"{type(exc).__name__}: {exc}"
    prof = {}
    for k, f in fields.items():
        h, v = _vertical(f, r, theta, R)
        prof["h"], prof[k] = _short(h), _short(v)
    m["profiles"] = prof
    m["section"] = {"z": _short(np.asarray(ds["z"].values, float).reshape(-1) / R),
                    "y": _short(np.asarray(ds["y"].values, float).reshape(-1) / R), "alpha": _short(alpha.reshape(-1))}
    return m


class _NotDeveloped(Exception):
    """The section force balance applies to a fully developed section only."""


def _development_metrics(ds, d) -> dict:
    """What a developing run adds: Δp over the second half of the pipe (developed in the paper from
    L = 120 D on) and over the first 0.3 m, −dp/dx at the end, the mean solids velocity at the inlet
    (Hinkle) and at the end, the momentum flux that accelerating the solids costs, M_s Δu_s / A, and
    Δp(x), holdup(x) for the figure."""
    x = np.asarray(ds["x"].values, float)
    p = -np.asarray(ds["pressure"].values, float)          # Δp from the inlet
    L = float(x[-1])
    rho_s, ms = float(d["solids"]["density"]), float(d["solids"]["mass_flow"])
    area = float(np.sum(ds["cell_area"].values))    # the section of the holdup's mean
    hold = np.asarray(ds["solids_holdup_x"].values, float)
    us_end = ms / (rho_s * area * hold[-1])
    us_in = float(ds.attrs.get("inlet_solids_velocity", math.nan))

    def dp_to(xx):
        return float(np.interp(xx, np.concatenate([[0.0], x]), np.concatenate([[0.0], p])))

    return {"dp_second_half": dp_to(L) - dp_to(0.5 * L), "dp_first_03m": dp_to(min(0.3, L)),
            "inlet_solids_velocity": us_in, "end_solids_velocity": us_end,
            "acceleration_kPa": ms * (us_end - us_in) / area / 1e3,
            "inlet_alpha": float(ds.attrs.get("inlet_alpha_s", math.nan)),
            "stations": int(len(x)), "x": _short(x), "dp_x": _short(p), "holdup_x": _short(hold)}


def _short(v: np.ndarray) -> np.ndarray:
    """``v`` to 5 significant digits (what the figures need; keeps the records small)."""
    return np.array([float(f"{x:.5g}") for x in np.asarray(v, float).reshape(-1)])


# ---------------------------------------------------------------------------- the study
def _parse_list(text, allowed, what, option):
    if text is None:
        return list(allowed)
    wanted = [w.strip() for w in text.split(",") if w.strip()]
    bad = [w for w in wanted if w not in allowed]
    if bad or not wanted:
        raise _BadInput(f"{option} {text}: unknown {what} {', '.join(bad) or '(none given)'}; "
                        f"allowed: a comma-separated list of {', '.join(allowed)}")
    return [a for a in allowed if a in wanted]


def study_ding_friction(args, outdir: Path, t_start: float) -> int:
    models = _parse_list(getattr(args, "only", None), MODELS, "friction models", "--only")
    rates = _parse_list(getattr(args, "rates", None), RATES, "supplementary gas rates", "--rates") \
        if getattr(args, "rates", None) is not None else None
    quick = bool(args.quick)
    plan = study_cases(quick, models, rates)
    records = {}
    for i, (name, (kind, info, case)) in enumerate(plan.items(), 1):
        label = f"[{STUDY} {i}/{len(plan)}] {name}"
        records[name] = run_case(args, name, case, outdir, label, _extractor(args, label, case))
    refuse_report_of_nothing(args, records.values(), outdir)
    rows = [_row(info, case, records[name]) for name, (kind, info, case) in plan.items() if kind == "matrix"]
    grid_rows = _grid_rows(plan, records)
    sens_rows = _sensitivity_rows(plan, records)
    dev_rows = _developing_rows(plan, records)
    figures = _figures(outdir, plan, records, quick)
    _write_readme(outdir, args, rows, grid_rows, sens_rows, plan, records, figures, t_start, dev_rows)
    return _finish(args, outdir, list(records.values()), allowed_failures=False)


def _status(rec: RunRecord) -> str:
    if rec.status == "converged":
        return "yes"
    return f"{rec.status}: {rec.message}" if rec.message else rec.status


def _row(info, case, rec: RunRecord) -> dict:
    d, m = case.data, rec.metrics
    meas = d.get("experiment", {}).get("pressure_drop")
    dp = m.get("dp")
    return {"Q_s": float(info["rate"]), "U_g": float(d["gas"]["superficial_velocity"]),
            "M_s": float(d["solids"]["mass_flow"]), "model": info["model"],
            "mesh": _grid_text(info["grid"]), "dp_kPa": dp / 1e3 if dp is not None else None,
            "dp_measured_kPa": meas / 1e3 if meas else None,
            "dp_error": (dp / meas - 1.0) * 100 if (meas and dp is not None) else None,
            "peak_alpha": m.get("peak_alpha"), "deposit_area": m.get("deposit_area"),
            "holdup": m.get("holdup"), "capped": m.get("capped"),
            "wall_over_weight": m.get("solids_wall_over_weight"),
            "converged": _status(rec), "iterations": rec.passes or None, "time_s": rec.time,
            "commit": m.get("commit")}


COLUMNS = [Column("Q_s", "Q_s [m³/h]", "{:.1f}"), Column("U_g", "U_g [m/s]", "{:.2f}"),
           Column("M_s", "M_s [kg/s]", "{:.3f}"), Column("model", "friction model"), Column("mesh", "mesh"),
           Column("dp_kPa", "Δp [kPa]", "{:.2f}"), Column("dp_measured_kPa", "measured Δp [kPa]", "{:.2f}"),
           Column("dp_error", "error [%]", "{:+.0f}"),
           Column("peak_alpha", "deposit peak α_s", "{:.3f}"), Column("deposit_area", "deposit area (α_s > α_min)", "{:.2f}"),
           Column("holdup", "mean α_s", "{:.3f}"), Column("capped", "capped cells", "{:d}"),
           Column("wall_over_weight", "solids wall force / weight", "{:.2f}"),
           Column("converged", "converged"), Column("iterations", "iterations", "{:d}"),
           Column("time_s", "run time [s]", "{:.1f}"), Column("commit", "commit")]


def _grid_rows(plan, records) -> list[dict]:
    rows = []
    for m in MODELS:
        runs_ = [(info, records[n]) for n, (k, info, c) in plan.items()
                 if info["model"] == m and info["rate"] == "0.8" and k in ("matrix", "grid")]
        runs_.sort(key=lambda t: t[0]["grid"][0])
        prev = None
        for info, rec in runs_:
            dp = rec.metrics.get("dp")
            g = info["grid"]
            rows.append({"model": m, "mesh": _grid_text(g), "cells": g[0] * g[1],
                         "dp_kPa": dp / 1e3 if dp is not None else None,
                         "change": (dp - prev) / 1e3 if (dp is not None and prev is not None) else None,
                         "error": (dp / 1e3 / PAPER_DP_MEASURED - 1) * 100 if dp is not None else None,
                         "peak_alpha": rec.metrics.get("peak_alpha"), "converged": _status(rec),
                         "time_s": rec.time})
            prev = dp
    return rows


GRID_COLUMNS = [Column("model", "friction model"), Column("mesh", "mesh (radial x azimuthal)"),
                Column("cells", "cells", "{:d}"), Column("dp_kPa", "Δp [kPa]", "{:.3f}"),
                Column("change", "change from the coarser [kPa]", "{:+.3f}"),
                Column("error", "vs measured 4.26 kPa [%]", "{:+.0f}"),
                Column("peak_alpha", "deposit peak α_s", "{:.3f}"), Column("converged", "converged"),
                Column("time_s", "run time [s]", "{:.1f}")]


def _sensitivity_rows(plan, records) -> list[dict]:
    base = next((records[n] for n, (k, info, c) in plan.items()
                 if k == "matrix" and info["model"] == "berzi" and info["rate"] == "0.8"), None)
    base_dp = base.metrics.get("dp") if base is not None else None
    notes = {label: note for label, *_, note in SENSITIVITY}
    rows = []
    for n, (k, info, c) in plan.items():
        if k != "sensitivity":
            continue
        dp = records[n].metrics.get("dp")
        v, scale = info["value"], info["scale"]
        value = f"{v * scale:g}" if scale else str(v)
        if info["key"] == "first_cell_yplus":
            from eulag.two_fluid import wall_ring_thickness

            value += f" ({wall_ring_thickness(c.data, v) / c.data['solids']['diameter']:.2f} d_s)"
        rows.append({"input": info["label"], "value": value,
                     "note": notes[info["label"]], "dp_kPa": dp / 1e3 if dp is not None else None,
                     "change": (dp / base_dp - 1) * 100 if (dp is not None and base_dp) else None,
                     "peak_alpha": records[n].metrics.get("peak_alpha"),
                     "converged": _status(records[n])})
    return rows


def _developing_rows(plan, records) -> list[dict]:
    mx = _matrix(plan, records)
    rows = []
    for n, (k, info, c) in plan.items():
        if k != "developing":
            continue
        m = records[n].metrics
        dp = m.get("dp")
        dev = mx.get((info["rate"], info["model"]), {})
        full = dev.get("dp")
        rows.append({"Q_s": float(info["rate"]), "model": info["model"],
                     "dp_kPa": dp / 1e3 if dp is not None else None,
                     "dp_error": (dp / 1e3 / PAPER_DP_MEASURED - 1) * 100 if (dp is not None and info["rate"] == "0.8")
                     else None,
                     "dp_full_kPa": full / 1e3 if full is not None else None,
                     "first": m["dp_first_03m"] / 1e3 if "dp_first_03m" in m else None,
                     "second_half": 2 * m["dp_second_half"] / 1e3 if "dp_second_half" in m else None,
                     "end_ratio": m["dpdx"] / dev["dpdx"] if ("dpdx" in m and dev.get("dpdx")) else None,
                     "alpha_in": m.get("inlet_alpha"), "us_in": m.get("inlet_solids_velocity"),
                     "us_end": m.get("end_solids_velocity"), "accel": m.get("acceleration_kPa"),
                     "converged": _status(records[n]), "time_s": records[n].time})
    return rows


DEV_COLUMNS = [Column("Q_s", "Q_s [m³/h]", "{:.1f}"), Column("model", "friction model"),
               Column("dp_kPa", "Δp developing, 0-2.4 m [kPa]", "{:.2f}"),
               Column("dp_error", "vs measured 4.26 kPa [%]", "{:+.0f}"),
               Column("dp_full_kPa", "Δp fully developed section [kPa]", "{:.2f}"),
               Column("first", "Δp over the first 0.3 m [kPa]", "{:.2f}"),
               Column("second_half", "2 × Δp over 1.2-2.4 m [kPa]", "{:.2f}"),
               Column("end_ratio", "−dp/dx at 2.4 m / developed", "{:.3f}"),
               Column("alpha_in", "inlet α_s (eq. 23)", "{:.3f}"),
               Column("us_in", "inlet u_s (Hinkle) [m/s]", "{:.2f}"),
               Column("us_end", "mean u_s at 2.4 m [m/s]", "{:.2f}"),
               Column("accel", "M_s Δu_s / A [kPa]", "{:.2f}"),
               Column("converged", "converged"), Column("time_s", "run time [s]", "{:.1f}")]


SENS_COLUMNS = [Column("input", "input"), Column("value", "value"), Column("note", "the case's value"),
                Column("dp_kPa", "Δp [kPa]", "{:.2f}"), Column("change", "vs base [%]", "{:+.1f}"),
                Column("peak_alpha", "deposit peak α_s", "{:.3f}"), Column("converged", "converged")]


# ---------------------------------------------------------------------------- the paper's statements
def _matrix(plan, records):
    """{(rate, model): metrics} of the finished matrix runs."""
    return {(info["rate"], info["model"]): records[n].metrics for n, (k, info, c) in plan.items()
            if k == "matrix" and records[n].ok and "dp" in records[n].metrics}


def _order(values: dict) -> str:
    return " > ".join(SHORT[m] for m in sorted(values, key=lambda m: -values[m]))


def statements(plan, records) -> list[dict]:
    """The paper's statements and what the matrix gives (computed from the rows)."""
    mx = _matrix(plan, records)
    rates = sorted({r for r, _ in mx}, key=float)
    models = [m for m in MODELS if any((r, m) in mx for r in rates)]
    out = []
    if not mx:
        return out
    # Δp against Q_s: falls then rises; the models' order (the developed section, then the pipe
    # developing from the paper's inlet)
    dev = _developing(plan, records)
    shape, dshape = _shape(mx, rates, models), _shape(dev, rates, models)
    if shape:
        out.append({"figure": "Fig. 3", "paper": "Δp first falls, then rises as Q_s rises (minimum near Q_s = 0.8)",
                    "here": shape + (f" — developing pipe: {dshape}" if dshape else "")})
    if ("0.8", "berzi") in mx:
        e = mx[("0.8", "berzi")]["dp"] / 1e3 / PAPER_DP_MEASURED - 1
        out.append({"figure": "Table 5", "paper": "Berzi, Q_s = 0.8: 3.77-4.09 kPa on meshes A-D, measured 4.26 kPa "
                    "(relative errors of all models -4.9 % to +7.6 %)",
                    "here": f"{mx[('0.8', 'berzi')]['dp'] / 1e3:.2f} kPa ({e * 100:+.0f} %)"
                            + (f" — developing pipe: {dev[('0.8', 'berzi')]['dp'] / 1e3:.2f} kPa "
                               f"({(dev[('0.8', 'berzi')]['dp'] / 1e3 / PAPER_DP_MEASURED - 1) * 100:+.0f} %)"
                               if ("0.8", "berzi") in dev else "")})
    per, dper = _ordering(mx, rates, models), _ordering(dev, rates, models)
    if per:
        out.append({"figure": "Fig. 3", "paper": "Δp: Dartevelle (D) highest and Berzi (B) lowest for Q_s ≤ 0.8; "
                    "B highest above 0.8; the spread shrinks as Q_s rises",
                    "here": per + (f" — developing pipe: {dper}" if dper else "")})
    dep = []
    for m in models:
        a = [mx[(r, m)]["deposit_area"] for r in rates if (r, m) in mx]
        if len(a) >= 2:
            mono = all(x > y for x, y in zip(a, a[1:]))
            dep.append(f"{SHORT[m]}: " + ", ".join(f"{x:.2f}" for x in a) + (" (falls)" if mono else " (not monotone)"))
    if dep:
        out.append({"figure": "Figs. 5-6", "paper": "the deposit thins as Q_s rises",
                    "here": "deposit area fraction (α_s > α_min) by Q_s: " + "; ".join(dep)})
    peak = max(v["peak_alpha"] for v in mx.values())
    out.append({"figure": "Fig. 6", "paper": "α_s in the deposit stays below the bulk packing ≈ 0.5",
                "here": f"largest deposit α_s of all runs {peak:.3f}"})
    pk = []
    for r in rates:
        vals = {m: mx[(r, m)]["peak_alpha"] for m in models if (r, m) in mx}
        if len(vals) == 3:
            pk.append(f"Q_s {r}: " + ", ".join(f"{SHORT[m]} {vals[m]:.3f}" for m in MODELS))
    if pk:
        out.append({"figure": "Figs. 6, 10f", "paper": "deposit α_s: Dartevelle lowest, Berzi highest",
                    "here": "deposit peak α_s: " + "; ".join(pk)})
    return out


def _developing(plan, records):
    """{(rate, model): metrics} of the finished developing-pipe runs."""
    return {(info["rate"], info["model"]): records[n].metrics for n, (k, info, c) in plan.items()
            if k == "developing" and records[n].ok and "dp" in records[n].metrics}


def _shape(runs: dict, rates, models) -> str:
    """Where Δp(Q_s) of each model has its minimum, and its max/min ('' with fewer than 3 rates)."""
    shape = []
    for m in models:
        got = [(r, runs[(r, m)]["dp"]) for r in rates if (r, m) in runs]
        if len(got) >= 3:
            i = int(np.argmin([d for _, d in got]))
            dps = [d for _, d in got]
            shape.append(f"{SHORT[m]}: minimum at Q_s = {got[i][0]}" + ("" if 0 < i < len(got) - 1 else " (an end)")
                         + f", max/min {max(dps) / min(dps):.2f}")
    return "; ".join(shape)


def _ordering(runs: dict, rates, models) -> str:
    """The models' Δp order and spread at each rate with all three ('' if none)."""
    per = []
    for r in rates:
        vals = {m: runs[(r, m)]["dp"] for m in models if (r, m) in runs}
        if len(vals) == 3:
            spread = (max(vals.values()) - min(vals.values())) / min(vals.values()) * 100
            per.append(f"Q_s {r}: {_order(vals)} (spread {spread:.1f} %)")
    return "; ".join(per)


STATEMENT_COLUMNS = [Column("figure", "paper"), Column("paper", "the paper's statement"), Column("here", "this study")]


# ---------------------------------------------------------------------------- figures
COLORS = {"dartevelle": "tab:red", "srivastava-sundaresan": "tab:green", "berzi": "tab:blue",
          "johnson-jackson": "tab:gray"}


def _figures(outdir: Path, plan, records, quick: bool) -> list[Path]:
    return draw_figures((_fig_pressure_drop, _fig_sections, _fig_alpha_profiles, _fig_frictional_pressure_closures,
                         _fig_pf_profiles, _fig_tau_profiles, _fig_profiles_qs08, _fig_developing), outdir, plan, records)


def _fig_developing(outdir, plan, records):
    """Δp(x) and the holdup along the developing pipe at Q_s = 0.8, each model, with the fully
    developed section's slope and the measured 4.26 kPa."""
    runs_ = [(info, records[n].metrics) for n, (k, info, c) in plan.items()
             if k == "developing" and info["rate"] == "0.8" and "x" in records[n].metrics]
    if not runs_:
        return None
    mx = _matrix(plan, records)
    fig = _figure()(10, 4)
    a1, a2 = fig.subplots(1, 2)
    for info, m in runs_:
        x, col, lab = np.concatenate([[0.0], m["x"]]), COLORS[info["model"]], LABELS[info["model"]]
        a1.plot(x, np.concatenate([[0.0], m["dp_x"]]) / 1e3, color=col, label=f"{lab}, developing")
        full = mx.get(("0.8", info["model"]), {}).get("dpdx")
        if full:
            a1.plot([0, x[-1]], [0, full * x[-1] / 1e3], ls=":", color=col, label=f"{lab}, fully developed section")
        a2.plot(x, np.concatenate([[m.get("inlet_alpha", np.nan)], m["holdup_x"]]), color=col, label=lab)
    a1.plot([2.4], [PAPER_DP_MEASURED], "k*", ms=10, label="measured (Table 5)")
    a1.set_xlabel("x [m]")
    a1.set_ylabel("Δp from the inlet [kPa]")
    a1.grid(alpha=0.3)
    a1.legend(fontsize=7)
    a2.axhline(runs_[0][1].get("inlet_alpha", np.nan), color="0.5", ls="--", lw=0.8, label="inlet α_s (eq. 23)")
    a2.set_xlabel("x [m]")
    a2.set_ylabel("section-mean α_s")
    a2.grid(alpha=0.3)
    a2.legend(fontsize=7)
    fig.suptitle("Developing pipe from the paper's inlet (eqs. 20-23), Q_s = 0.8 m³/h")
    return _save(fig, outdir / "fig_developing_qs0.8.png")


def _save(fig, path: Path) -> Path:
    fig.savefig(path, format="png")
    return path


def _fig_pressure_drop(outdir, plan, records):
    mx = _matrix(plan, records)
    if not mx:
        return None
    fig = _figure()(10, 4)
    axes = fig.subplots(1, 2)
    for m in MODELS:
        pts = sorted((float(r), plan_case_ug(plan, r), v["dp"] / 1e3) for (r, mm), v in mx.items() if mm == m)
        if not pts:
            continue
        q, ug, dp = zip(*pts)
        axes[0].plot(q, dp, "o-", color=COLORS[m], label=LABELS[m])
        axes[1].plot(ug, dp, "o-", color=COLORS[m], label=LABELS[m])
    for ax, x in zip(axes, (0.8, 6.43)):
        ax.plot([x], [PAPER_DP_MEASURED], "ks", ms=8, label="measured (Table 5)")
        ax.errorbar([x], [3.93], yerr=[[0.16], [0.16]], fmt="kx", capsize=4, label="paper, meshes A-D (Berzi)")
        ax.set_ylabel("Δp over 2.4 m [kPa]")
        ax.grid(alpha=0.3)
    axes[0].set_xlabel("supplementary gas Q_s [m³/h]")
    axes[1].set_xlabel("superficial gas velocity U_g [m/s]")
    axes[0].legend(fontsize=8)
    fig.suptitle("Pressure drop against supplementary gas (after Ding et al. 2024, Fig. 3)")
    return _save(fig, outdir / "fig3_pressure_drop.png")


def plan_case_ug(plan, rate):
    for k, info, c in plan.values():
        if info["rate"] == rate:
            return float(c.data["gas"]["superficial_velocity"])
    return math.nan


def _fig_sections(outdir, plan, records):
    from matplotlib.patches import Circle
    from matplotlib.tri import Triangulation

    mx = _matrix(plan, records)
    if not mx:
        return None
    rates = sorted({r for r, _ in mx}, key=float)
    models = [m for m in MODELS if any((r, m) in mx for r in rates)]
    fig = _figure()(2.2 * len(rates) + 1.0, 2.3 * len(models))
    axes = np.atleast_2d(fig.subplots(len(models), len(rates), squeeze=False))
    levels = np.linspace(0.0, 0.63, 22)
    cs = None
    for i, m in enumerate(models):
        for j, r in enumerate(rates):
            ax = axes[i, j]
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            if (r, m) not in mx:
                continue
            s = mx[(r, m)]["section"]
            z, y, a = (np.asarray(s[k]) for k in ("z", "y", "alpha"))
            cs = ax.tricontourf(Triangulation(z, y), np.clip(a, 0.0, 0.63), levels=levels, cmap="viridis")
            ax.add_patch(Circle((0, 0), 1.0, fill=False, lw=0.8))
            ax.set_xlim(-1.02, 1.02)
            ax.set_ylim(-1.02, 1.02)
            if i == 0:
                ax.set_title(f"Q_s = {r} m³/h", fontsize=9)
            if j == 0:
                ax.set_ylabel(LABELS[m], fontsize=9)
    if cs is not None:
        fig.colorbar(cs, ax=axes, label="α_s", shrink=0.8)
    fig.suptitle("Solids volume fraction on the section (after Fig. 5; cell centres, triangulated)")
    return _save(fig, outdir / "fig5_solids_fraction_sections.png")


def _profile_panels(outdir, plan, records, key, xlabel, title, fname, log=False):
    mx = _matrix(plan, records)
    if not mx:
        return None
    rates = sorted({r for r, _ in mx}, key=float)
    models = [m for m in MODELS if any((r, m) in mx for r in rates)]
    fig = _figure()(3.4 * len(models), 3.6)
    axes = np.atleast_1d(fig.subplots(1, len(models), squeeze=False)[0])
    cmap = __import__("matplotlib").colormaps["plasma"]
    for ax, m in zip(axes, models):
        for j, r in enumerate(rates):
            if (r, m) not in mx:
                continue
            p = mx[(r, m)]["profiles"]
            if key not in p:
                continue
            v = np.asarray(p[key], float)
            if log:
                v = np.where(v > 0, v, np.nan)
            ax.plot(v, p["h"], color=cmap(j / max(len(rates) - 1, 1) * 0.85), label=f"Q_s {r}")
        if log:
            ax.set_xscale("log")
        ax.set_title(LABELS[m], fontsize=9)
        ax.set_xlabel(xlabel)
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("height above the bottom / D")
    axes[0].legend(fontsize=7)
    fig.suptitle(title)
    return _save(fig, outdir / fname)


def _fig_alpha_profiles(outdir, plan, records):
    return _profile_panels(outdir, plan, records, "solids_fraction", "α_s",
                           "Solids fraction along the vertical diameter (after Fig. 6)", "fig6_solids_fraction_profiles.png")


def _fig_pf_profiles(outdir, plan, records):
    return _profile_panels(outdir, plan, records, "frictional_pressure", "p_f [Pa]",
                           "Frictional pressure along the vertical diameter (after Fig. 8)",
                           "fig8_frictional_pressure_profiles.png", log=True)


def _fig_tau_profiles(outdir, plan, records):
    return _profile_panels(outdir, plan, records, "frictional_shear", "τ_f = μ_f |∇u_s| [Pa]",
                           "Frictional shear stress along the vertical diameter (after Fig. 9)",
                           "fig9_frictional_shear_profiles.png", log=True)


def _fig_frictional_pressure_closures(outdir, plan, records):
    from tfm.friction import (berzi_2011_pressure, dartevelle_2004_pressure, johnson_jackson_1987_pressure)
    from tfm.parameters import SolidsParameters

    P = SolidsParameters()
    a = np.linspace(0.40, 0.50, 401)[1:]
    curves = {"dartevelle": dartevelle_2004_pressure(a, P.alpha_min, P.alpha_max),
              "berzi": berzi_2011_pressure(a, P.stiffness_over_diameter, P.berzi_a, P.alpha_min, P.alpha_max),
              "johnson-jackson": johnson_jackson_1987_pressure(a, P.fr, P.r, P.s, P.alpha_min, P.alpha_max)}
    names = {"dartevelle": "Dartevelle (eq. 13, as printed)",
             "berzi": f"modified Berzi (k_n/d_s = {P.stiffness_over_diameter / 1e6:g} MPa)",
             "johnson-jackson": f"Johnson-Jackson p_c (Fr {P.fr:g} Pa, r {P.r:g}, s {P.s:g}) = "
                                "Srivastava-Sundaresan at ∇·v = 0"}
    fig = _figure()(9, 3.8)
    axes = fig.subplots(1, 2)
    for k, v in curves.items():
        axes[0].plot(a, v, color=COLORS[k], label=names[k])
        axes[1].semilogy(a, v, color=COLORS[k], label=names[k])
    for ax in axes:
        for x in (0.43, 0.47):
            ax.axvline(x, color="k", lw=0.6, ls=":")
        ax.set_xlabel("α_s")
        ax.set_ylabel("p_f [Pa]")
        ax.grid(alpha=0.3)
    axes[0].set_ylim(0, 60)
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Frictional pressure of the closures (after Fig. 7; tfm.friction, Table 4 constants)")
    return _save(fig, outdir / "fig7_frictional_pressure_closures.png")


def _fig_profiles_qs08(outdir, plan, records):
    mx = _matrix(plan, records)
    models = [m for m in MODELS if ("0.8", m) in mx]
    if not models:
        return None
    panels = (("gas_ux", "(a) gas velocity u_g [m/s]", False), ("solids_ux", "(b) solids velocity u_s [m/s]", False),
              ("gas_k", "(c) gas k [m²/s²]", True), ("granular_temperature", "(e) Θ [m²/s²]", True),
              ("solids_fraction", "(f) α_s", False))
    fig = _figure()(14, 3.6)
    axes = fig.subplots(1, len(panels))
    for ax, (key, label, log) in zip(axes, panels):
        for m in models:
            p = mx[("0.8", m)]["profiles"]
            if key in p:
                v = np.asarray(p[key], float)
                ax.plot(np.where(v > 0, v, np.nan) if log else v, p["h"], color=COLORS[m], label=LABELS[m])
        if log:
            ax.set_xscale("log")
        ax.set_xlabel(label)
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("height above the bottom / D")
    axes[0].legend(fontsize=7)
    fig.suptitle("Profiles along the vertical diameter at Q_s = 0.8 m³/h (after Fig. 10; (d) solids turbulent "
                 "kinetic energy: not modelled)")
    return _save(fig, outdir / "fig10_profiles_qs0.8.png")


# ---------------------------------------------------------------------------- README
def _force_table(plan, records) -> str:
    mx = _matrix(plan, records)
    lines = ["| Q_s | model | gas wall / G A | solids wall / G A | solids wall / solids weight | "
             "collisional term / weight | frictional term (μ_w p_f) / weight |", "|---|---|---|---|---|---|---|"]
    for (r, m), v in sorted(mx.items(), key=lambda t: (float(t[0][0]), MODELS.index(t[0][1]))):
        if "gas_wall_share" not in v:
            continue
        lines.append(f"| {r} | {m} | {v['gas_wall_share']:.2f} | {v['solids_wall_share']:.2f} | "
                     f"{v['solids_wall_over_weight']:.2f} | {v['collisional_wall_over_weight']:.2f} | "
                     f"{v['frictional_wall_over_weight']:.3f} |")
    return "\n".join(lines)


def _write_readme(outdir, args, rows, grid_rows, sens_rows, plan, records, figures, t_start, dev_rows=()):
    import os

    from eulag.output import atomic_write

    csv_path = write_csv(outdir / f"{STUDY}.csv", COLUMNS, rows)
    if grid_rows:
        write_csv(outdir / f"{STUDY}-grid.csv", GRID_COLUMNS, grid_rows)
    if sens_rows:
        write_csv(outdir / f"{STUDY}-sensitivity.csv", SENS_COLUMNS, sens_rows)
    if dev_rows:
        write_csv(outdir / f"{STUDY}-developing.csv", DEV_COLUMNS, dev_rows)
    quick = bool(args.quick)
    cmd = f"eulag study {STUDY}" + (" --quick" if quick else "") + \
          (f" --only {args.only}" if getattr(args, "only", None) else "") + \
          (f" --rates {args.rates}" if getattr(args, "rates", None) else "") + \
          (" --resume" if getattr(args, "resume", False) else "") + (" --report" if getattr(args, "report", False) else "")
    grid = QUICK_GRID if quick else GRID
    L = ["# Frictional-stress models of the dense-phase two-fluid model (Ding et al. 2024)", "",
         "*Generated by `" + cmd + "`; do not edit by hand — re-run the command.*", ""]
    if quick:
        L += ["> **Quick mode**: Q_s = 0.8 only on coarse meshes, no sensitivity runs. These numbers check the "
              "study machinery; they are **not results**.", ""]
    L += ["The five operating points of Ding, Zhou, Tang, Xiao & Zhou (2024), Appl. Sci. 14, 2031, Table 1, with "
          "the three frictional-stress models (Dartevelle, Srivastava & Sundaresan, modified Berzi), computed as "
          "fully developed pipe cross-sections (`tfm.section`, through `eulag.runs.execute`; the cases "
          "`cases/two_fluid/ding_qs*.toml` with `friction.model` changed). Δp = −dp/dx × 2.4 m. The model, its "
          "stated deviations from the paper's 3-D unsteady simulation and the inferred inputs are in "
          "docs/two-fluid.md. Nothing is tuned to the measurements.", "",
          "The paper gives the measured Δp only at Q_s = 0.8 m³/h (4.26 kPa, Table 5); its Fig. 3 values at the other "
          "rates are not in the text (only the relative errors of all models, −4.91 % to +7.60 %).", "",
          "Columns: mesh = radial x azimuthal cells (the wall ring at y+ 30); deposit peak α_s = the largest α_s of "
          "the section; deposit area = the fraction of the section with α_s > α_min = 0.4; capped cells = cells "
          "whose frictional viscosity reached `friction.viscosity_cap`; solids wall force / weight = the solids "
          "wall shear of eq. 24 integrated over the wall, over the submerged solids weight per unit length.", "",
          "## Table", "", markdown_table(COLUMNS, rows), "",
          f"The same table as CSV: [{csv_path.name}]({csv_path.name}). Each run's dataset is `<run>.nc` in this "
          "folder; what the table and figures take from it is in `<run>.record.json` beside it (a failed run: "
          "`<run>.failed.json`), which `--resume` and `--report` use when the dataset is not there.", ""]
    st = statements(plan, records)
    if st:
        L += ["## The paper's statements against this study", "", markdown_table(STATEMENT_COLUMNS, st), ""]
    if grid_rows:
        L += ["## Grid convergence (after Table 5)", "",
              "Q_s = 0.8 m³/h, each model, three cross-section meshes (the first-cell y+ is held at 30, the "
              "refinement is inside).", "", markdown_table(GRID_COLUMNS, grid_rows), "",
              "The paper's Table 5 (modified Berzi, 3-D meshes of the 2.4 m pipe; measured 4.26 kPa):", "",
              "| mesh | inlet cells | axial size [mm] | total cells | simulated Δp [kPa] |", "|---|---|---|---|---|"]
        L += [f"| {n} | {c} | {dx:g} | {t:,} | {dp:.2f} |" for n, c, dx, t, dp in PAPER_TABLE5]
        L += ["", f"CSV: [{STUDY}-grid.csv]({STUDY}-grid.csv).", ""]
    if sens_rows:
        base = next((r for r in rows if r["model"] == "berzi" and r["Q_s"] == 0.8), None)
        L += ["## Sensitivity to the inputs the paper does not give", "",
              f"Modified Berzi, Q_s = 0.8 m³/h, mesh {_grid_text(grid)}, one input changed at a time (base: "
              + (f"{base['dp_kPa']:.2f} kPa" if base and base["dp_kPa"] is not None else "—") + ").", "",
              markdown_table(SENS_COLUMNS, sens_rows), "", f"CSV: [{STUDY}-sensitivity.csv]({STUDY}-sensitivity.csv).", ""]
    if dev_rows:
        L += ["## The developing pipe", "",
              "Each run marched over the 2.4 m pipe from the paper's inlet (`numerics.mode = \"developing\"`, "
              "`tfm.developing`): a uniform suspension at α_s,inlet of eq. 23 with the Hinkle solids velocity "
              "of eq. 22 and the 1/7-power profiles of eqs. 20-21, as the paper's 3-D model starts. Δp = ∫ −dp/dx "
              "dx. M_s Δu_s / A is the momentum flux that accelerating the solids from the inlet to the mean "
              "velocity at 2.4 m costs; the paper reports its profiles developed from L = 120 D (1.2 m) on.", "",
              markdown_table(DEV_COLUMNS, dev_rows), "", f"CSV: [{STUDY}-developing.csv]({STUDY}-developing.csv).", ""]
    ft = _force_table(plan, records)
    if ft.count("\n") > 1:
        L += ["## Force balance of the section", "",
              "Fully developed flow: −dp/dx × A = gas wall force + solids wall force (drag and the internal "
              "stresses cancel over the section). The solids wall force is eq. 24 (modified Schneiderbauer): a "
              "collisional term η_w μ_w α_s ρ_s g0 Θ erf(ū) and a frictional term μ_w p_f, both at the wall cells.",
              "", ft, ""]
    if figures:
        L += ["## Figures", ""]
        for f in figures:
            rel = os.path.relpath(f, outdir)
            L += [f"![{Path(rel).stem}]({rel})", ""]
    mi = machine_info()
    total = time.perf_counter() - t_start
    L += ["## Settings", "",
          f"Matrix mesh {_grid_text(grid)}; grid table meshes "
          + ", ".join(_grid_text(g) for g in (QUICK_GRIDS if quick else GRIDS))
          + "; the cases' numerics otherwise (k-ε gas turbulence, at most 400 outer iterations, tolerance 1e-4). "
          "Constants: Table 4 of the paper and the stated choices of docs/two-fluid.md.", "",
          "## Machine and wall time", "",
          f"- platform: {mi['platform']} ({mi['machine']}), CPU: {mi['cpu']}",
          f"- CPUs: {mi['cpu_count']} ({mi['cpus_usable']} usable)",
          f"- python {mi['python']}, eulag {mi['eulag']}, commit {mi['commit']}",
          f"- wall time of this invocation: {total:.1f} s (runs reused with `--resume` count with the time they "
          "took when they ran)",
          f"- written {time.strftime('%Y-%m-%d %H:%M:%S %Z')}", ""]
    text = "\n".join(L)
    atomic_write(outdir / "README.md", lambda tmp: Path(tmp).write_text(text))
