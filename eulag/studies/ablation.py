"""The ablation of eulag's departures from the reference paper's model (``eulag study
scenes-ablation``): each departure of :data:`eulag.config.DEVIATIONS` switched alone, and all
together (``profile = "paper"``), on proxies of the scenes whose pattern decides between the
models (b, d, h: four cells in the paper; c, e, g: two cells, c and g without inter-particle
collisions, where the paper's pair turns up on the axis; e, g: their strength).

A proxy is the scene's case file on a coarse grid with fewer parcels (:data:`PROXY_NUMERICS`):
the same pipe, station, particles and wall, so that one run takes minutes, not hours.  The
pattern metrics read the mirror-symmetric part of the section (``eulag.analysis.pattern_metrics``),
which noise of this parcel count does not turn into odd cell counts.  The table puts the paper's
pattern beside every row.  The proxies are not the scenes: their strengths and -dp/dx differ from
the full-resolution runs; what the table shows is which model ingredient moves the pattern.

Variants (one run per scene each): ``eulag`` (the defaults); ``<key>=<paper's form>`` for every
departure whose paper form differs from the default (among them ``partner_momentum=discarded``,
the fictitious partners of Sommerfeld 2001, since the momentum-returning treatment became the
default; left out for the two-way scenes, which have no collisions); ``paper`` (every departure
at the paper's form); on request (``--variants``) also the ingredients of
:data:`INGREDIENT_VARIANTS` switched off.  The committed table
(results/scenes-ablation) was run while the default was the discarded impulse, with
``partner_momentum=returned`` as an extra variant at the returned impulse's earlier gain α.
"""

from __future__ import annotations

import math
from pathlib import Path

from eulag.config import DEVIATIONS, PAPER_MODEL, CASES_DIR, Case, CaseError

from .patterns import PAPER_PATTERN, PAPER_SENSE, pattern_columns
from .report import Column, _run_cells, _run_columns, _settings_text, write_report
from .runner import _BadInput, _finish, _quick, _select, _with_parcels, run_case

ABLATION_SCENES = tuple("bcdegh")
#: The proxies' numerics: the studies' pipe on a 40 x 10 x 20 grid, 4,000 parcels in the early
#: and 8,000 in the final passes (about 1/80 of the scenes' cells and 1/30 of their parcels).
PROXY_NUMERICS = {"axial_cells": 40, "radial_cells": 10, "azimuthal_cells": 20, "parcels": 8000,
                  "parcels_start": 4000, "batch_size": 250, "max_passes": 40}


#: Model ingredients that are not departures from the paper, switched on request
#: (``--variants``) to find which one decides a pattern: the lift forces off, and the drift
#: correction's time factor of the particle's correlation (the former default).  Not in the
#: default set.
INGREDIENT_VARIANTS: tuple[tuple[str, dict], ...] = (
    ("saffman_mei_lift=false", {"physics": {"saffman_mei_lift": False}}),
    ("magnus_lift=false", {"physics": {"magnus_lift": False}}),
    ("langevin_drift_form=particle", {"physics": {"langevin_drift_form": "particle"}}),
)
#: Departures that only act through the inter-particle collisions (skipped for two-way scenes,
#: where they would repeat the ``eulag`` row).
_COLLISION_ONLY = ("physics.partner_momentum",)


def variants(case: Case | None = None, ingredients: bool = False) -> list[tuple[str, dict]]:
    """(label, changes for Case.replace) of every ablation variant, in the table's order.

    ``case``: the scene's case; a departure that acts only through the inter-particle collisions
    is left out when the case has none.  ``ingredients``: also :data:`INGREDIENT_VARIANTS`."""
    collisions = case is None or case.physics.inter_particle_collisions
    out = [("eulag", {})]
    for key, (ours, paper, _) in DEVIATIONS.items():
        section, leaf = key.split(".")
        if paper != ours and (collisions or key not in _COLLISION_ONLY):
            out.append((f"{leaf}={_text(paper)}", {section: {leaf: paper}}))
    out.append(("paper", PAPER_MODEL))
    if ingredients:
        out.extend(INGREDIENT_VARIANTS)
    return out


def _text(v) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else str(v)


