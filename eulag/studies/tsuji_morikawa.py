"""The Tsuji-Morikawa comparison (``eulag study tsuji-morikawa``): the base case at U0 = 10 and
15 m/s, four-way and two-way coupling, against the digitised profiles of Tsuji & Morikawa
(1982, J. Fluid Mech. 120, 385-409)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from eulag.config import Case

from .profiles import diameter_profile, profile_deviation, provenance, read_measurements
from .report import (COLLISION_MOMENTUM_TEXT, Column, _figure, _per_run_figures, _run_cells, _run_columns,
                     _settings_text, _station, _stations_text, write_csv, write_report)
from .runner import BASE_CASE, _BadInput, _base_case, _finish, _with_parcels, refuse_report_of_nothing, run_case


TM_VELOCITIES = (10.0, 15.0)
TM_COUPLINGS = ("four-way", "two-way")


def tsuji_morikawa_cases(quick: bool, parcels: int | None = None) -> list[tuple[str, Case]]:
    """The four runs: base case at U0 = 10 and 15 m/s, four-way and two-way coupling."""
    base = _with_parcels(_base_case(quick), parcels)
    out = []
    for u0 in TM_VELOCITIES:
        for coupling in TM_COUPLINGS:
            name = f"tm_U{u0:g}_{coupling}"
            case = base.replace(name=name, description=f"{base.description}; U0 = {u0:g} m/s, {coupling}",
                                gas={"bulk_velocity": u0}, physics={"coupling": coupling})
            out.append((name, case))
    return out


def study_tsuji_morikawa(args, outdir: Path, t_start: float) -> int:
    cases = tsuji_morikawa_cases(args.quick, getattr(args, "parcels", None))
    base = cases[0][1]
    ref_path = base.reference_data_path()
    if ref_path is None:
        raise _BadInput(f"{BASE_CASE}: pipe.reference_data names no existing file")
    meas = read_measurements(ref_path)
    x = base.pipe.sections[0]
    figdir = outdir / "figures"
    records = []
    curves = {}
    for i, (name, case) in enumerate(cases, 1):
        u0 = case.gas.bulk_velocity

        def extract(ds, rec, u0=u0, name=name):
            ys = np.linspace(-1.0, 1.0, 201)
            m = {"curves": {
                "y": ys,
                "gas": diameter_profile(ds, "gas_ux", x, ys, wall_value=0.0, scale=u0),
                "particle": diameter_profile(ds, "particle_ux", x, ys, scale=u0),
                "particle_se": diameter_profile(ds, "particle_ux_stderr", x, ys, scale=u0)}}
            for phase in ("gas", "particle"):
                if phase not in meas:
                    continue
                yp, up = meas[phase]["y_over_R"], meas[phase]["u"]
                if phase == "gas":
                    sim = diameter_profile(ds, "gas_ux", x, yp, wall_value=0.0, scale=u0)
                    se = None
                else:
                    sim = diameter_profile(ds, "particle_ux", x, yp, scale=u0)
                    se = diameter_profile(ds, "particle_ux_stderr", x, yp, scale=u0)
                m[phase] = profile_deviation(sim, up, se)
                m[f"{phase}_points"] = [{"run": name, "phase": phase, "y_over_R": float(a), "measured": float(b),
                                         "simulated": float(c), "stderr": float(d) if se is not None else None}
                                        for a, b, c, d in zip(yp, up, sim, se if se is not None else sim)]
            _per_run_figures(ds, x, figdir)
            m["x_station"] = _station(ds, x)
            return m

        rec = run_case(args, name, case, outdir, f"[tsuji-morikawa {i}/{len(cases)}] {name}", extract)
        records.append(rec)
        if "curves" in rec.metrics:
            curves[name] = rec.metrics["curves"]

    refuse_report_of_nothing(args, records, outdir)  # before the points' CSV is written
    rows = []
    for (name, case), rec in zip(cases, records):
        for phase in ("gas", "particle"):
            dev = rec.metrics.get(phase, {})
            rows.append({"run": name, "U0": case.gas.bulk_velocity, "coupling": case.physics.coupling,
                         "phase": phase, "rms": dev.get("rms"), "max": dev.get("max"),
                         "bias": dev.get("bias"), "stderr": dev.get("stderr"),
                         "points": dev.get("points"), **_run_cells(rec)})
    columns = [Column("U0", "U0 [m/s]", "{:g}"), Column("coupling", "coupling"), Column("phase", "phase"),
               Column("rms", "RMS dev. [% U0]", "{:.2f}"), Column("max", "max dev. [% U0]", "{:.2f}"),
               Column("bias", "mean dev. [% U0]", "{:+.2f}"),
               Column("stderr", "sim. std. error [% U0]", "{:.2f}"), Column("points", "points", "{:d}"),
               *_run_columns()]
    points = [pt for rec in records for ph in ("gas", "particle") for pt in rec.metrics.get(f"{ph}_points", [])]
    write_csv(outdir / "tsuji-morikawa_points.csv",
              [Column("run", ""), Column("phase", ""), Column("y_over_R", ""), Column("measured", ""),
               Column("simulated", ""), Column("stderr", "")], points)
    figures = []
    if curves:
        stations = sorted({round(r.metrics["x_station"], 4) for r in records if "x_station" in r.metrics})
        where = f"x = {x:g} m" if stations in ([], [round(x, 4)]) else \
            f"station x = {', '.join(f'{s:g}' for s in stations)} m (nearest {x:g} m)"
        figures.append(_tm_figure(outdir / "tsuji_morikawa_profiles.png", cases, curves, meas, where,
                                  quick=bool(getattr(args, "quick", False))))
    figures += sorted(figdir.glob("*_section*.png")) if figdir.is_dir() else []
    prov = "\n".join("    " + line for line in provenance(ref_path))
    intro = [
        f"Gas and particle mean axial velocity along the vertical diameter at x = {x:g} m of the base "
        f"case ({BASE_CASE.name}: D_p = {base.particles.diameter * 1e6:g} µm, eta = "
        f"{base.particles.mass_loading:g}, Delta-gamma = {base.walls.roughness_angle_std_deg:g} deg) "
        f"against the measurements of Tsuji & Morikawa (1982) in `{ref_path.name}`."
        + _stations_text(records, x),
        "",
        "The digitised profiles are normalised by 15 m/s and the source does not confirm the air "
        "velocity, so the case is run at U0 = 10 and 15 m/s and each run's profile is normalised by "
        "its own U0. Deviation = simulation - measurement at the measured points (the simulated "
        "profile interpolated linearly in y; particles: beyond the outermost cell centre with "
        "particles, that cell's value), in % of U0: RMS, maximum of the absolute value, and mean "
        "(bias). 'sim. std. error' is the RMS over the points of the particle velocity's batch "
        "standard error (`particle_ux_stderr`, final passes averaged); the gas field is "
        "deterministic given the relaxed particle sources and has no standard error of its own "
        "(their noise reaches it through the sources). The digitising error of the measured points "
        "is about ±1-2 % of the reference velocity (file header). Point by point (u_x / U0 at each "
        "measured y/R, measured and simulated, with the particle standard error): "
        "[tsuji-morikawa_points.csv](tsuji-morikawa_points.csv). Last two columns: "
        + COLLISION_MOMENTUM_TEXT + ".",
        "",
        "Provenance of the measurements (header of the file):", "", prov]
    write_report(outdir, "tsuji-morikawa", args, title="Tsuji–Morikawa comparison", intro=intro,
                 columns=columns, rows=rows, figures=figures, t_start=t_start,
                 settings=_settings_text([c for _, c in cases], args.quick), records=records)
    return _finish(args, outdir, records, allowed_failures=False)


def _tm_figure(path: Path, cases, curves, meas, where: str, quick: bool = False) -> Path:
    fig = _figure()(11.0, 5.6)
    axes = fig.subplots(1, 2, sharey=True)
    styles = {10.0: "-", 15.0: "--"}
    colours = {"four-way": "C0", "two-way": "C3"}
    for ax, phase in zip(axes, ("gas", "particle")):
        if phase in meas:
            ax.plot(meas[phase]["u"], meas[phase]["y_over_R"], "ko", mfc="none",
                    label="Tsuji & Morikawa (1982), U/15 m/s")
        for name, case in cases:
            c = curves.get(name)
            if c is None:
                continue
            u0, cpl = case.gas.bulk_velocity, case.physics.coupling
            ax.plot(c[phase], c["y"], styles.get(u0, ":"), color=colours.get(cpl, "k"),
                    label=f"eulag U0 = {u0:g} m/s, {cpl}")
            if phase == "particle":
                lo, hi = c["particle"] - 2 * c["particle_se"], c["particle"] + 2 * c["particle_se"]
                ax.fill_betweenx(c["y"], lo, hi, color=colours.get(cpl, "k"), alpha=0.12, lw=0)
        ax.set_xlabel("u_x / U0 [1]")
        ax.set_title(f"{phase}, {where}" + ("  (band: ±2 std. errors)" if phase == "particle" else "")
                     + ("\nquick mode: checks the machinery, not results" if quick else ""), fontsize=10)
        ax.set_xlim(left=0.0)
        ax.set_ylim(-1.0, 1.0)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y / R [1] (top +1, bottom -1, gravity down)")
    axes[0].legend(fontsize=7, loc="lower left")
    fig.savefig(path, format="png")
    return path
