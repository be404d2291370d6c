"""Plug conveying in a horizontal tube (``eulag study strauss``): the dense-phase DEM–Darcy
model (:mod:`eulag.slug`) on the system of Strauß, McNamara & Herrmann (SMH), "Plug conveying in
a horizontal tube", Granular Matter 8, 213–219 (2006), doi:10.1007/s10035-006-0009-0.

The runs (each a variant of ``cases/slug/strauss_horizontal.toml`` or ``strauss_vertical.toml``
through :func:`eulag.studies.runner.run_case`; names ``strauss__vs-1.0__feed-2.49[__eta-…][__mu-…][__t-…]``):

* ``default``: the paper's default run (v_s = 1 m/s, 2.49 kg/h, η = 0.0673 cP, μ = 0.5), a 4 s
  window as Fig. 1;
* ``curves``: the characteristic curves of Fig. 3, Δp against the superficial gas velocity v_s
  for the feed rates 2.49 and 9.95 kg/h, v_s from below the resting-bulk threshold to the
  nearly empty tube (0.2–5 m/s);
* ``mass-flux``: Δp against the solids feed at v_s = 1 m/s (Fig. 5);
* ``viscosity``: Δp against the effective gas viscosity η = 0.045, 0.0673, 0.085 cP (Fig. 6);
* ``friction``: Δp against the Coulomb coefficient μ (grain–grain and grain–wall, Fig. 7;
  0.05–0.9, around the paper's sliding-layer peak at μ ≈ 0.1);
* ``vertical``: the same tube with gravity along the axis (SMH §4);
* ``long`` (only with ``--long``; hours): the 22.5 s statistics run of §3.2.

Every run but the long one simulates ``--window`` seconds (default: the case files' 4 s). The
numbers of a run are taken over its records with t ≥ t_from = min(end/2, 6 s) (the horizontal
tube at the default feed fills in ≈ 6 s; results/strauss/README.md): :func:`eulag.slug.summarize`
(Δp, Δp/L, grains in the tube; slugs of ≥ 100 grains centred in the middle of the tube,
15–40 cm of the 52.5 cm tube, scaled with the tube length: minimum porosity, length, grain
count, velocity) and the maximum overlap / d and grains lost of the whole run.

Regime (SMH Fig. 3), :func:`classify_regime`, from the porosity φ and grain velocity u of the
cross-section slices (3.5 mm) of the records with t ≥ t_from; s = 1 − φ is a slice's solids
fraction, a slice is *dense* when φ < 0.6 (the slug criterion of the catalogue, an open packing
of these grains):

* dense share = Σ s over dense slices / Σ s over all slices — the share of the solids in the
  tube that sits in slugs or packings;
* push speed u_push = max(1.5 v_feed, 0.01 m/s), v_feed the speed at which the feed pushes its
  packing in (0.0446 m/s at 2.49 kg/h): a packing that only the feed moves goes at v_feed
  (slower where it is compacted below the feed porosity); the factor 1.5 leaves room for the
  noise of a slice mean, the floor of 0.01 m/s for a tube without feed;
* moving share = Σ s over slices with u > u_push / Σ s — the share of the solids that the gas,
  not the feed, moves; computed over all slices and over the dense slices alone.

Rules, in order: **nearly empty tube** when the tube holds no grains in the window, or when the
dense share is below 0.5 *and* the moving share of all solids is at least 0.5 — the grains are
carried through dispersed, as single grains or small groups that do not fill the section (SMH
§3.1: at high v_s "the plugs no longer contain the majority of the particles"); a resting layer
between slugs holds many grains but does not move, so the slug regime with a thick layer is not
taken for an empty tube; **resting bulk** when less than 0.1 of the dense solids (of all
solids when no slice is dense) moves faster than u_push: the drag does not overcome the wall
friction and the packing moves only as fast as the feed pushes it; **slugs** otherwise: dense
packings that the gas drives faster than the feed. The outflow over the feed is reported beside
the regime but is not part of the rule: before the tube has filled, no grain leaves in either the
resting-bulk or the slug regime, and once it has, mass conservation makes the outflow equal the
feed in every regime. The thresholds come from these physical
statements, not from the paper's regime boundaries.

Outputs in ``-o DIR`` (default results/strauss): ``<run>.nc`` (not committed), the run records
``<run>.record.json`` (what the tables and figures take from a dataset; ``--resume`` /
``--report`` use them when the dataset is absent), ``strauss.csv``, the figures (Fig. 3
characteristic curves with the regime as the marker, Δp against grains in the tube, Δp against
mass flux, η and μ, the space–time porosity plot of the default, vertical and long runs) and
a generated section of ``README.md`` between the markers ``BEGIN`` / ``END`` (text outside them — the
hand-written record of runs made before the study — is kept).

``--quick``: a 7 cm tube (20 gas cells), 0.02 s per run, a few points per curve; seconds per
run, not results.
"""

from __future__ import annotations

import copy
import math
import os
import time
from pathlib import Path

import numpy as np

from eulag.config import CASES_DIR

from .report import Column, _figure, draw_figures, machine_info, markdown_table, study_command, write_csv
from .runner import RunRecord, _BadInput, _finish, _log, _select, refuse_report_of_nothing, run_case

STUDY = "strauss"
CASE_DIR = CASES_DIR / "slug"
GROUPS = ("default", "curves", "mass-flux", "viscosity", "friction", "vertical", "long")
#: the plan of the full study
VELOCITIES = (0.2, 0.3, 0.4, 0.6, 1.0, 2.0, 3.0, 4.0, 5.0)
FEEDS = (2.49, 9.95)
MASS_FLUX_FEEDS = (1.245, 2.49, 4.98, 7.47, 9.95)
VISCOSITIES_CP = (0.045, 0.0673, 0.085)
FRICTIONS = (0.05, 0.1, 0.15, 0.3, 0.5, 0.7, 0.9)
LONG_END_S = 22.5
#: the quick plan
QUICK_VELOCITIES = {2.49: (0.2, 1.0, 5.0), 9.95: (1.0,)}
QUICK_MASS_FLUX_FEEDS = (2.49, 9.95)
QUICK_VISCOSITIES_CP = (0.045, 0.0673, 0.085)
QUICK_FRICTIONS = (0.1, 0.5, 0.9)
QUICK_CHANGES = {"tube": {"length_m": 0.07}, "numerics": {"cells_x": 20, "end_time_s": 0.02,
                 "output_interval_s": 0.005, "checkpoint_interval_s": 0.01}}
