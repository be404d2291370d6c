"""The eulag command line: bad input stops early with one line and exit status 2; a tiny
single-phase run writes a dataset that passes the schema check."""

import math
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from eulag.cli import main

ROOT = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("EULAG_SHARED_DATA", ROOT.parent / "shared" / "data")).parent
CHECK_DATASET = SHARED / "tools" / "check_dataset.py"

TINY = """\
name = "tiny"

[pipe]
diameter = 0.0305
length = 4.0
mode = "periodic"

[gas]
density = 1.205
viscosity = 1.81e-5
bulk_velocity = 10.0
inlet_k = 1.0

[numerics]
radial_cells = 8
azimuthal_cells = 16
"""


def run_cli(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.mark.parametrize("label, old, new, key, value, allowed", [
    ("negative diameter", "diameter = 0.0305", "diameter = -0.0305", "pipe.diameter", "-0.0305",
     "> 0"),
    ("zero velocity", "bulk_velocity = 10.0", "bulk_velocity = 0.0", "gas.bulk_velocity", "0.0",
     "> 0"),
    ("unknown key", "length = 4.0", "length = 4.0\nroughness = 1e-5", "pipe.roughness", "1e-05",
     "diameter, length"),
    ("odd azimuthal cells", "azimuthal_cells = 16", "azimuthal_cells = 15",
     "numerics.azimuthal_cells", "15", "even"),
])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys, label,
                                                            old, new, key, value, allowed):
    monkeypatch.chdir(tmp_path)
    case = tmp_path / "bad.toml"
    case.write_text(TINY.replace(old, new))
    status, out, err = run_cli(capsys, "run", case, "-o", tmp_path / "out.nc")
    assert status == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"eulag: error: {key} = {value}"), err
    assert "allowed" in lines[0] and allowed in lines[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]  # no output, no temp file


def test_bad_arguments_exit_2_with_one_line(tmp_path, capsys):
    case = tmp_path / "tiny.toml"
    case.write_text(TINY)
    status, out, err = run_cli(capsys, "run", case, "--parcels", "0")
    assert status == 2 and len(err.splitlines()) == 1 and "--parcels" in err
    status, out, err = run_cli(capsys, "run", tmp_path / "absent.toml")
    assert status == 2 and len(err.splitlines()) == 1 and "no such case file" in err
    status, out, err = run_cli(capsys, "run", case, "-o", tmp_path / "no_dir" / "out.nc")
    assert status == 2 and len(err.splitlines()) == 1 and "does not exist" in err
    status, out, err = run_cli(capsys, "frobnicate")
    assert status == 2 and len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == [case]


def test_sweep_of_a_missing_case_is_bad_input(capsys, tmp_path):
    status, out, err = run_cli(capsys, "sweep", str(tmp_path / "a.toml"), "-o", str(tmp_path / "out"))
    assert status == 2 and len(err.splitlines()) == 1 and "a.toml" in err


