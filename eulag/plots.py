"""Figures from eulag datasets (reads datasets only; never imports the solvers).

* :func:`three_panel` -- the reference paper's section figure: gas axial velocity with the
  secondary-flow stream lines, particle axial velocity, normalised particle concentration;
* :func:`vertical_profiles` -- gas and particle axial velocity over the vertical diameter,
  with measurements when given;
* :func:`convergence` -- residual (and pressure-gradient) history;
* dense-phase models: :func:`slug_spacetime`, :func:`slug_history`, :func:`slug_profiles_figure`,
  :func:`slug_cross_section`
  (``model = "dem-darcy"``; Strauss, McNamara & Herrmann Figs. 1, 12-16) and
  :func:`two_fluid_section`, :func:`two_fluid_profiles`, :func:`two_fluid_development`,
  :func:`two_fluid_convergence` (``model = "two-fluid"``; after Ding et al. Figs. 5-10);
* :func:`plot_all` -- all of a dataset's figures (chosen by its ``model`` attribute), written
  together or not at all.

Matplotlib with the Agg canvas and :class:`matplotlib.figure.Figure` objects only: no pyplot
state, nothing left open. Sections are drawn as seen looking downstream (z right, y up).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Mapping

import numpy as np
import xarray as xr
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle
from matplotlib.ticker import MaxNLocator, NullFormatter
from matplotlib.tri import Triangulation

from eulag import analysis as an
from eulag.reference import read_reference, table_to_profiles

__all__ = ["dataset_problem", "three_panel", "vertical_profiles", "convergence", "plot_all", "read_reference",
           "resolve_reference", "default_station", "slug_spacetime", "slug_history",
           "slug_profiles_figure", "slug_profile_data", "slug_cross_section", "two_fluid_section", "two_fluid_profiles", "two_fluid_development",
           "two_fluid_convergence"]


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def verdict_label(ds) -> str:
    """The run's verdict as the convergence figures title it (``eulag.output.is_converged``)."""
    from eulag.output import is_converged

    return "converged" if is_converged(ds) else "NOT converged"

def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path) -> Path:
    path = Path(path)
    fig.savefig(path, format="png")
    return path


def _case_name(ds: xr.Dataset) -> str:
    return str(an.attr(ds, "case.name", "") or ds.attrs.get("title", "") or "eulag dataset")


def _station(ds: xr.Dataset, x: float | None) -> float | None:
    """The x [m] of the station actually plotted (nearest to x), None if the dataset has no x."""
    if "x" not in ds.dims:
        return None
    return float(an.section(ds, x)["x"].values)


def _where(ds: xr.Dataset, x: float | None) -> str:
    xs = _station(ds, x)
    if xs is None:
        return ""
    if ds.sizes["x"] == 1 and an.attr(ds, "pipe.mode") == "periodic":
        return "fully developed (periodic)"
    return f"x = {xs:.4g} m"


def _has_values(ds: xr.Dataset, var: str, x) -> bool:
    if var not in ds:
        return False
    return bool(np.any(np.isfinite(an._field(ds, var, x))))


def _draw_wall(ax, radius: float) -> None:
    ax.add_patch(Circle((0.0, 0.0), radius, fill=False, color="k", lw=1.2, zorder=5))
    pad = 1.06 * radius
    ax.set_xlim(-pad, pad)
    ax.set_ylim(-pad, pad)
    ax.set_aspect("equal")
    ax.set_xlabel("z [m]")
    ax.set_ylabel("y [m]")


def _no_data(ax, radius: float, text: str = "no particles") -> None:
    _draw_wall(ax, radius)
    ax.text(0.0, 0.0, text, ha="center", va="center", fontsize=11, color="0.3")