DEFAULT_VS, DEFAULT_FEED, DEFAULT_ETA_CP, DEFAULT_MU = 1.0, 2.49, 0.0673, 0.5
#: simulated time of a run continued from a filled-tube state (--from-state); its statistics
#: are taken over the second half
FROM_STATE_WINDOW_S = 3.0
#: A run whose outflow over its statistics window is less than this share of the feed is still
#: filling (from an empty tube the first grains leave the horizontal tube at t ≈ 7 s, the
#: vertical one at 5.7 s; filled runs give 0.97–1.03): its numbers are not the paper's steady
#: state, and the comparison says so instead of judging them.  A reporting choice of ours.
FILLED_OUTFLOW_SHARE = 0.8

# the regime rule (module docstring)
DENSE_SHARE_MIN = 0.5
PUSH_FACTOR = 1.5
U_REST = 0.01
MOVING_SHARE_MAX = 0.1
MOVING_ALL_MIN = 0.5
REGIMES = ("resting bulk", "slugs", "nearly empty tube")
MARKERS = {"resting bulk": "s", "slugs": "o", "nearly empty tube": "^"}

BEGIN = "<!-- BEGIN generated by `eulag study strauss`; edit by re-running the study -->"
END = "<!-- END generated by `eulag study strauss` -->"


# ---------------------------------------------------------------------------- regime
def classify_regime(ds, t_min: float = 0.0, t_max: float = math.inf) -> dict:
    """The regime of SMH Fig. 3 of a slug dataset over its records with t_min ≤ time ≤ t_max: a
    dict with ``regime`` ("resting bulk" | "slugs" | "nearly empty tube") and the numbers behind
    it (``dense_share``, ``moving_share`` of the dense solids, ``moving_share_all`` of all solids,
    ``push_speed_m_s``, ``dense_velocity_m_s`` the
    solids-weighted mean grain velocity of the dense slices, ``outflow_per_feed``,
    ``grains_in_tube_window`` and ``pressure_drop_Pa`` the window's means); the rule is in the
    module docstring."""
    from eulag.slug import SLUG_POROSITY

    t = np.asarray(ds["time"].values, float)
    sel = (t >= t_min) & (t <= t_max)
    if not sel.any():
        sel = np.ones_like(t, bool)
    phi = np.asarray(ds["porosity"].values, float)[sel]
    u = np.asarray(ds["grain_velocity"].values, float)[sel]
    s = np.clip(1.0 - phi, 0.0, 1.0)
    s = np.where(np.isfinite(s), s, 0.0)
    u = np.where(np.isfinite(u), u, 0.0)
    v_feed = float(ds.attrs.get("feed_speed_m_s", 0.0) or 0.0)
    push = max(PUSH_FACTOR * v_feed, U_REST)
    dense = phi < SLUG_POROSITY
    total, sd = float(s.sum()), float(s[dense].sum())
    n_tube = float(np.mean(np.asarray(ds["grains_in_tube"].values, float)[sel]))
    moving = u > push
    out = {"push_speed_m_s": push, "grains_in_tube_window": n_tube,
           "pressure_drop_Pa": float(np.mean(np.asarray(ds["pressure_drop"].values, float)[sel]))
           if "pressure_drop" in ds else math.nan,
           "dense_share": sd / total if total > 0 else math.nan,
           "moving_share_all": float(s[moving].sum()) / total if total > 0 else math.nan,
           "moving_share": float(s[dense & moving].sum()) / sd if sd > 0 else math.nan,
           "dense_velocity_m_s": float((s * u)[dense].sum()) / sd if sd > 0 else math.nan}
    out["outflow_per_feed"] = _outflow_per_feed(ds, sel)
    if total <= 0 or n_tube < 1.0 or (out["dense_share"] < DENSE_SHARE_MIN and out["moving_share_all"] >= MOVING_ALL_MIN):
        out["regime"] = "nearly empty tube"
    elif (out["moving_share"] if sd > 0 else out["moving_share_all"]) < MOVING_SHARE_MAX:
        out["regime"] = "resting bulk"
    else:
        out["regime"] = "slugs"
    return out


def _outflow_per_feed(ds, sel) -> float:
    """Grain mass leaving through the outlet over the window over the feed's mass in that time
    (NaN: a periodic tube, no feed, or a window of one record).  ``outflow_count`` counts from
    the run's start, one output interval before its first record (t = 0, or the time of the state
    a continued run starts from); a window beginning at the first record is measured from there."""
    import json

    try:
        c = json.loads(ds.attrs["case"])
        if c["tube"]["periodic"] or "outflow_count" not in ds:
            return math.nan
        mdot = c["feed"]["mass_flow_kg_h"] / 3600.0
        d, rho = c["grains"]["diameter_m"], c["grains"]["density_kg_m3"]
        interval = float(c["numerics"]["output_interval_s"])
    except (KeyError, TypeError, ValueError):
        return math.nan
    t = np.asarray(ds["time"].values, float)
    idx = np.flatnonzero(sel)
    if mdot <= 0 or len(idx) < 2:
        return math.nan
    out = np.asarray(ds["outflow_count"].values, float)
    i0 = idx[0] - 1 if idx[0] > 0 else None
    n0, t0 = (out[i0], t[i0]) if i0 is not None else (0.0, t[0] - interval)
    m_p = rho * math.pi * d ** 3 / 6.0
    return float((out[idx[-1]] - n0) * m_p / (mdot * (t[idx[-1]] - t0)))


# ---------------------------------------------------------------------------- cases
def _tag(v: float) -> str:
    s = f"{v:.6f}".rstrip("0")
    return s + "0" if s.endswith(".") else s


def _load(name: str):
    from eulag import runs

    try:
        return runs.load_case(CASE_DIR / f"{name}.toml")
    except runs.RunError as exc:
        raise _BadInput(str(exc)) from None