def ablation_cases(quick: bool, scenes=ABLATION_SCENES, labels=None,
                   parcels: int | None = None) -> list[tuple[str, str, str, Case]]:
    """(run name, scene, variant label, case) of every run: the proxy of each scene (quick: the
    studies' quick numerics instead) under every variant (``labels``: a subset)."""
    out = []
    for s in scenes:
        base = Case.from_toml(CASES_DIR / "scenes" / f"scene_{s}.toml")
        base = _quick(base) if quick else base.replace(numerics=PROXY_NUMERICS)
        for label, changes in variants(base, ingredients=labels is not None):
            if labels is not None and label not in labels:
                continue
            name = f"proxy_{s}__{label.replace('=', '-')}"
            case = base.replace(name=name, **changes)
            out.append((name, s, label, _with_parcels(case, parcels)))
    return out


def _axis_k_single_phase(case: Case) -> float:
    """Gas k on the axis (innermost ring, section mean) at the case's first station, without
    particles: the reference of the axis-k ratio (one gas solve, cached per grid)."""
    key = (case.pipe, case.gas, case.numerics.axial_cells, case.numerics.radial_cells,
           case.numerics.azimuthal_cells)
    if key not in _SINGLE:
        from eulag import analysis as an
        from eulag import runs

        ds = runs.execute(case.replace(particles=None, name="single_phase_reference")).dataset
        _SINGLE[key] = float(an.section(ds, case.pipe.sections[0])["gas_k"].values[0].mean())
    return _SINGLE[key]


_SINGLE: dict = {}


def extract_metrics(ds, case: Case) -> dict:
    """The ablation's metrics of one finished run at its first station."""
    from eulag import analysis as an

    x = case.pipe.sections[0]
    m = an.pattern_metrics(ds, x)
    sec = an.section(ds, x)
    k_axis = float(sec["gas_k"].values[0].mean())
    out = {"cells": m["count_symmetrised"], "cells_raw": m["count_raw"], "index": m["mode_index"],
           "uy_pattern": an.sign_text(m["uy_sign_pattern"]),
           "sense": m["main_pair_sense"] or "-", "strength": m["strength"],
           "interior": m["interior_solenoidal_max"], "peak_ratio": m["upper_lower_peak_ratio"],
           "dpdx": float(sec["pressure_gradient"].values), "k_axis": k_axis / _axis_k_single_phase(case)}
    out.update({f"pattern_{k}": v for k, v in pattern_columns(ds, x).items()})
    for c in "xyz":
        name = f"particle_collision_force_total_{c}"
        out[f"coll_{c}"] = float(ds[name]) if name in ds else math.nan
        out[f"coll_{c}_se"] = float(ds[name + "_stderr"]) if name + "_stderr" in ds else math.nan
    return out


