"""Error against run time (``eulag study error-runtime CASE``): the section profiles of runs
varied one axis at a time (grid, parcels, particle step factor, step rule) against a reference
run and the measurements, with the Pareto front of total error against wall time."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from eulag.analysis import attr as _attr
from eulag.config import Case, CaseError

from .profiles import diameter_profile, pareto_front, profile_deviation, read_measurements
from .report import Column, _figure, _run_cells, _settings_text, _station, write_report
from .runner import QUICK_NUMERICS, _BadInput, _base_case, _finish, refuse_report_of_nothing, run_case


@dataclass
class Setting:
    name: str
    axis: str
    grid: tuple[int, int, int]
    parcels: int
    step_factor: float
    step_rule: str
    reference: bool = False


def _even(n: float) -> int:
    return max(8, 2 * int(round(n / 2.0)))


def error_runtime_plan(case: Case, quick: bool) -> tuple[list[Setting], Setting]:
    """The settings of the error-against-run-time study, one axis at a time around a centre
    setting, and the reference (the finest setting of every axis, its own seed).

    Full mode: grids at 0.5, 0.75 and 1 times the case's cells per direction; 1e4, 3e4, 1e5 and
    3e5 parcels per pass; step factors f0 and f0/2 (f0 the case's); step rules default and
    paper. Centre: the case's grid, 3e4 parcels, f0, the default rule. Quick mode: tiny grids and
    100-800 parcels.
    """
    n = case.numerics
    f0 = n.step_factor
    if quick:
        grids = [(10, 4, 8), (12, 4, 10), (16, 5, 12)]
        parcels = [100, 200, 400, 800]
    else:
        base = (n.axial_cells, n.radial_cells, n.azimuthal_cells)
        grids = [(max(10, int(round(f * base[0]))), max(4, int(round(f * base[1]))), _even(f * base[2]))
                 for f in (0.5, 0.75, 1.0)]
        parcels = [10_000, 30_000, 100_000, 300_000]
    centre = Setting("centre", "centre", grids[-1], parcels[1], f0, "default")
    runs = [centre]
    for g in grids[:-1]:
        runs.append(Setting(f"grid_{g[0]}x{g[1]}x{g[2]}", "grid", g, centre.parcels, f0, "default"))
    for p in parcels:
        if p != centre.parcels:
            runs.append(Setting(f"parcels_{p}", "parcels", centre.grid, p, f0, "default"))
    runs.append(Setting(f"step_factor_{f0 / 2:g}", "step factor", centre.grid, centre.parcels, f0 / 2, "default"))
    runs.append(Setting("step_rule_paper", "step rule", centre.grid, centre.parcels, f0, "paper"))
    ref = Setting("reference", "reference", grids[-1], parcels[-1], f0 / 2, "default", reference=True)
    return runs, ref


def _default_verdict(own: Case, best: dict) -> str:
    """Whether the case file's own numerics are the best setting of the table."""
    n = own.numerics
    mine = (f"{n.axial_cells}x{n.radial_cells}x{n.azimuthal_cells}", n.parcels, n.step_factor, n.step_rule)
    if mine == (best["grid"], best["parcels"], best["step_factor"], best["step_rule"]):
        return "It is the default of the case file (`eulag run` on the case uses it)."
    return (f"The case file's defaults ({mine[0]} cells, {n.parcels} parcels, step {n.step_rule} x "
            f"{n.step_factor:g}) differ from it.")


def _setting_case(case: Case, s: Setting, quick: bool) -> Case:
    n = case.numerics
    num = dict(QUICK_NUMERICS) if quick else {}
    num.update({"axial_cells": s.grid[0], "radial_cells": s.grid[1], "azimuthal_cells": s.grid[2],
                "parcels": s.parcels, "parcels_start": min(num.get("parcels_start", n.parcels_start), s.parcels),
                "step_factor": s.step_factor, "step_rule": s.step_rule})
    if quick:
        num["batch_size"] = max(8, s.parcels // 8)
    if s.reference:
        num["seed"] = (n.seed + 1000) % (2 ** 63)  # its noise independent of the other runs'
    return case.replace(name=f"{case.name}_{s.name}", numerics=num)


ER_POINTS = np.linspace(-0.95, 0.95, 39)  # y/R of the comparison points on the vertical diameter


def _er_profiles(ds, x: float) -> dict[str, np.ndarray]:
    from eulag import analysis as an

    u0 = float(_attr(ds, "gas.bulk_velocity"))
    ys = ER_POINTS
    cbar = an.section_mean(ds, np.nan_to_num(an._field(ds, "particle_concentration", x)), x)
    if not cbar > 0.0:  # no particles at the station: no concentration profile
        cbar = math.nan
    return {"gas": diameter_profile(ds, "gas_ux", x, ys, wall_value=0.0, scale=u0),
            "particle": diameter_profile(ds, "particle_ux", x, ys, scale=u0),
            "particle_se": diameter_profile(ds, "particle_ux_stderr", x, ys, scale=u0),
            "concentration": diameter_profile(ds, "particle_concentration", x, ys, scale=cbar),
            "concentration_se": diameter_profile(ds, "particle_concentration_stderr", x, ys, scale=cbar)}


def study_error_runtime(args, outdir: Path, t_start: float) -> int:
    try:
        own = Case.from_toml(args.case)  # the case file's own defaults
        case = _base_case(False, Path(args.case))  # the base case at the studies' resolution
    except CaseError as exc:
        raise _BadInput(str(exc)) from None
    if case.particles is None:
        raise _BadInput(f"{args.case}: a single-phase case; allowed: a case with [particles]")
    x = case.pipe.sections[0]
    ref_path = case.reference_data_path()
    meas = read_measurements(ref_path) if ref_path is not None else {}
    runs, ref = error_runtime_plan(case, args.quick)
    settings = [ref] + runs  # the reference first: every other run is compared with it
    records, profiles = {}, {}
    for i, s in enumerate(settings, 1):
        c = _setting_case(case, s, args.quick)

        def extract(ds, rec, s=s):
            m = {"x_station": _station(ds, x), "profiles": _er_profiles(ds, x)}
            u0 = float(_attr(ds, "gas.bulk_velocity"))
            for phase in ("gas", "particle"):
                if phase in meas:
                    sim = diameter_profile(ds, f"{phase}_ux", x, meas[phase]["y_over_R"],
                                           wall_value=0.0 if phase == "gas" else None, scale=u0)
                    m[f"meas_{phase}"] = profile_deviation(sim, meas[phase]["u"])["rms"]
            return m

        records[s.name] = run_case(args, s.name, c, outdir, f"[error-runtime {i}/{len(settings)}] {s.name}",
                                   extract)
        if "profiles" in records[s.name].metrics:
            profiles[s.name] = records[s.name].metrics["profiles"]

    refuse_report_of_nothing(args, records.values(), outdir)
    refp = profiles.get(ref.name)
    rows = []
    for s in settings:
        rec = records[s.name]
        row = {"run": s.name, "axis": s.axis, "grid": "x".join(map(str, s.grid)), "parcels": s.parcels,
               "step_factor": s.step_factor, "step_rule": s.step_rule, **_run_cells(rec),
               "meas_gas": rec.metrics.get("meas_gas"), "meas_particle": rec.metrics.get("meas_particle")}
        p = profiles.get(s.name)
        if p is not None and refp is not None and not s.reference:
            sq_total, sq_disc = [], []
            for q, se in (("gas", None), ("particle", "particle_se"), ("concentration", "concentration_se")):
                e = profile_deviation(p[q], refp[q])["rms"]
                noise = 0.0
                if se is not None:
                    a = profile_deviation(p[se], np.zeros_like(p[se]))["rms"]
                    b = profile_deviation(refp[se], np.zeros_like(refp[se]))["rms"]
                    noise = math.sqrt(a * a + b * b) if math.isfinite(a) and math.isfinite(b) else math.nan
                row[f"err_{q}"] = e
                row[f"noise_{q}"] = noise if se is not None else None
                disc = math.sqrt(max(e * e - noise * noise, 0.0)) if math.isfinite(e) and math.isfinite(noise) else math.nan
                sq_total.append(e * e)
                sq_disc.append(disc * disc)
            row["err_total"] = math.sqrt(sum(sq_total) / 3.0)
            row["err_disc"] = math.sqrt(sum(sq_disc) / 3.0)
        rows.append(row)
    # the front takes converged runs measured against a converged reference: a run stopped at
    # max_passes is not a setting to recommend, and an unconverged reference is no reference
    ref_ok = records[ref.name].status == "converged"
    cand = [r for r in rows if r["axis"] != "reference" and ref_ok and records[r["run"]].status == "converged"]
    front = pareto_front([r["time_s"] for r in cand], [r.get("err_total", math.nan) for r in cand])
    for i, r in enumerate(cand):
        r["pareto"] = "yes" if i in front else ""
    best = None
    if front:
        best = min(front, key=lambda i: cand[i]["time_s"] * cand[i]["err_total"])
        cand[best]["pareto"] = "yes (best: min error x time)"
    columns = [Column("run", "run"), Column("axis", "axis"), Column("grid", "cells (x·r·θ)"),
               Column("parcels", "parcels", "{:d}"), Column("step_factor", "step factor", "{:g}"),
               Column("step_rule", "step rule"), Column("time_s", "run time [s]", "{:.1f}"),
               Column("err_gas", "gas u err. [% U0]", "{:.3g}"),
               Column("err_particle", "part. u err. [% U0]", "{:.3g}"),
               Column("noise_particle", "part. u noise [% U0]", "{:.3g}"),
               Column("err_concentration", "conc. err. [% c̄]", "{:.3g}"),
               Column("noise_concentration", "conc. noise [% c̄]", "{:.3g}"),
               Column("err_total", "total err. [%]", "{:.3g}"),
               Column("err_disc", "discretisation part [%]", "{:.3g}"),
               Column("meas_gas", "gas vs meas. [% U0]", "{:.3g}"),
               Column("meas_particle", "part. vs meas. [% U0]", "{:.3g}"),
               Column("pareto", "Pareto"), Column("converged", "converged"),
               Column("passes", "passes", "{:d}"), Column("commit", "commit")]
    fig = _er_figure(outdir / "error_runtime.png", [r for r in rows if r["axis"] != "reference"], cand, front, rows)
    pareto_lines = []
    for i in front:
        r = cand[i]
        pareto_lines.append(f"- `{r['run']}`: {r['grid']} cells, {r['parcels']} parcels, step "
                            f"{r['step_rule']} x {r['step_factor']:g}: {r['time_s']:.1f} s, total error "
                            f"{r['err_total']:.3g} %")
    if best is not None:
        r = cand[best]
        pareto_lines += ["", f"Best by the stated criterion (smallest error x run time on the front): "
                             f"`{r['run']}` ({r['grid']} cells, {r['parcels']} parcels, step {r['step_rule']} "
                             f"x {r['step_factor']:g})." + ("" if args.quick else " " + _default_verdict(own, r))]
    n_ref = _setting_case(case, ref, args.quick).numerics
    intro = [
        f"Case `{args.case}`: error of the section profiles at x = {x:g} m against the reference run "
        f"(station used: the cell centre nearest x; the grids differ, so the stations may differ by up "
        f"to half a cell) "
        f"(the finest setting of every axis: {'x'.join(map(str, ref.grid))} cells, {ref.parcels} "
        f"parcels, step {ref.step_rule} x {ref.step_factor:g}, seed {n_ref.seed} so that its noise is "
        "independent of the other runs') and against the measurements, as a function of the run's "
        "wall time. One axis is varied at a time around the centre setting (`centre`): the grid, the "
        "parcels per pass, the particle time-step factor and the step rule (default / the paper's)."
        + (f" The axes are built around the studies' resolution of the base case "
           f"({case.numerics.axial_cells}x{case.numerics.radial_cells}x{case.numerics.azimuthal_cells} cells, "
           "`eulag.studies.STUDY_NUMERICS`), not the case file's own default."
           if case.numerics != own.numerics and not args.quick else ""),
        "",
        f"Profiles: along the vertical diameter at {ER_POINTS.size} points y/R in [-0.95, 0.95] "
        "(linear interpolation): gas and particle axial velocity / U0, particle concentration / its "
        "section mean. Error = RMS difference over the points, in % (of U0, of the section-mean "
        "concentration). Noise = the statistical part expected from the batch standard errors of the "
        "run and the reference, sqrt(se_run² + se_ref²) (RMS over the points); the discretisation part "
        "= sqrt(max(error² - noise², 0)). The gas field has no standard error of its own (the noise "
        "of the sources reaches it), so its error is counted as discretisation error. Total = RMS of "
        "the three quantities. 'vs meas.': RMS deviation from the Tsuji–Morikawa points "
        "(normalised by each run's U0; the data are normalised by 15 m/s, see the tsuji-morikawa study)."
        if meas else
        f"Profiles: along the vertical diameter at {ER_POINTS.size} points y/R in [-0.95, 0.95]; "
        "the case names no measurement file."]
    write_report(outdir, "error-runtime", args, title="Error against run time", intro=intro,
                 columns=columns, rows=rows, figures=[fig],
                 sections=[("Pareto front (total error against run time)", "\n".join(pareto_lines) or
                            ("no converged run finished with an error estimate" if ref_ok else
                             "none: the reference run did not converge"))],
                 t_start=t_start,
                 settings=_settings_text([_setting_case(case, r, args.quick) for r in settings], args.quick),
                 records=list(records.values()))
    return _finish(args, outdir, list(records.values()), allowed_failures=False)


def _er_figure(path: Path, runs, cand, front, rows) -> Path:
    """Error against run time of every run (``runs``); the Pareto front over ``cand`` (the
    converged runs; an unconverged run is drawn in grey)."""
    fig = _figure()(11.5, 4.8)
    ax1, ax2 = fig.subplots(1, 2)
    markers = {"centre": ("k", "*"), "grid": ("C0", "s"), "parcels": ("C1", "o"), "step factor": ("C2", "^"),
               "step rule": ("C3", "D")}
    seen = set()
    for r in runs:
        t, e = r.get("time_s"), r.get("err_total")
        if not (isinstance(t, float) and isinstance(e, float) and t > 0 and e > 0):
            continue
        col, mk = markers.get(r["axis"], ("0.5", "x"))
        if not any(r is c for c in cand):
            col = "0.7"  # not converged (or no converged reference): no candidate for the front
        ax1.loglog([t], [e], mk, color=col, label=None if r["axis"] in seen else r["axis"])
        d = r.get("err_disc")
        if isinstance(d, float) and d > 0:
            ax1.loglog([t], [d], mk, mfc="none", color=col)
        seen.add(r["axis"])
        for key, mk2, lab in (("meas_gas", "o", "gas"), ("meas_particle", "s", "particle")):
            v = r.get(key)
            if isinstance(v, float) and v > 0:
                ax2.loglog([t], [v], mk2, color=col, mfc="none" if key == "meas_gas" else col,
                           label=f"{lab}" if (key, r["axis"]) == (key, "centre") else None)
    for r in rows:
        if r["axis"] == "reference":
            for key, mk2 in (("meas_gas", "o"), ("meas_particle", "s")):
                v, t = r.get(key), r.get("time_s")
                if isinstance(v, float) and v > 0 and isinstance(t, float) and t > 0:
                    ax2.loglog([t], [v], mk2, color="0.5", mfc="none" if key == "meas_gas" else "0.5",
                               label="reference run" if key == "meas_gas" else None)
    pts = [(cand[i]["time_s"], cand[i]["err_total"]) for i in front]
    if len(pts) > 1:
        ax1.loglog(*zip(*pts), "-", color="0.4", lw=1, label="Pareto front")
    ax1.set_xlabel("run wall time [s]")
    ax1.set_title("grey: not converged (not a candidate for the front)", fontsize=9)
    ax1.set_ylabel("error vs reference [%] (filled: total, open: discretisation part)")
    ax1.grid(alpha=0.3, which="both")
    if seen:
        ax1.legend(fontsize=8)
    ax2.set_xlabel("run wall time [s]")
    ax2.set_ylabel("RMS deviation from the measurements [% U0]")
    ax2.set_title("vs Tsuji & Morikawa (o gas, ■ particles)", fontsize=10)
    ax2.grid(alpha=0.3, which="both")
    if ax2.get_legend_handles_labels()[0]:
        ax2.legend(fontsize=8)
    fig.savefig(path, format="png")
    return path
