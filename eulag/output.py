"""Self-describing NetCDF datasets.

:func:`gas_dataset` turns a solved gas field into an :class:`xarray.Dataset` (CF-1.8,
``units`` and ``long_name`` on every variable, the whole case in the global attributes);
:func:`write_dataset` writes it atomically, so no partial file is ever left behind.
"""

from __future__ import annotations

import datetime as _dt
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import xarray as xr

import eulag
from eulag.config import dataset_attr_name
from eulag.files import atomic_write

__all__ = ["gas_dataset", "coupled_dataset", "write_dataset", "atomic_write", "CONVENTIONS"]

#: The CF version the datasets follow: nothing newer than CF-1.8 is used, and 1.8 is the newest
#: the CF Checker (cfchecker 4.1) checks.
CONVENTIONS = "CF-1.8"


def _missing_replicas(loop) -> str:
    """The note the replica variables carry when some final passes' own solves failed."""
    failed = getattr(loop, "replica_failures", None) or []
    if not failed:
        return ""
    n = len(failed) + len(loop.replica_pressure_gradients)
    return (f" ({n - len(failed)} of the {n} final passes: the solves on the others' sources failed, "
            "see the attribute replica_solve_failures)")


def _var(dims, values, units: str, long_name: str, **extra) -> xr.Variable:
    attrs = {"units": units, "long_name": long_name, **extra}
    return xr.Variable(dims, np.asarray(values, dtype=np.float64), attrs)


