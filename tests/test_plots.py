"""eulag.plots and `eulag plot`: figures are non-empty PNGs for a gas-only dataset (the real
output schema) and a synthetic particle dataset; bad input exits 2 with one line and leaves
no figure behind."""

from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr

from eulag import plots
from eulag.cli import main
from eulag.config import Case
from eulag.output import gas_dataset, write_dataset

from .conftest import SHARED_DATA
from .test_analysis import R, U_B, mesh, psi_two_cell, secondary_dataset

PNG = b"\x89PNG\r\n\x1a\n"

CASE = {
    "name": "plot_test",
    "pipe": {"diameter": 0.0305, "length": 4.0, "mode": "developing", "sections": [3.56]},
    "gas": {"density": 1.205, "viscosity": 1.81e-5, "bulk_velocity": U_B, "inlet_k": 1.0},
    "numerics": {"axial_cells": 10, "radial_cells": 10, "azimuthal_cells": 16},
}


def is_png(path):
    data = path.read_bytes()
    return data.startswith(PNG) and len(data) > 5000


@pytest.fixture
def gas_nc(tmp_path):
    """A single-phase dataset written by eulag.output (the real schema) from an analytic field."""
    case = Case.from_dict(CASE)
    m = mesh(10, 16, mode="developing", nx=10)
    shape = m.shape
    ux = np.broadcast_to(1.2 * U_B * (1 - m.r[:, None] / R) ** (1 / 7), shape).copy()
    field = SimpleNamespace(
        ux=ux, uy=np.zeros(shape), uz=np.zeros(shape), k=np.full(shape, 0.5),
        epsilon=np.full(shape, 10.0), p=np.zeros(shape), nut=np.full(shape, 1e-4),
        residuals=[1.0, 1e-3, 1e-7], pressure_gradient=np.full(m.nx, 60.0),
        friction_factor=np.full(m.nx, 0.026), wall_yplus=np.full((m.nx, m.nt), 30.0),
        wall_shear=np.full((m.nx, m.nt), 0.4), converged=True, iterations=3)
    return write_dataset(gas_dataset(case, m, field), tmp_path / "gas.nc")


def particle_dataset():
    """Two-cell secondary flow, particles settled toward the bottom, NaN in one empty sector."""
    m = mesh(12, 24)
    ds, _ = secondary_dataset(m, psi_two_cell)
    pux = 0.9 * ds["gas_ux"].values.copy()
    pux[:, :, 5] = np.nan
    ds["particle_ux"] = (("x", "r", "theta"), pux)
    ds["particle_concentration"] = (("x", "r", "theta"), (2.0 - m.y / R)[None])
    ds["wall_collision_rate"] = (("x", "theta"), np.ones((1, m.nt)))
    ds["residual"] = ("iteration", [1.0, 0.1, 0.02, 0.003])
    ds["pressure_gradient_history"] = ("iteration", [60.0, 80.0, 85.0, 86.0])
    ds.attrs["pipe.sections"] = np.array([3.56])
    return ds


def test_plot_all_gas_only_dataset(gas_nc):
    written = plots.plot_all(gas_nc)
    outdir = gas_nc.parent / "gas_figures"
    assert [p.parent for p in written] == [outdir] * 3
    assert all(is_png(p) for p in written)
    assert sorted(p.name for p in outdir.iterdir()) == sorted(p.name for p in written)
    assert "x3.4m" in written[0].name   # pipe.sections[0] = 3.56 -> nearest centre x = 3.4


def test_plot_all_particle_dataset_with_reference(tmp_path):
    ds = particle_dataset()
    ref = SHARED_DATA / "tsuji_morikawa_1982_horizontal_eta2.2.csv"
    section = plots.three_panel(ds, None, tmp_path / "section.png")
    profiles = plots.vertical_profiles(ds, None, tmp_path / "profiles.png",
                                       reference=ref if ref.exists() else
                                       {"phase": ["gas", "particle"], "y_over_R": [0.0, 0.0],
                                        "U_over_Uref": [1.2, 1.0]})
    conv = plots.convergence(ds, tmp_path / "convergence.png")
    assert all(is_png(p) for p in (section, profiles, conv))
    written = plots.plot_all(ds, outdir=tmp_path / "figs")
    assert len(written) == 3 and all(is_png(p) for p in written)