def _variant(base, *, vs, feed, eta_cp, mu, end, quick, state=None):
    """The run of ``base`` (a ModelCase) at v_s [m/s], feed [kg/h], η [cP], μ, end time [s]
    (None: the case's); ``state`` (path, time [s]): continued from that state, ``end`` after
    its time; returns (name, ModelCase)."""
    from eulag.runs import ModelCase
    from eulag.slug import validate_slug_case

    data = copy.deepcopy(base.data)
    name = f"{base.name.replace('_horizontal', '')}__vs-{_tag(vs)}__feed-{_tag(feed)}"
    if not math.isclose(eta_cp, DEFAULT_ETA_CP):
        name += f"__eta-{_tag(eta_cp)}"
    if not math.isclose(mu, DEFAULT_MU):
        name += f"__mu-{_tag(mu)}"
    data.setdefault("gas", {}).update(superficial_velocity_m_s=float(vs), viscosity_Pa_s=float(eta_cp) * 1e-3)
    data.setdefault("feed", {})["mass_flow_kg_h"] = float(feed)
    data.setdefault("grains", {}).update(friction=float(mu), wall_friction=float(mu))
    if quick:
        for sec, kv in QUICK_CHANGES.items():
            data.setdefault(sec, {}).update(kv)
        name += "__quick"
    elif state is not None:
        data.setdefault("initial", {})["state"] = str(state[0])
        data["numerics"]["end_time_s"] = float(state[1] + end)
        name += f"__from-{_tag(state[1])}__t-{_tag(end)}"
    elif end is not None and not math.isclose(end, data["numerics"]["end_time_s"]):
        data["numerics"]["end_time_s"] = float(end)
        name += f"__t-{_tag(end)}"
    data["name"] = name
    try:
        validate_slug_case(data)
    except ValueError as exc:
        raise _BadInput(" ".join(str(exc).split())) from None
    return name, ModelCase(base.model, name, data, base.source)


def study_cases(quick: bool = False, groups=None, feeds=None, velocities=None, window=None, long=False,
                from_state=None):
    """The study's runs: a dict name -> (groups, info, ModelCase); ``groups`` the groups the run
    belongs to (a run shared by several, e.g. the default run, appears once); info: orientation,
    vs, feed, eta_cP, mu, end_s.  ``groups`` None: all but ``long`` (``long=True`` adds it);
    ``feeds`` / ``velocities``: the characteristic curves' (None: the plan's); ``window``: end
    time of every run but the long one (None: the case's).  ``from_state`` (a state file of the
    horizontal case): only the horizontal runs, each continued from it for ``window`` seconds
    (None: 3 s) with its own v_s, feed, η and μ."""
    groups = [g for g in GROUPS if g != "long"] if groups is None else list(groups)
    if long and "long" not in groups:
        groups.append("long")
    horiz, vert = _load("strauss_horizontal"), _load("strauss_vertical")
    out: dict = {}
    state = None
    if from_state is not None:
        from eulag.slug import END_TIME_MAX_S, read_state, validate_slug_case

        if quick:
            raise _BadInput("--from-state: not with --quick (quick runs use a 7 cm tube)")
        probe = copy.deepcopy(horiz.data)
        probe.setdefault("initial", {})["state"] = str(from_state)
        probe.setdefault("numerics", {})["end_time_s"] = END_TIME_MAX_S  # any state's time is before it
        try:
            state = (str(from_state), read_state(str(from_state), validate_slug_case(probe))[1])
        except ValueError as exc:
            raise _BadInput(f"--from-state {from_state}: {' '.join(str(exc).split())}") from None
        window = FROM_STATE_WINDOW_S if window is None else window

    def add(group, base, vs=DEFAULT_VS, feed=DEFAULT_FEED, eta=DEFAULT_ETA_CP, mu=DEFAULT_MU, end=window):
        if state is not None and (base is not horiz or group == "long"):
            return  # a state of the horizontal tube continues only horizontal runs
        name, case = _variant(base, vs=vs, feed=feed, eta_cp=eta, mu=mu, end=end, quick=quick, state=state)
        info = {"orientation": case.data["tube"]["orientation"], "vs": vs, "feed": feed, "eta_cP": eta, "mu": mu,
                "end_s": case.data["numerics"]["end_time_s"]}
        if name in out:
            out[name][0].append(group)
        else:
            out[name] = ([group], info, case)

    if "default" in groups:
        add("default", horiz)
    if "curves" in groups:
        for feed in (feeds or (tuple(QUICK_VELOCITIES) if quick else FEEDS)):
            vss = velocities or (QUICK_VELOCITIES.get(feed, (DEFAULT_VS,)) if quick else VELOCITIES)
            for vs in vss:
                add("curves", horiz, vs=vs, feed=feed)
    if "mass-flux" in groups:
        for feed in (QUICK_MASS_FLUX_FEEDS if quick else MASS_FLUX_FEEDS):
            add("mass-flux", horiz, feed=feed)
    if "viscosity" in groups:
        for eta in (QUICK_VISCOSITIES_CP if quick else VISCOSITIES_CP):
            add("viscosity", horiz, eta=eta)
    if "friction" in groups:
        for mu in (QUICK_FRICTIONS if quick else FRICTIONS):
            add("friction", horiz, mu=mu)
    if "vertical" in groups:
        add("vertical", vert)
    if "long" in groups and not quick:
        add("long", horiz, end=LONG_END_S)
    return {k: (tuple(g), i, c) for k, (g, i, c) in out.items()}


# ---------------------------------------------------------------------------- one run
def window_of(case_data: dict) -> tuple[float, tuple[float, float]]:
    """(t_from [s], (x0, x1) [m]) of a run's statistics (:func:`eulag.slug.statistics_window`: from
    an empty tube t ≥ min(end/2, 6 s), a run continued from a state over the second half of its
    window; slugs centred in 15–40 cm of the paper's 52.5 cm, scaled with the length)."""
    from eulag.slug import statistics_window

    return statistics_window(case_data)