def gas_dataset(case, mesh, field, *, timings: Mapping[str, float] | None = None,
                attrs: Mapping[str, Any] | None = None) -> xr.Dataset:
    """The gas variables of a solved case as a CF-1.8 dataset.

    Parameters
    ----------
    case : eulag.config.Case
        The case; flattened into the global attributes (every default included).
    mesh : rans.PipeMesh
        The mesh the field lives on.
    field : rans.GasField
        The solved gas field (velocities [m s-1], p [Pa], k [m2 s-2], epsilon [m2 s-3]).
    timings : mapping phase -> wall-clock seconds, optional
        Stored as global attributes ``time_<phase>`` [s] (e.g. ``time_gas_solve``).
    attrs : mapping, optional
        Further global attributes (str, int, float or arrays).

    For a single-phase run ``pressure_gradient_single_phase`` equals ``pressure_gradient``
    and ``residual(iteration)`` holds one entry, the gas solver's final residual; the full
    gas-solver history is ``gas_residual(gas_iteration)``.
    """
    nx, nr, nt = mesh.shape
    periodic = mesh.mode == "periodic"
    xyz = ("x", "r", "theta")

    residuals = np.asarray(field.residuals, dtype=np.float64).ravel()
    final_residual = residuals[-1] if residuals.size else np.nan
    dpdx = np.asarray(field.pressure_gradient, dtype=np.float64).reshape(nx)

    coords = {
        "x": _var("x", mesh.x, "m", "axial position of the cell centre (flow direction)",
                  axis="X"),
        "r": _var("r", mesh.r, "m", "radius of the ring centroid"),
        "theta": _var("theta", mesh.theta, "rad",
                      "azimuthal angle of the sector centre, from the +z axis towards +y"),
        "x_edge": _var("x_edge", mesh.x_edges, "m", "axial position of the cell faces"),
        "r_edge": _var("r_edge", mesh.r_edges, "m", "radius of the ring faces (last: the wall)"),
        "theta_edge": _var("theta_edge", mesh.theta_edges, "rad", "azimuthal angle of the sector faces"),
        "y": _var(("r", "theta"), mesh.y, "m", "vertical position of the cell centroid (up)"),
        "z": _var(("r", "theta"), mesh.z, "m", "horizontal position of the cell centroid"),
        "iteration": xr.Variable("iteration", np.arange(1, dtype=np.int64),
                                 {"long_name": "coupling pass (0: the single-phase gas solve)",
                                  "units": "1"}),
        "gas_iteration": xr.Variable("gas_iteration", np.arange(1, residuals.size + 1, dtype=np.int64),
                                     {"long_name": "gas-solver outer iteration", "units": "1"}),
    }
    data_bounds = {}
    for name, edges in (("x", mesh.x_edges), ("r", mesh.r_edges), ("theta", mesh.theta_edges)):
        e = np.asarray(edges, dtype=np.float64)
        coords[name].attrs["bounds"] = f"{name}_bnds"
        data_bounds[f"{name}_bnds"] = _var((name, "nv"), np.stack([e[:-1], e[1:]], axis=1),
                                      coords[name].attrs["units"], f"faces of the cells along {name}")
    if periodic:
        coords["x"].attrs["comment"] = "axially periodic (fully developed) flow: a single station"

    cell_vars = dict(coordinates="y z", cell_measures="area: cell_area")
    p_ref = "its section mean (periodic, fully developed)" if periodic else "the outlet"
    data = {
        "cell_area": _var(("r", "theta"), mesh.cell_area, "m2",
                          "cross-section area of the cell (exact, curved wall)", coordinates="y z"),
        "gas_ux": _var(xyz, field.ux, "m s-1", "mean gas velocity, axial (x)", **cell_vars),
        "gas_uy": _var(xyz, field.uy, "m s-1", "mean gas velocity, vertical up (y)", **cell_vars),
        "gas_uz": _var(xyz, field.uz, "m s-1", "mean gas velocity, horizontal (z)", **cell_vars),
        "gas_k": _var(xyz, field.k, "m2 s-2", "turbulent kinetic energy of the gas", **cell_vars),
        "gas_epsilon": _var(xyz, field.epsilon, "m2 s-3",
                            "dissipation rate of turbulent kinetic energy", **cell_vars),
        "gas_p": _var(xyz, field.p, "Pa", f"gas pressure relative to {p_ref}", **cell_vars),
        "gas_nut": _var(xyz, field.nut, "m2 s-1", "turbulent kinematic viscosity", **cell_vars),
        "pressure_gradient": _var("x", dpdx, "Pa m-1", "section-mean -dp/dx"),
        "pressure_gradient_single_phase": _var(
            "x", dpdx, "Pa m-1", "section-mean -dp/dx without particles (single-phase gas solve)"),
        "friction_factor": _var("x", np.asarray(field.friction_factor).reshape(nx), "1",
                                "Darcy friction factor from the section-mean -dp/dx"),
        "wall_yplus": _var(("x", "theta"), np.asarray(field.wall_yplus).reshape(nx, nt), "1",
                           "y+ of the wall-cell centroid"),
        "wall_shear": _var(("x", "theta"), np.asarray(field.wall_shear).reshape(nx, nt), "Pa",
                           "wall shear stress magnitude"),
        "residual": _var("iteration", [final_residual], "1",
                         "coupling residual per pass; single-phase run: the gas solver's final residual"),
        "gas_residual": _var("gas_iteration", residuals, "1", "gas-solver residual history"),
    }
    if getattr(field, "station_converged", None) is not None:  # rans.GasField of a solve (not a checkpoint's)
        ch = np.asarray(field.station_change, dtype=np.float64).reshape(nx, 2)
        data["gas_station_converged"] = xr.Variable(
            "x", np.asarray(field.station_converged, dtype=np.int8).reshape(nx),
            {"long_name": "whether the gas solve reached its tolerance at this station (1) or not (0)",
             "units": "1"})
        data["gas_station_change_velocity"] = _var(
            "x", ch[:, 0], "1", "largest velocity change of the station's last gas-solver iteration, over U_b")
        data["gas_station_change_turbulence"] = _var(
            "x", ch[:, 1], "1", "largest relative change of k or epsilon in the station's last gas-solver iteration")

    converged = bool(field.converged)
    glob: dict[str, Any] = {
        "Conventions": CONVENTIONS,
        "title": f"eulag result: {case.name}",
        "source": f"eulag {eulag.__version__}",
        "history": f"{_dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds')} "
                   f"eulag {eulag.__version__} run {case.name}",
        "model": "euler-lagrange",
        "eulag_version": eulag.__version__,
        "eulag_commit": eulag.git_commit(),
        "seed": int(case.numerics.seed),
        "gas_converged": "true" if converged else "false",
        "gas_iterations": int(getattr(field, "iterations", residuals.size)),
        "phases": "single-phase" if case.particles is None else "gas-particle",
        "cells": int(nx * nr * nt),
        "reynolds_number": float(case.reynolds_number),
    }
    glob.update({dataset_attr_name(k): v for k, v in case.to_attrs().items()})
    if case.source:
        glob["case_file"] = str(case.source)
        try:  # the case file itself, verbatim, so the dataset can be re-run without it
            glob["case_toml"] = Path(case.source).read_text(encoding="utf-8")
        except OSError:
            pass
    if timings:
        glob["time_units"] = "s"
        for phase, seconds in timings.items():
            glob[f"time_{phase}"] = float(seconds)
    if attrs:
        glob.update(attrs)
    ds = xr.Dataset({**data, **data_bounds}, coords=coords, attrs=glob)
    set_converged(ds, converged)
    return ds


