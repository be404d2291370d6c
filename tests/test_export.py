"""eulag.export: a tiny result dataset exported and read back — the .vtu with meshio (cell
count, cell types, every cell field and the gas velocity vector in (x, r, theta) order, each cell
where the dataset puts it, the theta seam closed by shared points, VTK's cell orientation), the
.vts with VTK's own XML reader (dimensions, cell count, cell fields in VTK's i-fastest order, the
seam's last point column on the first, cell volumes of the polygonal pipe)."""

import dataclasses

import numpy as np
import pytest

meshio = pytest.importorskip("meshio")

from eulag.config import Case  # noqa: E402
from eulag.export import ExportError, export_path, export_vts  # noqa: E402
from eulag.output import gas_dataset, write_dataset  # noqa: E402
from rans import PipeMesh  # noqa: E402
from tests.particle_support import uniform_field  # noqa: E402

NX, NR, NT = 3, 4, 8


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("export")
    mesh = PipeMesh.build(0.0305, 0.12, axial_cells=NX, radial_cells=NR, azimuthal_cells=NT)
    i, j, k = np.indices(mesh.shape)
    field = dataclasses.replace(
        uniform_field(mesh, ux=10.0),
        ux=100.0 * i + 10.0 * j + k,  # the cell's own indices: shows any mix-up
        uy=np.broadcast_to(np.sin(mesh.theta), mesh.shape).copy(),
        uz=np.broadcast_to(np.cos(mesh.theta), mesh.shape).copy(),
        k=1.0 + 0.5 * j)
    case = Case.from_dict({"name": "tiny", "pipe": {"diameter": 0.0305, "length": 0.12},
                           "gas": {"density": 1.205, "viscosity": 1.81e-5, "bulk_velocity": 10.0,
                                   "inlet_k": 1.0},
                           "numerics": {"radial_cells": NR, "azimuthal_cells": NT}})  # attributes only
    ds = gas_dataset(case, mesh, field)
    nc = tmp / "tiny.nc"
    write_dataset(ds, nc)
    written = export_vts(nc, tmp / "tiny.vtu")
    return mesh, field, written, meshio.read(written)


def test_vtu_reads_back_with_the_cell_count(exported):
    mesh, _, written, grid = exported
    assert written.name == "tiny.vtu" and written.is_file()
    assert sum(len(block.data) for block in grid.cells) == NX * NR * NT
    assert [(b.type, len(b.data)) for b in grid.cells] == [("wedge", NX * NT),
                                                           ("hexahedron", NX * (NR - 1) * NT)]
    # one point per corner: the axis once per axial face, no duplicated seam column
    assert len(grid.points) == (NX + 1) * (1 + NR * NT)
    assert len(np.unique(np.round(grid.points, 12), axis=0)) == len(grid.points)


def _cells(grid, name):
    """A cell array back in (x, r, theta) order (wedges = ring 0, hexahedra = rings 1..)."""
    wedge, hexa = grid.cell_data[name]
    tail = wedge.shape[1:]
    out = np.empty((NX, NR, NT) + tail)
    out[:, 0] = wedge.reshape((NX, NT) + tail)
    out[:, 1:] = hexa.reshape((NX, NR - 1, NT) + tail)
    return out


def test_cell_fields_and_vectors(exported):
    mesh, field, _, grid = exported
    names = set(grid.cell_data)
    assert {"gas_ux", "gas_uy", "gas_uz", "gas_k", "gas_epsilon", "gas_p", "gas_nut", "gas_u"} <= names
    np.testing.assert_array_equal(_cells(grid, "gas_ux"), field.ux)
    np.testing.assert_array_equal(_cells(grid, "gas_k"), field.k)
    vec = _cells(grid, "gas_u")
    assert vec.shape == (NX, NR, NT, 3)
    np.testing.assert_array_equal(vec, np.stack([field.ux, field.uy, field.uz], axis=-1))
    for c, name in enumerate(("cell_i", "cell_j", "cell_k")):
        np.testing.assert_array_equal(_cells(grid, name), np.indices((NX, NR, NT))[c])