def extract_metrics(ds, case, outdir: Path | None = None, name: str = "", spacetime: bool = False) -> dict:
    """What the tables and figures take from a finished slug dataset (:func:`eulag.slug.summarize`,
    :func:`classify_regime`, maximum overlap, grains lost; the development along the tube for the
    horizontal default and long runs; with ``spacetime`` the space–time figure and the averaged slug
    profiles, over the run's statistics window, beside the record)."""
    from eulag.slug import summarize

    t_from, xw = window_of(case.data)
    m = summarize(ds, x_window=xw, t_min=t_from)
    m["x_window_m"] = list(xw)
    m["max_overlap_per_d"] = float(np.nanmax(ds["max_overlap_per_d"].values))
    m["grains_lost"] = int(ds["grains_lost"].values)
    m["porosity_clipped_cells"] = int(ds.attrs.get("porosity_clipped_cells", 0))  # (slug.record_verdict)
    m["wall_time_s"] = float(ds.attrs.get("wall_time_s", math.nan))
    reg = classify_regime(ds, t_min=t_from)
    m.update(reg)
    if "section_solids_fraction" in ds and "section_x_m" in ds.attrs:  # the cross-section (SMH §3.4)
        from eulag.slug import cross_section_layers, layer_shear

        lay = cross_section_layers(ds, t_min=t_from)
        m["layers"] = {"coordinate": ds.attrs.get("layer_coordinate", "height"),
                       "records_slug": lay.attrs["records_slug"], "records_between": lay.attrs["records_between"],
                       "slug": layer_shear(lay, "slug"), "between": layer_shear(lay, "between")}
    if spacetime and outdir is not None:
        from eulag.plots import slug_cross_section, slug_profiles_figure, slug_spacetime

        m["figures"] = [slug_spacetime(ds, outdir / f"spacetime_{name}.png", title=name),
                        slug_profiles_figure(ds, outdir / f"slug_profiles_{name}.png", x_window=xw, t_min=t_from)]
        cs = slug_cross_section(ds, outdir / f"cross_section_{name}.png", t_min=t_from)
        if cs is not None:
            m["figures"].append(cs)
    if spacetime and case.data["tube"]["orientation"] == "horizontal":
        L = float(case.data["tube"]["length_m"])
        dev = []
        step = L / 10.5 * 1.0  # 5 cm bins of the paper's tube
        for k in range(int(round(L / step))):
            b = summarize(ds, x_window=(k * step, (k + 1) * step), t_min=t_from)
            dev.append({"x0": k * step, "x1": (k + 1) * step, "records": b["slug_records"],
                        "velocity": b["slug_velocity_m_s"],
                        "max_velocity": b.get("slug_max_grain_velocity_m_s", math.nan),
                        "min_porosity": b.get("slug_min_porosity", math.nan),
                        "grains": b.get("slug_grains", math.nan)})
        m["development"] = dev
    return m


def _extractor(args, label, case, outdir, name, spacetime):
    def extract(ds, rec: RunRecord) -> dict:
        try:
            metrics = extract_metrics(ds, case, outdir, name, spacetime)
        except Exception as exc:  # noqa: BLE001 - a metric must not lose the row
            metrics = {"extract_error": f"{type(exc).__name__}: {exc}"}
        _log(args, f"  {label}: Δp {metrics.get('pressure_drop_Pa', math.nan):.1f} Pa, "
                   f"{metrics.get('grains_in_tube', math.nan):.0f} grains, {metrics.get('regime', '?')}")
        return metrics
    return extract


# ---------------------------------------------------------------------------- the study
def _float_list(text, option):
    if text is None:
        return None
    try:
        vals = tuple(float(w) for w in text.split(",") if w.strip())
    except ValueError:
        vals = ()
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise _BadInput(f"{option} {text}: allowed a comma-separated list of positive numbers")
    return vals


def _groups(text, long):
    if text is None:
        return None
    wanted = _select(text, list(GROUPS), "groups")
    if "long" in wanted and not long:
        raise _BadInput(f"--only {text}: the long run takes hours; allowed only with --long")
    return wanted


def study_strauss(args, outdir: Path, t_start: float) -> int:
    quick, long = bool(args.quick), bool(getattr(args, "long", False))
    if quick and long:
        raise _BadInput("--long: not with --quick (the long run is the 22.5 s statistics run)")
    window = getattr(args, "window", None)
    if window is not None and not (math.isfinite(window) and window > 0):
        raise _BadInput(f"--window {window}: allowed a positive number of seconds")
    if quick and window is not None:
        raise _BadInput("--window: not with --quick (quick runs are 0.02 s)")
    groups = _groups(getattr(args, "only", None), long)
    plan = study_cases(quick, groups, _float_list(getattr(args, "feeds", None), "--feeds"),
                       _float_list(getattr(args, "velocities", None), "--velocities"), window, long,
                       getattr(args, "from_state", None))
    if not plan:
        raise _BadInput(f"--only {getattr(args, 'only', None)}: no run of these groups starts from a state; "
                        f"allowed with --from-state: default, curves, mass-flux, viscosity, friction")
    records = {}
    for i, (name, (grp, info, case)) in enumerate(plan.items(), 1):
        label = f"[{STUDY} {i}/{len(plan)}] {name}"
        spacetime = bool({"default", "vertical", "long"} & set(grp))
        records[name] = run_case(args, name, case, outdir, label, _extractor(args, label, case, outdir, name, spacetime))
    refuse_report_of_nothing(args, records.values(), outdir)
    rows = [_row(name, grp, info, records[name]) for name, (grp, info, case) in plan.items()]
    figures = _figures(outdir, plan, records)
    _write_readme(outdir, args, rows, plan, records, figures, t_start)
    return _finish(args, outdir, list(records.values()), allowed_failures=False)


def _status(rec: RunRecord) -> str:
    if rec.status == "converged":
        return "yes" if rec.metrics.get("grains_lost", 0) == 0 else "grains lost"
    return f"{rec.status}: {rec.message}" if rec.message else rec.status


def _row(name, grp, info, rec: RunRecord) -> dict:
    m = rec.metrics
    return {"run": name, "groups": " ".join(grp), "orientation": info["orientation"], "vs": info["vs"],
            "feed": info["feed"], "eta": info["eta_cP"], "mu": info["mu"], "end": info["end_s"],
            "t_from": m.get("t_from_s"), "dp": m.get("pressure_drop_Pa"),
            "dpdx": m["pressure_drop_per_length_Pa_m"] / 100 if m.get("pressure_drop_per_length_Pa_m") is not None
            else None, "grains": m.get("grains_in_tube"),
            "slug_velocity": m.get("slug_velocity_m_s"), "max_grain_velocity": m.get("slug_max_grain_velocity_m_s"),
            "min_porosity": m.get("slug_min_porosity"),
            "slug_length_cm": m["slug_length_m"] * 100 if m.get("slug_length_m") is not None else None,
            "slug_grains": m.get("slug_grains"), "slug_records": m.get("slug_records"),
            "overlap_pct": m["max_overlap_per_d"] * 100 if m.get("max_overlap_per_d") is not None else None,
            "lost": m.get("grains_lost"), "regime": m.get("regime"), "dense_share": m.get("dense_share"),
            "moving_share": m.get("moving_share"), "moving_all": m.get("moving_share_all"),
            "dense_velocity": m.get("dense_velocity_m_s"),
            "outflow_per_feed": m.get("outflow_per_feed"), "status": _status(rec), "time_s": rec.time,
            "commit": m.get("commit")}


