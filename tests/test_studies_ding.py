"""eulag study ding-friction: the quick mode runs the three frictional-stress models end to end
through the run layer and writes its table (Markdown + CSV), grid table and figures; --resume
and --report reuse the runs; bad options exit 2 with one line.

Quick-mode numbers are not results: the tests check the machinery, never specific values.
"""

import csv
import math

import pytest

from eulag import studies
from eulag.cli import main


def study(*argv):
    return main(["study", "ding-friction", *[str(a) for a in argv]])


def rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_registered():
    assert "ding-friction" in studies.STUDIES
    plan = studies.ding_friction_cases(True)
    assert {info["model"] for _, info, _ in plan.values()} == {"dartevelle", "srivastava-sundaresan", "berzi"}
    assert {info["rate"] for _, info, _ in plan.values()} == {"0.8"}
    assert sum(kind == "matrix" for kind, _, _ in plan.values()) == 3
    full = studies.ding_friction_cases(False)
    assert sum(kind == "matrix" for kind, _, _ in full.values()) == 15
    assert all(c.data["friction"]["model"] == info["model"] for _, info, c in full.values())


def test_quick_runs_end_to_end_and_writes_the_table(tmp_path, capsys):
    out = tmp_path / "ding"
    assert study("--quick", "--quiet", "-o", out) == 0
    readme = (out / "README.md").read_text()
    assert "Quick mode" in readme and "not results" in readme and "wall time of this invocation" in readme
    table = rows(out / "ding-friction.csv")
    assert [r["model"] for r in table] == ["dartevelle", "srivastava-sundaresan", "berzi"]
    for r in table:
        assert r["converged"] == "yes"
        dp = float(r["dp_kPa"])
        assert math.isfinite(dp) and dp > 0
        assert float(r["dp_measured_kPa"]) == pytest.approx(4.26)
        assert 0.0 < float(r["peak_alpha"]) < 0.63
        assert int(r["capped"]) >= 0
    md_rows = [ln for ln in readme.split("## Table")[1].split("##")[0].splitlines() if ln.startswith("| ")]
    assert len(md_rows) == len(table) + 1
    grid = rows(out / "ding-friction-grid.csv")
    assert len(grid) == 9 and all(math.isfinite(float(g["dp_kPa"])) for g in grid)
    assert "Table 5" in readme and "3.77" in readme
    for ln in readme.splitlines():  # every figure the README shows exists
        if ln.startswith("!["):
            target = out / ln[ln.index("(") + 1: ln.rindex(")")]
            assert target.is_file() and target.stat().st_size > 1000, target
    assert (out / "fig7_frictional_pressure_closures.png").is_file()
    assert len(list(out.glob("*.record.json"))) == 10
    dev = rows(out / "ding-friction-developing.csv")      # Berzi at Q_s = 0.8, marched from the inlet
    assert [(d["model"], d["Q_s"]) for d in dev] == [("berzi", "0.8")] and dev[0]["converged"] == "yes"
    assert float(dev[0]["us_in"]) == pytest.approx(6.088, abs=1e-3)        # Hinkle, eq. 22
    assert "## The developing pipe" in readme and (out / "fig_developing_qs0.8.png").is_file()

    # --resume runs nothing again; --report without the datasets reports from the records
    for nc in out.glob("*.nc"):
        nc.unlink()
    capsys.readouterr()
    assert study("--quick", "--report", "-o", out) == 0
    err = capsys.readouterr().err
    assert "running" not in err and "reported from its record" in err
    assert rows(out / "ding-friction.csv") == table


@pytest.mark.parametrize("argv, message", [
    (["--quick", "--frobnicate"], "unrecognized arguments"),
    (["--quick", "--only", "berzi,coulomb"], "unknown friction models coulomb"),
    (["--quick", "--rates", "0.9"], "unknown supplementary gas rates 0.9"),
    (["--quick", "--parcels", "100"], "unrecognized arguments"),
])
def test_bad_option_exits_2_with_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert study(*argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("eulag: error:") and message in err[0]
    assert not any(tmp_path.rglob("*.nc"))


def _without_the_developing_run(monkeypatch):
    """The study's plan without its marched pipe (12 s of the quick study's 18): for the tests of
    the run machinery, which the matrix runs exercise alike."""
    import functools

    from eulag.studies import ding_friction

    monkeypatch.setattr(ding_friction, "study_cases",
                        functools.partial(ding_friction.study_cases, developing=False))


def test_a_failing_run_is_one_line_and_the_study_goes_on(tmp_path, monkeypatch, capsys):
    from eulag import runs

    _without_the_developing_run(monkeypatch)
    real = runs.execute

    def execute(case, out=None, **kw):
        if case.name.endswith("__6x12"):
            # what the run layer raises for a failing solve (runs._execute_other)
            raise runs.RunError("two-fluid x: alpha_s = nan in cell 3 (ring 0, sector 3) at iteration 7")
        return real(case, out, **kw)

    monkeypatch.setattr(runs, "execute", execute)
    out = tmp_path / "ding"
    assert study("--quick", "--quiet", "--only", "berzi", "-o", out) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "1 of 3 runs did not finish" in err[0]
    grid = rows(out / "ding-friction-grid.csv")
    failed = [g for g in grid if g["mesh"] == "6x12"]
    assert failed[0]["converged"].startswith("failed: two-fluid x: alpha_s = nan in cell 3")
    assert "\n" not in failed[0]["converged"]
    assert (out / "ding_qs0.8__berzi__6x12.failed.json").is_file()
    assert [r["model"] for r in rows(out / "ding-friction.csv")] == ["berzi"]


def test_resume_replaces_a_dataset_of_another_case(tmp_path, capsys, monkeypatch):
    """--resume beside a dataset of another case (the case file was edited) runs the case again
    and replaces it, instead of recording a failure."""
    import xarray as xr

    _without_the_developing_run(monkeypatch)
    out = tmp_path / "ding"
    assert study("--quick", "--quiet", "--only", "berzi", "-o", out) == 0
    capsys.readouterr()
    nc = out / "ding_qs0.8__berzi__8x16.nc"
    with xr.open_dataset(nc) as ds:
        ds = ds.load()
    ds.attrs["case_json"] = ds.attrs["case_json"].replace('"berzi"', '"dartevelle"')
    ds.to_netcdf(nc)
    assert study("--quick", "--resume", "--only", "berzi", "-o", out) == 0
    assert "holds another case or cannot be read; it is replaced" in capsys.readouterr().err
    assert not (out / "ding_qs0.8__berzi__8x16.failed.json").exists()
    with xr.open_dataset(nc) as ds:
        assert '"berzi"' in ds.attrs["case_json"]
