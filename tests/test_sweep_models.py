"""eulag sweep over the dense-phase models: a slug case and a two-fluid case in one sweep, each
written as `eulag run` writes it, with its model's numbers in the summary; a second sweep runs
nothing; --parcels with a dense-phase case is one line and exit 2 before any work."""

import re
import tomllib

import xarray as xr

from eulag import slug, sweep
from eulag.cli import main
from eulag.config import CASES_DIR


def _slug_case(path):
    text = (CASES_DIR / "slug" / "periodic_slug.toml").read_text()
    for key, value in (("end_time_s", "0.02"), ("output_interval_s", "0.005"), ("checkpoint_interval_s", "0.01")):
        text, n = re.subn(rf"(?m)^{key} = [0-9.e-]+", f"{key} = {value}", text)
        assert n == 1, key
    path.write_text(text)
    return path


def _two_fluid_case(path):
    text = (CASES_DIR / "two_fluid" / "ding_qs0.8.toml").read_text()
    text = re.sub(r"(?m)^radial_cells = \d+", "radial_cells = 5", text)
    text = re.sub(r"(?m)^azimuthal_cells = \d+", "azimuthal_cells = 8", text)
    path.write_text(text)
    return path


def test_a_sweep_runs_dense_phase_cases_beside_each_other(tmp_path, capsys):
    cases = [_slug_case(tmp_path / "s.toml"), _two_fluid_case(tmp_path / "tf.toml")]
    out = tmp_path / "out"
    status = main(["sweep", *map(str, cases), "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    rows = {r["case"]: r for r in sweep.read_summary(out / "sweep_summary.csv")}
    assert set(rows) == {"periodic_slug", "ding_qs0.8"}
    s, tf = rows["periodic_slug"], rows["ding_qs0.8"]
    assert s["model"] == "dem-darcy" and tf["model"] == "two-fluid"
    assert s["status"] == tf["status"] == "ran", err
    assert s["passes"] == tf["passes"] == ""
    # the slug run's Δp/L is its pressure drop over the tube, averaged over the statistics window
    with xr.open_dataset(out / "periodic_slug.nc") as ds:
        t_from, xw = slug.statistics_window(slug.validate_slug_case(tomllib.loads(cases[0].read_text())))
        dp = float(ds["pressure_drop"].where(ds["time"] >= t_from, drop=True).mean())
        assert float(s["pressure_drop"]) == dp and float(s["pressure_gradient"]) == dp / 0.07
        assert s["converged"] == ("true" if slug.verdict(ds)[0] else "false")
    with xr.open_dataset(out / "ding_qs0.8.nc") as ds:
        assert ds.attrs["model"] == "two-fluid"
        assert float(tf["pressure_drop"]) == float(ds["pressure_drop"])
        assert float(tf["pressure_gradient"]) == float(ds["pressure_gradient"].mean())
        assert tf["converged"] == ("true" if ds.attrs["converged"] == "true" else "false")
    assert status == (0 if s["converged"] == tf["converged"] == "true" else 1)
    md = (out / "sweep_summary.md").read_text()
    assert "| periodic_slug | dem-darcy |" in md and "| ding_qs0.8 | two-fluid |" in md
    # everything finished: a second sweep runs nothing
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*.nc")}
    main(["sweep", *map(str, cases), "-o", str(out)])
    assert capsys.readouterr().out.count("finished earlier") == 2
    assert stamps == {p: p.stat().st_mtime_ns for p in out.glob("*.nc")}


def test_parcels_with_a_dense_phase_case_is_one_line_before_any_work(tmp_path, capsys):
    case = _slug_case(tmp_path / "s.toml")
    out = tmp_path / "out"
    assert main(["sweep", str(case), "-o", str(out), "--parcels", "1000"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--parcels 1000" in err and "dem-darcy" in err and "tracks no parcels" in err
    assert not out.exists()
    assert main(["run", str(case), "-o", str(tmp_path / "s.nc"), "--parcels", "1000"]) == 2
    assert "tracks no parcels" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