COLUMNS = [Column("run", "run"), Column("groups", "groups"), Column("vs", "v_s [m/s]", "{:g}"),
           Column("feed", "feed [kg/h]", "{:g}"), Column("eta", "η [cP]", "{:g}"), Column("mu", "μ", "{:g}"),
           Column("orientation", "tube"), Column("end", "end [s]", "{:g}"), Column("t_from", "from t [s]", "{:g}"),
           Column("dp", "Δp [Pa]", "{:.1f}"), Column("dpdx", "Δp/L [hPa/m]", "{:.2f}"),
           Column("grains", "grains in tube", "{:.0f}"), Column("slug_velocity", "slug velocity [m/s]", "{:.3f}"),
           Column("max_grain_velocity", "max granular velocity [m/s]", "{:.3f}"),
           Column("min_porosity", "slug min φ", "{:.3f}"), Column("slug_length_cm", "slug length [cm]", "{:.1f}"),
           Column("slug_grains", "grains per slug", "{:.0f}"), Column("slug_records", "slug records", "{:d}"),
           Column("overlap_pct", "max overlap [% d]", "{:.2f}"), Column("lost", "grains lost", "{:d}"),
           Column("regime", "regime"), Column("dense_share", "dense share", "{:.2f}"),
           Column("moving_share", "moving share (dense)", "{:.2f}"),
           Column("moving_all", "moving share (all)", "{:.2f}"),
           Column("dense_velocity", "dense-solids velocity [m/s]", "{:.3f}"),
           Column("outflow_per_feed", "outflow / feed", "{:.2f}"), Column("status", "finished"),
           Column("time_s", "run time [s]", "{:.0f}"), Column("commit", "commit")]


# ---------------------------------------------------------------------------- against the paper
def _runs(plan, records, group):
    """[(info, metrics)] of the finished runs of ``group``."""
    return [(info, records[n].metrics) for n, (grp, info, c) in plan.items()
            if group in grp and records[n].ok and "pressure_drop_Pa" in records[n].metrics]


def _fmt(value, fmt):
    return fmt.format(value) if value is not None and math.isfinite(value) else "—"


def _within(value, lo, hi):
    if value is None or not math.isfinite(value):
        return "—"
    return "within" if lo <= value <= hi else "outside"


def _filling(m) -> str:
    """"" for a run in its steady state; else what says it is still filling (FILLED_OUTFLOW_SHARE)."""
    share = m.get("outflow_per_feed")
    if share is None or not math.isfinite(share) or share >= FILLED_OUTFLOW_SHARE:
        return ""
    return f"tube still filling (outflow / feed {share:.2f})"


def _layer_row(m, quantity: str, paper: str, rising: bool) -> dict:
    """The comparison row of the layer velocities in the slugs at the recorded cross-section
    (``m["layers"]``, :func:`eulag.slug.layer_shear`): last minus first layer, its share of the mean
    velocity and the rank correlation with the layer.  ``rising``: the paper's horizontal slugs
    (sheared, the uppermost layer fastest: "within" when the rank correlation is ≥ 0.8); else the
    vertical plugs (one velocity: "within" when the difference is below 10 % of the mean)."""
    lay = m.get("layers")
    if not lay or lay["slug"].get("layers", 0) < 2:
        why = "no records of the cross-section (runs before it was recorded)" if not lay else "no slug passed it"
        return {"quantity": quantity, "paper": paper, "tolerance": "—", "here": why, "verdict": "—"}
    sl = lay["slug"]
    share = sl["shear_m_s"] / sl["mean_velocity_m_s"] if sl["mean_velocity_m_s"] else math.nan
    here = (f"{sl['shear_m_s']:+.3f} ({100 * share:+.0f} % of the mean {sl['mean_velocity_m_s']:.3f}), rank correlation "
            f"{sl['rank_correlation_with_layer']:+.2f}, {lay['records_slug']} records in a slug")
    if rising:
        ok = sl["rank_correlation_with_layer"] >= 0.8
        tol = "rank correlation with height ≥ 0.8"
    else:
        ok = abs(share) < 0.1
        tol = "|difference| < 10 % of the mean"
    return {"quantity": quantity, "paper": paper, "tolerance": tol, "here": here,
            "verdict": "within" if ok else "outside"}