def test_single_phase_run_end_to_end(tmp_path, monkeypatch, capsys):
    xr = pytest.importorskip("xarray")
    from fluids.friction import Colebrook

    from eulag.config import Case

    monkeypatch.chdir(tmp_path)
    case_path = tmp_path / "tiny.toml"
    case_path.write_text(TINY)
    status, out, err = run_cli(capsys, "run", case_path)
    assert status == 0, err
    assert "friction f_D" in out and "Colebrook" in out and "wall y+" in out
    result = tmp_path / "tiny.nc"  # default: <case name>.nc in the current directory
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.nc", "tiny.toml", "tiny_figures"]
    assert len(list((tmp_path / "tiny_figures").glob("*.png"))) == 3 and "figures" in out  # as every run draws

    if not CHECK_DATASET.exists():
        pytest.skip(f"schema checker {CHECK_DATASET} not available")
    check = subprocess.run([sys.executable, str(CHECK_DATASET), str(result)],
                           capture_output=True, text=True)
    assert check.returncode == 0, check.stdout + check.stderr

    with xr.open_dataset(result) as ds:
        assert ds.attrs["Conventions"] == "CF-1.8"
        assert int(ds["converged"]) == 1
        assert ds.attrs["seed"] == 1 and "time_gas_solve" in ds.attrs
        assert Case.from_attrs(ds.attrs) == Case.from_toml(case_path)
        assert dict(ds.sizes)["x"] == 1 and ds.sizes["r"] == 8 and ds.sizes["theta"] == 16
        for name in ds.variables:
            if name.endswith("_bnds"):  # CF 7.1: bounds take the units of their coordinate
                assert ds[name[:-5]].attrs["bounds"] == name and "units" in ds[name[:-5]].attrs
            elif "flag_values" in ds[name].attrs or ds[name].dtype.kind in "OSU":  # flags, names: no units
                assert "long_name" in ds[name].attrs, name
            elif name not in ("iteration", "gas_iteration"):
                assert "units" in ds[name].attrs and "long_name" in ds[name].attrs, name
        assert ds["residual"].size == 1
        assert float(ds["residual"][0]) == float(ds["gas_residual"][-1])
        assert float(ds["residual"][0]) <= 1e-6
        assert (ds["pressure_gradient_single_phase"] == ds["pressure_gradient"]).all()
        assert ds["wall_yplus"].dims == ("x", "theta")
        area = float(ds["cell_area"].sum())
        assert area == pytest.approx(math.pi * 0.0305 ** 2 / 4, rel=1e-10)
        # coarse mesh: the friction factor is still the physics, within 10 % of Colebrook
        f_ref = Colebrook(10.0 * 0.0305 * 1.205 / 1.81e-5, 0.0)
        assert float(ds["friction_factor"][0]) == pytest.approx(f_ref, rel=0.10)
        ub = float((ds["gas_ux"][0] * ds["cell_area"]).sum()) / area
        assert ub == pytest.approx(10.0, rel=1e-3)

    # --resume on a finished run of the same case succeeds without recomputing
    mtime = result.stat().st_mtime_ns
    status, out, err = run_cli(capsys, "run", case_path, "--resume", "--quiet")
    assert status == 0 and out == "" and err == ""
    assert result.stat().st_mtime_ns == mtime


def test_python_dash_m_eulag(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "eulag", "--version"], capture_output=True,
                          text=True, cwd=tmp_path)
    assert proc.returncode == 0 and proc.stdout.startswith("eulag ")


def test_solver_divergence_exits_1_with_one_line_and_no_file(tmp_path, monkeypatch, capsys):
    import rans

    def diverge(*args, **kwargs):
        raise rans.SolverDivergence("k = nan at x = 0.5 m, r = 0.01 m, theta = 90 deg")

    monkeypatch.setattr(rans, "solve", diverge)
    case = tmp_path / "tiny.toml"
    case.write_text(TINY)
    status, out, err = run_cli(capsys, "run", case, "-o", tmp_path / "out.nc")
    assert status == 1
    assert err.splitlines() == ["eulag: error: k = nan at x = 0.5 m, r = 0.01 m, theta = 90 deg"]
    assert list(tmp_path.iterdir()) == [case]


def test_unconverged_gas_solve_is_written_flagged_and_exits_1(tmp_path, monkeypatch, capsys):
    """A solver that returns (rather than raises) with converged = False: the dataset is
    written, flagged converged = "false", and the run exits 1 with one line."""
    xr = pytest.importorskip("xarray")
    import rans

    real_solve = rans.solve

    class Unconverged:
        converged = False

        def __init__(self, field):
            self._field = field

        def __getattr__(self, name):
            return getattr(self._field, name)

    monkeypatch.setattr(rans, "solve", lambda *a, **kw: Unconverged(real_solve(*a, **kw)))
    case = tmp_path / "tiny.toml"
    case.write_text(TINY)
    status, out, err = run_cli(capsys, "run", case, "-o", tmp_path / "out.nc", "--quiet")
    assert status == 1 and len(err.splitlines()) == 1 and "did not converge" in err
    with xr.open_dataset(tmp_path / "out.nc") as ds:
        assert int(ds["converged"]) == 0