def set_converged(ds: xr.Dataset, converged: bool) -> None:
    """The run's verdict as one CF flag variable ``converged`` (0 not converged, 1 converged)."""
    ds["converged"] = xr.Variable((), np.int8(1 if converged else 0),
                                  {"long_name": "whether the run converged",
                                   "flag_values": np.array([0, 1], dtype=np.int8),
                                   "flag_meanings": "not_converged converged"})


def is_converged(ds) -> bool:
    """The run's verdict from a dataset (the ``converged`` flag variable, or the global
    attribute of datasets written before it). A slug (dem-darcy) dataset is judged again by
    today's rules (:func:`eulag.slug.verdict`), so a run stored before a rule existed is not
    taken as finished when it breaks it."""
    if ds.attrs.get("model") == "dem-darcy":
        from eulag.slug import verdict

        return verdict(ds)[0]
    if "converged" in ds.variables:
        return bool(int(ds["converged"].values))
    return ds.attrs.get("converged") == "true"


def write_dataset(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write ``ds`` to NetCDF4 at ``path`` atomically (:func:`atomic_write`)."""
    encoding = {}
    for name, var in ds.variables.items():
        enc: dict[str, Any] = {}
        if name in ds.coords or name.endswith("_bnds"):
            enc["_FillValue"] = None
        if var.dtype.kind in "OU":  # CF: character arrays, not variable-length strings
            enc["dtype"] = "S1"
        if var.size >= 4096 and var.dtype.kind == "f":
            enc.update(zlib=True, complevel=1)
        if enc:
            encoding[name] = enc
    return atomic_write(path, lambda tmp: ds.to_netcdf(tmp, format="NETCDF4", engine="netcdf4",
                                                       encoding=encoding))


def coupled_dataset(loop, *, attrs: Mapping[str, Any] | None = None) -> xr.Dataset:
    """The dataset of a finished :class:`eulag.coupling.CouplingLoop` (gas + particles).

    Gas variables are the last gas solve's; particle statistics and their ``*_stderr`` (from
    the batch spread) average the final ``numerics.average_passes`` passes; ``source_*`` are
    the relaxed sources as the gas used them (zero for one-way coupling, which applies none);
    the coupling history has one entry per Lagrangian pass.
    """
    case, mesh = loop.case, loop.mesh
    nx, nr, nt = mesh.shape
    xyz = ("x", "r", "theta")
    cell_vars = dict(coordinates="y z", cell_measures="area: cell_area")
    s = loop.sample()
    h = loop.history.arrays()
    npass = h["residual"].size
    timings = {k: float(v) for k, v in loop.timings.items()}
    ds = gas_dataset(case, mesh, loop.gas, timings=timings)
    ds = ds.drop_vars(["residual"]).drop_dims("iteration", errors="ignore")
    ds = ds.assign_coords(iteration=xr.Variable("iteration", np.arange(1, npass + 1, dtype=np.int64),
                                                {"long_name": "coupling pass (Lagrangian pass + gas solve)",
                                                 "units": "1"}))

    def cell(name, values, units, long_name, **extra):
        ds[name] = _var(xyz, values, units, long_name, **cell_vars, **extra)

    names = ("x", "y", "z")
    for c in range(3):
        cell(f"particle_u{names[c]}", s.velocity(c), "m s-1",
             f"mass-weighted mean particle velocity, {names[c]} (NaN where no particles)")
        cell(f"particle_u{names[c]}_stderr", s.velocity_stderr(c), "m s-1",
             f"standard error of particle_u{names[c]} (batch spread)")
        cell(f"particle_u{names[c]}_rms", s.velocity_rms(c), "m s-1",
             f"rms of the particle velocity fluctuation, {names[c]}")
        cell(f"particle_u{names[c]}_rms_stderr", s.velocity_rms_stderr(c), "m s-1",
             f"standard error of particle_u{names[c]}_rms (batch spread)")
    cell("particle_concentration", s.concentration, "kg m-3", "particle mass concentration")
    cell("particle_concentration_stderr", s.concentration_stderr, "kg m-3",
         "standard error of particle_concentration (batch spread)")
    cell("particle_number_density", s.number_density, "m-3", "particle number concentration")
    cell("particle_mass_flux", s.mass_flux, "kg m-2 s-1", "axial particle mass flux")
    cell("particle_mass_flux_stderr", s.mass_flux_stderr, "kg m-2 s-1",
         "standard error of particle_mass_flux (batch spread)")
    if case.physics.inter_particle_collisions:
        for c in range(3):
            cell(f"particle_collision_force_{names[c]}", s.collision_force(c), "N m-3",
                 f"net force of the inter-particle collisions on the particles, {names[c]} "
                 f"(physics.partner_momentum = {case.physics.partner_momentum}; zero in the mean "
                 "for momentum-conserving collisions)")
            cell(f"particle_collision_force_{names[c]}_stderr", s.collision_force_stderr(c), "N m-3",
                 f"standard error of particle_collision_force_{names[c]} (batch spread)")
        tot, se = s.collision_force_total
        for c in range(3):
            ds[f"particle_collision_force_total_{names[c]}"] = _var(
                (), tot[c], "N", f"pipe integral of particle_collision_force_{names[c]}")
            ds[f"particle_collision_force_total_{names[c]}_stderr"] = _var(
                (), se[c], "N", f"standard error of particle_collision_force_total_{names[c]} (batch spread)")
    src = loop.sources
    applied = src is not None
    zero = np.zeros(mesh.shape)
    note = {} if applied else {"comment": "one-way coupling: no source applied to the gas"}
    for c in range(3):
        cell(f"source_u{names[c]}", src["momentum"][c] if applied else zero, "N m-3",
             f"momentum source on the gas, {names[c]} (relaxed, as used)", **note)
        cell(f"source_u{names[c]}_stderr", s.momentum_source_stderr(c), "N m-3",
             f"standard error of the sampled momentum source, {names[c]} (batch spread)")
    cell("source_k", src["k"] if applied else zero, "W m-3",
         "turbulence source S_k = -<u'_F . J> (relaxed, as used)", **note)
    cell("source_k_stderr", s.k_source_stderr, "W m-3", "standard error of the sampled S_k")
    cell("source_epsilon", src["epsilon"] if applied else zero, "W m-3 s-1",
         "dissipation source C_eps3 (eps/k) S_k, C_eps3 = 1.8 (relaxed, as used)", **note)
    k0 = loop.gas0.k
    cell("turbulence_modulation", loop.gas.k / k0, "1", "k with particles / k single-phase")
    dpdx0 = np.asarray(loop.gas0.pressure_gradient, dtype=float).reshape(nx)
    ds["pressure_gradient_single_phase"] = _var("x", dpdx0, "Pa m-1",
                                                "section-mean -dp/dx without particles (first gas solve)")
    ds["wall_collision_rate"] = _var(("x", "theta"), s.wall_collision_rate, "m-2 s-1",
                                     "particle-wall impacts (rebounds) per wall area and time")
    ds["wall_collision_rate_stderr"] = _var(("x", "theta"), s.wall_collision_rate_stderr, "m-2 s-1",
                                            "standard error of wall_collision_rate (batch spread)")
    ds["wall_impact_angle_mean"] = _var(("x", "theta"), s.wall_impact_angle_mean, "degree",
                                        "mean nominal wall-impact angle (NaN: no impacts)")
    ds["wall_impact_speed_mean"] = _var(("x", "theta"), s.wall_impact_speed_mean, "m s-1",
                                        "mean wall-impact speed (NaN: no impacts)")
    a_edges, a_pdf = s.impact_angle_pdf
    v_edges, v_pdf = s.impact_speed_pdf
    ds = ds.assign_coords(
        impact_angle=_var("impact_angle", 0.5 * (a_edges[1:] + a_edges[:-1]), "degree",
                          "wall-impact angle bin centre (1 degree bins)"),
        impact_speed=_var("impact_speed", 0.5 * (v_edges[1:] + v_edges[:-1]), "m s-1",
                          "wall-impact speed bin centre (last bin: also faster impacts)"))
    ds["wall_impact_angle_pdf"] = _var("impact_angle", a_pdf, "1",
                                       "fraction of wall impacts per angle bin (erosion)")
    ds["wall_impact_speed_pdf"] = _var("impact_speed", v_pdf, "1",
                                       "fraction of wall impacts per speed bin (erosion)")
    it = "iteration"
    ds["residual"] = _var(it, h["residual"], "1",
                          "coupling residual: RMS change of the relaxed sources in units of their noise "
                          "(NaN for the first pass)")
    ds["parcels"] = xr.Variable(it, h["parcels"].astype(np.int64), {"long_name": "parcels tracked in the pass",
                                                                     "units": "1"})
    ds["parcels_lost"] = xr.Variable(it, h["lost"].astype(np.int64),
                                     {"long_name": "parcels lost (left through a wall or non-finite): must be 0",
                                      "units": "1"})
    ds["parcels_stuck"] = xr.Variable(it, h["stuck"].astype(np.int64),
                                      {"long_name": "parcels stopped by the residence-time cap", "units": "1"})
    ds["relaxation"] = _var(it, h["relaxation"], "1", "source under-relaxation factor used in the pass")
    ds["gas_floored_cells"] = xr.Variable(
        it, h["floored"].astype(np.int64),
        {"long_name": "gas cells held at the k/epsilon floors after the pass's gas solve (should be 0)",
         "units": "1"})
    ds["gas_turbulence_relaxation"] = _var(
        it, h["gas_relaxation"], "1",
        "smallest implicit k-epsilon under-relaxation a station of the pass's gas solve needed "
        "(1: every station converged at the first attempt)")
    ds["collision_momentum_history"] = _var(
        it, h["collision_momentum"], "1",
        "net axial momentum the inter-particle collisions gave the particles in the pass / the "
        "particles' axial momentum inflow (about 0 when the collision statistics match the "
        "particles: the stochastic partners conserve momentum only on average)")
    ds["pressure_gradient_history"] = _var(it, h["pressure_gradient"], "Pa m-1",
                                           "pipe-mean -dp/dx after the pass's gas solve")
    # the loop's own verdict: each convergence criterion after each judged pass, and the last
    # judgement (eulag.coupling.convergence_criteria)
    CRITERIA = loop.criteria_names

    ds["criterion_name"] = xr.Variable("criterion", np.array(CRITERIA, dtype=object),
                                       {"long_name": "convergence criterion of the coupling loop"})
    ds["criterion_history"] = _var(
        ("iteration", "criterion"), np.stack([h["criterion_" + c] for c in CRITERIA], axis=1), "1",
        "value of each convergence criterion after the pass (NaN: final pass, not judged)")
    judged = {c.name: c for c in loop.criteria}
    ds["criterion_value"] = _var("criterion", [judged[c].value if c in judged else np.nan for c in CRITERIA],
                                 "1", "value of each convergence criterion at the last judged pass")
    ds["criterion_threshold"] = _var("criterion", [judged[c].threshold if c in judged else np.nan
                                                   for c in CRITERIA],
                                     "1", "threshold each criterion's value must stay below")
    ds["criterion_met"] = xr.Variable("criterion", np.array([1 if c in judged and judged[c].met else 0
                                                             for c in CRITERIA], dtype=np.int8),
                                      {"long_name": "criterion met at the last judged pass",
                                       "flag_values": np.array([0, 1], dtype=np.int8),
                                       "flag_meanings": "not_met met"})
    if loop.replicas:  # the gas at the first station, solved on each final pass's own sources
        rep = np.stack(loop.replicas)  # (replica, 3, nr, nt)
        for c, comp in enumerate("xyz"):
            ds[f"replica_gas_u{comp}"] = _var(
                ("replica", "r", "theta"), rep[:, c], "m s-1",
                f"gas velocity {comp} at x = {case.pipe.sections[0]:g} m (the nearest station), solved on the "
                "sources of one final pass alone: the replicas behind the pattern metrics' error bars"
                + _missing_replicas(loop),
                coordinates="y z")
    if loop.replica_pressure_gradients:
        ds["replica_pressure_gradient"] = _var(
            ("replica", "x"), np.stack(loop.replica_pressure_gradients), "Pa m-1",
            ("section-mean -dp/dx solved on the sources of one final pass alone, in the order of the "
            "final passes: its spread is the error bar of pressure_gradient, its trend a drift "
            "over the final passes" if getattr(loop, "final_solve_failure", None) is None else
            "section-mean -dp/dx solved on the sources of one final pass alone, in the order of the "
            "final passes (the solve on their averaged sources failed: pressure_gradient is the relaxed "
            "iterate's, which their spread does not bound)") + _missing_replicas(loop))
    ds["time_gas_solve_pass"] = _var(it, h["time_gas"], "s", "wall-clock time of the pass's gas solve")
    ds["time_lagrangian_pass"] = _var(it, h["time_particles"], "s", "wall-clock time of the Lagrangian pass")

    dx = mesh.dx
    dp_total = float(np.sum(np.asarray(loop.gas.pressure_gradient).reshape(nx) * dx))
    dp_gas = float(np.sum(dpdx0 * dx))
    eta = case.particles.mass_loading
    dyn = 0.5 * case.gas.density * case.gas.bulk_velocity**2 * case.pipe.length / case.pipe.diameter
    ratio = dp_total / dp_gas
    lam_z = (dp_total - dp_gas) / (eta * dyn) if eta > 0 else float("nan")
    ds["solids_pressure_drop_ratio"] = _var((), ratio, "1", "pressure drop with particles / without (whole pipe)")
    ds["additional_pressure_loss_coefficient"] = _var(
        (), lam_z, "1", "lambda_Z = (dp_total - dp_gas) / (eta rho U0^2 L / (2 D))")
    set_converged(ds, loop.converged)
    c = s.counts
    b = s.budget
    ds.attrs.update({
        "coupling_passes": int(npass),
        "parcels": int(case.numerics.parcels),
        "final_passes_averaged": int(s.passes),
        "parcels_injected_final": c["injected"], "parcels_exited_final": c["exited"],
        "parcels_stuck_final": c["stuck"], "wall_rebounds_final": c["wall_rebounds"],
        "wall_sliding_steps_final": c["wall_sliding"] + c["wall_rolling"],
        "inter_particle_collisions_final": c["particle_collisions"],
        "inlet_reflections_final": c["inlet_reflections"],
        "particle_steps_final": c["steps"],
        "mean_residence_time": float(b["mean_residence_time"]),
        "solids_pressure_drop_ratio": ratio,
        "additional_pressure_loss_coefficient": lam_z,
        "relaxation_final": float(h["relaxation"][-1]),
        "stop_reason": loop.stop_reason,
        "gas_field": loop.gas_field_note,
    })
    if getattr(loop, "final_solve_failure", None) is not None:  # the solve on the averaged sources failed
        ds.attrs["final_solve_failure"] = loop.final_solve_failure
    if getattr(loop, "replica_failures", None):  # final passes whose own solve failed: no replica
        ds.attrs["replica_solve_failures"] = "; ".join(loop.replica_failures)
    if attrs:
        ds.attrs.update(attrs)
    return ds