def comparison(plan, records) -> list[dict]:
    """Each measured number beside the paper's (rows: quantity, paper, tolerance, this study,
    verdict); a run still filling over its window (:func:`_filling`) is listed, not judged."""
    out = []
    horiz = _runs(plan, records, "long") or _runs(plan, records, "default")

    def judged(row, *runs):  # the row's verdict, unless one of the runs it rests on is still filling
        why = next((f for f in map(_filling, runs) if f), "")
        if why and row["verdict"] in ("within", "outside"):
            row["verdict"] = "not judged: " + why
        return row

    if horiz:
        info, m = horiz[0]
        src = f"({info['end_s']:g} s run, t ≥ {m['t_from_s']:g} s)"
        rows = (("Δp/L, horizontal [hPa/m]", "10", "× 2 (5–20)", m["pressure_drop_per_length_Pa_m"] / 100, 5, 20, "{:.2f}"),
                ("slug velocity: the slug centres' speed [m/s]", "0.42 (§3)", "± 30 % (0.29–0.55)",
                 m.get("slug_velocity_m_s"), 0.294, 0.546, "{:.3f}"),
                ("slug velocity: the maximal granular velocity in the slug [m/s]", "0.3 (§3.2, Fig. 10)",
                 "± 30 % (0.21–0.39)", m.get("slug_max_grain_velocity_m_s"), 0.21, 0.39, "{:.3f}"),
                ("min slug porosity", "0.47–0.49", "± 0.03 (0.44–0.52)", m.get("slug_min_porosity"), 0.44, 0.52, "{:.3f}"),
                ("slug length [cm]", "4–8", "—", (m.get("slug_length_m") or math.nan) * 100, 4, 8, "{:.1f}"),
                ("grains per slug", "470–500", "± 25 % (353–625)", m.get("slug_grains"), 352.5, 625, "{:.0f}"),
                ("grains in tube", "3,200", "± 25 % (2,400–4,000)", m["grains_in_tube"], 2400, 4000, "{:.0f}"))
        for q, paper, tol, v, lo, hi, fmt in rows:
            v = math.nan if v is None else float(v)
            out.append(judged({"quantity": q, "paper": paper, "tolerance": tol,
                               "here": (fmt.format(v) if math.isfinite(v) else "—") + " " + src,
                               "verdict": _within(v, lo, hi)}, m))
        out.append(judged(_layer_row(m, "layers in a slug at half the length: uppermost minus lowest [m/s]",
                                     "lowest slowest, uppermost fastest (§3.4, Fig. 19)", rising=True), m))
        out.append({"quantity": "grains lost; max overlap / d", "paper": "0; < 1 % (choice)", "tolerance": "—",
                    "here": f"{m['grains_lost']}; {m['max_overlap_per_d'] * 100:.2f} %",
                    "verdict": "within" if m["grains_lost"] == 0 and m["max_overlap_per_d"] < 0.01 else "outside"})
    vert = _runs(plan, records, "vertical")
    if vert:
        info, m = vert[0]
        # SMH §4 sets the vertical plugs' 0.17 m/s beside the horizontal 0.3 m/s, the saturated
        # maximal granular velocity of Fig. 10 (§3.2 catalogues each slug's maximal granular
        # velocity), so that is the likelier measure; the paper does not say, and words it as the
        # plugs' own speed, so the plug centres' speed is judged against it as well.
        v = m.get("slug_max_grain_velocity_m_s")
        out.append(judged({"quantity": "vertical plug velocity: the maximal granular velocity in the plug [m/s]",
                           "paper": "0.17 (§4, beside the 0.3 of Fig. 10)", "tolerance": "± 30 % (0.12–0.22)",
                           "here": _fmt(v, "{:.3f}") + f" (t ≥ {m['t_from_s']:g} s)",
                           "verdict": _within(v, 0.119, 0.221)}, m))
        out.append(judged(_layer_row(m, "vertical: radial layers in a plug, wall minus axis layer [m/s]",
                                     "a small difference, one velocity within the plug (§4)", rising=False), m))
        vc = m.get("slug_velocity_m_s")
        out.append(judged({"quantity": "vertical plug velocity: the plug centres' speed [m/s]",
                           "paper": "0.17, if it is the plugs' own speed", "tolerance": "± 30 % (0.12–0.22)",
                           "here": _fmt(vc, "{:.3f}"), "verdict": _within(vc, 0.119, 0.221)}, m))
        if horiz:
            vh = horiz[0][1].get("slug_max_grain_velocity_m_s")
            ratio = v / vh if v is not None and vh else math.nan
            out.append({"quantity": "vertical / horizontal maximal granular velocity", "paper": "0.57 (0.17 / 0.3)",
                        "tolerance": "—", "here": _fmt(ratio, "{:.2f}"), "verdict": "—"})
        if horiz:
            mh = horiz[0][1]
            r = m["pressure_drop_Pa"] / mh["pressure_drop_Pa"] if mh["pressure_drop_Pa"] else math.nan
            per = (m["pressure_drop_Pa"] / m["grains_in_tube"]) / (mh["pressure_drop_Pa"] / mh["grains_in_tube"]) \
                if m["grains_in_tube"] and mh["grains_in_tube"] and mh["pressure_drop_Pa"] else math.nan
            out.append(judged({"quantity": "vertical Δp / horizontal Δp", "paper": "≈ 4", "tolerance": "2.5–6",
                               "here": f"{r:.2f} (per grain in the tube: {per:.2f})",
                               "verdict": _within(r, 2.5, 6)}, m, mh))
    out += _regime_rows(plan, records)
    mf = sorted((i["feed"], m["pressure_drop_Pa"]) for i, m in _runs(plan, records, "mass-flux"))
    if len(mf) >= 3:
        x, y = np.array(mf).T
        a, b = np.polyfit(x, y, 1)
        r2 = 1 - np.sum((y - (a * x + b)) ** 2) / max(np.sum((y - y.mean()) ** 2), 1e-300)
        out.append({"quantity": "Δp against mass flux (v_s = 1 m/s)", "paper": "linear (Fig. 5)", "tolerance": "—",
                    "here": f"slope {a:.1f} Pa per kg/h, intercept {b:.1f} Pa, R² {r2:.3f}",
                    "verdict": "within" if r2 >= 0.9 else "outside"})
    vis = sorted((i["eta_cP"], m["pressure_drop_Pa"]) for i, m in _runs(plan, records, "viscosity"))
    if len(vis) >= 2:
        falls = all(b[1] < a[1] for a, b in zip(vis, vis[1:]))
        out.append({"quantity": "Δp against η (v_s = 1 m/s)", "paper": "falls with η (Fig. 6)", "tolerance": "—",
                    "here": ", ".join(f"{e:g} cP: {p:.0f} Pa" for e, p in vis),
                    "verdict": "within" if falls else "outside"})
    fr = sorted((i["mu"], m["pressure_drop_Pa"], m.get("regime")) for i, m in _runs(plan, records, "friction"))
    if len(fr) >= 2:
        above = [p for mu, p, _ in fr if mu >= 0.15]
        rising = len(above) >= 2 and all(b > a for a, b in zip(above, above[1:]))
        out.append({"quantity": "Δp against μ (v_s = 1 m/s)",
                    "paper": "small below μ = 0.1 (grains slide singly), a peak at 0.1 (sliding layer), a dip at "
                             "0.1–0.15, rising above 0.15 (Fig. 7)", "tolerance": "—",
                    "here": ", ".join(f"{mu:g}: {p:.0f} Pa ({(reg or '?')})" for mu, p, reg in fr),
                    "verdict": ("rising above 0.15" if rising else "not rising above 0.15") if len(above) >= 2 else "—"})
    curve = [(m["grains_in_tube"], m["pressure_drop_Pa"]) for i, m in _runs(plan, records, "curves")
             if m.get("regime") == "slugs" and m["grains_in_tube"] > 0]
    if len(curve) >= 3:
        per = np.array([p / n for n, p in curve])
        out.append({"quantity": "Δp against grains in the tube (slug regime)", "paper": "nearly proportional (§3.1)",
                    "tolerance": "—", "here": f"Δp/N {per.mean():.3f} Pa per grain, spread (sd/mean) "
                                              f"{per.std() / per.mean():.2f} over {len(per)} runs", "verdict": "—"})
    return out


