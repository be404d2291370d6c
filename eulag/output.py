"""Self-describing NetCDF datasets (DESIGN.md, "Dataset schema").

:func:`gas_dataset` turns a solved gas field into an :class:`xarray.Dataset` (CF-1.10,
``units`` and ``long_name`` on every variable, the whole case in the global attributes);
:func:`write_dataset` writes it atomically, so no partial file is ever left behind.
"""

from __future__ import annotations

import datetime as _dt
import os
import tempfile
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import xarray as xr

import eulag

__all__ = ["gas_dataset", "write_dataset", "CONVENTIONS"]

CONVENTIONS = "CF-1.10"


def _var(dims, values, units: str, long_name: str, **extra) -> xr.Variable:
    attrs = {"units": units, "long_name": long_name, **extra}
    return xr.Variable(dims, np.asarray(values, dtype=np.float64), attrs)


def gas_dataset(case, mesh, field, *, timings: Mapping[str, float] | None = None,
                attrs: Mapping[str, Any] | None = None) -> xr.Dataset:
    """The gas variables of a solved case as a CF-1.10 dataset.

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
        "cell_area": _var(("r", "theta"), mesh.cell_area, "m2",
                          "cross-section area of the cell (exact, curved wall)"),
        "iteration": xr.Variable("iteration", np.arange(1, dtype=np.int64),
                                 {"long_name": "coupling pass (0: the single-phase gas solve)",
                                  "units": "1"}),
        "gas_iteration": xr.Variable("gas_iteration", np.arange(1, residuals.size + 1, dtype=np.int64),
                                     {"long_name": "gas-solver outer iteration", "units": "1"}),
    }
    if periodic:
        coords["x"].attrs["comment"] = "axially periodic (fully developed) flow: a single station"

    cell_vars = dict(coordinates="y z", cell_measures="area: cell_area")
    p_ref = "section mean (periodic, fully developed)" if periodic else "the outlet"
    data = {
        "gas_ux": _var(xyz, field.ux, "m s-1", "mean gas velocity, axial (x)", **cell_vars),
        "gas_uy": _var(xyz, field.uy, "m s-1", "mean gas velocity, vertical up (y)", **cell_vars),
        "gas_uz": _var(xyz, field.uz, "m s-1", "mean gas velocity, horizontal (z)", **cell_vars),
        "gas_k": _var(xyz, field.k, "m2 s-2", "turbulent kinetic energy of the gas", **cell_vars),
        "gas_epsilon": _var(xyz, field.epsilon, "m2 s-3",
                            "dissipation rate of turbulent kinetic energy", **cell_vars),
        "gas_p": _var(xyz, field.p, "Pa", f"gas pressure relative to the {p_ref}", **cell_vars),
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

    converged = bool(field.converged)
    glob: dict[str, Any] = {
        "Conventions": CONVENTIONS,
        "title": f"eulag result: {case.name}",
        "source": f"eulag {eulag.__version__}",
        "history": f"{_dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds')} "
                   f"eulag {eulag.__version__} run {case.name}",
        "eulag_version": eulag.__version__,
        "seed": int(case.numerics.seed),
        "converged": "true" if converged else "false",
        "gas_converged": "true" if converged else "false",
        "gas_iterations": int(getattr(field, "iterations", residuals.size)),
        "phases": "single-phase" if case.particles is None else "gas-particle",
        "cells": int(nx * nr * nt),
        "reynolds_number": float(case.reynolds_number),
    }
    glob.update(case.to_attrs())
    if case.source:
        glob["case_file"] = str(case.source)
    if timings:
        glob["time_units"] = "s"
        for phase, seconds in timings.items():
            glob[f"time_{phase}"] = float(seconds)
    if attrs:
        glob.update(attrs)
    return xr.Dataset(data, coords=coords, attrs=glob)


def write_dataset(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write ``ds`` to NetCDF4 at ``path`` atomically.

    The data go to a temporary file in the same directory, are flushed to disk, and the
    file is renamed over ``path`` (``os.replace``). On any failure the temporary file is
    removed and ``path`` is left as it was.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    os.close(fd)
    try:
        encoding = {}
        for name, var in ds.variables.items():
            enc: dict[str, Any] = {}
            if name in ds.coords:
                enc["_FillValue"] = None
            if var.size >= 4096 and var.dtype.kind == "f":
                enc.update(zlib=True, complevel=1)
            if enc:
                encoding[name] = enc
        ds.to_netcdf(tmp, format="NETCDF4", engine="netcdf4", encoding=encoding)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path