def _wall_triangulation(geo: an.PolarSection) -> tuple[Triangulation, np.ndarray]:
    """Structured triangulation of the cell centres, an axis point and wall points.

    Nodes: the nr x nt cell centres (ring-major), then one wall point per sector at its
    mid-angle (r = R), then the axis point. Each quad between rings j, j+1 (and between the
    last ring and the wall) and sectors k, k+1 is split into two triangles; ring 0 is a fan
    around the axis point. Returns the triangulation and a mask over the nodes that marks
    the extra (wall and axis) points, which the caller gives values to.
    """
    nr, nt = geo.nr, geo.nt
    zz = np.concatenate([geo.z.ravel(), geo.radius * np.cos(geo.theta), [0.0]])
    yy = np.concatenate([geo.y.ravel(), geo.radius * np.sin(geo.theta), [0.0]])
    node = np.arange((nr + 1) * nt).reshape(nr + 1, nt)   # row nr: the wall points
    axis = (nr + 1) * nt
    k, k1 = np.arange(nt), (np.arange(nt) + 1) % nt
    tris = [np.column_stack([np.full(nt, axis), node[0, k], node[0, k1]])]
    for j in range(nr):
        a, b, c, d = node[j, k], node[j, k1], node[j + 1, k1], node[j + 1, k]
        tris += [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
    extra = np.zeros(zz.size, dtype=bool)
    extra[nr * nt:] = True
    return Triangulation(zz, yy, np.vstack(tris)), extra


def _with_wall(geo: an.PolarSection, values: np.ndarray, wall_value: float = 0.0) -> np.ndarray:
    """Node values for :func:`_wall_triangulation`: the cells, the wall value on the wall
    points, and the ring-0 mean on the axis point."""
    values = np.asarray(values, dtype=float)
    return np.concatenate([values.ravel(), np.full(geo.nt, wall_value),
                           [float(np.average(values[0], weights=geo.area[0]))]])


def _corners(geo: an.PolarSection) -> tuple[np.ndarray, np.ndarray]:
    """Cell corners (nr+1, nt+1) in z and y [m] for pcolormesh on the true polar cells."""
    re, te = geo.r_edges[:, None], geo.theta_edges[None, :]
    return re * np.cos(te), re * np.sin(te)


def _colour_cells(fig, ax, geo, values, label, cmap="viridis"):
    zc, yc = _corners(geo)
    mesh = ax.pcolormesh(zc, yc, np.ma.masked_invalid(values), cmap=cmap, shading="flat")
    fig.colorbar(mesh, ax=ax, shrink=0.8, label=label)


# ---------------------------------------------------------------------------
# the section figure
# ---------------------------------------------------------------------------

def three_panel(ds: xr.Dataset, x: float | None, path) -> Path:
    """Write the three-panel section figure at the station nearest ``x`` [m] to ``path`` (PNG).

    (a) gas axial velocity u_x [m s-1], filled contours on the cell centres plus the wall
    (u_x = 0), with contour lines of the secondary-flow stream function
    (:func:`eulag.analysis.stream_function`; solid: counter-clockwise, dashed: clockwise as
    seen looking downstream); (b) particle axial velocity [m s-1] and (c) particle mass
    concentration divided by its section mean [1], both coloured per cell on the true polar
    cells (blank where no particle passed). Panels (b) and (c) say "no particles" if the
    variables are absent or all NaN.
    """
    geo = an.polar_section(ds)
    R = geo.radius
    fig = _new_figure(14.0, 4.8)
    ax_a, ax_b, ax_c = fig.subplots(1, 3)

    # (a) gas
    tri, _ = _wall_triangulation(geo)
    ux = _with_wall(geo, an._field(ds, "gas_ux", x))   # no slip: u_x = 0 on the wall
    filled = ax_a.tricontourf(tri, ux, levels=16, cmap="viridis")
    fig.colorbar(filled, ax=ax_a, shrink=0.8, label="gas $u_x$ [m s$^{-1}$]")
    note = "no in-plane velocity in the dataset"
    if "gas_uy" in ds and "gas_uz" in ds:
        strength = an.secondary_flow_strength(ds, x)
        n_cells = an.recirculation_cells(ds, x)
        if n_cells > 0:
            psi = an.stream_function(ds, x)
            psi_all = _with_wall(geo, psi)                  # psi = 0 on the wall
            top = float(np.abs(psi).max())
            levels = np.concatenate([np.linspace(-top, -0.1 * top, 5), np.linspace(0.1 * top, top, 5)])
            ax_a.tricontour(tri, psi_all, levels=np.unique(levels), colors="w", linewidths=0.8,
                            negative_linestyles="dashed")
            note = f"secondary flow: max {strength:.3g} % of $U_b$, {n_cells} cells"
        else:
            note = f"secondary flow: max {strength:.2g} % of $U_b$ (none)"
    ax_a.set_title(f"(a) gas axial velocity\n{note}", fontsize=10)
    _draw_wall(ax_a, R)

    # (b) particle axial velocity
    if _has_values(ds, "particle_ux", x):
        _colour_cells(fig, ax_b, geo, an._field(ds, "particle_ux", x),
                      "particle $u_x$ [m s$^{-1}$]")
        _draw_wall(ax_b, R)
    else:
        _no_data(ax_b, R)
    ax_b.set_title("(b) particle axial velocity", fontsize=10)

    # (c) particle concentration / section mean
    if _has_values(ds, "particle_concentration", x):
        c = np.nan_to_num(an._field(ds, "particle_concentration", x))  # no particles: 0 kg m-3
        mean = float((c * geo.area).sum() / geo.area.sum())
        if mean > 0.0:
            _colour_cells(fig, ax_c, geo, np.where(c > 0, c / mean, np.nan),
                          r"$c / \bar{c}$ [1]", cmap="magma")
            _draw_wall(ax_c, R)
            ax_c.set_title(f"(c) particle concentration / section mean\n"
                           rf"$\bar{{c}}$ = {mean:.3g} kg m$^{{-3}}$", fontsize=10)
        else:
            _no_data(ax_c, R)
            ax_c.set_title("(c) particle concentration / section mean", fontsize=10)
    else:
        _no_data(ax_c, R)
        ax_c.set_title("(c) particle concentration / section mean", fontsize=10)

    where = _where(ds, x) or "the only station"
    fig.suptitle(f"{_case_name(ds)}: cross-section, {where} (looking downstream, gravity -y)")
    return _save(fig, path)


# ---------------------------------------------------------------------------
# vertical profiles and reference data
# ---------------------------------------------------------------------------

def _reference_profiles(reference) -> dict[str, dict[str, np.ndarray]]:
    """Normalise ``reference``: a CSV path, a table (dict of columns), or {phase: table}."""
    if isinstance(reference, (str, os.PathLike)):
        return read_reference(reference)
    if not isinstance(reference, Mapping):
        raise TypeError(f"reference: expected a path or a dict of arrays, got {type(reference).__name__}")
    if all(isinstance(v, Mapping) for v in reference.values()):
        out = {}
        for phase, table in reference.items():
            out.update({phase: p for p in table_to_profiles(table, f"reference[{phase!r}]").values()})
        return out
    return table_to_profiles(reference, "reference")


def resolve_reference(ds: xr.Dataset, dataset_path=None) -> Path | None:
    """The measurement file named by the case attribute ``pipe.reference_data``, or None.

    A relative name is looked up beside the case file (attribute ``case_file``), in eulag's
    ``cases/`` directory, beside the dataset, and in ``$EULAG_SHARED_DATA``; the first file
    that exists wins. None when the case names no file or none is found.
    """
    name = an.attr(ds, "pipe.reference_data")
    if not name or str(name).strip().lower() in ("none", ""):
        return None
    name = Path(str(name))
    if name.is_absolute():
        return name if name.is_file() else None
    dirs = []
    if ds.attrs.get("case_file"):
        dirs.append(Path(str(ds.attrs["case_file"])).parent)
    try:
        import cases
        dirs.append(Path(cases.__file__).parent)
    except ImportError:  # pragma: no cover - cases is part of the distribution
        pass
    source = dataset_path or ds.encoding.get("source")
    if source:
        dirs.append(Path(source).parent)
    if os.environ.get("EULAG_SHARED_DATA"):
        dirs.append(Path(os.environ["EULAG_SHARED_DATA"]))
    for d in dirs:
        if (d / name).is_file():
            return d / name
    return None


def vertical_profiles(ds: xr.Dataset, x: float | None, path, reference=None) -> Path:
    """Write the vertical-diameter profiles of the axial velocity at the station nearest x.

    Gas and particle u_x divided by the bulk velocity U_b (``gas.bulk_velocity``) on the
    horizontal axis, y/D on the vertical axis (top of the pipe at +0.5), from
    :func:`eulag.analysis.vertical_profile`; the gas curve ends at the wall with u_x = 0.
    ``reference``: measured points (a CSV path such as
    ``tsuji_morikawa_1982_horizontal_eta2.2.csv``, a table dict of columns ``phase``,
    ``y_over_R`` | ``y_over_D``, ``U_over_Uref`` | ``u_over_ub``, or ``{phase: table}``),
    drawn as markers with the velocity as given in the file.
    """
    geo = an.polar_section(ds)
    D = 2.0 * geo.radius
    ub = an.bulk_velocity(ds)
    fig = _new_figure(5.2, 5.6)
    ax = fig.subplots()
    y, u = an.vertical_profile(ds, "gas_ux", x)
    ax.plot(np.concatenate([[0.0], u, [0.0]]) / ub, np.concatenate([[-D / 2], y, [D / 2]]) / D,
            "-", color="C0", label="gas (eulag)")
    if _has_values(ds, "particle_ux", x):
        y, u = an.vertical_profile(ds, "particle_ux", x)
        ax.plot(u / ub, y / D, "--", color="C3", label="particles (eulag)")
    if reference is not None:
        marks = {"gas": ("o", "C0"), "particle": ("s", "C3")}
        for phase, prof in _reference_profiles(reference).items():
            m, c = marks.get(phase, ("^", "k"))
            ax.plot(prof["u"], prof["y_over_D"], m, mfc="none", color=c,
                    label=f"{phase}, measured ({prof['column']})")
    ax.axhline(0.0, color="0.8", lw=0.6)
    ax.set_ylim(-0.5, 0.5)
    ax.set_xlim(left=0.0)
    ax.set_xlabel(rf"$u_x / U_b$ [1]   ($U_b$ = {ub:.3g} m s$^{{-1}}$)")
    ax.set_ylabel("y / D [1]  (top +0.5, bottom -0.5)")
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"{_case_name(ds)}\nvertical diameter, {_where(ds, x)}", fontsize=10)
    return _save(fig, path)