def _regime_rows(plan, records) -> list[dict]:
    out = []
    by_feed: dict = {}
    for i, m in _runs(plan, records, "curves"):
        by_feed.setdefault(i["feed"], []).append((i["vs"], m.get("regime")))
    for feed, pts in sorted(by_feed.items()):
        pts.sort()
        seq = ", ".join(f"{vs:g}: {r}" for vs, r in pts)
        bulk = [vs for vs, r in pts if r == "resting bulk"]
        slugs = [vs for vs, r in pts if r == "slugs"]
        empty = [vs for vs, r in pts if r == "nearly empty tube"]
        if bulk and slugs:
            lo, hi = max(bulk), min(v for v in slugs if v > max(bulk)) if any(v > max(bulk) for v in slugs) else math.nan
            here = f"between {lo:g} and {hi:g} m/s" if math.isfinite(hi) else f"above {lo:g} m/s"
            ok = math.isfinite(hi) and lo <= 0.38 + 0.15 and hi >= 0.25 - 0.15
            verdict = "within" if ok else "outside"
        else:
            here, verdict = ("no resting bulk measured" if slugs else "no slugs measured"), "—"
        if feed == 2.49 or len(by_feed) == 1:
            out.append({"quantity": f"resting bulk → slugs, {feed:g} kg/h", "paper": "0.25 (Fig. 3) – 0.38 m/s (text)",
                        "tolerance": "± 0.15 m/s", "here": here, "verdict": verdict})
        if slugs and empty and max(slugs) < max(empty):
            lo = max(slugs)
            hi = min(v for v in empty if v > lo)
            ok = lo <= 4 + 0.15 and hi >= 4 - 0.15
            here2, verdict2 = f"between {lo:g} and {hi:g} m/s", ("within" if ok else "outside")
        else:
            here2, verdict2 = ("no nearly empty tube measured" if slugs else "no slugs measured"), "—"
        out.append({"quantity": f"slugs → nearly empty tube, {feed:g} kg/h", "paper": "≈ 4 m/s",
                    "tolerance": "± 0.15 m/s", "here": here2, "verdict": verdict2})
        out.append({"quantity": f"regimes along the curve, {feed:g} kg/h (v_s: regime)", "paper": "bulk, slugs, empty",
                    "tolerance": "—", "here": seq, "verdict": "—"})
    return out


COMPARISON_COLUMNS = [Column("quantity", "quantity"), Column("paper", "paper"), Column("tolerance", "tolerance"),
                      Column("here", "this study"), Column("verdict", "verdict")]


# ---------------------------------------------------------------------------- figures
def _figures(outdir: Path, plan, records) -> list[Path]:
    out = draw_figures((_fig_curves, _fig_mass_flux, _fig_viscosity, _fig_friction), outdir, plan, records)
    for n, (grp, info, c) in plan.items():
        for f in records[n].metrics.get("figures", []):
            if Path(f).is_file():
                out.append(Path(f))
    return out


def _regime_legend(ax):
    for reg, mk in MARKERS.items():
        ax.plot([], [], mk, color="k", mfc="none", label=reg)


def _fig_curves(outdir, plan, records):
    runs_ = _runs(plan, records, "curves")
    if not runs_:
        return None
    # runs that ended unconverged (e.g. a jammed tube beyond numerics.overlap_limit) are drawn
    # with a grey cross over their regime marker
    unconverged = {(i["feed"], i["vs"]) for n, (grp, i, c) in plan.items()
                   if "curves" in grp and records[n].status == "not converged"}
    fig = _figure()(10, 4)
    ax, ax2 = fig.subplots(1, 2)
    feeds = sorted({i["feed"] for i, _ in runs_})
    colors = dict(zip(feeds, ("tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange")))
    for f in feeds:
        pts = sorted((i["vs"], m["pressure_drop_Pa"] / 100, m.get("regime"), m["grains_in_tube"])
                     for i, m in runs_ if i["feed"] == f)
        vs, dp, reg, n = zip(*pts)
        ax.plot(vs, dp, "-", color=colors[f], label=f"{f:g} kg/h")
        for x, y, r, nn in pts:
            ax.plot([x], [y], MARKERS.get(r, "x"), color=colors[f], mfc="none", ms=8)
            ax2.plot([nn], [y], MARKERS.get(r, "x"), color=colors[f], mfc="none", ms=8)
            if (f, x) in unconverged:
                ax.plot([x], [y], "x", color="0.4", ms=10)
                ax2.plot([nn], [y], "x", color="0.4", ms=10)
    _regime_legend(ax)
    if unconverged:
        ax.plot([], [], "x", color="0.4", label="not converged (e.g. overlap limit)")
    dps = [m["pressure_drop_Pa"] for _, m in runs_ if m["pressure_drop_Pa"] > 0]
    if dps and max(dps) > 20 * min(dps):  # a jammed tube's Δp beside slug flow's
        ax.set_yscale("log")
        ax2.set_yscale("log")
    ax.set_xlabel("superficial gas velocity v_s [m/s]")
    ax.set_ylabel("Δp [hPa]")
    ax.set_xscale("log")
    from matplotlib.ticker import NullFormatter

    ticks = sorted({i["vs"] for i, _ in runs_})
    ax.set_xticks(ticks, [f"{v:g}" for v in ticks])
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax2.set_xlabel("grains in the tube (mean over the window)")
    ax2.set_ylabel("Δp [hPa]")
    ax2.grid(alpha=0.3)
    fig.suptitle("Characteristic curves (after SMH Fig. 3); marker = regime")
    return _save(fig, outdir / "fig3_characteristic_curves.png")