def study_scenes_ablation(args, outdir: Path, t_start: float) -> int:
    names = _select(getattr(args, "only", None), list(ABLATION_SCENES), "scenes")
    labels = None
    if getattr(args, "variants", None) is not None:
        known = [v for v, _ in variants(ingredients=True)]
        labels = [v.strip() for v in args.variants.split(",") if v.strip()]
        bad = [v for v in labels if v not in known]
        if bad or not labels:
            raise _BadInput(f"--variants {args.variants}: unknown {', '.join(bad) or '(none given)'}; "
                            f"allowed: {', '.join(known)}")
    try:
        runs_ = ablation_cases(args.quick, names, labels, getattr(args, "parcels", None))
    except CaseError as exc:
        raise _BadInput(str(exc)) from None
    if not runs_:
        raise _BadInput(f"--variants {args.variants}: none of them applies to scenes {', '.join(names)} "
                        f"(a collision-only departure has no run in a two-way scene)")
    records = []
    for i, (name, scene, label, case) in enumerate(runs_, 1):
        records.append(run_case(args, name, case, outdir, f"[ablation {i}/{len(runs_)}] {name}",
                                lambda ds, rec, case=case: extract_metrics(ds, case)))
    rows = []
    for (name, scene, label, case), rec in zip(runs_, records):
        paper_cells, paper_text = PAPER_PATTERN[scene]
        coll = rec.metrics.get("coll_y")
        coll_se = rec.metrics.get("coll_y_se")
        rows.append({"scene": scene, "variant": label, "paper": paper_text,
                     **{k: rec.metrics.get(k) for k in ("cells", "pattern_cells_sym", "pattern_index", "uy_pattern",
                                                        "sense", "pattern_second", "strength", "interior",
                                                        "peak_ratio", "dpdx", "k_axis")},
                     "coll_y": (f"{coll:+.2g} ± {coll_se:.1g}" if coll is not None and math.isfinite(coll)
                                else None),
                     "matches": _matches(rec.metrics.get("cells"), rec.metrics.get("sense"), paper_cells,
                                         PAPER_SENSE.get(scene)),
                     **_run_cells(rec)})
    columns = [Column("scene", "scene"), Column("variant", "variant"), Column("paper", "paper's pattern"),
               Column("pattern_cells_sym", "cells (symmetrised; replica agreement)"),
               Column("pattern_index", "sin2θ/cosθ index ± replicas"),
               Column("uy_pattern", "u_y signs bottom→top"), Column("sense", "main pair"),
               Column("pattern_second", "second pair [% of max ψ_s], centre y/R"),
               Column("strength", "strength [% U0]", "{:.3g}"), Column("interior", "interior max [% U0]", "{:.3g}"),
               Column("peak_ratio", "ψ upper/lower", "{:.2f}"), Column("dpdx", "-dp/dx [Pa/m]", "{:.4g}"),
               Column("k_axis", "axis k / single-phase", "{:.2f}"),
               Column("coll_y", "collision force y [N]"), Column("matches", "pattern as the paper"),
               *_run_columns()]
    intro = [
        "Each departure of eulag's model from the reference paper's (`eulag.config.DEVIATIONS`; "
        "docs/physics.md, \"Departures from the reference paper\") switched alone to the paper's "
        "form (among them the discarded partners' impulse, `physics.partner_momentum = \"discarded\"`), "
        "and all departures at the paper's form (`profile = \"paper\"`), on proxies of scenes "
        + ", ".join(names) + " (the scene's case file on the numerics "
        f"{PROXY_NUMERICS}; quick mode: the studies' quick numerics).",
        "",
        "Columns: cells = recirculation cells of the mirror-symmetrised stream function "
        "(`eulag.analysis.pattern_metrics`, count_symmetrised; odd counts cannot occur); index = "
        "amplitude of sin 2θ over cos θ in the symmetrised stream function (> 1 four-cell-like); u_y "
        "signs = the signs of the mirror-even vertical gas velocity along the vertical diameter from the "
        "bottom wall up (four cells: one change); main pair = rotation sense of the strongest cell "
        "pair (\"up on the axis\" is the paper's collision-free two-cell sense); second pair = the "
        "strongest cell turning against the main pair at any strength, in % of the symmetrised stream "
        "function's maximum, and the y/R of its centre (the count keeps only cells above 10 %); strength = largest "
        "in-plane gas speed; interior max = largest speed of the solenoidal part outside the wall ring; "
        "ψ upper/lower = peak ratio of the symmetrised stream function; axis k = gas k on the axis over "
        "its single-phase value on the same grid; collision force y = the pipe integral of the net "
        "vertical force of the inter-particle collisions on the particles ± its standard error (zero "
        "for momentum-conserving collisions). The proxies are not the scenes: compare rows of one "
        "scene with each other, not with the paper's strengths."]
    write_report(outdir, "scenes-ablation", args, title="Ablation of the departures from the paper's model "
                 "(scene proxies)", intro=intro, columns=columns, rows=rows, figures=[], t_start=t_start,
                 settings=_settings_text([c for *_, c in runs_], args.quick), records=records)
    return _finish(args, outdir, records, allowed_failures=True)


def _matches(cells, sense, paper_cells, paper_sense=None) -> str | None:
    """"yes" when the cell count is the paper's and, where the paper states it, the main pair's
    sense too; "no (sense)" when only the sense differs."""
    if cells is None:
        return None
    if int(cells) != paper_cells:
        return "no"
    return "no (sense)" if paper_sense is not None and sense != paper_sense else "yes"