def test_write_dataset_is_atomic(tmp_path, monkeypatch):
    xr = pytest.importorskip("xarray")
    import numpy as np

    from eulag.output import write_dataset

    target = tmp_path / "out.nc"
    write_dataset(xr.Dataset({"a": ("x", np.arange(3.0))}), target)
    before = target.read_bytes()

    def broken(self, path, *args, **kwargs):
        Path(path).write_bytes(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", broken)
    with pytest.raises(OSError, match="disk full"):
        write_dataset(xr.Dataset({"a": ("x", np.arange(5.0))}), target)
    assert target.read_bytes() == before  # the old file is untouched
    assert [p.name for p in tmp_path.iterdir()] == ["out.nc"]  # no temporary left behind


def test_commit_names_code_changes_not_result_changes(tmp_path):
    """A dataset's ``eulag_commit`` says "(with uncommitted changes)" when code differs from the
    commit, not when a study has just rewritten its own committed table under results/."""
    import eulag

    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]
    assert eulag._commit_of(tmp_path) == "unknown (not a git checkout)"
    (tmp_path / "eulag").mkdir()
    (tmp_path / "results").mkdir()
    (tmp_path / "eulag" / "m.py").write_text("x = 1\n")
    (tmp_path / "results" / "table.md").write_text("| a |\n")
    subprocess.run([*git, "init", "-q"], cwd=tmp_path, check=True)
    subprocess.run([*git, "add", "."], cwd=tmp_path, check=True)
    subprocess.run([*git, "commit", "-q", "-m", "c"], cwd=tmp_path, check=True)
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=tmp_path, capture_output=True,
                          text=True, check=True).stdout.strip()
    assert eulag._commit_of(tmp_path) == head
    (tmp_path / "results" / "table.md").write_text("| b |\n")
    assert eulag._commit_of(tmp_path) == head
    (tmp_path / "eulag" / "m.py").write_text("x = 2\n")
    assert eulag._commit_of(tmp_path) == f"{head} (with uncommitted changes)"


def test_check_of_a_slug_case_prints_the_resolved_case_and_its_numbers(capsys):
    """`eulag check` of a dense-phase case: every key with its default marked, and derived numbers
    recomputed here from their textbook forms."""
    status, out, err = run_cli(capsys, "check", ROOT / "cases" / "slug" / "strauss_horizontal.toml")
    assert status == 0, err
    assert "grains.tangential_damping_ratio = 1.0  (default)" in out and "feed.mass_flow_kg_h = 2.49 [kg h-1]" in out
    m = 937.0 * math.pi / 6.0 * 1.4e-3 ** 3
    assert f"m = {m:.4g} [kg]" in out
    ln_e = math.log(0.5)
    zeta = -ln_e / math.sqrt(math.pi ** 2 + ln_e ** 2)
    k_n = tomllib.loads((ROOT / "cases" / "slug" / "strauss_horizontal.toml").read_text())["grains"]["stiffness_N_m"]
    t_c = math.pi / (math.sqrt(k_n / (0.5 * m)) * math.sqrt(1.0 - zeta ** 2))  # pair of reduced mass m/2
    assert f"t_c = {t_c:.4g} [s]" in out
    assert f"{2.49 / 3600.0 / m:.4g} [s-1]" in out
    kappa = 1.4e-3 ** 2 * 0.48 ** 3 / (180.0 * 0.52 ** 2)  # Carman-Kozeny
    assert f"kappa = {kappa:.4g} [m2] in a slug" in out
    assert f"{6.73e-5 / kappa / 100:.4g} [hPa m-1]" in out
    packed = (1 - 0.57) * math.pi / 4 * 0.007 ** 2 * 0.525 / (math.pi / 6 * 1.4e-3 ** 3)  # the tube packed as the feed
    assert f"at most {packed:,.0f} grains" in out


def test_check_of_a_continued_slug_case_counts_from_the_states_time(capsys, tmp_path):
    """A case continued from a saved state simulates from the state's time to end_time_s: the
    steps, records and cost `eulag check` prints are those of that span, not of 0 to end_time_s."""
    text = (ROOT / "results" / "strauss-filled" / "grain-weights" / "vs1.toml").read_text()
    state = ROOT / "results" / "strauss" / "state_horizontal_t13.25.npz"  # t = 13.25 s
    text = text.replace('state = "results/strauss/state_horizontal_t13.25.npz"', f'state = "{state.as_posix()}"')
    case = tmp_path / "continued.toml"
    case.write_text(text)
    status, out, err = run_cli(capsys, "check", case)
    assert status == 0, err
    assert "time         3 s (from the state's t = 13.25 s to 16.25 s): 30,000 gas steps" in out  # 3 s / 1e-4 s
    assert "a record every 0.01 s (300)" in out


