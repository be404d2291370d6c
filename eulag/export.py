"""Result dataset -> VTK file of the 3-D pipe, for ParaView and other VTK readers.

:func:`export_vts` reads a result NetCDF (:mod:`eulag.output`: cell fields on the dimensions
``x``, ``r``, ``theta`` with the cell faces ``x_edge``, ``r_edge``, ``theta_edge``) and writes
the pipe as a VTK XML file with every cell field as cell data.

Geometry. The mesh is the solver's (:mod:`rans.mesh`): axial slabs x a polar cross-section
of rings and sectors. Points are the cell corners at the axial faces ``x_edge``, the ring
faces ``r_edge`` and the sector faces ``theta_edge``, in the dataset's Cartesian frame:
x along the axis, y vertical up, z horizontal, y = r sin(theta), z = r cos(theta). The
sector faces are straight chords between corners (VTK cells are linear), so the cell
volumes of the file are those of a polygonal pipe: short of the exact annular sectors by
about (2 pi / nt)^2 / 6 in relative terms (0.4 % at 40 sectors); the field values are the
cell means of the solver, unchanged. Every cell has a positive volume. How the axis and
the theta seam are represented depends on the format (below): the unstructured grid shares
points there, the structured grid repeats them.

Cell data: every variable whose dimensions are (x, r, theta), in any order, under its own
name (float64; NaN kept, e.g. particle statistics in cells no particle reached); the
Cartesian vectors of the schema also as 3-component arrays: ``gas_u`` from
``gas_ux, gas_uy, gas_uz``, ``particle_u``, ``source_u``, ``particle_collision_force`` from
their ``_x, _y, _z`` components, and in general ``P`` from ``Pux, Puy, Puz`` or
``P_x, P_y, P_z``. The integer arrays ``cell_i``, ``cell_j``, ``cell_k`` give each cell's
axial, ring and sector index (threshold on them to pick a station, ring or sector).
Variables on (x, theta) (wall fields) or (x,) (per-station numbers) are not cell fields and
are not exported.

Formats, chosen by the target's suffix:

* ``.vts``: VTK XML *structured* grid, written with VTK's own Python package (``vtk``, Kitware;
  the optional extra ``eulag[vtk]``; only its data-model and XML-writer modules are loaded, no
  rendering library). The grid's index directions are (x, theta, r), a right-handed order in
  this frame, so that every cell has a positive volume: points are the (nx + 1) x (nt + 1) x
  (nr + 1) corners, x fastest, then theta, then r; cells in the same order (cell (i, j, k) of
  the dataset is number i + nx (k + nt j)). The theta
  seam is closed geometrically: the last column of points (theta = 2 pi) holds exactly the
  coordinates of the first, so the sectors k = nt - 1 and k = 0 touch without a gap (a
  structured grid cannot share the point ids, so point-data filters such as cell-to-point
  interpolation see a seam unless the points are merged, e.g. by ParaView's "Merge Points"
  or "Clean to Grid"). The
  ring-0 cells are hexahedra whose four inner corners lie on the axis (degenerate: they have
  the wedge's volume).
* ``.vtu``: VTK XML *unstructured* grid, written with meshio (pure Python, a dependency):
  ring 0 as wedges (VTK_WEDGE) around one shared axis point per axial face, rings 1.. as
  hexahedra, the seam closed by shared points. Cells: the wedges of ring 0 first, then the
  hexahedra, each block in (x, r, theta) C order.

The file appears complete or not at all (written beside the target, then renamed).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["export_vts", "export_path", "ExportError", "VECTOR_SUFFIXES"]

#: component suffixes of a Cartesian vector in the dataset schema (x axial, y up, z horizontal)
VECTOR_SUFFIXES = (("ux", "uy", "uz"), ("_x", "_y", "_z"))

_CELL_DIMS = ("x", "r", "theta")


class ExportError(ValueError):
    """The dataset or the target path cannot be exported. The message is one line."""


def export_path(vts_path: str | os.PathLike) -> Path:
    """The file :func:`export_vts` writes for the target ``vts_path`` (checked: ``.vts`` or ``.vtu``)."""
    path = Path(vts_path)
    if path.suffix.lower() not in (".vts", ".vtu"):
        raise ExportError(f"{path}: unknown suffix {path.suffix or '(none)'!r}; allowed: .vts (VTK structured "
                          "grid) or .vtu (VTK unstructured grid)")
    from eulag.files import target_problem

    problem = target_problem(path)
    if problem is not None:
        raise ExportError(f"{path}: {problem}")
    return path


def _vtk_modules():
    """VTK's data-model and XML-IO modules (the optional extra ``eulag[vtk]``)."""
    try:
        from vtkmodules.util.numpy_support import numpy_to_vtk
        from vtkmodules.vtkCommonCore import vtkPoints
        from vtkmodules.vtkCommonDataModel import vtkStructuredGrid
        from vtkmodules.vtkIOXML import vtkXMLStructuredGridWriter
    except ImportError:
        raise ExportError("a .vts file is written with VTK's Python package, which is not installed; "
                          "allowed: pip install 'eulag[vtk]', or a .vtu target (meshio)") from None
    return numpy_to_vtk, vtkPoints, vtkStructuredGrid, vtkXMLStructuredGridWriter