# ---------------------------------------------------------------------------
# convergence
# ---------------------------------------------------------------------------

def convergence(ds: xr.Dataset, path) -> Path | None:
    """Write the convergence history: coupling residual per pass (log scale, with the
    tolerance), the gas-solver residual history ``gas_residual`` (periodic runs; developing
    runs show the wall time per pass split into gas solve and Lagrangian pass instead) and
    any ``pressure_gradient*`` variable over ``iteration`` [Pa m-1], each in its own panel
    when present. Returns None (and writes
    nothing) if the dataset holds none of them."""
    panels = []
    if "residual" in ds and ds["residual"].size:
        panels.append(("residual", "coupling pass", "coupling residual [1]", True))
    # the march's residual history is a station-by-station concatenation: it says little as
    # one curve, so a developing-pipe run with a coupling history shows time per pass instead
    marching = an.attr(ds, "pipe.mode") == "developing" and "time_gas_solve_pass" in ds
    if "gas_residual" in ds and ds["gas_residual"].size and not marching:
        panels.append(("gas_residual", "gas-solver iteration", "gas residual [1]", True))
    for name in ds.data_vars:
        if name.startswith("pressure_gradient") and ds[name].dims == ("iteration",):
            panels.append((name, "coupling pass", f"{name} [Pa m$^{{-1}}$]", False))
    if marching:
        panels.append(("time", "coupling pass", "wall time per pass [s]", False))
    if not panels:
        return None
    fig = _new_figure(4.6 * len(panels), 4.0)
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (name, xlabel, ylabel, log) in zip(axes, panels):
        if name == "time":
            tg = np.asarray(ds["time_gas_solve_pass"].values, dtype=float)
            tl = np.asarray(ds["time_lagrangian_pass"].values, dtype=float)
            it = np.arange(1, tg.size + 1)
            ax.bar(it, tg, label="gas solve")
            ax.bar(it, tl, bottom=tg, label="Lagrangian pass")
            ax.legend(fontsize="small")
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.grid(True, axis="y", alpha=0.3)
            continue
        v = np.asarray(ds[name].values, dtype=float)
        dim = ds[name].dims[0]
        it = np.asarray(ds[dim].values) if dim in ds.coords else np.arange(v.size)
        positive = np.where(v > 0, v, np.nan) if log else v
        ax.plot(it, positive, "o-" if v.size < 50 else "-", ms=3)
        if log and np.any(v > 0):
            ax.set_yscale("log")
        tol = an.attr(ds, "numerics.coupling_tolerance")
        if name == "residual" and tol is not None:
            ax.axhline(float(tol), color="0.4", ls="--", lw=1, label=f"tolerance {float(tol):g}")
            ax.legend(fontsize="small")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"{_case_name(ds)}: convergence ({verdict_label(ds)})")
    return _save(fig, path)