def test_check_of_a_two_fluid_case_prints_the_resolved_case_and_its_numbers(capsys):
    import re
    import tomllib

    path = ROOT / "cases" / "two_fluid" / "ding_qs0.8.toml"
    c = tomllib.loads(path.read_text())
    status, out, err = run_cli(capsys, "check", path)
    assert status == 0, err
    assert "walls.law = \"ding\"  (default)" in out
    D, rho, mu, U = c["pipe"]["diameter"], c["gas"]["density"], c["gas"]["viscosity"], c["gas"]["superficial_velocity"]
    d, rho_s = c["solids"]["diameter"], c["solids"]["density"]
    assert f"Re = rho U_g D / mu = {rho * U * D / mu:.4g}" in out
    u_s = U * (1.0 - 0.68 * d ** 0.92 * rho_s ** 0.5 * rho ** -0.2 * D ** -0.54)  # Hinkle (1953)
    assert f"u_s = {u_s:.4g} [m s-1]" in out
    assert f"alpha_s = {4 * c['solids']['mass_flow'] / (rho_s * u_s * math.pi * D * D):.4g}" in out
    # the single-phase gradient within 3 % of Haaland's explicit form of Colebrook
    f_h = (-1.8 * math.log10(6.9 / (rho * U * D / mu))) ** -2
    dpdx = float(re.search(r"-dp/dx = ([0-9.e+]+) \[Pa m-1\]", out).group(1))
    assert dpdx == pytest.approx(f_h * rho * U * U / (2 * D), rel=0.03)


def test_cases_lists_every_packaged_case_with_its_file(capsys):
    status, out, err = run_cli(capsys, "cases")
    assert status == 0, err
    for path in sorted((ROOT / "cases").rglob("*.toml")):
        line = next((ln for ln in out.splitlines() if ln.split()[:1] == [path.stem]), None)
        assert line is not None, path
        assert str(path.relative_to(ROOT / "cases")) in line