def _write_structured(out: Path, x_edge, r_edge, theta_edge, cell_data: dict) -> None:
    """The .vts file: corner points x fastest, then theta, then r; the seam's last column a copy
    of the first; ``cell_data`` {name: array (nx, nr, nt[, 3])}."""
    from eulag.output import atomic_write

    numpy_to_vtk, vtkPoints, vtkStructuredGrid, vtkXMLStructuredGridWriter = _vtk_modules()
    nx, nr, nt = x_edge.size - 1, r_edge.size - 1, theta_edge.size - 1
    th = np.append(theta_edge[:nt], theta_edge[0])  # closed seam: the same coordinates at 2 pi
    X, R, T = np.meshgrid(x_edge, r_edge, th, indexing="ij")
    pts = np.stack([X, R * np.sin(T), R * np.cos(T)], axis=-1)  # x axial, y up, z horizontal
    pts = np.ascontiguousarray(pts.transpose(1, 2, 0, 3).reshape(-1, 3))  # (r, theta, x): x fastest
    grid = vtkStructuredGrid()
    grid.SetDimensions(nx + 1, nt + 1, nr + 1)
    points = vtkPoints()
    points.SetData(numpy_to_vtk(pts, deep=True))
    grid.SetPoints(points)
    for name, values in cell_data.items():
        v = np.asarray(values)
        flat = v.transpose(1, 2, 0, *range(3, v.ndim)).reshape(nx * nr * nt, *v.shape[3:])
        arr = numpy_to_vtk(np.ascontiguousarray(flat), deep=True)
        arr.SetName(name)
        grid.GetCellData().AddArray(arr)

    def write(tmp):
        w = vtkXMLStructuredGridWriter()
        w.SetFileName(str(tmp))
        w.SetInputData(grid)
        w.SetDataModeToBinary()
        w.SetCompressorTypeToZLib()
        if not w.Write():
            raise ExportError(f"{out}: VTK could not write the file")
    atomic_write(out, write)