def test_read_reference_tsuji_morikawa_columns():
    ref = SHARED_DATA / "tsuji_morikawa_1982_horizontal_eta2.2.csv"
    if not ref.exists():
        pytest.skip(f"{ref} not available")
    prof = plots.read_reference(ref)
    assert set(prof) == {"gas", "particle"}
    for p in prof.values():   # y/R in [-1, 1] becomes y/D in [-0.5, 0.5]
        assert p["y_over_D"].size > 5 and np.all(np.abs(p["y_over_D"]) <= 0.5)


def test_convergence_without_history_writes_nothing(tmp_path):
    ds = particle_dataset().drop_vars(["residual", "pressure_gradient_history"])
    assert plots.convergence(ds, tmp_path / "c.png") is None
    assert list(tmp_path.iterdir()) == []


def test_plot_all_bad_station_leaves_nothing(tmp_path):
    ds = particle_dataset()
    with pytest.raises(ValueError, match="outside the pipe"):
        plots.plot_all(ds, x=9.0, outdir=tmp_path / "figs")
    assert list(tmp_path.iterdir()) == []


def run_cli(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_plot_writes_figures_beside_the_dataset(gas_nc, capsys):
    status, out, err = run_cli(capsys, "plot", gas_nc, "--x", "3.56")
    assert status == 0, err
    paths = out.split()
    assert len(paths) == 3 and all(p.endswith(".png") for p in paths)
    assert all(is_png(p) for p in (gas_nc.parent / "gas_figures").iterdir())


@pytest.mark.parametrize("argv, words", [
    (["absent.nc"], "no such dataset"),
    (["{nc}", "--x", "5.0"], "outside the pipe"),
    (["{nc}", "--x", "-1"], "outside the pipe"),
    (["{txt}"], "cannot be read"),
    (["{nc}", "-o", "{txt}"], "not a directory"),
])
def test_cli_plot_bad_input_exits_2_with_one_line(gas_nc, tmp_path, capsys, argv, words):
    txt = tmp_path / "notes.txt"
    txt.write_text("not a dataset")
    before = sorted(p.name for p in tmp_path.iterdir())
    argv = [a.format(nc=gas_nc, txt=txt) for a in argv]
    if argv[0] == "absent.nc":
        argv[0] = str(tmp_path / "absent.nc")
    status, out, err = run_cli(capsys, "plot", *argv)
    assert status == 2
    assert len(err.splitlines()) == 1 and words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before   # no figures, no directory


def test_plots_leave_no_open_pyplot_figures(tmp_path):
    import matplotlib.pyplot as plt

    before = len(plt.get_fignums())
    plots.plot_all(particle_dataset(), outdir=tmp_path / "figs")
    assert len(plt.get_fignums()) == before


# --- a gas dataset from a real (tiny, periodic) gas solve ---------------------------------

@pytest.fixture(scope="module")
def gas_only_dataset(tmp_path_factory):
    from eulag.coupling import build_mesh
    from rans import GasProperties, solve

    case = Case.from_dict({"name": "plot_gas", "pipe": {"diameter": 0.0305, "length": 1.0, "mode": "periodic"},
                           "gas": {"density": 1.205, "viscosity": 1.81e-5, "bulk_velocity": 10.0, "inlet_k": 1.0},
                           "numerics": {"radial_cells": 8, "azimuthal_cells": 16}})
    mesh_ = build_mesh(case)
    field = solve(mesh_, GasProperties(1.205, 1.81e-5), 10.0, 1.0)
    path = tmp_path_factory.mktemp("plots") / "plot_gas.nc"
    write_dataset(gas_dataset(case, mesh_, field), path)
    return path


def test_plot_writes_the_figures_of_a_gas_dataset(gas_only_dataset, capsys):
    out = gas_only_dataset.parent / "figs"
    status, stdout, err = run_cli(capsys, "plot", gas_only_dataset, "-o", out)
    assert status == 0, err
    pngs = sorted(out.glob("*.png"))
    assert len(pngs) >= 2 and all(p.stat().st_size > 10_000 for p in pngs)


def test_solved_single_phase_flow_has_no_recirculation_cells(gas_only_dataset):
    """Single-phase, mirror-symmetric flow: no secondary-flow cells, no preferred half."""
    from eulag import analysis as an

    with xr.open_dataset(gas_only_dataset) as ds:
        ds = ds.load()
    assert an.recirculation_cells(ds) == 0
    assert an.gas_maximum_half(ds) == "neither"
