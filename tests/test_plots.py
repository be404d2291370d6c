"""eulag.plots and `eulag plot`: figures are non-empty PNGs for a gas-only dataset (the real
output schema), a synthetic particle dataset, a synthetic slug run and a (tiny) two-fluid run;
bad input exits 2 with one line and leaves no figure behind."""

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


# --- the dense-phase models ---------------------------------------------------------------

def slug_dataset(grains=400):
    """A synthetic 2 s run of the paper's open 52.5 cm tube: one slug (porosity 0.5 over 5 cm, 0.9
    elsewhere, grains at 0.3 m/s inside it) moving at 0.3 m/s, catalogued at every record, the gas
    pressure falling across it only."""
    import json
    import tomllib

    from eulag.config import CASES_DIR
    from eulag.slug import validate_slug_case

    raw = tomllib.loads((CASES_DIR / "slug" / "strauss_horizontal.toml").read_text())
    raw["numerics"]["end_time_s"] = 2.0
    case = validate_slug_case(raw)
    t = np.arange(1, 201) * 0.01
    x = (np.arange(150) + 0.5) * 0.0035
    centre = 0.3 * t - 0.1
    inside = np.abs(x[None, :] - centre[:, None]) < 0.025
    phi = np.where(inside, 0.5, 0.9)
    p = np.cumsum(np.where(inside, 1e4 * 0.0035, 0.0)[:, ::-1], axis=1)[:, ::-1]
    n = t.size
    ds = xr.Dataset(
        {"porosity": (("time", "x"), phi), "grain_velocity": (("time", "x"), np.where(inside, 0.3, 0.0)),
         "gas_pressure": (("time", "x"), p), "wall_normal_stress": (("time", "x"), np.where(inside, 20.0, 2.0)),
         "granular_temperature": (("time", "x"), np.where(inside, 1e-3, 0.0)),
         "contact_force": (("time", "x"), np.where(inside, 1e-4, 1e-5)),
         "pressure_drop": ("time", p[:, 0]), "grains_in_tube": ("time", np.full(n, 3000)),
         "outflow_mass_rate": ("time", np.full(n, 2.49 / 3600)),
         "slug_time": ("slug", t), "slug_position": ("slug", centre), "slug_grains": ("slug", np.full(n, grains)),
         "slug_min_porosity": ("slug", np.full(n, 0.5)), "slug_length": ("slug", np.full(n, 0.05)),
         "slug_max_velocity": ("slug", np.full(n, 0.3))},
        coords={"time": t, "x": x}, attrs={"case": json.dumps(case), "model": "dem-darcy"})
    return ds


def with_cross_section(ds):
    """``ds`` of :func:`slug_dataset` with the cross-section records at x_s = L/2: while the slice
    lies in the slug (t ≈ 1.13-1.29 s) 5 grains per layer at u = 0.2 + 50 h, rms 0.01 m/s, the
    slice half full; between slugs 4 grains in each of the 3 lowest layers at 0.01 m/s."""
    from dem.sections import layer_edges, pixel_centres, pixel_inside_fraction

    e = layer_edges(3.5e-3, 1.4e-3)
    h = 0.5 * (e[1:] + e[:-1])
    xs = 0.2625
    slug_at = np.array([np.interp(xs, ds["x"].values, row) for row in ds["porosity"].values]) < 0.6
    nt, nl = ds.sizes["time"], len(h)
    n = np.where(slug_at[:, None], 5.0, np.where(np.arange(nl)[None, :] < 3, 4.0, 0.0))
    u = np.where(slug_at[:, None], 0.2 + 50.0 * h[None, :], np.where(n > 0, 0.01, 0.0))
    rms = np.where(slug_at[:, None], 0.01, 0.0) * np.ones((nt, nl))
    img = np.where(slug_at[:, None, None], 0.5, 0.1) * (pixel_inside_fraction(3.5e-3, 14) >= 0.5)[None]
    c = pixel_centres(3.5e-3, 14)
    return ds.assign(section_solids_fraction=(("time", "section_z", "section_y"), img),
                     section_pixel_inside=(("section_z", "section_y"), pixel_inside_fraction(3.5e-3, 14)),
                     layer_grains=(("time", "layer"), n), layer_velocity=(("time", "layer"), u),
                     layer_velocity_rms=(("time", "layer"), rms)).assign_coords(
        section_y=c, section_z=c, layer=h).assign_attrs(section_x_m=xs, section_width_m=3.5e-3)