def _points_and_cells(x_edge, r_edge, theta_edge):
    """Corner points (n, 3) and the wedge and hexahedron connectivity, cells in (i, j, k) order.

    Point numbering: per axial face i, first the axis point, then ring faces j = 1..nr times
    sector faces k = 0..nt-1 (the face at theta = 2 pi is the one at 0).
    """
    nxe = x_edge.size
    nr = r_edge.size - 1
    nt = theta_edge.size - 1
    per_face = 1 + nr * nt
    th = theta_edge[:nt]
    pts = np.empty((nxe, per_face, 3))
    pts[:, :, 0] = x_edge[:, None]
    rr = np.repeat(r_edge[1:], nt)
    tt = np.tile(th, nr)
    pts[:, 0, 1:] = 0.0
    pts[:, 1:, 1] = rr * np.sin(tt)  # y, up
    pts[:, 1:, 2] = rr * np.cos(tt)  # z, horizontal
    pts = pts.reshape(-1, 3)

    i = np.arange(nxe - 1)[:, None]
    k = np.arange(nt)[None, :]
    kp = (k + 1) % nt  # the closed seam: sector nt-1 ends at sector 0's first face

    def node(i_face, j_face, k_face):
        """Point index of ring face j_face >= 1, sector face k_face on axial face i_face."""
        return i_face * per_face + 1 + (j_face - 1) * nt + k_face

    # wedges, ring 0: triangle (axis, ring-1 face at k, at k+1) on face i, the same on face
    # i+1 (the orientation VTK_WEDGE expects: positive volume with VTK's own cell volume).
    a0 = np.broadcast_to(i * per_face, (nxe - 1, nt))
    a1 = a0 + per_face
    wedges = np.stack([a0, node(i, 1, k), node(i, 1, kp),
                       a1, node(i + 1, 1, k), node(i + 1, 1, kp)], axis=-1).reshape(-1, 6)

    # hexahedra, rings 1..nr-1: quad (j,k) (j,k+1) (j+1,k+1) (j+1,k) on face i, then the same
    # on face i+1 (positive volume as VTK_HEXAHEDRON).
    if nr > 1:
        ii = np.arange(nxe - 1)[:, None, None]
        jj = np.arange(1, nr)[None, :, None]
        kk = np.arange(nt)[None, None, :]
        kkp = (kk + 1) % nt
        quad = lambda f: [node(f, jj, kk), node(f, jj, kkp), node(f, jj + 1, kkp),  # noqa: E731
                          node(f, jj + 1, kk)]
        hexes = np.stack([np.broadcast_to(v, (nxe - 1, nr - 1, nt)) for v in quad(ii) + quad(ii + 1)],
                         axis=-1).reshape(-1, 8)
    else:
        hexes = np.empty((0, 8), dtype=np.int64)
    return pts, wedges.astype(np.int64), hexes.astype(np.int64)


def _edges(ds, dim: str):
    """Cell faces along ``dim`` [m or rad]: the variable ``<dim>_edge``, or the CF bounds
    variable the coordinate names (``bounds`` attribute, shape (n, 2)); None if neither."""
    if f"{dim}_edge" in ds.variables:
        return np.asarray(ds[f"{dim}_edge"].values, dtype=np.float64)
    name = ds[dim].attrs.get("bounds") if dim in ds.variables else None
    if name and name in ds.variables:
        b = np.asarray(ds[name].values, dtype=np.float64)
        return np.concatenate([b[:, 0], b[-1:, 1]])
    return None


def _vector_triplets(names) -> dict[str, tuple[str, str, str]]:
    """{vector name: (x, y, z) component names} of the component triplets among ``names``."""
    names = set(names)
    out = {}
    for name in sorted(names):
        for sx, sy, sz in VECTOR_SUFFIXES:
            if name.endswith(sx):
                stem = name[: -len(sx)]
                comps = (stem + sx, stem + sy, stem + sz)
                if all(c in names for c in comps):
                    vec = stem + ("u" if sx == "ux" else "")
                    if vec in names:  # never shadow a scalar of that name
                        vec += "_vector"
                    out[vec] = comps
    return out