# ---------------------------------------------------------------------------
# dense-phase models
# ---------------------------------------------------------------------------

#: what each model's figures read from a dataset
_NEEDS = {"euler-lagrange": ("gas_ux", "y", "z", "cell_area"),
          "two-fluid": ("gas_ux", "solids_ux", "solids_fraction", "y", "z", "cell_area"),
          "dem-darcy": ("time", "x", "porosity", "grain_velocity", "gas_pressure", "pressure_drop", "grains_in_tube",
                        "slug_time", "slug_position", "slug_grains")}
_SLUG_CASE_KEYS = (("tube", "length_m"), ("tube", "periodic"), ("grains", "diameter_m"), ("numerics", "end_time_s"),
                   ("numerics", "output_interval_s"))


def dataset_problem(ds: xr.Dataset) -> str | None:
    """Why :func:`plot_all` cannot draw ``ds`` (one line: the model, what is missing), or None."""
    import json

    model = str(ds.attrs.get("model", "euler-lagrange"))
    if model not in _NEEDS:
        return f"model attribute {model!r}: allowed {', '.join(_NEEDS)}"
    missing = [v for v in _NEEDS[model] if v not in ds.variables]
    if missing:
        return f"not an eulag {model} dataset (no {', '.join(missing)})"
    if model == "dem-darcy":
        try:
            c = json.loads(ds.attrs["case"])
            for sec, key in _SLUG_CASE_KEYS:
                c[sec][key]
        except (KeyError, TypeError, ValueError) as exc:
            return f"its 'case' attribute is not a dem-darcy case ({type(exc).__name__}: {' '.join(str(exc).split())})"
    return None


def _slug_case(ds: xr.Dataset) -> dict:
    import json

    return json.loads(ds.attrs["case"])


def _slug_title(ds: xr.Dataset) -> str:
    c = _slug_case(ds)
    g, t = c.get("gas", {}), c.get("tube", {})
    bits = [c.get("name", "dem-darcy run"), t.get("orientation", ""),
            f"v_s = {g.get('superficial_velocity_m_s', float('nan')):g} m/s" if "superficial_velocity_m_s" in g else "",
            "periodic" if t.get("periodic") else
            f"feed {c['feed']['mass_flow_kg_h']:g} kg/h" if c.get("feed", {}).get("mass_flow_kg_h") else ""]
    text = ", ".join(b for b in bits if b)
    partial = ds.attrs.get("partial")
    return f"{text} ({partial})" if partial else text


def slug_spacetime(ds: xr.Dataset, path, t0: float = 0.0, t1: float = np.inf, title: str = "") -> Path:
    """Write the space-time image of the cross-section porosity of a slug run (SMH Figs. 1, 4
    and 20): time across, the tube axis up, dark = dense (porosity 0.4-1); ``t0``, ``t1`` [s]
    the time window drawn, ``title`` (default: the case name and its conveying conditions)."""
    ds = ds.sel(time=slice(t0, t1 if np.isfinite(t1) else None))
    fig = _new_figure(9.0, 3.2)
    ax = fig.subplots()
    im = ax.pcolormesh(ds["time"].values, ds["x"].values * 100, np.asarray(ds["porosity"].values).T, cmap="gray",
                       vmin=0.4, vmax=1.0, shading="auto")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("x [cm]")
    partial = ds.attrs.get("partial")
    head = f"{title} ({partial})" if title and partial else (title or _slug_title(ds))
    ax.set_title(f"porosity, {head}", fontsize=9)
    fig.colorbar(im, ax=ax, label="porosity")
    return _save(fig, path)


def slug_history(ds: xr.Dataset, path) -> Path:
    """Write the run's time series: the pressure drop over the tube [Pa], the grains in the
    tube and the solids outflow [kg/h] beside the feed rate (an open tube only)."""
    c = _slug_case(ds)
    t = np.asarray(ds["time"].values, dtype=float)
    fed = None if c["tube"].get("periodic") else c.get("feed", {}).get("mass_flow_kg_h")
    panels = [("pressure_drop", "pressure drop [Pa]", 1.0), ("grains_in_tube", "grains in the tube", 1.0)]
    if fed is not None and "outflow_mass_rate" in ds:
        panels.append(("outflow_mass_rate", "solids outflow [kg/h]", 3600.0))
    fig = _new_figure(4.2 * len(panels), 3.4)
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (name, label, scale) in zip(axes, panels):
        ax.plot(t, np.asarray(ds[name].values, dtype=float) * scale, lw=0.9)
        if name == "outflow_mass_rate":
            ax.axhline(float(fed), color="C3", ls="--", lw=1, label=f"feed {float(fed):g} kg/h")
            ax.legend(fontsize="small")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    fig.suptitle(_slug_title(ds), fontsize=10)
    return _save(fig, path)