def test_each_cell_lies_where_the_dataset_puts_it(exported):
    mesh, _, _, grid = exported
    i, j, k = (_cells(grid, name).astype(int).ravel() for name in ("cell_i", "cell_j", "cell_k"))
    blocks = [b.data for b in grid.cells]
    corners = [grid.points[blocks[0].reshape(NX, NT, 6)],
               grid.points[blocks[1].reshape(NX, NR - 1, NT, 8)]]
    pts = np.empty((NX, NR, NT, 8, 3))
    pts[:, 0, :, :6], pts[:, 0, :, 6:] = corners[0], corners[0][..., [0, 3], :]  # + the axis again
    pts[:, 1:] = corners[1]
    pts = pts.reshape(-1, 8, 3)
    x, y, z = np.moveaxis(pts, -1, 0)
    r = np.hypot(y, z)
    assert np.allclose(x.min(axis=1), mesh.x_edges[i])
    assert np.allclose(x.max(axis=1), mesh.x_edges[i + 1])
    assert np.allclose(r.min(axis=1), mesh.r_edges[j])
    assert np.allclose(r.max(axis=1), mesh.r_edges[j + 1])
    cy, cz = y.mean(axis=1), z.mean(axis=1)
    th = np.mod(np.arctan2(cy, cz), 2 * np.pi)
    assert np.allclose(th, mesh.theta[k])  # the corners are symmetric about the sector's mid-ray


def test_seam_is_closed_and_cells_are_oriented_as_vtk_wants(exported):
    _, _, _, grid = exported
    wedge, hexa = grid.cells[0].data, grid.cells[1].data
    # the last sector's closing face is the first sector's opening face (shared point ids)
    last = wedge.reshape(NX, NT, 6)[:, NT - 1]
    first = wedge.reshape(NX, NT, 6)[:, 0]
    np.testing.assert_array_equal(last[:, [2, 5]], first[:, [1, 4]])
    p = grid.points
    # VTK cell conventions (vtkWedge, vtkHexahedron): the wedge's base triangle (0, 1, 2) has its
    # right-hand normal pointing away from the face (3, 4, 5); the hexahedron's base quad
    # (0, 1, 2, 3) towards the face (4, 5, 6, 7)
    n = np.cross(p[wedge[:, 1]] - p[wedge[:, 0]], p[wedge[:, 2]] - p[wedge[:, 0]])
    up = p[wedge[:, 3:]].mean(axis=1) - p[wedge[:, :3]].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", n, up) < 0)
    n = np.cross(p[hexa[:, 2]] - p[hexa[:, 0]], p[hexa[:, 3]] - p[hexa[:, 1]])
    up = p[hexa[:, 4:]].mean(axis=1) - p[hexa[:, :4]].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", n, up) > 0)


def test_target_suffixes(tmp_path):
    assert export_path(tmp_path / "a.vts") == tmp_path / "a.vts"
    assert export_path(tmp_path / "a.vtu") == tmp_path / "a.vtu"
    with pytest.raises(ExportError, match="suffix"):
        export_path(tmp_path / "a.vtk")
    with pytest.raises(ExportError, match="no such dataset"):
        export_vts(tmp_path / "absent.nc", tmp_path / "a.vtu")
    assert list(tmp_path.iterdir()) == []
    # a missing directory or a directory in the target's place: refused before any work
    with pytest.raises(ExportError, match="directory .*missing does not exist"):
        export_path(tmp_path / "missing" / "a.vtu")
    (tmp_path / "d.vtu").mkdir()
    with pytest.raises(ExportError, match="is a directory"):
        export_path(tmp_path / "d.vtu")