def _fig_param(outdir, plan, records, group, key, xlabel, title, fname, scale=1.0):
    runs_ = _runs(plan, records, group)
    if not runs_:
        return None
    pts = sorted((i[key] * scale, m["pressure_drop_Pa"] / 100, m.get("regime")) for i, m in runs_)
    fig = _figure()(5, 3.8)
    ax = fig.subplots()
    x, y, r = zip(*pts)
    ax.plot(x, y, "-", color="tab:blue")
    for a, b, rr in pts:
        ax.plot([a], [b], MARKERS.get(rr, "x"), color="tab:blue", mfc="none", ms=8)
    _regime_legend(ax)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("Δp [hPa]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=9)
    return _save(fig, outdir / fname)


def _fig_mass_flux(outdir, plan, records):
    return _fig_param(outdir, plan, records, "mass-flux", "feed", "solids feed [kg/h]",
                      "Δp against mass flux at v_s = 1 m/s (after SMH Fig. 5)", "fig5_mass_flux.png")


def _fig_viscosity(outdir, plan, records):
    return _fig_param(outdir, plan, records, "viscosity", "eta_cP", "effective gas viscosity η [cP]",
                      "Δp against η at v_s = 1 m/s (after SMH Fig. 6)", "fig6_viscosity.png")


def _fig_friction(outdir, plan, records):
    return _fig_param(outdir, plan, records, "friction", "mu", "Coulomb coefficient μ (grains and wall)",
                      "Δp against μ at v_s = 1 m/s (after SMH Fig. 7)", "fig7_friction.png")


def _save(fig, path: Path) -> Path:
    fig.savefig(path, format="png")
    return path


# ---------------------------------------------------------------------------- README
def _development_text(plan, records) -> list[str]:
    for group in ("long", "default"):
        for info, m in _runs(plan, records, group):
            dev = m.get("development")
            if not dev:
                continue
            head = "| x [cm] | " + " | ".join(f"{d['x0'] * 100:.0f}–{d['x1'] * 100:.0f}" for d in dev) + " |"
            sep = "|---|" + "---|" * len(dev)

            def line(label, key, fmt):
                return f"| {label} | " + " | ".join(_fmt(d.get(key), fmt) for d in dev) + " |"
            return ["## Development along the tube (after SMH Figs. 9–10)", "",
                    f"The {group} run, t ≥ {m['t_from_s']:g} s, slugs of ≥ 100 grains in bins of 5 cm (SMH: minimum "
                    "porosity 0.57 → 0.47 and maximal granular velocity 0.04 → 0.3 m/s within the first ≈ 0.2 m; the "
                    "slug centres' speed beside it).", "",
                    head, sep, line("slug velocity (centres) [m/s]", "velocity", "{:.2f}"),
                    *([line("max granular velocity [m/s]", "max_velocity", "{:.2f}")]
                      if any("max_velocity" in d for d in dev) else []),  # records written before it
                    line("min porosity", "min_porosity", "{:.3f}"), line("grains per slug", "grains", "{:.0f}"), ""]
    return []


def _write_readme(outdir, args, rows, plan, records, figures, t_start):
    from eulag.output import atomic_write

    csv_path = write_csv(outdir / f"{STUDY}.csv", COLUMNS, rows)
    quick = bool(args.quick)
    L = [BEGIN, "", "## `eulag study strauss`", "",
         f"*Generated by `{study_command(STUDY, args)}`; do not edit this section by hand — re-run the command.*", ""]
    if quick:
        L += ["> **Quick mode**: a 7 cm tube, 0.02 s per run. These numbers check the study machinery; they are "
              "**not results**.", ""]
    L += ["Runs of `cases/slug/strauss_horizontal.toml` / `strauss_vertical.toml` with v_s, feed, η and μ changed "
          "(μ for grain–grain and grain–wall contacts alike). Numbers over each run's records with t ≥ min(end/2, 6 s) "
          "(a run continued from a filled-tube state, `--from-state`: over the second half of its window); "
          "slug statistics over slugs of ≥ 100 grains centred in 15–40 cm of the tube (`eulag.slug.summarize`). "
          "Regime: `eulag.studies.strauss.classify_regime` — *nearly empty tube* when slices of porosity < 0.6 (dense) "
          "hold less than half of the solids in the tube and at least half of the solids move faster than the push "
          "speed u_push = max(1.5 × the feed's speed, 0.01 m/s); *resting bulk* when less than 10 % of the dense "
          "solids move faster than u_push; *slugs* otherwise (the reasons are in the module docstring). "
          "Nothing is tuned to the paper's numbers.", ""]
    comp = comparison(plan, records)
    if comp:
        L += ["### Against the paper", "", markdown_table(COMPARISON_COLUMNS, comp), ""]
    L += ["### Runs", "", markdown_table(COLUMNS, rows), "",
          f"The same table as CSV: [{csv_path.name}]({csv_path.name}). Datasets `<run>.nc` are not committed; what the "
          "tables and figures take from them is in `<run>.record.json`, which `--resume` and `--report` use when the "
          "dataset is not here.", ""]
    dev = _development_text(plan, records)
    if dev:
        L += ["#" + dev[0]] + dev[1:]
    if figures:
        L += ["### Figures", ""]
        for f in figures:
            rel = os.path.relpath(f, outdir)
            L += [f"![{Path(rel).stem}]({rel})", ""]
    mi = machine_info()
    L += ["### Machine and wall time", "",
          f"- platform: {mi['platform']} ({mi['machine']}), CPU: {mi['cpu']}",
          f"- CPUs: {mi['cpu_count']} ({mi['cpus_usable']} usable)",
          f"- python {mi['python']}, eulag {mi['eulag']}, commit {mi['commit']}",
          f"- wall time of this invocation: {time.perf_counter() - t_start:.1f} s (runs reused with `--resume` count "
          "with the time they took when they ran)",
          f"- written {time.strftime('%Y-%m-%d %H:%M:%S %Z')}", "", END, ""]
    section = "\n".join(L)
    path = outdir / "README.md"
    old = path.read_text() if path.is_file() else ""
    if BEGIN in old and END in old:
        head, rest = old.split(BEGIN, 1)
        tail = rest.split(END, 1)[1].lstrip("\n")
        text = head + section + tail
    elif old:
        text = old.rstrip("\n") + "\n\n" + section
    else:
        text = "# Plug conveying in a horizontal tube (Strauß, McNamara & Herrmann 2006)\n\n" + section
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))