def test_cross_section_layers_average_in_and_between_slugs(tmp_path, capsys):
    from eulag.slug import cross_section_layers, layer_shear

    ds = with_cross_section(slug_dataset())
    lay = cross_section_layers(ds, t_min=1.0)
    h = ds["layer"].values
    assert lay.attrs["records_slug"] + lay.attrs["records_between"] == 101
    assert 10 <= lay.attrs["records_slug"] <= 20
    assert np.allclose(lay["velocity_slug"], 0.2 + 50.0 * h)
    assert np.allclose(lay["velocity_rms_slug"], 0.01)
    assert np.allclose(lay["velocity_between"][:3], 0.01) and np.isnan(lay["velocity_between"][3:]).all()
    assert np.allclose(lay["section_slug"].values[7, 7], 0.5)
    num = layer_shear(lay)
    assert num["shear_m_s"] == pytest.approx(50.0 * (h[-1] - h[0]))
    assert num["rank_correlation_with_layer"] == pytest.approx(1.0)
    assert num["fluctuation_over_mean"] == pytest.approx(0.01 / 0.2)
    # the pooled statistics against the pooled grains: records of one layer with other n, u, rms
    uneven = ds.copy(deep=True)
    slug_rec = np.flatnonzero(uneven["layer_grains"].values[:, 0] == 5)
    rng = np.random.default_rng(2)
    samples = []
    for i in slug_rec:
        g = rng.normal(0.2, 0.05, int(rng.integers(1, 9)))
        uneven["layer_grains"].values[i, 0], uneven["layer_velocity"].values[i, 0] = len(g), g.mean()
        uneven["layer_velocity_rms"].values[i, 0] = g.std()
        samples.extend(g)
    lay = cross_section_layers(uneven, t_min=0.0)
    assert np.isclose(lay["velocity_slug"].values[0], np.mean(samples))
    assert np.isclose(lay["velocity_rms_slug"].values[0], np.std(samples))
    # ties: a constant profile has no rank correlation; a tied one the average-rank value
    flat = lay.copy(deep=True)
    flat["velocity_slug"].values[:] = 0.3
    assert np.isnan(layer_shear(flat)["rank_correlation_with_layer"])
    with pytest.raises(ValueError, match="without the recorded cross-section"):
        cross_section_layers(slug_dataset())
    assert is_png(plots.slug_cross_section(ds, tmp_path / "cs.png"))
    assert plots.slug_cross_section(slug_dataset(), tmp_path / "none.png") is None
    nc = tmp_path / "slug.nc"
    ds.to_netcdf(nc)
    status, out, err = run_cli(capsys, "plot", nc)
    assert status == 0, err
    assert out.split()[-1].endswith("slug_cross_section.png")


def test_slug_profiles_average_in_the_studys_window():
    """The figure's default window is the strauss study's: t >= min(end/2, 6 s) = 1 s, slugs centred
    in 15-40 cm; the synthetic slug's centre is there from t = 1.00 to 1.66 s (67 records)."""
    prof, n, xw, t_min = plots.slug_profile_data(slug_dataset())
    assert (n, t_min) == (67, 1.0) and xw == pytest.approx((0.15, 0.40))
    assert float(prof["porosity"].sel(dx_over_d=0.0)) == pytest.approx(0.5)
    assert float(prof["porosity"].sel(dx_over_d=30.0)) == pytest.approx(0.9)
    assert float(prof["drag"].sel(dx_over_d=0.0)) == pytest.approx(1e4)


def test_slug_profiles_figure_says_when_no_slug_qualifies(tmp_path):
    """Slugs of 50 grains are below the catalogue's 100: the figure is drawn with a note."""
    from eulag.slug import slug_profiles

    ds = slug_dataset(grains=50)
    assert float(slug_profiles(ds, x_window=(0.15, 0.40), t_min=14.0)["samples"].max()) == 0
    assert is_png(plots.slug_profiles_figure(ds, tmp_path / "p.png"))


@pytest.mark.parametrize("change, words", [
    (lambda ds: ds.drop_vars("gas_pressure"), "not an eulag dem-darcy dataset (no gas_pressure)"),
    (lambda ds: ds.assign_attrs(case="{}"), "not a dem-darcy case (KeyError"),
    (lambda ds: ds.assign_attrs(case="not json"), "not a dem-darcy case (JSONDecodeError"),
    (lambda ds: ds.assign_attrs(model="two-fluid"), "two-fluid dataset (no gas_ux, solids_ux, solids_fraction"),
])
def test_cli_plot_of_an_incomplete_dense_dataset_is_bad_input(tmp_path, capsys, change, words):
    nc = tmp_path / "bad.nc"
    change(slug_dataset()).to_netcdf(nc)
    status, out, err = run_cli(capsys, "plot", nc)
    assert status == 2 and len(err.splitlines()) == 1 and words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.nc"]


def test_cli_plot_slug_dataset_and_no_station_for_it(tmp_path, capsys):
    """A slug run's figures span the tube and the run's time: space-time porosity, time series,
    averaged slug profiles; --x is refused with one line and nothing drawn."""
    nc = tmp_path / "slug.nc"
    slug_dataset().to_netcdf(nc)
    status, out, err = run_cli(capsys, "plot", nc, "--x", "0.2")
    assert status == 2 and len(err.splitlines()) == 1 and "no cross-section station" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["slug.nc"]
    status, out, err = run_cli(capsys, "plot", nc)
    assert status == 0, err
    assert [p.rsplit("/", 1)[-1] for p in out.split()] == ["slug_spacetime.png", "slug_history.png",
                                                           "slug_slug_profiles.png"]
    assert all(is_png(p) for p in (tmp_path / "slug_figures").iterdir())