def test_cf_bounds_instead_of_edges(exported, tmp_path):
    """Cell faces from CF ``bounds`` variables (x_bnds etc.) give the same grid."""
    xr = pytest.importorskip("xarray")
    mesh, field, written, grid = exported
    with xr.open_dataset(written.with_suffix(".nc")) as ds:
        ds = ds.load()
    for dim in ("x", "r", "theta"):
        e = ds[f"{dim}_edge"].values
        ds[f"{dim}_bnds"] = ((dim, "nv"), np.stack([e[:-1], e[1:]], axis=1))
        ds[dim].attrs["bounds"] = f"{dim}_bnds"
        ds = ds.drop_vars(f"{dim}_edge")
    nc = tmp_path / "bounds.nc"
    ds.to_netcdf(nc)
    again = meshio.read(export_vts(nc, tmp_path / "bounds.vtu"))
    np.testing.assert_array_equal(again.points, grid.points)
    np.testing.assert_array_equal(_cells(again, "gas_ux"), field.ux)


def _read_vts(path):
    pytest.importorskip("vtkmodules")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLStructuredGridReader

    reader = vtkXMLStructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    grid = reader.GetOutput()
    cd = grid.GetCellData()
    arrays = {cd.GetArrayName(n): vtk_to_numpy(cd.GetArray(n)) for n in range(cd.GetNumberOfArrays())}
    return grid, vtk_to_numpy(grid.GetPoints().GetData()), arrays


def test_vts_structured_grid_reads_back(exported, tmp_path):
    pytest.importorskip("vtkmodules")
    mesh, field, written, _ = exported
    target = export_vts(written.with_suffix(".nc"), tmp_path / "tiny.vts")
    assert target == tmp_path / "tiny.vts" and target.is_file()
    grid, points, arrays = _read_vts(target)
    dims = [0, 0, 0]
    grid.GetDimensions(dims)
    assert tuple(dims) == (NX + 1, NT + 1, NR + 1)
    assert grid.GetNumberOfCells() == NX * NR * NT
    # cell (i, j, k) is number i + NX (k + NT j): back to (x, r, theta) by a transpose
    back = lambda a: a.reshape((NR, NT, NX) + a.shape[1:]).transpose(2, 0, 1, *range(3, a.ndim + 2))  # noqa: E731
    np.testing.assert_array_equal(back(arrays["gas_ux"]), field.ux)
    np.testing.assert_array_equal(back(arrays["gas_k"]), field.k)
    np.testing.assert_array_equal(back(arrays["gas_u"]), np.stack([field.ux, field.uy, field.uz], axis=-1))
    for c, name in enumerate(("cell_i", "cell_j", "cell_k")):
        np.testing.assert_array_equal(back(arrays[name]), np.indices((NX, NR, NT))[c])
    pts = points.reshape(NR + 1, NT + 1, NX + 1, 3)
    np.testing.assert_array_equal(pts[:, NT], pts[:, 0])  # the seam closed: theta = 2 pi on theta = 0
    np.testing.assert_allclose(pts[:, 0, 0, 2], mesh.r_edges)  # theta = 0: along +z
    np.testing.assert_allclose(pts[0, :, :, 1:], 0.0)  # ring 0's inner corners on the axis
    np.testing.assert_allclose(pts[0, 0, :, 0], mesh.x_edges)
    # VTK's own cell volumes: the polygonal pipe, (sin(dth)/dth) of the exact annular sectors
    from vtkmodules.vtkFiltersVerdict import vtkCellSizeFilter

    sizes = vtkCellSizeFilter()
    sizes.SetInputData(grid)
    sizes.Update()
    from vtkmodules.util.numpy_support import vtk_to_numpy

    vols = vtk_to_numpy(sizes.GetOutput().GetCellData().GetArray("Volume"))
    assert np.all(vols > 0)  # right-handed cells
    vol = vols.sum()
    dth = 2 * np.pi / NT
    exact = np.pi * (0.0305 / 2) ** 2 * 0.12
    assert vol == pytest.approx(exact * np.sin(dth) / dth, rel=1e-9)


def test_vts_without_vtk_is_one_clear_error(exported, tmp_path, monkeypatch):
    import builtins

    real = builtins.__import__

    def no_vtk(name, *args, **kwargs):
        if name.startswith("vtkmodules"):
            raise ImportError(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_vtk)
    _, _, written, _ = exported
    with pytest.raises(ExportError, match=r"eulag\[vtk\]"):
        export_vts(written.with_suffix(".nc"), tmp_path / "x.vts")
    assert not (tmp_path / "x.vts").exists()