def slug_profile_data(ds: xr.Dataset, x_window=None, t_min=None, min_grains: int = 100):
    """What :func:`slug_profiles_figure` draws: ``(profiles, records, x_window, t_min)``, the
    averaged profiles of :func:`eulag.slug.slug_profiles`, the number of slug records averaged,
    and the window. Defaults: :func:`eulag.slug.statistics_window` (the window the strauss
    study measures in), or the second half of the records of a run that has not reached it."""
    from eulag.slug import slug_profiles, statistics_window

    t = np.asarray(ds["time"].values, dtype=float)
    t_from, xw = statistics_window(_slug_case(ds), times=t)
    if t.size and t_from > t[-1]:  # a partial run (from a checkpoint) that has not reached its window
        t_from = float(t[0] + 0.5 * (t[-1] - t[0]))
    x_window = xw if x_window is None else x_window
    t_min = t_from if t_min is None else t_min
    prof = slug_profiles(ds, x_window=x_window, t_min=t_min, min_grains=min_grains)
    n = int(np.max(prof["samples"].values)) if prof["samples"].size else 0
    return prof, n, x_window, t_min


def slug_profiles_figure(ds: xr.Dataset, path, x_window=None, t_min=None, min_grains: int = 100) -> Path:
    """Write the averaged slug profiles against the distance from the slug centre in grain
    diameters (SMH Figs. 12-16; Δx > 0 ahead of the slug): porosity, axial grain velocity, the
    gas force per unit volume −∂P'/∂x, and where the dataset has them the wall normal stress,
    the granular temperature and the mean contact force per grain (:func:`eulag.slug.slug_profiles`).

    Slugs of ≥ ``min_grains`` grains centred in ``x_window`` [m] at time ≥ ``t_min`` [s]; the
    defaults are those of :func:`slug_profile_data`. Without such a slug the figure says so.
    """
    prof, n, x_window, t_min = slug_profile_data(ds, x_window, t_min, min_grains)
    q = np.asarray(prof["dx_over_d"].values, dtype=float)
    panels = [("porosity", "porosity [1]", 1.0, "Fig. 12"), ("grain_velocity", "grain velocity [m s$^{-1}$]", 1.0, "Fig. 13"),
              ("drag", r"$-\partial P'/\partial x$ [hPa m$^{-1}$]", 0.01, "Fig. 14"),
              ("wall_normal_stress", "wall normal stress [Pa]", 1.0, "Fig. 15"),
              ("granular_temperature", "granular temperature [mm$^2$ s$^{-2}$]", 1e6, "Fig. 16"),
              ("contact_force", "contact force per grain [mN]", 1e3, "")]
    panels = [p for p in panels if p[0] in prof]
    ncol = 3
    nrow = -(-len(panels) // ncol)
    fig = _new_figure(4.0 * ncol, 3.1 * nrow)
    axes = np.atleast_2d(fig.subplots(nrow, ncol, squeeze=False)).ravel()
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    for ax, (name, label, scale, ref) in zip(axes, panels):
        if n == 0:
            ax.text(0.5, 0.5, f"no slug of ≥ {min_grains} grains\nin the window", ha="center", va="center",
                    transform=ax.transAxes, color="0.3")
        else:
            ax.plot(q, np.asarray(prof[name].values, dtype=float) * scale, "-", lw=1.2)
        ax.axvline(0.0, color="0.8", lw=0.6)
        ax.set_xlabel(r"$\Delta x / d$ (ahead of the slug > 0)")
        ax.set_ylabel(label)
        if ref:
            ax.set_title(f"after SMH {ref}", fontsize=8)
        ax.grid(alpha=0.3)
    fig.suptitle(f"{_slug_title(ds)}\naveraged slug: {n} slug record{'' if n == 1 else 's'} (≥ {min_grains} grains, "
                 f"centred in {100 * x_window[0]:.3g}-{100 * x_window[1]:.3g} cm, t ≥ {t_min:.4g} s)", fontsize=10)
    return _save(fig, path)


def slug_cross_section(ds: xr.Dataset, path, t_min=None, frames: int = 11, span_s: float = 0.2) -> Path | None:
    """Write the recorded cross-section of a slug run (``section_x_m``, SMH §3.4):

    - top (after Fig. 17): ``frames`` solids-fraction images of the slice over ``span_s`` seconds
      centred on the record after ``t_min`` where the slice is densest (a slug passing; among
      the records at least 2.5 ``span_s`` from the run's ends where there are such);
    - bottom left (after Fig. 18): each layer's mean axial grain velocity against time around it;
    - bottom right (after Fig. 19): the layer velocities against height, averaged over the records
      while a slug passes and between slugs (:func:`eulag.slug.cross_section_layers`), with the
      grains' rms about them.

    ``t_min`` defaults to the start of the statistics window (:func:`slug_profile_data`). None
    for a dataset without the cross-section records."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    from eulag.slug import SLUG_POROSITY, cross_section_layers, section_porosity

    if "section_solids_fraction" not in ds or "section_x_m" not in ds.attrs:
        return None
    if t_min is None:
        t_min = slug_profile_data(ds)[3]
    t = np.asarray(ds["time"].values, dtype=float)
    xs = float(ds.attrs["section_x_m"])
    phi_s = section_porosity(ds)
    recorded = np.asarray(ds["section_recorded"].values) == 1 if "section_recorded" in ds else np.ones(len(t), bool)
    after = np.flatnonzero((t >= t_min) & recorded)
    if not after.size:
        after = np.flatnonzero(recorded)
    if not after.size:
        return None
    half_window = 2.5 * span_s  # of the layer velocities' panel (after Fig. 18) about that record
    # the densest record whose frames and layer window lie inside the run, if there is one
    whole = after[(t[after] - half_window >= t[0]) & (t[after] + half_window <= t[-1])]
    pool = whole if whole.size else after
    k0 = int(pool[np.argmin(phi_s[pool])])
    dt = float(np.median(np.diff(t))) if len(t) > 1 else span_s
    step = max(1, int(round(span_s / max(frames - 1, 1) / dt)))
    idx = [k0 + (j - frames // 2) * step for j in range(frames)]
    idx = [i for i in idx if 0 <= i < len(t)]
    layers = cross_section_layers(ds, t_min=t_min)
    fig = _new_figure(11.0, 6.8)
    top, bottom = fig.subfigures(2, 1, height_ratios=[1.0, 2.3])
    R = 500.0 * float(_slug_case(ds)["tube"]["diameter_m"])  # tube radius [mm]
    inside = np.asarray(ds["section_pixel_inside"].values) >= 0.5
    axes = np.atleast_1d(top.subplots(1, frames))
    im = None
    for j, ax in enumerate(axes):
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_aspect("equal")
        if j >= len(idx):
            ax.set_axis_off()
            continue
        i = idx[j]
        img = np.where(inside, np.asarray(ds["section_solids_fraction"].values[i], dtype=float), np.nan)
        im = ax.imshow(img, origin="lower", extent=(-R, R, -R, R), cmap="gray_r", vmin=0.0, vmax=0.7)
        ax.add_patch(Circle((0, 0), R, fill=False, lw=0.6))
        ax.set_title(f"{t[i]:.2f} s", fontsize=7)
        if j == 0:
            ax.set_ylabel("z (up), y across" if ds.attrs.get("layer_coordinate") != "radius" else "y, z across",
                          fontsize=6)
    if im is not None:
        top.colorbar(im, ax=list(axes), fraction=0.015, pad=0.01, label="solids fraction")
    top.suptitle("solids fraction of the slice (after SMH Fig. 17)", fontsize=8)
    ax, axr = bottom.subplots(1, 2)
    h = 1e3 * ds["layer"].values
    win = (t >= t[k0] - half_window) & (t <= t[k0] + half_window)
    n = np.asarray(ds["layer_grains"].values, dtype=float)
    u = np.where(n > 0, np.asarray(ds["layer_velocity"].values, dtype=float), np.nan)
    norm = Normalize(h.min(), h.max())
    cmap = colormaps["viridis"]
    for q in range(len(h)):
        ax.plot(t[win], u[win, q], lw=1.0, color=cmap(norm(h[q])), label=f"{h[q]:.2f} mm")
    ax2 = ax.twinx()
    ax2.plot(t[win], phi_s[win], color="0.5", lw=0.8, ls="--")
    ax2.axhline(SLUG_POROSITY, color="0.8", lw=0.6)
    ax2.set_ylabel("slice porosity (dashed)", fontsize=8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("layer grain velocity [m s$^{-1}$]")
    ax.set_title("layers through the slug (after SMH Fig. 18)", fontsize=8)
    ax.legend(fontsize=6, ncol=2, title="centre " + ("radius" if ds.attrs.get("layer_coordinate") == "radius"
                                                      else "height"), title_fontsize=6)
    ax.grid(alpha=0.3)
    ax = axr
    for tag, colour in (("slug", "C0"), ("between", "C1")):
        v, r = layers[f"velocity_{tag}"].values, layers[f"velocity_rms_{tag}"].values
        ax.plot(v, h, "o-", color=colour, ms=3, label=f"{'in slugs' if tag == 'slug' else 'between slugs'} "
                                                      f"({layers.attrs['records_' + tag]} records)")
        ax.fill_betweenx(h, v - r, v + r, color=colour, alpha=0.15)
    ax.set_xlabel("axial grain velocity [m s$^{-1}$] (band: rms)")
    radial = ds.attrs.get("layer_coordinate") == "radius"
    ax.set_ylabel(("distance of the grain centres from the axis" if radial else "height of the grain centres") + " [mm]")
    ax.set_title("layer velocities (after SMH Fig. 19)", fontsize=8)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.suptitle(f"{_slug_title(ds)}\ncross-section at x = {100 * xs:.3g} cm (slice {1e3 * float(ds.attrs['section_width_m']):.3g} mm), "
                 f"statistics t ≥ {t_min:.4g} s", fontsize=9)
    return _save(fig, path)


_TWO_FLUID_SECTION = (("solids_fraction", r"$\alpha_s$ [1]", "viridis"),
                      ("gas_ux", r"gas $u_x$ [m s$^{-1}$]", "viridis"),
                      ("solids_ux", r"solids $u_x$ [m s$^{-1}$]", "viridis"),
                      ("granular_temperature", r"$\Theta$ [m$^2$ s$^{-2}$]", "magma"))


def _two_fluid_name(ds: xr.Dataset) -> str:
    c = ds.attrs
    bits = [str(c.get("name", "") or "two-fluid run"), f"friction {c['friction.model']}" if "friction.model" in c else "",
            f"U_g = {float(c['gas.superficial_velocity']):.3g} m/s" if "gas.superficial_velocity" in c else "",
            f"M_s = {float(c['solids.mass_flow']):.3g} kg/s" if "solids.mass_flow" in c else ""]
    return ", ".join(b for b in bits if b)


def _two_fluid_where(ds: xr.Dataset, x) -> str:
    if ds.sizes.get("x", 1) == 1:
        return "fully developed section"
    return f"x = {_station(ds, x):.4g} m from the inlet"


def two_fluid_section(ds: xr.Dataset, x: float | None, path) -> Path:
    """Write the cross-section of a two-fluid run at the station nearest ``x`` [m] (a fully
    developed run has one): solids volume fraction (after Ding et al. Fig. 5), gas and solids
    axial velocity and granular temperature, coloured per cell on the true polar cells."""
    geo = an.polar_section(ds)
    names = [v for v in _TWO_FLUID_SECTION if v[0] in ds]
    fig = _new_figure(4.4 * len(names), 4.2)
    axes = np.atleast_1d(fig.subplots(1, len(names)))
    for ax, (name, label, cmap) in zip(axes, names):
        _colour_cells(fig, ax, geo, an._field(ds, name, x), label, cmap=cmap)
        _draw_wall(ax, geo.radius)
    fig.suptitle(f"{_two_fluid_name(ds)}: {_two_fluid_where(ds, x)} (looking downstream, gravity -y)", fontsize=10)
    return _save(fig, path)


def two_fluid_profiles(ds: xr.Dataset, x: float | None, path) -> Path:
    """Write profiles along the vertical diameter at the station nearest ``x`` [m] (after Ding
    et al. Figs. 6, 8 and 10): α_s; gas and solids axial velocity; granular temperature; and
    the frictional pressure p_f (log scale, where positive)."""
    geo = an.polar_section(ds)
    D = 2.0 * geo.radius

    def line(name):
        y, v = an.vertical_profile(ds, name, x)
        return v, y / D

    panels = [("solids_fraction", r"$\alpha_s$ [1]", False), ("velocity", r"$u_x$ [m s$^{-1}$]", False),
              ("granular_temperature", r"$\Theta$ [m$^2$ s$^{-2}$]", True),
              ("frictional_pressure", r"$p_f$ [Pa]", True)]
    panels = [p for p in panels if p[0] == "velocity" or p[0] in ds]
    fig = _new_figure(3.6 * len(panels), 4.4)
    axes = np.atleast_1d(fig.subplots(1, len(panels), sharey=True))
    for ax, (name, label, log) in zip(axes, panels):
        if name == "velocity":
            for var, style, text in (("gas_ux", "-", "gas"), ("solids_ux", "--", "solids")):
                if var in ds:
                    ax.plot(*line(var), style, label=text)
            ax.legend(fontsize="small")
        else:
            v, h = line(name)
            ax.plot(np.where(v > 0, v, np.nan) if log else v, h, "-")
            if log and np.any(v > 0):
                ax.set_xscale("log")
                ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(label)
        ax.set_ylim(-0.5, 0.5)
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("y / D [1]  (top +0.5, bottom -0.5)")
    fig.suptitle(f"{_two_fluid_name(ds)}: vertical diameter, {_two_fluid_where(ds, x)}", fontsize=10)
    return _save(fig, path)


def two_fluid_convergence(ds: xr.Dataset, path) -> Path | None:
    """Write the outer iterations' change (log scale; a marched pipe: of its last station) and,
    for a marched pipe, the outer iterations each station took against x [m]. None (nothing
    written) without a ``residual`` history."""
    if "residual" not in ds or not ds["residual"].size:
        return None
    marched = "station_iterations" in ds and ds.sizes.get("x", 1) > 1
    fig = _new_figure(9.0 if marched else 6.4, 3.8)
    axes = np.atleast_1d(fig.subplots(1, 2 if marched else 1))
    v = np.asarray(ds["residual"].values, dtype=float)
    axes[0].semilogy(np.asarray(ds["iteration"].values), np.where(v > 0, v, np.nan), "-")
    axes[0].set_xlabel("outer iteration" + (" (last station)" if marched else ""))
    axes[0].set_ylabel("outer-iteration change [1]")
    if marched:
        axes[1].plot(np.asarray(ds["x"].values, float), np.asarray(ds["station_iterations"].values), "o-", ms=2)
        axes[1].set_xlabel("x [m]")
        axes[1].set_ylabel("outer iterations of the station")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(f"{_two_fluid_name(ds)}:\nconvergence ({verdict_label(ds)})", fontsize=10)
    return _save(fig, path)


def two_fluid_development(ds: xr.Dataset, path) -> Path | None:
    """Write the development along a marched two-fluid pipe: the pressure drop from the inlet
    [kPa] and the section-mean solids fraction against x [m]. None (nothing written) for a fully
    developed section."""
    if ds.sizes.get("x", 1) < 2 or "pressure" not in ds:
        return None
    x = np.asarray(ds["x"].values, dtype=float)
    fig = _new_figure(9.0, 3.6)
    ax_p, ax_h = fig.subplots(1, 2)
    ax_p.plot(np.concatenate([[0.0], x]), np.concatenate([[0.0], -np.asarray(ds["pressure"].values, float)]) / 1e3)
    ax_p.set_ylabel("pressure drop from the inlet [kPa]")
    if "solids_holdup_x" in ds:
        ax_h.plot(x, np.asarray(ds["solids_holdup_x"].values, float))
    ax_h.set_ylabel(r"section-mean $\alpha_s$ [1]")
    for ax in (ax_p, ax_h):
        ax.set_xlabel("x [m]")
        ax.grid(alpha=0.3)
    fig.suptitle(f"{_two_fluid_name(ds)}: development along the pipe", fontsize=10)
    return _save(fig, path)


# ---------------------------------------------------------------------------
# everything
# ---------------------------------------------------------------------------

def default_station(ds: xr.Dataset) -> float | None:
    """The first ``pipe.sections`` entry [m] of the case attributes, else the last x."""
    sections = an.attr(ds, "pipe.sections")
    if sections is not None and np.size(sections):
        return float(np.atleast_1d(sections)[0])
    return float(ds["x"].values[-1]) if "x" in ds.dims else None


def plot_all(ds_or_path, x: float | None = None, outdir=None) -> list[Path]:
    """Write all figures of a dataset (PNG) and return their paths.

    ``ds_or_path``: an xarray Dataset or a NetCDF path. ``outdir``: default
    ``<dataset stem>_figures/`` beside the dataset (``<case name>_figures/`` in the current
    directory for an in-memory dataset). The figures follow the dataset's ``model`` attribute:

    * Euler-Lagrange (and single-phase gas): ``<stem>_section_x<x>.png``,
      ``<stem>_profiles_x<x>.png`` and, when there is a history, ``<stem>_convergence.png``;
      ``x`` [m] the section (default :func:`default_station`);
    * ``"two-fluid"``: ``<stem>_section[_x<x>].png``, ``<stem>_profiles[_x<x>].png``, a marched
      pipe's ``<stem>_development.png`` and ``<stem>_convergence.png``; ``x`` a station of a
      marched pipe (default: its end);
    * ``"dem-darcy"``: ``<stem>_spacetime.png``, ``<stem>_history.png`` and
      ``<stem>_slug_profiles.png``; these span the tube and the run's time, so ``x`` must be None.

    ValueError if the dataset lacks what its figures need (:func:`dataset_problem`) or ``x`` lies
    outside the pipe (or is given for a dem-darcy dataset). The figures
    are drawn in a temporary directory and moved into ``outdir`` only when all of them
    succeeded, so an error leaves no partial set (and no new ``outdir``).
    """
    source = None
    if isinstance(ds_or_path, (str, os.PathLike)):
        source = Path(ds_or_path)
        with xr.open_dataset(source) as opened:
            ds = opened.load()
    else:
        ds = ds_or_path
        if ds.encoding.get("source"):
            source = Path(ds.encoding["source"])
    problem = dataset_problem(ds)
    if problem is not None:
        raise ValueError(problem)
    model = str(ds.attrs.get("model", "euler-lagrange"))
    name = (_slug_case(ds).get("name", "") if model == "dem-darcy" else
            ds.attrs.get("name", "") if model == "two-fluid" else _case_name(ds))
    stem = source.stem if source is not None else (str(name).replace(" ", "_") or "eulag")
    if outdir is None:
        outdir = (source.parent if source is not None else Path(".")) / f"{stem}_figures"
    outdir = Path(outdir)
    draw = _figure_set(ds, model, x, stem, source)

    parent = outdir.parent if str(outdir.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.", dir=parent))
    try:
        made = [p for p in draw(tmp) if p is not None]
        outdir.mkdir(parents=True, exist_ok=True)
        written = []
        for p in made:
            target = outdir / p.name
            os.replace(p, target)
            written.append(target)
        return written
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _figure_set(ds: xr.Dataset, model: str, x: float | None, stem: str, source):
    """The function drawing ``model``'s figures into a directory (a list of paths, None for a
    figure the dataset has nothing for); raises ValueError for a bad ``x`` before any drawing."""
    if model == "dem-darcy":
        if x is not None:
            raise ValueError(f"x = {x:g}: a dem-darcy (slug) dataset has no cross-section station; its "
                             "figures span the tube and the run's time; allowed: no x")
        return lambda tmp: [slug_spacetime(ds, tmp / f"{stem}_spacetime.png"),
                            slug_history(ds, tmp / f"{stem}_history.png"),
                            slug_profiles_figure(ds, tmp / f"{stem}_slug_profiles.png"),
                            slug_cross_section(ds, tmp / f"{stem}_cross_section.png")]
    if model == "two-fluid":
        an.check_station(ds, x)
        tag = f"_x{_station(ds, x):.4g}m" if ds.sizes.get("x", 1) > 1 else ""
        return lambda tmp: [two_fluid_section(ds, x, tmp / f"{stem}_section{tag}.png"),
                            two_fluid_profiles(ds, x, tmp / f"{stem}_profiles{tag}.png"),
                            two_fluid_development(ds, tmp / f"{stem}_development.png"),
                            two_fluid_convergence(ds, tmp / f"{stem}_convergence.png")]
    if x is None:
        x = default_station(ds)
    an.check_station(ds, x)
    xs = _station(ds, x)
    tag = f"_x{xs:.4g}m" if xs is not None and ds.sizes.get("x", 1) > 1 else ""
    reference = resolve_reference(ds, source)
    return lambda tmp: [three_panel(ds, x, tmp / f"{stem}_section{tag}.png"),
                        vertical_profiles(ds, x, tmp / f"{stem}_profiles{tag}.png", reference=reference),
                        convergence(ds, tmp / f"{stem}_convergence.png")]
