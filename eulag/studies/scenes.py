"""The secondary-flow scene matrix a-h (``eulag study scenes``): the shipped scene files
``cases/scenes/scene_<a..h>.toml`` at x = 3.56 m, with the secondary-flow strength, the
recirculation cells, the half holding the gas maximum, the wall impact rates and -dp/dx."""

from __future__ import annotations

import math
from pathlib import Path

from eulag.analysis import attr as _attr
from eulag.config import CASES_DIR, Case, CaseError

from .report import (COLLISION_MOMENTUM_TEXT, Column, _per_run_figures, _run_cells, _run_columns,
                     _settings_text, _station, _stations_text, write_report)
from .patterns import PAPER_PATTERN, PATTERN_COLUMNS, PATTERN_KEYS, pattern_columns
from .runner import _BadInput, _finish, _quick, _select, _with_parcels, run_case

SCENES_DIR = CASES_DIR / "scenes"
SCENE_NAMES = tuple("abcdefgh")


def scene_cases(quick: bool, names=SCENE_NAMES, parcels: int | None = None) -> list[tuple[str, Case]]:
    """The shipped scene files cases/scenes/scene_<a..h>.toml (quick: with the quick numerics)."""
    out = []
    for s in names:
        path = SCENES_DIR / f"scene_{s}.toml"
        case = Case.from_toml(path)
        out.append((f"scene_{s}", _with_parcels(_quick(case) if quick else case, parcels)))
    return out


def scene_metrics(ds, x: float, figdir: Path | None = None) -> dict:
    """The scene table's numbers of a coupled dataset at the station nearest x [m] (pattern
    metrics with their replica error bars, strength, cells, gas-maximum half, wall impacts, -dp/dx
    and its single-phase ratio); with ``figdir``, the run's figures are written there too."""
    from eulag import analysis as an

    sec = an.section(ds, x)
    rates = an.wall_impact_rates(ds, x)
    dp = float(sec["pressure_gradient"].values)
    dp0 = float(sec["pressure_gradient_single_phase"].values)
    figs = _per_run_figures(ds, x, figdir) if figdir is not None else []
    # -dp/dx at the station solved on each final pass's sources alone (in their order)
    reps = ([float(v) for v in ds["replica_pressure_gradient"].sel(x=x, method="nearest").values]
            if "replica_pressure_gradient" in ds else [])
    return {**pattern_columns(ds, x),
            "strength": an.secondary_flow_strength(ds, x), "cells": an.recirculation_cells(ds, x),
            "half": an.gas_maximum_half(ds, x), "impact_upper": rates["upper"],
            "impact_lower": rates["lower"], "dpdx": dp, "dpdx_ratio": dp / dp0 if dp0 else math.nan,
            "dpdx_replicas": reps,
            "x_station": _station(ds, x), "u0": float(_attr(ds, "gas.bulk_velocity")),
            "figures": [str(f) for f in figs]}


def study_scenes(args, outdir: Path, t_start: float) -> int:
    names = _select(getattr(args, "only", None), list(SCENE_NAMES), "scenes")
    try:
        cases = scene_cases(args.quick, names, getattr(args, "parcels", None))
    except CaseError as exc:
        raise _BadInput(str(exc)) from None
    figdir = outdir / "figures"
    records = []
    for i, (name, case) in enumerate(cases, 1):
        x = case.pipe.sections[0]

        def extract(ds, rec, x=x):
            return scene_metrics(ds, x, figdir)

        records.append(run_case(args, name, case, outdir, f"[scenes {i}/{len(cases)}] {name}", extract))

    rows = []
    for (name, case), rec in zip(cases, records):
        p = case.particles
        eta0 = 2.2
        rows.append({"scene": name.split("_")[-1], "dp_um": p.diameter * 1e6,
                     "dgamma": case.walls.roughness_angle_std_deg, "coupling": case.physics.coupling,
                     "loading": f"{p.mass_loading / eta0:g} eta0 = {p.mass_loading:g}",
                     **{k: rec.metrics.get(k) for k in ("strength", "cells", "half", "impact_upper",
                                                        "impact_lower", "dpdx", "dpdx_ratio", *PATTERN_KEYS)},
                     "paper": PAPER_PATTERN[name.split("_")[-1]][1],
                     **_run_cells(rec)})
    columns = [Column("scene", "scene"), Column("dp_um", "D_p [µm]", "{:g}"),
               Column("dgamma", "Δγ [deg]", "{:g}"), Column("coupling", "coupling"),
               Column("loading", "loading"), Column("strength", "secondary flow [% U0]", "{:.3g}"),
               Column("cells", "recirc. cells", "{:d}"), *PATTERN_COLUMNS, Column("paper", "paper's pattern"),
               Column("half", "gas max in half"),
               Column("impact_upper", "wall impacts upper [1/(m² s)]", "{:.3g}"),
               Column("impact_lower", "wall impacts lower [1/(m² s)]", "{:.3g}"),
               Column("dpdx", "-dp/dx [Pa/m]", "{:.4g}"), Column("dpdx_ratio", "/ single-phase", "{:.3f}"),
               *_run_columns()]
    figures = []
    for rec in records:
        figures += [Path(f) for f in rec.metrics.get("figures", []) if "_section" in Path(f).name]
    x0 = cases[0][1].pipe.sections[0] if cases else 3.56
    intro = [
        f"The secondary-flow scene matrix of the reference paper at x = {x0:g} m, U0 = 10 m/s, "
        "rho_p = 1020 kg/m³, eta0 = 2.2. One case file per scene ships in `cases/scenes/` "
        "(`scene_<a..h>.toml`, derived from the base case `cases/tsuji_morikawa_200um.toml`; the "
        "header of each says what differs)." + _stations_text(records, x0),
        "",
        "Columns: secondary-flow strength = largest in-plane gas speed in % of U0 "
        "(`eulag.analysis.secondary_flow_strength`); recirculation cells = connected same-sign "
        "regions of the in-plane stream function above 10 % of its maximum "
        "(`recirculation_cells`); the pattern metrics of the mirror-symmetrised section "
        "(`eulag.analysis.pattern_metrics`, ± the standard error of the replicas, the gas solved on "
        "each final pass's own sources), among them the second pair = the strongest cell turning "
        "against the main pair at any strength, in % of the symmetrised stream function's maximum, "
        "and the y/R of its centre (the count keeps only cells above 10 %); the half (upper y > 0 / "
        "lower y < 0) holding the maximum of the gas "
        "axial velocity; particle-wall impacts per wall area and time on the upper and lower wall "
        "halves at the station; the section-mean -dp/dx at the station and its ratio to the "
        "single-phase value; coupling passes and run time; " + COLLISION_MOMENTUM_TEXT + ". "
        "Figures: the three-panel section figure of "
        "each scene (gas axial velocity with the secondary-flow stream lines, particle axial "
        "velocity, particle concentration / section mean); profile and convergence figures of each "
        "scene are in `figures/`."]
    write_report(outdir, "scenes", args, title="Secondary-flow scene matrix (scenes a–h)", intro=intro,
                 columns=columns, rows=rows, figures=figures, t_start=t_start,
                 settings=_settings_text([c for _, c in cases], args.quick), records=records)
    return _finish(args, outdir, records, allowed_failures=False)
