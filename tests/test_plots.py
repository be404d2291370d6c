"""`eulag plot`: figures from datasets (the plots read datasets only)."""

from pathlib import Path

import pytest

from .test_cli import run_cli


@pytest.fixture(scope="module")
def gas_only_dataset(tmp_path_factory):
    from eulag.config import Case
    from eulag.coupling import build_mesh
    from eulag.output import gas_dataset, write_dataset
    from rans import GasProperties, solve

    case = Case.from_dict({"name": "plot_gas", "pipe": {"diameter": 0.0305, "length": 1.0, "mode": "periodic"},
                           "gas": {"density": 1.205, "viscosity": 1.81e-5, "bulk_velocity": 10.0, "inlet_k": 1.0},
                           "numerics": {"radial_cells": 8, "azimuthal_cells": 16}})
    mesh = build_mesh(case)
    field = solve(mesh, GasProperties(1.205, 1.81e-5), 10.0, 1.0)
    path = tmp_path_factory.mktemp("plots") / "plot_gas.nc"
    write_dataset(gas_dataset(case, mesh, field), path)
    return path


def test_plot_writes_the_figures_of_a_gas_dataset(gas_only_dataset, capsys):
    out = gas_only_dataset.parent / "figs"
    status, stdout, err = run_cli(capsys, "plot", gas_only_dataset, "-o", out)
    assert status == 0, err
    pngs = sorted(Path(out).glob("*.png"))
    assert len(pngs) >= 2 and all(p.stat().st_size > 10_000 for p in pngs)


def test_plot_of_a_missing_file_exits_2(tmp_path, capsys):
    status, stdout, err = run_cli(capsys, "plot", tmp_path / "nothing.nc")
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