def export_vts(dataset_path: str | os.PathLike, vts_path: str | os.PathLike) -> Path:
    """Write the 3-D pipe of the result ``dataset_path`` as a VTK file (.vts or .vtu).

    Parameters
    ----------
    dataset_path : path
        A result NetCDF of eulag (:mod:`eulag.output`).
    vts_path : path
        The target: ``.vts`` (structured grid, VTK) or ``.vtu`` (unstructured grid, meshio);
        see the module docstring. The file appears complete or not at all.

    Returns
    -------
    Path
        The file written.

    Cells: nx * nr * nt, in the order of the module docstring; cell data as listed there.
    """
    import xarray as xr

    out = export_path(vts_path)
    if out.suffix.lower() == ".vts":
        _vtk_modules()  # the optional library is there before any work
    if not Path(dataset_path).is_file():
        raise ExportError(f"{dataset_path}: no such dataset")
    try:
        ds = xr.open_dataset(dataset_path)
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad input
        from eulag.arguments import short_reason

        raise ExportError(f"{dataset_path}: cannot read the dataset ({short_reason(exc)})") from None
    with ds:
        if ds.attrs.get("model") == "dem-darcy":
            raise ExportError(f"{dataset_path}: a dem-darcy (slug) dataset holds cross-section means along the "
                              "tube, not the cells of a pipe; allowed: a gas, Euler-Lagrange or two-fluid dataset")
        edges = {dim: _edges(ds, dim) for dim in _CELL_DIMS}
        missing = [dim for dim, e in edges.items() if e is None]
        if missing and ds.attrs.get("model") == "two-fluid":
            raise ExportError(f"{dataset_path}: a two-fluid dataset written before the datasets kept their cell "
                              f"faces (no {', '.join(d + '_edge' for d in missing)}); run the case again to export it")
        if missing:
            raise ExportError(f"{dataset_path}: not a result dataset of eulag (no cell faces of "
                              f"{', '.join(missing)})")
        x_edge, r_edge, theta_edge = (edges[dim] for dim in _CELL_DIMS)
        nx, nr, nt = x_edge.size - 1, r_edge.size - 1, theta_edge.size - 1
        if (ds.sizes.get("x"), ds.sizes.get("r"), ds.sizes.get("theta")) != (nx, nr, nt):
            raise ExportError(f"{dataset_path}: the cell faces do not match the dimensions x, r, theta")
        if r_edge[0] != 0.0 or not np.isclose(theta_edge[-1] - theta_edge[0], 2.0 * np.pi):
            raise ExportError(f"{dataset_path}: the cross-section is not a full disc (r_edge[0] = "
                              f"{r_edge[0]:g} m, theta span {theta_edge[-1] - theta_edge[0]:g} rad)")
        fields = {}
        for name, var in ds.data_vars.items():
            if set(var.dims) == set(_CELL_DIMS) and var.ndim == 3 and var.dtype.kind in "fiu":
                fields[name] = np.asarray(var.transpose(*_CELL_DIMS).values, dtype=np.float64)

    cell_fields = dict(fields)
    for vec, comps in _vector_triplets(fields).items():
        cell_fields[vec] = np.stack([fields[c] for c in comps], axis=-1)
    for label, a in zip(("cell_i", "cell_j", "cell_k"), np.indices((nx, nr, nt), dtype=np.int32)):
        cell_fields[label] = a
    if out.suffix.lower() == ".vts":
        _write_structured(out, x_edge, r_edge, theta_edge, cell_fields)
        return out
    _write_unstructured(out, x_edge, r_edge, theta_edge, cell_fields)
    return out


def _write_unstructured(out: Path, x_edge, r_edge, theta_edge, cell_fields: dict) -> None:
    """The .vtu file (meshio): ring 0 as wedges, then the hexahedra; ``cell_fields`` {name:
    array (nx, nr, nt[, 3])}."""
    import meshio

    from eulag.output import atomic_write

    nr = r_edge.size - 1
    points, wedges, hexes = _points_and_cells(x_edge, r_edge, theta_edge)
    cells = [("wedge", wedges)]
    if hexes.size:
        cells.append(("hexahedron", hexes))

    def blocks(values):
        values = np.asarray(values)
        parts = [values[:, 0, :].reshape(-1, *values.shape[3:])]
        if nr > 1:
            parts.append(values[:, 1:, :].reshape(-1, *values.shape[3:]))
        return parts

    cell_data = {name: blocks(v) for name, v in cell_fields.items()}
    mesh = meshio.Mesh(points, cells, cell_data=cell_data)
    atomic_write(out, lambda tmp: meshio.write(tmp, mesh, file_format="vtu", binary=True,
                                               compression="zlib"))
