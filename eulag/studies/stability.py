"""Stiff and extreme cases (``eulag study stability``): variants of the base case that must
converge or stop with a clear diagnosis (never NaN, negative k or epsilon, a lost parcel or a
silent hang); the table states each run's health and the first quantity to go wrong."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from eulag.analysis import attr as _attr
from eulag.config import Case, CaseError

from .report import (COLLISION_MOMENTUM_TEXT, Column, _figure, _settings_text, write_report)
from .runner import (STABILITY_QUICK, _attr_float, _base_case, _finish, _quick, _select, _with_parcels,
                     refuse_report_of_nothing, run_case)


def _reynolds_velocity(case: Case, diameter: float, re: float) -> float:
    return re * case.gas.viscosity / (case.gas.density * diameter)


def stability_cases(quick: bool, parcels: int | None = None) -> list[tuple[str, str, Case | CaseError]]:
    """(name, what changes, case or the CaseError the change raised) for every stiff/extreme case.

    Each derives from the base case (200 µm, eta = 2.2, Delta-gamma = 1.5 deg, U0 = 10 m/s,
    four-way); quick mode on the quick numerics with 200 parcels (the 1 µm tracers take ~10^5
    steps each), where "4x cells" doubles the radial and azimuthal cells of the quick grid and
    "1e6 parcels" is 8x the quick parcels.
    """
    base = _base_case(False)
    if quick:
        base = _quick(base, **STABILITY_QUICK)
    base = _with_parcels(base, parcels)
    n = base.numerics
    d0, length, sections = base.pipe.diameter, base.pipe.length, base.pipe.sections
    d_big = 0.3
    u_big = _reynolds_velocity(base, d_big, 1.0e6)
    scale = d_big / d0
    # quick mode: the rings the 0.3 m pipe's wall cell (y+ 30 at Re 1e6, 0.5 mm) needs on top of the
    # quick grid's five (rans.mesh.MAX_RING_GROWTH)
    big_rings = max(n.radial_cells, _rings_needed(base, d_big, u_big))
    many = 8 * n.parcels if quick else 1_000_000
    # 1 µm tracers at eta = 2.2: ~5e15 particles per m3, so the stochastic collision frequency
    # (~5e3 /s) limits the step to 0.1/f_coll: ~7.5e4 steps per parcel, 40x the base case's.
    # A fifteenth of the parcels keeps the pass at about the base case's cost; the noise this
    # leaves is in the batch standard errors and the coupling residual's noise units.
    tracer_parcels = n.parcels if quick else max(1000, n.parcels_start // 15)
    specs = [
        ("tracers_1um", f"D_p = 1 µm (tracers), {tracer_parcels} parcels per pass (each takes ~7.5·10^4 "
                        "collision-limited steps)",
         {"particles": {"diameter": 1e-6},
          "numerics": {"parcels": tracer_parcels, "parcels_start": min(n.parcels_start, tracer_parcels)}}),
        ("pellets_3.4mm", "D_p = 3.4 mm (the experiment's pellets)", {"particles": {"diameter": 3.4e-3}}),
        ("loading_eta10", "eta = 10", {"particles": {"mass_loading": 10.0}}),
        ("loading_eta30", "eta = 30", {"particles": {"mass_loading": 30.0}}),
        ("roughness_20deg", "Delta-gamma = 20 deg", {"walls": {"roughness_angle_std_deg": 20.0}}),
        ("U0_5", "U0 = 5 m/s (near saltation)", {"gas": {"bulk_velocity": 5.0}}),
        ("U0_30", "U0 = 30 m/s", {"gas": {"bulk_velocity": 30.0}}),
        ("pipe_0.3m_Re1e6", f"D = 0.3 m, U0 = {u_big:.3g} m/s (Re = 1e6), L/D and x/D as the base case"
                            + (f" ({big_rings} radial cells: the quick grid's would grow too fast from the thin "
                               "wall cell)" if quick else ""),
         {"pipe": {"diameter": d_big, "length": length * scale, "sections": [s * scale for s in sections]},
          "gas": {"bulk_velocity": u_big}, **({"numerics": {"radial_cells": big_rings}} if quick else {})}),
        ("cells_4x", f"4x cells: {n.radial_cells * 2} radial x {n.azimuthal_cells * 2} azimuthal "
                     f"(x {n.axial_cells} axial)",
         {"numerics": {"radial_cells": 2 * n.radial_cells, "azimuthal_cells": 2 * n.azimuthal_cells}}),
        ("parcels_1e6", f"{many} parcels per pass" + (" (quick: 8x the quick parcels)" if quick else ""),
         {"numerics": {"parcels": many}}),
    ]
    out = []
    for name, what, changes in specs:
        try:
            case = base.replace(name=f"stability_{name}", description=f"{base.description}; {what}",
                                **changes)
        except CaseError as exc:
            case = exc
        out.append((name, what, case))
    return out


def _rings_needed(base: Case, diameter: float, velocity: float) -> int:
    from rans.mesh import rings_for_growth, wall_cell_thickness

    g = base.gas
    wall, _ = wall_cell_thickness(diameter, base.numerics.first_cell_yplus, velocity, g.density, g.viscosity)
    return rings_for_growth(0.5 * diameter, wall)


def _field_health(ds) -> dict[str, Any]:
    bad = [v for v in ("gas_ux", "gas_uy", "gas_uz", "gas_k", "gas_epsilon", "gas_p", "pressure_gradient")
           if v in ds and not np.all(np.isfinite(ds[v].values))]
    kmin = float(np.nanmin(ds["gas_k"].values)) if "gas_k" in ds else math.nan
    emin = float(np.nanmin(ds["gas_epsilon"].values)) if "gas_epsilon" in ds else math.nan
    stuck = int(np.sum(ds["parcels_stuck"].values)) if "parcels_stuck" in ds else 0
    lost = int(np.sum(ds["parcels_lost"].values)) if "parcels_lost" in ds else 0
    relax = np.asarray(ds["relaxation"].values, dtype=float) if "relaxation" in ds else np.array([math.nan])
    steps = _attr_float(ds, "particle_steps_final", math.nan)
    sliding = _attr_float(ds, "wall_sliding_steps_final", math.nan)
    return {"nonfinite": ", ".join(bad) if bad else "none", "k_min": kmin, "eps_min": emin,
            "stuck_total": stuck, "stuck_final": int(_attr_float(ds, "parcels_stuck_final", 0)),
            "lost": lost, "relax_min": float(np.nanmin(relax)) if np.any(np.isfinite(relax)) else math.nan,
            "sliding_pct": 100.0 * sliding / steps if steps and math.isfinite(steps) else math.nan,
            "floored_max": int(np.max(ds["gas_floored_cells"].values)) if "gas_floored_cells" in ds else None,
            "floored_last": int(ds["gas_floored_cells"].values[-1]) if "gas_floored_cells" in ds else None,
            **_floored_where(ds),
            "residual_history": [float(v) for v in np.asarray(ds["residual"].values, dtype=float)],
            "relaxation_history": [float(v) for v in relax]}


def _floored_where(ds) -> dict[str, Any]:
    """Where the final gas field sits at the k/ε floor (rans.solver.K_FLOOR): the axial range
    of those cells and how many of them are in the wall ring (empty when none or unknown)."""
    from rans.solver import turbulence_floors
    try:
        k = np.asarray(ds["gas_k"].values, dtype=float)
        eps = np.asarray(ds["gas_epsilon"].values, dtype=float)
        x = np.asarray(ds["x"].values, dtype=float)
        k_floor, eps_floor = turbulence_floors(float(_attr(ds, "gas.bulk_velocity")),
                                               float(_attr(ds, "pipe.diameter")))
    except (KeyError, ValueError, TypeError):
        return {}
    at = (k <= k_floor * (1.0 + 1e-6)) | (eps <= eps_floor * (1.0 + 1e-6))  # (x, r, theta)
    if not at.any():
        return {}
    xs = x[at.any(axis=(1, 2))]
    return {"floored_x": [float(xs.min()), float(xs.max())], "floored_wall": int(at[:, -1, :].sum())}


def _wall_cell_thickness(case: Case) -> float:
    from eulag.coupling import build_mesh

    mesh = build_mesh(case)
    re = np.asarray(mesh.r_edges, dtype=float)
    return float(re[-1] - re[-2])


def study_stability(args, outdir: Path, t_start: float) -> int:
    specs = stability_cases(args.quick, getattr(args, "parcels", None))
    names = _select(getattr(args, "only", None), [s[0] for s in specs], "cases")
    specs = [s for s in specs if s[0] in names]
    records = []
    for i, (name, what, case) in enumerate(specs, 1):
        rec = run_case(args, name, case, outdir, f"[stability {i}/{len(specs)}] {name}",
                       lambda ds, rec, name=name: {**_field_health(ds),
                                                   **(_tracer_ratios(ds) if name == "tracers_1um" else {})})
        records.append(rec)
    refuse_report_of_nothing(args, records, outdir)
    rows = []
    for (name, what, case), rec in zip(specs, records):
        m = rec.metrics
        if rec.status == "converged":
            wrong = "—"
        elif rec.status == "rejected":
            wrong = f"case rejected: {rec.message}"
        else:
            wrong = rec.message
        if rec.ok and m.get("nonfinite") not in (None, "none"):
            wrong = f"non-finite {m['nonfinite']}; " + wrong
        rows.append({"case": name, "change": what,
                     "converged": {"converged": "yes", "not converged": "no"}.get(rec.status, rec.status),
                     "passes": rec.passes if rec.status != "rejected" else None,
                     "time_s": rec.time, "final_residual": rec.residual, "relaxation": rec.relaxation,
                     "relax_min": m.get("relax_min"), "stuck_total": m.get("stuck_total"),
                     "stuck_final": m.get("stuck_final"), "lost": m.get("lost"),
                     "sliding_pct": m.get("sliding_pct"), "nonfinite": m.get("nonfinite"),
                     "k_min": m.get("k_min"), "eps_min": m.get("eps_min"),
                     "floored": _floored_cell(m),
                     "collision_momentum": m.get("collision_momentum"), "commit": m.get("commit"),
                     "first_wrong": wrong})
    columns = [Column("case", "case"), Column("change", "change from the base case"),
               Column("converged", "converged"), Column("passes", "passes", "{:d}"),
               Column("time_s", "run time [s]", "{:.1f}"), Column("final_residual", "final residual", "{:.3g}"),
               Column("relaxation", "relaxation (final)", "{:g}"), Column("relax_min", "relaxation (min)", "{:g}"),
               Column("stuck_total", "parcels stuck (all passes)", "{:d}"),
               Column("stuck_final", "stuck (final passes)", "{:d}"), Column("lost", "lost", "{:d}"),
               Column("sliding_pct", "sliding/rolling steps [%]", "{:.3g}"),
               Column("nonfinite", "non-finite gas fields"), Column("k_min", "min k [m²/s²]", "{:.3g}"),
               Column("eps_min", "min ε [m²/s³]", "{:.3g}"),
               Column("floored", "cells at the k/ε floor: last pass (max)"),
               Column("collision_momentum", "collision momentum / inflow", "{:+.2g}"),
               Column("commit", "commit"),
               Column("first_wrong", "first quantity to go wrong / why not converged")]
    base = _base_case(args.quick)
    try:
        wall = _wall_cell_thickness(base)
        wall_text = f"{wall * 1e3:.2f} mm"
    except Exception:  # noqa: BLE001
        wall, wall_text = math.nan, "n/a"
    r_p = 0.5 * 3.4e-3
    if math.isfinite(wall) and wall < r_p:
        where = (f"so the centre of a 3.4 mm pellet (radius {r_p * 1e3:.2f} mm) never enters the "
                 f"{wall_text} wall cell: its sources land in the rings further in")
    else:
        where = (f"so the centre of a 3.4 mm pellet (radius {r_p * 1e3:.2f} mm) reaches only the inner "
                 f"part of the {wall_text} wall cell")
    pellet = (
        f"The pellets (D_p = 3.4 mm) are larger than the wall cell of the base mesh (radial thickness "
        f"{wall_text} at U0 = {base.gas.bulk_velocity:g} m/s, from `numerics.first_cell_yplus` = "
        f"{base.numerics.first_cell_yplus:g}), but below the limit of the case validation "
        f"(`eulag.config`: D_p < pipe.diameter / 5 = {base.pipe.diameter * 200:.3g} mm), so they run as "
        "point particles. The PSI-cell sources of a parcel go into the cell that holds its centre along "
        "each trajectory segment (particles/tracking.py), split between the cells the segment crosses "
        "by time fraction; they are not spread over the volume the pellet covers. The wall contact is "
        f"at the centre distance R - D_p/2 from the axis, {where}, and the gas it sees is "
        "interpolated at its centre. What the point-particle model cannot capture at D_p/D = 0.11: "
        "the flow around the "
        "pellet and its wake (it spans the log layer, particle Reynolds numbers of order 10^2-10^3), "
        "the volume it displaces (volume fraction is not in the gas equations), finite-size lift and "
        "the shear across the pellet, and the rolling/sliding contact geometry of a particle that is "
        "not small against the wall curvature.")
    intro = [
        "Stiff and extreme variants of the base case (200 µm, eta = 2.2, Delta-gamma = 1.5 deg, U0 = "
        "10 m/s, four-way). Each must run to convergence or stop with a clear diagnosis: never NaN, "
        "never negative k or epsilon, never a lost parcel, never a silent hang; parcels stopped by the "
        "residence-time cap are counted.",
        "",
        "Columns: converged (yes / no = finished at max_passes / failed = the coupling loop stopped "
        "with a diagnosis / rejected = the case validation refused it); final coupling residual; the "
        "source under-relaxation the loop chose (final and smallest; the loop halves it, down to "
        "0.05, when a gas solve with the sources fails or the residual stagnates above the tolerance, "
        "and doubles it again, once, when the residual at a halved α is below the tolerance but the "
        "loop has not converged); "
        "parcels stopped by the residence-time cap "
        "(all passes, and in the averaged final passes); lost parcels (must be 0); the share of "
        "particle steps spent sliding or rolling on the wall (final passes; near saltation this is "
        "the bottom layer); gas fields with a non-finite value; the smallest k and epsilon; the gas "
        "cells where k or epsilon was held at its floor (k = 1e-10 U0², rans.solver.K_FLOOR) in the last pass's gas solve and the "
        "most in any pass (counted by the solver, `gas_floored_cells`; — where the record predates the "
        "column), and where the final field has them: their axial range and how many lie in the wall "
        "ring (the wall function's cell); "
        + COLLISION_MOMENTUM_TEXT + "; the first "
        "quantity to go wrong (the CouplingError message), or why the run did not converge."]
    fig = _stability_figure(outdir / "stability_history.png", specs, records)  # None: no history
    write_report(outdir, "stability", args, title="Stiff and extreme cases", intro=intro, columns=columns,
                 rows=rows, figures=[fig] if fig is not None else [],
                 sections=[("The 3.4 mm pellets", pellet),
                           ("The 1 µm tracers", _tracer_sink_text(specs, records))], t_start=t_start,
                 settings=_settings_text([c for _, _, c in specs if isinstance(c, Case)], args.quick),
                 records=records)
    return _finish(args, outdir, records, allowed_failures=True)


def _tracer_sink_text(specs, records) -> str:
    """What the first-order Langevin model makes of tracers' S_k, with the run's own ratio."""
    from particles.kernel import C_T

    text = (
        "The seen fluid velocity is a first-order Langevin (Ornstein-Uhlenbeck) process, whose "
        "acceleration is white noise. A particle filters it with its response time tau_p, and the "
        "slip that is left dissipates, per unit particle mass, <u'_F (u_F - u_p)>/tau_p = "
        "2k/(T_L + tau_p) (the two-fluid result k - k_fp = k tau_p/(T_L + tau_p)). For tau_p -> 0 "
        f"this does not vanish: S_k -> -2 c_p k/T_L = -(3/C_T) c_p eps = -{3 / C_T:.1f} c_p eps "
        f"(T_L = C_T (2/3) k/eps, C_T = {C_T:g}), with c_p the particle mass concentration; "
        "tests/test_coupling.py checks the sampled S_k of 1 and 10 µm particles against it. At eta = "
        "2.2 that is some 20-27 times the gas's own dissipation rho eps, so the sinks all but remove "
        "the turbulence and, through the wall function, lower the wall shear: -dp/dx can fall below "
        "the single-phase value. Real 1 µm particles (tau_p = 3 µs, far below the Kolmogorov time "
        "(nu/eps)^1/2, 0.2 ms in the wall cells of the converged base case) follow the fluid down to the dissipative scales and add almost no "
        "dissipation. The tracer run shows what the point-particle model with this dispersion model "
        "gives, not what 1 µm particles do.")
    for (name, _, _), rec in zip(specs, records):
        ratio, gas_ratio = rec.metrics.get("tracer_sk_ratio"), rec.metrics.get("tracer_sk_gas_ratio")
        if name != "tracers_1um" or not rec.ok or ratio is None or gas_ratio is None:
            continue
        text += (f" In this run (core, r < R/2, median over the cells with particles; S_k as applied, "
                 f"i.e. relaxed, so it reaches the sampled value only as the loop converges): "
                 f"-S_k/(c_p eps) = {ratio:.3g} against {3 / C_T:.1f}, and -S_k/(rho eps) = {gas_ratio:.3g}.")
    return text


def _floored_cell(m: dict) -> str | None:
    if m.get("floored_max") is None:
        return None
    text = f"{m['floored_last']} (max {m['floored_max']})"
    if m.get("floored_x"):
        x0, x1 = m["floored_x"]
        text += f"; final field: x = {x0:.3g}–{x1:.3g} m, {m.get('floored_wall', 0)} in the wall ring"
    return text


def _tracer_ratios(ds) -> dict[str, float]:
    """Median -S_k/(c_p eps) and -S_k/(rho eps) in the core (r < R/2) cells with particles."""
    try:
        r = np.asarray(ds["r"].values)
        core = r < 0.5 * float(_attr(ds, "pipe.diameter")) / 2
        cp = ds["particle_concentration"].values[:, core, :]
        sk = ds["source_k"].values[:, core, :]
        eps = ds["gas_epsilon"].values[:, core, :]
        rho = float(_attr(ds, "gas.density"))
        ok = cp > 0
        return {"tracer_sk_ratio": float(np.median(-sk[ok] / (cp[ok] * eps[ok]))),
                "tracer_sk_gas_ratio": float(np.median(-sk[ok] / (rho * eps[ok])))}
    except Exception:  # noqa: BLE001 - the explanation stands without the run's numbers
        return {}


def _stability_figure(path: Path, specs, records) -> Path | None:
    """Coupling residual and chosen relaxation per pass of every stability run (None, and no
    file, when no run has a history: e.g. all reported from carried records)."""
    if not any(len(rec.metrics.get("residual_history", [])) for rec in records):
        path.unlink(missing_ok=True)
        return None
    fig = _figure()(11.5, 4.6)
    ax1, ax2 = fig.subplots(1, 2)
    for i, ((name, _, _), rec) in enumerate(zip(specs, records)):
        res = np.asarray(rec.metrics.get("residual_history", []), dtype=float)
        rel = np.asarray(rec.metrics.get("relaxation_history", []), dtype=float)
        if res.size == 0:
            continue
        style = "-" if rec.status == "converged" else ("--" if rec.status == "not converged" else ":")
        it = np.arange(1, res.size + 1)
        ax1.semilogy(it, np.where(res > 0, res, np.nan), style, marker="o", ms=3, color=f"C{i % 10}",
                     label=f"{name} ({rec.status})")
        ax2.plot(it[: rel.size], rel, style, marker="o", ms=3, color=f"C{i % 10}")
    ax1.set_xlabel("coupling pass")
    ax1.set_ylabel("coupling residual [noise units]")
    ax1.grid(alpha=0.3, which="both")
    if ax1.get_legend_handles_labels()[0]:
        ax1.legend(fontsize=7)
    ax1.set_title("residual (solid: converged, dashed: not, dotted: failed)", fontsize=9)
    from matplotlib.ticker import MaxNLocator

    for ax in (ax1, ax2):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax2.set_xlabel("coupling pass")
    ax2.set_ylabel("source under-relaxation used [1]")
    ax2.grid(alpha=0.3)
    fig.savefig(path, format="png")
    return path