def test_output_that_is_not_a_regular_nc_file_is_refused_and_left_alone(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    case = tmp_path / "tiny.toml"
    case.write_text(TINY)
    os.mkfifo(tmp_path / "pipe.nc")
    (tmp_path / "link.nc").symlink_to(tmp_path / "target.nc")
    for out, what in ((case, "ending in .nc"), (tmp_path / "result.txt", "ending in .nc"),
                      (tmp_path / "pipe.nc", "not a regular file"), (tmp_path / "link.nc", "symbolic link"),
                      ("", "empty path")):
        status, stdout, err = run_cli(capsys, "run", case, "-o", out)
        assert status == 2 and len(err.splitlines()) == 1 and what in err, (out, err)
    assert case.read_text() == TINY
    assert (tmp_path / "pipe.nc").is_fifo() and (tmp_path / "link.nc").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.nc", "pipe.nc", "tiny.toml"]


@pytest.mark.parametrize("old, new, key", [
    # each value within its own range; together a Reynolds number of 367 (laminar)
    ("viscosity = 1.81e-5", "viscosity = 1e-3", "Re = rho U0 D / mu = 367.5"),
    ("density = 1.205", "density = 1e-300", "Re = rho U0 D / mu"),
    # a wall cell (its centre at y+ = 500) thicker than the radius at U0 = 2 m/s
    ("bulk_velocity = 10.0\ninlet_k = 1.0\n\n[numerics]", "bulk_velocity = 2.0\ninlet_k = 0.04\n\n[numerics]\n"
     "first_cell_yplus = 500", "numerics.first_cell_yplus = 500"),
    ("diameter = 0.0305", "diameter = 1" + "0" * 400, "pipe.diameter = "),
    # a 0.3 m pipe on 4 rings: each ring 8 times as thick as the next one out from the 2 mm wall cell
    ("diameter = 0.0305", "diameter = 0.3", "numerics.radial_cells = 4"),
    # 400 x 1000 x 4000 cells of a developing pipe (a periodic one has a single station)
    ('mode = "periodic"', 'mode = "developing"', "numerics.axial_cells x radial_cells x azimuthal_cells"),
])
def test_values_that_clash_or_overflow_are_bad_input_naming_the_keys(tmp_path, capsys, old, new, key):
    assert old in TINY
    text = TINY.replace(old, new)
    if "developing" in new:
        text = text.replace("radial_cells = 8\nazimuthal_cells = 16", "radial_cells = 1000\nazimuthal_cells = 4000")
    if "0.3" in new:
        text = text.replace("radial_cells = 8", "radial_cells = 4")
    case = tmp_path / "clash.toml"
    case.write_text(text)
    status, out, err = run_cli(capsys, "check", case)
    assert status == 2, (status, err)
    assert len(err.splitlines()) == 1 and err.startswith(f"eulag: error: {key}"), err
    assert "allowed" in err and len(err) < 600


def test_parcels_beyond_the_cap_are_bad_input(tmp_path, capsys):
    case = tmp_path / "tiny.toml"
    case.write_text(TINY)
    status, out, err = run_cli(capsys, "check", ROOT / "cases" / "tsuji_morikawa_200um.toml")
    assert status == 0
    status, out, err = run_cli(capsys, "run", ROOT / "cases" / "tsuji_morikawa_200um.toml",
                               "--parcels", "9" * 23, "-o", tmp_path / "x.nc")
    assert status == 2 and len(err.splitlines()) == 1 and "--parcels" in err and "<= 1000000000" in err
    assert list(tmp_path.iterdir()) == [case]


def test_dense_model_cases_follow_the_name_rule_and_their_cross_checks(tmp_path, capsys):
    slug = (ROOT / "cases" / "slug" / "periodic_slug.toml").read_text()
    tf = (ROOT / "cases" / "two_fluid" / "ding_qs0.8.toml").read_text()
    bad = {
        "slug_path": re.sub(r'(?m)^name = .*$', 'name = "a/b"', slug),
        "tf_escape": re.sub(r'(?m)^name = .*$', 'name = "../escape"', tf),
        "tf_empty": re.sub(r'(?m)^name = .*$', 'name = ""', tf),
        # solids lighter than the gas
        "tf_light": re.sub(r'(?ms)(\[solids\][^\[]*?)^density = [^\n]*', r'\1density = 1.0', tf),
        "slug_huge": re.sub(r'(?m)^length_m = .*$', "length_m = 1" + "0" * 400, slug),
        # SI quantities in other units: the tube diameter in mm, the pressure in bar
        "slug_mm": re.sub(r'(?ms)(\[tube\][^\[]*?)^diameter_m = [^\n]*', r'\1diameter_m = 7.0', slug),
        "slug_bar": re.sub(r'(?m)^pressure_Pa = .*$', "pressure_Pa = 1.01325", slug),
        # a wall cell wider than the radius at a low gas velocity
        "tf_yplus": re.sub(r"(?m)^first_cell_yplus = .*$", "first_cell_yplus = 900.0",
                           re.sub(r"(?m)^superficial_velocity = .*$", "superficial_velocity = 0.5", tf)),
        # two rings: the inner one 45 times as thick as the wall ring
        "tf_rings": re.sub(r"(?m)^radial_cells = .*$", "radial_cells = 2", tf),
    }
    expected = {"slug_path": 'name = "a/b"', "tf_escape": 'name = "../escape"', "tf_empty": 'name = ""',
                "tf_light": "solids.density = 1.0", "slug_huge": "tube.length_m = ",
                "slug_mm": "tube.diameter_m = 7.0", "slug_bar": "gas.pressure_Pa = 1.01325",
                "tf_yplus": "numerics.first_cell_yplus = 900.0", "tf_rings": "numerics.radial_cells = 2"}
    for label, text in bad.items():
        path = tmp_path / f"{label}.toml"
        path.write_text(text)
        for verb in ("check", "run"):
            status, out, err = run_cli(capsys, verb, path, *(["-o", tmp_path / "o.nc"] if verb == "run" else []))
            assert status == 2, (label, verb, err)
            assert len(err.splitlines()) == 1 and err.startswith(f"eulag: error: {expected[label]}"), (label, err)
        path.unlink()
    assert list(tmp_path.iterdir()) == []


def test_unreadable_reference_data_is_bad_input_when_the_case_is_read(tmp_path, capsys):
    (tmp_path / "notes.csv").write_text("# not profiles\nname,value\na,1\n")
    case = tmp_path / "ref.toml"
    case.write_text(TINY.replace('mode = "periodic"', 'mode = "periodic"\nreference_data = "notes.csv"'))
    status, out, err = run_cli(capsys, "check", case)
    assert status == 2 and len(err.splitlines()) == 1, err
    assert err.startswith('eulag: error: pipe.reference_data = "notes.csv": cannot be read'), err


def test_a_study_with_a_bad_case_leaves_no_output_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "empty.toml").write_text("")
    status, out, err = run_cli(capsys, "study", "error-runtime", tmp_path / "empty.toml")
    assert status == 2 and len(err.splitlines()) == 1, err
    for study in ("stability", "tsuji-morikawa", "scenes"):  # --parcels beyond the cap
        status, out, err = run_cli(capsys, "study", study, "--quick", "--parcels", "2000000000")
        assert status == 2 and len(err.splitlines()) == 1 and "--parcels 2000000000" in err, (study, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.toml"]


def test_an_empty_selection_is_bad_input_not_everything(tmp_path, monkeypatch, capsys):
    """``--only ""`` (an empty list) selects nothing: bad input, not the whole study."""
    monkeypatch.chdir(tmp_path)
    for argv in (("scenes", "--only", ""), ("scenes-ablation", "--only", " , "), ("stability", "--only", ""),
                 ("ding-friction", "--only", ""), ("ding-friction", "--rates", ""), ("strauss", "--only", ""),
                 ("scenes-ablation", "--variants", "")):
        status, out, err = run_cli(capsys, "study", argv[0], "--quick", *argv[1:])
        assert status == 2 and len(err.splitlines()) == 1 and "(none given)" in err, (argv, err)
    assert list(tmp_path.iterdir()) == []


def test_report_with_other_quick_or_parcels_settings_is_refused(tmp_path, monkeypatch, capsys):
    """--report in a folder a --quick (or --parcels) study wrote: its runs are other cases, every
    row would say "not run", and the folder's README would be replaced. Bad input, nothing written."""
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "qs"
    folder.mkdir()
    readme = "# Stiff and extreme cases\n\n*Generated by `eulag study stability --quick --only U0_30`; do not edit*\n"
    (folder / "README.md").write_text(readme)
    for extra, differs in (((), "--quick setting"), (("--quick", "--parcels", "500"), "--parcels setting")):
        status, out, err = run_cli(capsys, "study", "stability", "--report", "--only", "U0_30", "-o", folder, *extra)
        assert status == 2 and len(err.splitlines()) == 1, err
        assert "were made by `eulag study stability --quick --only U0_30`" in err and differs in err, err
    assert (folder / "README.md").read_text() == readme and sorted(p.name for p in folder.iterdir()) == ["README.md"]
    # the same settings, in either spelling, are a report of those runs (here the folder keeps none
    # of them, which is the next refusal: a README alone is no run to report)
    (folder / "README.md").write_text(readme.replace("--quick --only", "--quick --parcels=300 --only"))
    status, out, err = run_cli(capsys, "study", "stability", "--report", "--quick", "--parcels", "300", "--only",
                               "U0_30", "-o", folder)
    assert status == 2 and "were made by" not in err and "holds no run of its own" in err, err


def test_a_file_that_is_not_a_dataset_is_bad_input_in_one_short_line(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.nc").write_text("not a dataset\n")
    (tmp_path / "tiny.toml").write_text(TINY)
    for argv, what in ((("plot", "notes.nc"), "cannot be read as a NetCDF dataset"),
                       (("plot", "."), "is a directory"),
                       (("export", "notes.nc", "x.vts"), "cannot read the dataset"),
                       (("run", "tiny.toml", "-o", "notes.nc", "--resume"), "cannot be read as a dataset")):
        status, out, err = run_cli(capsys, *argv)
        if status == 2 and "vtk" in err.lower() and argv[0] == "export":
            continue  # the optional VTK package is not installed: that is checked first
        assert status == 2, (argv, err)
        assert len(err.splitlines()) == 1 and what in err and "http" not in err and len(err) < 300, (argv, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.nc", "tiny.toml"]
    assert (tmp_path / "notes.nc").read_text() == "not a dataset\n"


def _tiny_two_fluid(restitution=0.7):
    """Ding et al.'s Q_s = 0.4 case on a 6 x 8 section with 60 iterations: about 2 s, and it
    ends unconverged, so it keeps its checkpoint."""
    text = (ROOT / "cases" / "two_fluid" / "ding_qs0.4.toml").read_text()
    text = re.sub(r'(?m)^name = .*$', 'name = "tf_tiny"', text)
    text = re.sub(r"(?m)^radial_cells = .*$", "radial_cells = 6", text)
    text = re.sub(r"(?m)^azimuthal_cells = .*$", "azimuthal_cells = 8", text)
    text = re.sub(r"(?m)^max_iterations = .*$", "max_iterations = 60", text)
    return re.sub(r"(?ms)(\[kinetic\][^\[]*?)^restitution = [^\n]*", rf"\1restitution = {restitution}", text)


def test_resume_refuses_another_cases_output_and_unusable_checkpoints(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.toml").write_text(_tiny_two_fluid(0.7))
    (tmp_path / "b.toml").write_text(_tiny_two_fluid(0.8))
    status, out, err = run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--quiet", "--no-plots")
    ckpt = tmp_path / "a.nc.checkpoint.npz"
    assert status == 1 and ckpt.is_file(), err  # unconverged after 60 iterations: its checkpoint stays
    kept = (tmp_path / "a.nc").read_bytes()
    # another case's output is never overwritten by a resume, with a checkpoint beside it or not
    status, out, err = run_cli(capsys, "run", "b.toml", "-o", "a.nc", "--resume", "--quiet", "--no-plots")
    assert status == 2 and len(err.splitlines()) == 1 and "holds a different case" in err, err
    assert "(kinetic.restitution = 0.7 stored, 0.8 in this case)" in err, err
    assert (tmp_path / "a.nc").read_bytes() == kept
    # a checkpoint of another case, or one that is not an archive, is named and refused
    (tmp_path / "a.nc").unlink()
    status, out, err = run_cli(capsys, "run", "b.toml", "-o", "a.nc", "--resume", "--quiet", "--no-plots")
    assert status == 2 and "a.nc.checkpoint.npz: checkpoint of a different case (kinetic.restitution" in err, err
    good = ckpt.read_bytes()
    ckpt.write_bytes(good[:len(good) // 2])
    status, out, err = run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--resume", "--quiet", "--no-plots")
    assert status == 2 and len(err.splitlines()) == 1, err
    assert "a.nc.checkpoint.npz: cannot be read (not a NumPy .npz archive" in err and "pickle" not in err, err
    assert not (tmp_path / "a.nc").exists()
    # a fresh run says that it removes an earlier run's checkpoint, and removes the temporary
    # files of a write a kill interrupted (its own only)
    ckpt.write_bytes(good)
    for name in (".a.nc.k3x9_q2p.tmp", ".a.nc.checkpoint.npz.zz_9yx12.tmp", ".other.nc.abcd1234.tmp",
                 ".a.nc.nc.abcd1234.tmp"):
        (tmp_path / name).write_bytes(b"partial")
    status, out, err = run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--no-plots")
    assert status == 1 and "a.nc.checkpoint.npz: the checkpoint of an earlier run was removed" in err, err
    assert sorted(p.name for p in tmp_path.glob(".*.tmp")) == [".a.nc.nc.abcd1234.tmp", ".other.nc.abcd1234.tmp"]
    assert (tmp_path / "a.nc").read_bytes() != b""
    # a finished unconverged two-fluid run without its checkpoint is taken as finished
    ckpt.unlink()
    before = (tmp_path / "a.nc").stat().st_mtime_ns
    status, out, err = run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--resume", "--no-plots")
    assert status == 1 and "already a finished run" in out and "converged = false" in err, (out, err)
    assert (tmp_path / "a.nc").stat().st_mtime_ns == before and not ckpt.exists()
    # without --resume another case's output is replaced, and the run says so before it starts
    status, out, err = run_cli(capsys, "run", "b.toml", "-o", "a.nc", "--no-plots")
    assert "a.nc holds a different case (kinetic.restitution = 0.7 stored, 0.8 in this case); this run " \
           "replaces it when it ends" in err, err


def test_resume_continues_this_cases_checkpoint_beside_another_runs_output(tmp_path, monkeypatch, capsys):
    """A run started (without --resume) on an output that held another run's dataset and then
    interrupted keeps its checkpoint beside that dataset: --resume continues the checkpoint and
    replaces the dataset, instead of refusing the output as another case's."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.toml").write_text(_tiny_two_fluid(0.8))
    (tmp_path / "b.toml").write_text(_tiny_two_fluid(0.7))
    assert run_cli(capsys, "run", "b.toml", "-o", "b.nc", "--quiet", "--no-plots")[0] == 1  # unconverged
    assert run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--quiet", "--no-plots")[0] == 0
    # b's checkpoint beside a's dataset: what an interrupted "eulag run b.toml -o a.nc" leaves
    (tmp_path / "a.nc.checkpoint.npz").write_bytes((tmp_path / "b.nc.checkpoint.npz").read_bytes())
    status, out, err = run_cli(capsys, "run", "b.toml", "-o", "a.nc", "--resume", "--no-plots")
    assert status == 1, err  # continued (and unconverged again after its iterations), not bad input
    assert "the checkpoint beside it is this case's and continues" in err, err
    import xarray as xr

    from eulag import runs
    with xr.open_dataset(tmp_path / "a.nc") as ds:
        assert runs.same_case(dict(ds.attrs), runs.load_case("b.toml"))


def test_an_unconverged_two_fluid_run_is_run_again_when_its_iteration_budget_is_raised(tmp_path, monkeypatch,
                                                                                      capsys):
    """numerics.max_iterations is not part of a two-fluid case's identity; an unconverged result
    with fewer iterations than the case now allows is not its final answer: --resume and the
    sweep run it again (with the same budget they keep it, as running it again gives the same)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.toml").write_text(_tiny_two_fluid(0.7))
    assert run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--quiet", "--no-plots")[0] == 1
    (tmp_path / "a.nc.checkpoint.npz").unlink()
    status, out, err = run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--resume", "--quiet", "--no-plots")
    assert status == 1 and "holds this case's finished run" in err, (out, err)  # the same budget: kept
    (tmp_path / "a.toml").write_text(_tiny_two_fluid(0.7).replace("max_iterations = 60", "max_iterations = 90"))
    from eulag import runs

    assert runs.dataset_state(tmp_path / "a.nc", runs.load_case("a.toml")) == "budget raised"
    status, out, err = run_cli(capsys, "run", "a.toml", "-o", "a.nc", "--resume", "--quiet", "--no-plots")
    assert "finished run" not in err, err
    import xarray as xr

    with xr.open_dataset(tmp_path / "a.nc") as ds:
        assert int(ds.attrs["iterations"]) > 60


def test_dask_options_on_a_case_that_runs_in_one_process_are_bad_input(tmp_path, capsys):
    (tmp_path / "tf.toml").write_text(_tiny_two_fluid())
    status, out, err = run_cli(capsys, "run", tmp_path / "tf.toml", "-o", tmp_path / "tf.nc", "--dask-local", "2")
    assert status == 2 and len(err.splitlines()) == 1 and "runs in this process" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tf.toml"]


def test_plot_x_of_a_fully_developed_two_fluid_section_is_bad_input(tmp_path, capsys):
    (tmp_path / "tf.toml").write_text(_tiny_two_fluid(0.8))
    assert run_cli(capsys, "run", tmp_path / "tf.toml", "-o", tmp_path / "tf.nc", "--quiet", "--no-plots")[0] == 0
    status, out, err = run_cli(capsys, "plot", tmp_path / "tf.nc", "--x", "1.0", "-o", tmp_path / "figs")
    assert status == 2 and "has no axial position" in err and not (tmp_path / "figs").exists(), err


def test_an_interrupted_run_points_to_its_checkpoint(capsys, monkeypatch):
    from eulag import cli

    def interrupted(args):
        raise KeyboardInterrupt
    monkeypatch.setattr(cli, "cmd_check", interrupted)
    status, out, err = run_cli(capsys, "check", "single_phase_pipe")
    assert status == 130 and "--resume" in err and "checkpoint" in err, err


def test_a_sweep_names_the_case_file_of_bad_input(tmp_path, capsys):
    (tmp_path / "bad.toml").write_text("[pipe]\ndiameter = 0.03\n")
    status, out, err = run_cli(capsys, "sweep", tmp_path / "bad.toml", "-o", tmp_path / "sw")
    assert status == 2 and f"{tmp_path / 'bad.toml'}: " in err, err


def test_the_sweep_continues_this_cases_checkpoint_beside_another_runs_output(tmp_path, monkeypatch, capsys):
    """The sweep takes an output as eulag run --resume does: this case's checkpoint beside another
    run's dataset is continued, not refused."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.toml").write_text(_tiny_two_fluid(0.8))
    (tmp_path / "b.toml").write_text(_tiny_two_fluid(0.7))
    (tmp_path / "sw").mkdir()
    assert run_cli(capsys, "run", "b.toml", "-o", "b.nc", "--quiet", "--no-plots")[0] == 1  # unconverged
    assert run_cli(capsys, "run", "a.toml", "-o", "sw/tf_tiny.nc", "--quiet", "--no-plots")[0] == 0
    (tmp_path / "sw" / "tf_tiny.nc.checkpoint.npz").write_bytes((tmp_path / "b.nc.checkpoint.npz").read_bytes())
    status, out, err = run_cli(capsys, "sweep", "b.toml", "-o", "sw", "--quiet")
    assert status == 1 and "holds a different case" not in err, (out, err)  # ran (unconverged again)
    from eulag import runs
    import xarray as xr

    with xr.open_dataset(tmp_path / "sw" / "tf_tiny.nc") as ds:
        assert runs.same_case(dict(ds.attrs), runs.load_case("b.toml"))