def test_run_of_a_two_fluid_case_writes_its_figures(tmp_path, capsys):
    """`eulag run` draws a dense-phase model's figures beside its dataset, as for the dilute one
    (a marched pipe of 1 cm on a 6 x 12 section: also its development); `eulag plot` redraws them
    at another station and rejects one outside the pipe."""
    import re

    from eulag.config import CASES_DIR

    text = (CASES_DIR / "two_fluid" / "ding_qs0.8.toml").read_text()
    for key, value in (("radial_cells", "6"), ("azimuthal_cells", "12"), ("length", "0.01")):
        text, n = re.subn(rf"(?m)^{key} = [0-9.]+", f"{key} = {value}", text)
        assert n == 1, key
    text = re.sub(r"(?m)^\[numerics\]$", '[numerics]\nmode = "developing"', text)
    (tmp_path / "tf.toml").write_text(text)
    status, out, err = run_cli(capsys, "run", tmp_path / "tf.toml", "-o", tmp_path / "tf.nc", "--quiet")
    assert status == 0, err
    figs = sorted(p.name for p in (tmp_path / "tf_figures").iterdir())
    assert figs == ["tf_convergence.png", "tf_development.png", "tf_profiles_x0.01m.png", "tf_section_x0.01m.png"]
    assert all(is_png(tmp_path / "tf_figures" / f) for f in figs)
    status, out, err = run_cli(capsys, "plot", tmp_path / "tf.nc", "--x", "0.003", "-o", tmp_path / "at")
    assert status == 0, err
    assert sorted(p.name for p in (tmp_path / "at").iterdir())[2:] == ["tf_profiles_x0.0025m.png",
                                                                       "tf_section_x0.0025m.png"]
    status, out, err = run_cli(capsys, "plot", tmp_path / "tf.nc", "--x", "5", "-o", tmp_path / "other")
    assert status == 2 and "outside the pipe" in err and not (tmp_path / "other").exists()
    # the marched pipe as cells for ParaView: one cell per station, ring and sector, from x = 0 to L
    import meshio

    status, out, err = run_cli(capsys, "export", tmp_path / "tf.nc", tmp_path / "tf.vtu")
    assert status == 0, err
    ds = xr.open_dataset(tmp_path / "tf.nc")
    mesh = meshio.read(tmp_path / "tf.vtu")
    assert sum(len(c.data) for c in mesh.cells) == ds.sizes["x"] * 6 * 12
    assert mesh.points[:, 0].min() == 0.0 and mesh.points[:, 0].max() == pytest.approx(0.01)
    assert "solids_fraction" in mesh.cell_data


def test_a_slug_dataset_is_not_exported_as_cells(tmp_path, capsys):
    nc = tmp_path / "slug.nc"
    slug_dataset().to_netcdf(nc)
    status, out, err = run_cli(capsys, "export", nc, tmp_path / "slug.vtu")
    assert status == 2 and len(err.splitlines()) == 1 and "cross-section means along the tube" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["slug.nc"]


def test_a_failing_figure_keeps_the_dataset_and_says_so_even_quietly(tmp_path, capsys, monkeypatch):
    import re

    from eulag.config import CASES_DIR

    text = (CASES_DIR / "two_fluid" / "ding_qs0.8.toml").read_text()
    text = re.sub(r"(?m)^radial_cells = \d+", "radial_cells = 5", text)
    text = re.sub(r"(?m)^azimuthal_cells = \d+", "azimuthal_cells = 8", text)
    (tmp_path / "tf.toml").write_text(text)

    def broken(ds, x, path):
        raise RuntimeError("no canvas\nat all")

    monkeypatch.setattr(plots, "two_fluid_section", broken)
    status, out, err = run_cli(capsys, "run", tmp_path / "tf.toml", "-o", tmp_path / "tf.nc", "--quiet")
    assert status == 0 and out == ""
    assert err.splitlines() == [f"eulag: warning: figures not written (RuntimeError: no canvas at all); the dataset "
                                f"{tmp_path / 'tf.nc'} is complete"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tf.nc", "tf.toml"]


def test_convergence_figure_titles_the_runs_verdict(tmp_path, monkeypatch):
    """The title states the verdict the dataset stores (the ``converged`` variable), for a
    converged and an unconverged run."""
    from matplotlib.figure import Figure

    titles = []
    real = Figure.suptitle
    monkeypatch.setattr(Figure, "suptitle", lambda self, t, **kw: (titles.append(t), real(self, t, **kw))[1])
    ds = particle_dataset()
    for flag in (1, 0):
        ds["converged"] = ((), np.int8(flag))
        plots.convergence(ds, tmp_path / f"c{flag}.png")
    assert titles[0].endswith("(converged)") and titles[1].endswith("(NOT converged)"), titles
