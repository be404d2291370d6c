"""eulag study: each study in --quick mode writes its datasets, a consistent table (Markdown +
CSV, machine and wall times stated) and its figures; --resume reuses finished runs; a failing
run is recorded with its diagnosis instead of stopping the study; bad input exits 2.

Quick-mode numbers are not results: the tests check the machinery and the bookkeeping (row
counts, finite numbers, lost parcels = 0), never specific values.
"""

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from eulag import studies
from eulag.cli import main
from eulag.config import CASES_DIR, Case

ROOT = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("EULAG_SHARED_DATA", ROOT.parent / "shared" / "data")).parent
CHECK_DATASET = SHARED / "tools" / "check_dataset.py"
BASE = CASES_DIR / "tsuji_morikawa_200um.toml"


def study(*argv):
    return main(["study", *[str(a) for a in argv]])


def rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def number(text):
    return float(text) if text not in ("", None) else math.nan


def check_report(folder: Path, stem: str, n_rows: int):
    readme = (folder / "README.md").read_text()
    assert "Quick mode" in readme and "not results" in readme
    assert "platform:" in readme and "CPUs:" in readme and "wall time of this invocation" in readme
    table = rows(folder / f"{stem}.csv")
    assert len(table) == n_rows
    # the Markdown table has the same rows
    md_rows = [ln for ln in readme.splitlines() if ln.startswith("| ") and not ln.startswith("| ---")]
    assert len(md_rows) == n_rows + 1  # + the header
    for ln in readme.splitlines():  # every figure the README shows exists
        if ln.startswith("!["):
            target = folder / ln[ln.index("(") + 1: ln.rindex(")")]
            assert target.is_file() and target.stat().st_size > 1000, target
    return table


# ------------------------------------------------------------------------------ tsuji-morikawa

@pytest.fixture(scope="module")
def tm(tmp_path_factory):
    out = tmp_path_factory.mktemp("tsuji_morikawa")
    status = study("tsuji-morikawa", "--quick", "--quiet", "-o", out)
    return status, out


def test_tsuji_morikawa_quick_compares_four_runs_with_the_digitised_profiles(tm):
    status, out = tm
    assert status == 0
    assert sorted(p.name for p in out.glob("*.nc")) == [
        "tm_U10_four-way.nc", "tm_U10_two-way.nc", "tm_U15_four-way.nc", "tm_U15_two-way.nc"]
    assert not list(out.glob("*.checkpoint"))  # finished runs leave no checkpoint behind
    table = check_report(out, "tsuji-morikawa", 8)  # 2 velocities x 2 couplings x (gas, particle)
    assert {(r["U0"], r["coupling"], r["phase"]) for r in table} == {
        (u, c, p) for u in ("10.0", "15.0") for c in ("four-way", "two-way") for p in ("gas", "particle")}
    for r in table:
        rms, mx = number(r["rms"]), number(r["max"])
        assert np.isfinite(rms) and 0.0 <= rms <= mx + 1e-12
        assert int(r["points"]) == 15  # the file's points per profile
        assert number(r["time_s"]) > 0
        assert r["commit"] and r["commit"] != "None"  # the code that made the run (eulag_commit)
        if r["phase"] == "particle":
            assert number(r["stderr"]) > 0.0  # the batch standard error of the simulation
        # the collision model's momentum error: from the run's history; none without collisions
        cm = number(r["collision_momentum"])
        if r["coupling"] == "two-way":
            assert math.isnan(cm)  # no inter-particle collisions: an empty cell, not a zero
        else:
            import xarray as xr

            with xr.open_dataset(out / f"tm_U{r['U0'][:2]}_four-way.nc") as ds:
                want = float(np.mean(ds["collision_momentum_history"].values[-int(ds.attrs["case_numerics_average_passes"]):]))
            assert np.isfinite(cm) and cm == pytest.approx(want, rel=0.01, abs=1e-3)
    points = rows(out / "tsuji-morikawa_points.csv")
    assert len(points) == 4 * 2 * 15
    assert all(np.isfinite(number(pt["simulated"])) for pt in points)
    assert (out / "tsuji_morikawa_profiles.png").stat().st_size > 10_000
    readme = (out / "README.md").read_text()
    assert "tsuji_morikawa_1982_horizontal_eta2.2.csv" in readme and "DIGITIZED" in readme


def test_tsuji_morikawa_datasets_pass_the_schema_check(tm):
    _, out = tm
    if not CHECK_DATASET.exists():
        pytest.skip(f"schema checker {CHECK_DATASET} not available")
    check = subprocess.run([sys.executable, str(CHECK_DATASET), str(out / "tm_U10_four-way.nc"),
                            "--particles"], capture_output=True, text=True)
    assert check.returncode == 0, check.stdout + check.stderr


def test_resume_reuses_finished_runs(tm, capsys):
    status, out = tm
    assert status == 0
    before = {p.name: p.stat().st_mtime_ns for p in out.glob("*.nc")}
    old = rows(out / "tsuji-morikawa.csv")
    assert study("tsuji-morikawa", "--quick", "--resume", "-o", out) == 0
    err = capsys.readouterr().err
    assert err.count("not run again") == 4 and "running" not in err
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.nc")} == before
    new = rows(out / "tsuji-morikawa.csv")
    assert [r["rms"] for r in new] == [r["rms"] for r in old]


def test_resume_reports_finished_runs_from_their_records_when_the_datasets_are_gone(tm, tmp_path, capsys):
    # the datasets are not committed; the records are, and a clean clone must not re-run them
    status, out = tm
    assert status == 0
    records = sorted(out.glob("*.record.json"))
    assert len(records) == 4
    for r in records:
        (tmp_path / r.name).write_text(r.read_text())
    assert study("tsuji-morikawa", "--quick", "--resume", "-o", tmp_path) == 0
    err = capsys.readouterr().err
    assert err.count("reported from its record") == 4 and "running" not in err
    assert not list(tmp_path.glob("*.nc"))
    old, new = rows(out / "tsuji-morikawa.csv"), rows(tmp_path / "tsuji-morikawa.csv")
    for key in ("rms", "max", "bias", "stderr", "passes", "time_s", "commit"):
        assert [r[key] for r in new] == [r[key] for r in old], key
    assert (tmp_path / "tsuji_morikawa_profiles.png").stat().st_size > 1000  # drawn from the records
    # a record is taken only for its own case and record version
    name, case = studies.tsuji_morikawa_cases(True)[0]
    rec = tmp_path / f"{name}.record.json"
    assert studies.read_record(rec, case) is not None
    other = case.replace(gas={"bulk_velocity": case.gas.bulk_velocity + 1.0})
    assert studies.read_record(rec, other) is None
    rec.write_text(rec.read_text().replace('"version": 1', '"version": 0'))
    assert studies.read_record(rec, case) is None


def test_a_checkpoint_from_before_a_later_key_is_kept_by_the_study(tmp_path):
    """The study keeps a checkpoint (and resumes it) when its stored case lacks a key of
    config.LATER_KEYS that today's case holds at its earlier value; one of another value of
    that key, or an unreadable file, is not the case's (the study then starts afresh)."""
    from eulag.coupling import CHECKPOINT_VERSION, _json_default

    name, case = studies.scene_cases(False, parcels=30000)[0]
    ckpt = tmp_path / "c.checkpoint"

    def write(attrs, version=CHECKPOINT_VERSION):
        meta = {"version": version, "case": json.loads(json.dumps(attrs, default=_json_default))}
        np.savez(ckpt, meta=np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8))
        ckpt.with_suffix(".checkpoint.npz").replace(ckpt)

    attrs = case.to_attrs()
    assert attrs["physics.partner_correlation"] == "particle"
    write(attrs)
    assert studies.checkpoint_of(ckpt, case)
    write({k: v for k, v in attrs.items() if k != "physics.partner_correlation"})  # v0.1.0
    assert studies.checkpoint_of(ckpt, case)
    write({**attrs, "physics.partner_correlation": "cell"})
    assert not studies.checkpoint_of(ckpt, case)
    assert studies.checkpoint_of(ckpt, case.replace(physics={"partner_correlation": "cell"}))
    write(attrs, version=CHECKPOINT_VERSION - 1)  # an older layout: the loop could not resume it
    assert not studies.checkpoint_of(ckpt, case)
    ckpt.write_text("not a checkpoint")
    assert not studies.checkpoint_of(ckpt, case)


# the study cases as the commands in results/README.md run them
RESULT_CASES = {
    "scenes": lambda: studies.scene_cases(False),
    "scenes-former": lambda: studies.scene_cases(False, parcels=30000),
    "stability": lambda: [(n, c) for n, _, c in studies.stability_cases(False, parcels=30000)
                          if isinstance(c, Case)],
    "tsuji-morikawa": lambda: studies.tsuji_morikawa_cases(False),
    "scenes-ablation": lambda: [(n, c) for n, _, _, c in studies.ablation_cases(False)],
}


#: results/ folders whose records were run with today's defaults (the others predate them)
TODAYS_DEFAULTS = {"scenes", "tsuji-morikawa", "scenes-ablation"}


@pytest.mark.parametrize("folder", sorted(RESULT_CASES))
def test_committed_records_belong_to_the_shipped_cases(folder):
    """The run records in results/scenes-former and results/stability (written before
    physics.partner_correlation, physics.partner_momentum, numerics.mirror_symmetry,
    physics.langevin_drift_form and numerics.drag_implicit_weight existed) are the records of the
    study cases with those keys at their earlier behaviour (config.LATER_KEYS), so --resume
    on a fresh clone reports them, not re-runs; the key at another value is another case —
    today's defaults, mirror-symmetric sampling and the returned partner momentum, included:
    those cases are re-run.  results/scenes and results/tsuji-morikawa hold runs of today's
    defaults: their records are those of the shipped cases as they are."""
    found = 0
    for name, today in RESULT_CASES[folder]():
        if folder in TODAYS_DEFAULTS:
            case = today
        else:
            case = today.replace(numerics={"mirror_symmetry": False, "drag_implicit_weight": 1.0},
                                 physics={"partner_momentum": "discarded", "langevin_drift_form": "particle"})
        rec = ROOT / "results" / folder / f"{name}.record.json"
        if rec.is_file() and today.particles is not None and folder not in TODAYS_DEFAULTS:
            assert studies.read_record(rec, today) is None, name
        if rec.is_file():
            found += 1
            assert studies.read_record(rec, case) is not None, name
            assert studies.read_record(rec, case.replace(physics={"partner_correlation": "cell"})) is None
        failed = rec.with_name(f"{name}.failed.json")
        if failed.is_file():  # compared as run_one compares it
            found += 1
            stored = json.loads(failed.read_text())["case"]
            assert stored == studies._canonical(case), name
            assert stored != studies._canonical(case.replace(physics={"partner_correlation": "cell"}))
    assert found >= 4


@pytest.mark.parametrize("folder", sorted(RESULT_CASES))
def test_committed_checkpoints_resume_as_the_shipped_cases(folder):
    """A run too long to finish at once is committed with its checkpoint (docs/history.md), so
    that the command in results/README.md continues it on a fresh machine: each committed
    ``<run>.nc.checkpoint`` must be resumable as its shipped case (else --resume would delete
    it and start afresh), and must not sit beside a record of that case (a finished run)."""
    cases = dict(RESULT_CASES[folder]())
    for ckpt in sorted((ROOT / "results" / folder).glob("*.nc.checkpoint")):
        name = ckpt.name[: -len(".nc.checkpoint")]
        assert name in cases, ckpt
        assert studies.checkpoint_of(ckpt, cases[name]), ckpt
        assert studies.read_record(ckpt.with_name(f"{name}.record.json"), cases[name]) is None, ckpt


def test_resume_continues_an_interrupted_run_from_its_checkpoint(tmp_path, capsys):
    from eulag.coupling import CouplingLoop

    name, case = studies.tsuji_morikawa_cases(quick=True)[0]
    loop = CouplingLoop(case, checkpoint=tmp_path / f"{name}.nc.checkpoint")
    loop.step()  # "killed" after the first pass
    del loop
    capsys.readouterr()
    rec = studies.run_case(SimpleNamespace(resume=True, quiet=False), name, case, tmp_path, name)
    err = capsys.readouterr().err
    assert rec.ok and rec.passes == case.numerics.max_passes
    assert f"{name}: pass 2 " in err and f"{name}: pass 1 " not in err  # pass 1 was not run again
    assert (tmp_path / f"{name}.nc").is_file() and not (tmp_path / f"{name}.nc.checkpoint").exists()


# ------------------------------------------------------------------------------ scenes

SCENE_TABLE = {  # the issue's table: D_p [um], Delta-gamma [deg], coupling, loading / eta0
    "a": (200, 1.5, "four-way", 1), "b": (200, 10, "four-way", 1), "c": (200, 5, "two-way", 1),
    "d": (200, 5, "four-way", 1), "e": (50, 10, "four-way", 1), "f": (50, 10, "four-way", 2),
    "g": (50, 10, "two-way", 4), "h": (50, 10, "four-way", 4)}


def test_scene_case_files_match_the_issue_table():
    base = studies._base_case(False)  # the base case at the studies' resolution
    for s, (dp, dg, coupling, f) in SCENE_TABLE.items():
        case = Case.from_toml(CASES_DIR / "scenes" / f"scene_{s}.toml")
        assert case.name == f"scene_{s}"
        assert case.particles.diameter == pytest.approx(dp * 1e-6)
        assert case.walls.roughness_angle_std_deg == dg
        assert case.physics.coupling == coupling
        assert case.physics.inter_particle_collisions == (coupling == "four-way")
        assert case.particles.mass_loading == pytest.approx(2.2 * f)
        assert case.gas.bulk_velocity == 10.0 and case.particles.density == 1020.0
        assert case.pipe.sections == (3.56,)
        # everything else is the base case's, but the pass limits of g and h and the weight of
        # their linearised drag (their slow drift at 4 eta0)
        assert case.numerics.max_passes == {"g": 80, "h": 160}.get(s, base.numerics.max_passes)
        assert case.numerics.drag_implicit_weight == (0.6 if s in "gh" else 1.0)
        assert case.replace(name=base.name, description=base.description,
                            particles={"diameter": 200e-6, "mass_loading": 2.2},
                            walls={"roughness_angle_std_deg": 1.5}, physics={"coupling": "four-way"},
                            pipe={"reference_data": base.pipe.reference_data},
                            numerics={"max_passes": base.numerics.max_passes,
                                      "drag_implicit_weight": base.numerics.drag_implicit_weight}) == base


def test_settings_name_the_numerics_that_differ_from_the_first_run():
    """The settings paragraph shows the first run's numerics and names what differs in the others
    (g's and h's pass limits are in no column of the scenes table)."""
    a, g, h = (Case.from_toml(CASES_DIR / "scenes" / f"scene_{s}.toml") for s in "agh")
    text = studies._settings_text([a, g, h], False)
    assert "at most 40 passes" in text
    assert ("differing in the others: scene_g max_passes 80, drag_implicit_weight 0.6; "
            "scene_h max_passes 160, drag_implicit_weight 0.6") in text
    assert "the others' are the same" in studies._settings_text([a, a.replace(name="x")], False)
    assert studies._settings_text([a], False).startswith("Numerics of the run: 400 axial")
    fine = a.replace(name="fine", numerics={"axial_cells": 800, "step_factor": 0.25})
    assert "fine axial_cells 800, step_factor 0.25" in studies._settings_text([a, fine], False)


def check_scene_rows(table, names):
    assert [r["scene"] for r in table] == names
    for r in table:
        assert np.isfinite(number(r["strength"])) and number(r["strength"]) >= 0
        assert int(r["cells"]) >= 0
        assert r["half"] in ("upper", "lower", "neither")
        assert number(r["impact_upper"]) >= 0 and number(r["impact_lower"]) >= 0
        assert np.isfinite(number(r["dpdx"]))
        assert int(r["passes"]) >= 1 and number(r["time_s"]) > 0


def test_scenes_quick_subset(tmp_path):
    assert study("scenes", "--quick", "--quiet", "--only", "c,a", "-o", tmp_path) == 0
    table = check_report(tmp_path, "scenes", 2)
    check_scene_rows(table, ["a", "c"])
    for s in "ac":
        assert (tmp_path / f"scene_{s}.nc").is_file()
        assert len(list((tmp_path / "figures").glob(f"scene_{s}_section*.png"))) == 1


def test_report_runs_nothing_and_says_how_far_an_unfinished_run_got(tmp_path):
    """--report writes the table from what the folder holds: a run with only a checkpoint is
    "unfinished" with its passes, residual and relaxation (read from the checkpoint), one with
    nothing "not run"; no run starts, the checkpoint stays, and the exit status is 0."""
    from eulag.coupling import CouplingLoop

    (name, case), = studies.scene_cases(quick=True, names="a")
    ckpt = tmp_path / f"{name}.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()  # "killed" after the first pass
    del loop
    before = ckpt.read_bytes()
    assert study("scenes", "--quick", "--quiet", "--report", "--only", "a,c", "-o", tmp_path) == 0
    table = check_report(tmp_path, "scenes", 2)
    a, c = table
    assert a["converged"].startswith(f"unfinished: checkpoint after pass 1 of at most {case.numerics.max_passes}")
    assert int(a["passes"]) == 1 and number(a["time_s"]) > 0
    assert c["converged"].startswith("not run")
    assert ckpt.read_bytes() == before
    assert "--report`" in (tmp_path / "README.md").read_text()
    assert not list(tmp_path.glob("*.nc")) and not list(tmp_path.glob("*.record.json"))
    assert study("scenes", "--quick", "--quiet", "--report", "-o", tmp_path / "typo") == 2
    assert not (tmp_path / "typo").exists()


def test_report_leaves_a_folder_alone_when_its_runs_are_not_todays_cases(tmp_path):
    """--report in a folder whose records are runs of other cases (made with former defaults) or
    that keeps no runs at all refuses with one line naming why, instead of replacing its table
    with "not run" rows; nothing in the folder changes."""
    import shutil

    folder = tmp_path / "stability"
    shutil.copytree(ROOT / "results" / "stability", folder)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert study("stability", "--parcels", "30000", "--quiet", "--report", "-o", folder) == 2
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "README.md").write_text("a table\n")
    assert study("scenes", "--quiet", "--report", "-o", bare) == 2
    assert [p.name for p in bare.iterdir()] == ["README.md"]


def _generated_folder(folder, command, run_file):
    """A study folder whose README was generated by ``command`` and that holds ``run_file``."""
    folder.mkdir()
    (folder / "README.md").write_text(f"*Generated by `{command}`; do not edit by hand — re-run the command.*\n")
    (folder / run_file).write_bytes(b"not a dataset of these runs")
    return folder


def _report_refused(capsys, folder, says, *argv):
    """``eulag study ... --report -o folder`` exits 2 with one line holding ``says`` and changes nothing."""
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert study(*argv, "--quiet", "--report", "-o", folder) == 2
    err = capsys.readouterr().err
    assert says in err and err.count("eulag: error") == 1, err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_report_refuses_another_studys_folder(tmp_path, capsys):
    """--report pointed at a folder of another study (its generated README names that study, or
    it holds only other runs) refuses with one line and changes nothing: it used to replace the
    README with a table of "not run" rows and exit 0."""
    other = _generated_folder(tmp_path / "tm", "eulag study tsuji-morikawa --quick", "tm_u10_four-way.nc")
    _report_refused(capsys, other, "holds the study `eulag study tsuji-morikawa --quick`, not scenes",
                    "scenes", "--quick")
    (other / "README.md").write_text("edited by hand\n")  # no generated line: the runs decide
    _report_refused(capsys, other, "holds none of the runs of eulag study scenes", "scenes", "--quick", "--only", "a,c")


def test_report_refuses_another_selection_of_the_runs(tmp_path, capsys):
    """A folder generated by `--only a` (or `--long`) reported without that selection would get
    "not run" rows for the rest in place of its table: refused, the folder unchanged; the same
    selection in another order is the same selection."""
    folder = _generated_folder(tmp_path / "sel", "eulag study scenes --quick --only c,a", "scene_a.nc")
    _report_refused(capsys, folder, "allowed: --report with the same --only setting", "scenes", "--quick")
    from eulag.studies import runner

    class Args:
        quick, parcels, from_state, window, only, long, study_name = True, None, None, None, "a,c", False, "scenes"
    runner._check_report_settings(Args, folder)  # the same selection: no refusal


@pytest.mark.slow
def test_scenes_quick_all_eight(tmp_path):
    assert study("scenes", "--quick", "--quiet", "-o", tmp_path) == 0
    check_scene_rows(check_report(tmp_path, "scenes", 8), list("abcdefgh"))


# ------------------------------------------------------------------------------ error-runtime

def test_error_runtime_plan_covers_the_axes_of_the_issue():
    case = studies._base_case(False, BASE)  # at the studies' resolution, not the file's default
    for quick in (False, True):
        runs, ref = studies.error_runtime_plan(case, quick)
        settings = runs + [ref]
        assert len({s.grid for s in settings}) >= 3
        assert len({s.parcels for s in settings}) >= 4
        assert len({s.step_factor for s in settings}) == 2
        assert {s.step_rule for s in settings} == {"default", "paper"}
        # the reference is the finest setting of every axis
        assert ref.parcels == max(s.parcels for s in settings)
        assert ref.step_factor == min(s.step_factor for s in settings)
        assert ref.grid == max((s.grid for s in settings), key=lambda g: g[0] * g[1] * g[2])
        if not quick:
            assert min(s.parcels for s in settings) == 10_000
            assert ref.grid == (400, 20, 40)


def test_the_base_case_runs_at_the_study_resolution_wherever_its_file_lies(tmp_path):
    copy = tmp_path / "copy.toml"
    copy.write_text(BASE.read_text())
    n = studies._base_case(False, copy).numerics
    assert (n.axial_cells, n.radial_cells, n.azimuthal_cells, n.parcels) == (400, 20, 40, 240_000)
    own = Case.from_toml(BASE).numerics  # the file's default: error-runtime's Pareto-best
    assert (own.axial_cells, own.radial_cells, own.azimuthal_cells, own.parcels) == (200, 10, 20, 30_000)
    # a case with numerics of its own keeps them
    changed = tmp_path / "changed.toml"
    changed.write_text(BASE.read_text().replace("axial_cells = 200", "axial_cells = 160"))
    assert studies._base_case(False, changed).numerics.axial_cells == 160


@pytest.mark.slow
def test_error_runtime_quick(tmp_path):
    """The quick study end to end: nine coupled loops, one of them with the paper's step rule, a
    kernel of its own (46 s from a cold numba cache, so in the slow set; the plan is tested by
    test_error_runtime_plan_covers_the_axes_of_the_issue, the Pareto front and the profile
    deviation by the tests below)."""
    assert study("error-runtime", BASE, "--quick", "--quiet", "-o", tmp_path) == 0
    table = check_report(tmp_path, "error-runtime", 9)
    assert len(list(tmp_path.glob("*.nc"))) == 9
    assert (tmp_path / "error_runtime.png").stat().st_size > 10_000
    others = [r for r in table if r["axis"] != "reference"]
    assert {r["axis"] for r in others} == {"centre", "grid", "parcels", "step factor", "step rule"}
    for r in others:
        total, disc = number(r["err_total"]), number(r["err_disc"])
        assert np.isfinite(total) and 0.0 <= disc <= total + 1e-12
        assert number(r["noise_particle"]) > 0.0
        assert np.isfinite(number(r["meas_gas"])) and np.isfinite(number(r["meas_particle"]))
    # the front takes converged runs against a converged reference only (the quick runs stop at
    # their pass limit, so there it is empty and the README says so)
    ref_ok = next(r for r in table if r["axis"] == "reference")["converged"] == "yes"
    front = [r for r in others if r["pareto"].startswith("yes")]
    assert all(r["converged"] == "yes" for r in front) and (ref_ok or not front)
    assert sum("best" in r["pareto"] for r in others) == (1 if front else 0)
    text = (tmp_path / "README.md").read_text()
    assert "Pareto front" in text and (front or "no converged run" in text or "reference run did not" in text)
    # the front over the converged runs only: the records edited to say so, then --report
    for p in tmp_path.glob("*.nc"):
        p.unlink()  # reported from the records
    converged = {"centre", "grid_10x4x8"}
    for name in converged | {"reference"}:
        rec = tmp_path / f"{name}.record.json"
        data = json.loads(rec.read_text())
        data["status"] = "converged"
        rec.write_text(json.dumps(data))
    assert study("error-runtime", BASE, "--quick", "--quiet", "--report", "-o", tmp_path) == 0
    table = check_report(tmp_path, "error-runtime", 9)
    front = {r["run"] for r in table if r["pareto"].startswith("yes")}
    assert front and front <= converged, front
    assert sum("best" in r["pareto"] for r in table) == 1


# ------------------------------------------------------------------------------ stability

def test_parcels_option_lightens_every_run_but_the_million_parcel_case():
    for name, case in studies.tsuji_morikawa_cases(quick=False, parcels=20_000):
        assert case.numerics.parcels == 20_000 and case.numerics.parcels_start == 20_000
    assert all(c.numerics.parcels == 5000 for _, c in studies.scene_cases(False, parcels=5000))
    cases = {name: c for name, _, c in studies.stability_cases(quick=False, parcels=20_000)}
    assert cases["parcels_1e6"].numerics.parcels == 1_000_000
    assert cases["U0_5"].numerics.parcels == 20_000


def test_stability_cases_cover_the_issue_list():
    specs = studies.stability_cases(quick=False)
    names = [s[0] for s in specs]
    assert names == ["tracers_1um", "pellets_3.4mm", "loading_eta10", "loading_eta30", "roughness_20deg",
                     "U0_5", "U0_30", "pipe_0.3m_Re1e6", "cells_4x", "parcels_1e6"]
    cases = {name: case for name, _, case in specs}
    assert cases["pipe_0.3m_Re1e6"].reynolds_number == pytest.approx(1e6)
    assert cases["parcels_1e6"].numerics.parcels == 1_000_000
    n0, n4 = studies._base_case(False).numerics, cases["cells_4x"].numerics
    assert (n4.axial_cells * n4.radial_cells * n4.azimuthal_cells
            == 4 * n0.axial_cells * n0.radial_cells * n0.azimuthal_cells)


def check_stability_rows(table):
    for r in table:
        assert r["converged"] in ("yes", "no", "failed", "rejected")
        if r["converged"] in ("yes", "no"):
            assert int(r["lost"]) == 0
            assert r["nonfinite"] == "none"
            assert number(r["k_min"]) > 0 and number(r["eps_min"]) > 0
            assert int(r["stuck_total"]) >= 0
            assert 0.05 <= number(r["relax_min"]) <= 1.0
        if r["converged"] != "yes":
            assert r["first_wrong"]  # a diagnosis


def test_stability_quick_subset(tmp_path):
    only = "pellets_3.4mm,U0_5,loading_eta30"
    assert study("stability", "--quick", "--quiet", "--only", only, "-o", tmp_path) == 0
    table = check_report(tmp_path, "stability", 3)
    assert [r["case"] for r in table] == ["pellets_3.4mm", "loading_eta30", "U0_5"]  # the study's order
    check_stability_rows(table)
    assert (tmp_path / "stability_history.png").is_file()
    assert "3.4 mm pellets" in (tmp_path / "README.md").read_text()


def test_stability_quick_large_pipe_gets_the_rings_its_wall_cell_needs():
    from rans.mesh import MAX_RING_GROWTH, radial_growth, wall_cell_thickness

    cases = {name: c for name, _, c in studies.stability_cases(quick=True)}
    pipe = cases["pipe_0.3m_Re1e6"]
    assert isinstance(pipe, Case) and pipe.numerics.radial_cells == 6  # the quick grid's 5 grow 6.4 per ring
    g = pipe.gas
    wall, _ = wall_cell_thickness(0.3, pipe.numerics.first_cell_yplus, g.bulk_velocity, g.density, g.viscosity)
    assert radial_growth(0.15, 6, wall) <= MAX_RING_GROWTH
    assert all(c.numerics.radial_cells == 5 for n, c in cases.items() if n not in ("pipe_0.3m_Re1e6", "cells_4x"))


@pytest.mark.slow
def test_stability_quick_all(tmp_path):
    assert study("stability", "--quick", "--quiet", "-o", tmp_path) == 0
    check_stability_rows(check_report(tmp_path, "stability", 10))


def test_a_failing_run_is_recorded_with_its_diagnosis(tmp_path, monkeypatch):
    import eulag.runs as runs

    calls = []

    def failing_run(case, out=None, **kw):
        calls.append(case.name)
        raise runs.RunError("pass 2: k < 0 in cell (3, 4, 7) after the gas solve")

    monkeypatch.setattr(runs, "execute", failing_run)
    case = studies._quick(Case.from_toml(BASE))
    args = SimpleNamespace(resume=False, quiet=True)
    # a record of an earlier success must not outlive the failed re-run
    studies.write_record(tmp_path / "boom.record.json", case,
                         studies.RunRecord("boom", case, tmp_path / "boom.nc", "converged", passes=3))
    rec = studies.run_case(args, "boom", case, tmp_path, "boom")
    assert rec.status == "failed" and "k < 0" in rec.message and not rec.ok
    assert (tmp_path / "boom.failed.json").is_file() and not (tmp_path / "boom.nc").exists()
    assert not (tmp_path / "boom.record.json").exists()
    n = len(calls)
    again = studies.run_case(SimpleNamespace(resume=True, quiet=True), "boom", case, tmp_path, "boom")
    assert again.reused and again.status == "failed" and len(calls) == n  # not run again
    import eulag

    assert again.metrics["commit"] == eulag.git_commit()  # the code that failed is named
    # a whole study goes on and reports it; failures are results of the stability study
    assert study("stability", "--quick", "--quiet", "--only", "U0_30,eta", "-o", tmp_path) == 2
    assert study("stability", "--quick", "--quiet", "--only", "U0_30", "-o", tmp_path) == 0
    table = rows(tmp_path / "stability.csv")
    assert table[0]["converged"] == "failed" and "k < 0" in table[0]["first_wrong"]
    # ... while the other studies exit 1 when a run failed, after writing their table
    assert study("scenes", "--quick", "--quiet", "--only", "a", "-o", tmp_path / "sc") == 1
    assert "failed: pass 2: k < 0" in (tmp_path / "sc" / "README.md").read_text()


# ------------------------------------------------------------------------------ helpers

def test_pareto_front_keeps_the_non_dominated_points():
    t = [1.0, 2.0, 3.0, 4.0, 2.5, math.nan]
    e = [10.0, 5.0, 6.0, 1.0, 5.0, 0.1]
    assert studies.pareto_front(t, e) == [0, 1, 3]


def test_profile_deviation_in_percent():
    d = studies.profile_deviation([1.0, 1.1, np.nan], [1.0, 1.0, 1.0], se=[0.01, 0.03, 0.02])
    assert d["points"] == 2
    assert d["rms"] == pytest.approx(100 * math.sqrt(0.01 / 2))
    assert d["max"] == pytest.approx(10.0) and d["bias"] == pytest.approx(5.0)
    assert d["stderr"] == pytest.approx(100 * math.sqrt((0.01**2 + 0.03**2) / 2))


# ------------------------------------------------------------------------------ bad input

@pytest.mark.parametrize("argv, message", [
    (["study"], "required"),
    (["study", "nonsense"], "invalid choice"),
    (["study", "error-runtime", "no_such_case.toml", "--quick"], "no such case file"),
    (["study", "error-runtime", CASES_DIR / "single_phase_pipe.toml", "--quick"], "single-phase"),
    (["study", "scenes", "--quick", "--only", "a,z"], "unknown scenes z"),
    (["study", "stability", "--quick", "--only", "tracers"], "unknown cases tracers"),
    (["study", "tsuji-morikawa", "--quick", "--frobnicate"], "unrecognized arguments"),
    (["study", "scenes", "--quick", "--parcels", "0"], "out of range"),
    (["study", "error-runtime", BASE, "--parcels", "100"], "unrecognized arguments"),
])
def test_bad_input_exits_2_with_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("eulag: error:") and message in err[0]
    assert not (tmp_path / "results").exists() or not any((tmp_path / "results").rglob("*.nc"))


def test_output_dir_that_is_a_file_exits_2(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert study("scenes", "--quick", "-o", f) == 2
    assert "not a directory" in capsys.readouterr().err


def test_floored_cells_are_located_in_the_final_field():
    """The stability table says where k/ε sit at their floor: axial range and wall-ring count."""
    import xarray as xr

    from eulag.studies import _floored_cell, _floored_where
    from rans.kepsilon import C_MU
    from rans.solver import K_FLOOR

    u0, d = 10.0, 0.03
    k_floor = K_FLOOR * u0**2
    x = np.linspace(0.05, 3.95, 40)
    k = np.full((40, 5, 8), 0.5)
    eps = np.full_like(k, 10.0)
    k[3:7, 0:2, :] = k_floor                          # the core of x = 0.35-0.65 m
    eps[30, 4, 2] = C_MU * k_floor**1.5 / d           # one wall-ring cell with epsilon at its floor
    ds = xr.Dataset({"gas_k": (("x", "r", "theta"), k), "gas_epsilon": (("x", "r", "theta"), eps)},
                    coords={"x": x}, attrs={"gas.bulk_velocity": u0, "pipe.diameter": d})
    where = _floored_where(ds)
    assert where["floored_x"] == [pytest.approx(x[3]), pytest.approx(x[30])]
    assert where["floored_wall"] == 1
    text = _floored_cell({"floored_last": 65, "floored_max": 70, **where})
    assert text.startswith("65 (max 70); final field: x = ") and "1 in the wall ring" in text
    k[3:7, 0:2, :] = 2.0 * k_floor                    # above the floor: not counted
    eps[30, 4, 2] = 10.0
    assert _floored_where(ds) == {}


def test_an_unconverged_gas_solve_is_located_in_the_record(tmp_path):
    """A run whose gas march stopped short at some stations says which, where, and how far their
    last iteration still moved the velocity and k/eps: from the per-station record of a real
    (small) march given three iterations per station."""
    import xarray as xr

    from eulag.output import gas_dataset
    from eulag.studies import _gas_not_converged
    from rans import GasProperties, PipeMesh, solve

    case = Case.from_toml(CASES_DIR / "single_phase_pipe.toml")
    mesh = PipeMesh.build(0.03, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                          bulk_velocity=10.0, density=1.205, viscosity=1.81e-5)
    f = solve(mesh, GasProperties(), 10.0, tol=1e-9, station_iterations=(2, 3))
    ds = gas_dataset(case, mesh, f)
    ds.to_netcdf(tmp_path / "g.nc")
    ds = xr.open_dataset(tmp_path / "g.nc")
    bad = ~f.station_converged
    assert ds.attrs["gas_converged"] == "false" and bad.any()
    assert np.array_equal(ds["gas_station_converged"].values == 0, bad)
    text = _gas_not_converged(ds, 1e-9)
    assert text.startswith(f"gas solve not converged at {bad.sum()} of 12 stations (x = ")
    assert f"{f.station_change[bad, 0].max():.1e} U_b" in text
    assert f"k/eps by {f.station_change[bad, 1].max():.1e}" in text
    assert _gas_not_converged(ds.drop_vars("gas_station_converged"), 1e-9) == "gas solve not converged"


def test_a_run_failing_after_a_resume_keeps_its_earlier_passes(tmp_path):
    """The failed record of a resumed run counts the passes run before the resume: their
    residuals and relaxations (from the checkpoint) and their time."""
    from types import SimpleNamespace

    from eulag.studies import _resumed_part

    ckpt = tmp_path / "run.nc.checkpoint"
    with open(ckpt, "wb") as f:  # (a path without .npz would get one appended)
        np.savez(f, hist_residual=[np.nan, 10.4, 10.1, 12.5, 11.3, 14.4, 27.2],
                 hist_relaxation=[0.3] * 7, hist_time_gas=[136.4, 85.5, 150.2, 165.1, 161.4, 166.5, 143.9],
                 hist_time_particles=[2.8, 40.9, 33.7, 29.9, 31.5, 29.7, 30.9])
    history = [SimpleNamespace(index=7, residual=27.2, relaxation=0.3),
               SimpleNamespace(index=8, residual=19.0, relaxation=0.3)]
    hist = {"residual_history": [27.2, 19.0], "relaxation_history": [0.3, 0.3]}
    t, n = _resumed_part(ckpt, history, hist)
    assert n == 6 and t == pytest.approx(136.4 + 85.5 + 150.2 + 165.1 + 161.4 + 166.5
                                         + 2.8 + 40.9 + 33.7 + 29.9 + 31.5 + 29.7)
    assert hist["residual_history"][1:] == [10.4, 10.1, 12.5, 11.3, 14.4, 27.2, 19.0]
    assert len(hist["relaxation_history"]) == 8
    # failed in the first pass after the resume: every pass of the checkpoint came before
    none = {"residual_history": [], "relaxation_history": []}
    t, n = _resumed_part(ckpt, [], none)
    assert n == 7 and t == pytest.approx(1009.0 + 199.4) and len(none["residual_history"]) == 7
    fresh = {"residual_history": [1.0], "relaxation_history": [0.3]}
    assert _resumed_part(ckpt, [SimpleNamespace(index=1)], fresh) == (0.0, 0)  # nothing resumed
    assert fresh["residual_history"] == [1.0]


def test_ablation_variants_follow_the_scene():
    """A two-way proxy gets no collision-only variant; ingredient switches only on request; the
    two-way scenes' match column also checks the paper's sense of the main pair."""
    from eulag.studies.ablation import _matches, ablation_cases

    two_way = [label for _, _, label, _ in ablation_cases(False, "c")]
    four_way = [label for _, _, label, _ in ablation_cases(False, "d")]
    assert "partner_momentum=discarded" in four_way and "partner_momentum=discarded" not in two_way
    assert two_way[0] == "eulag" and two_way[-1] == "paper"
    assert not any("lift" in label for label in four_way)
    [(_, _, label, case)] = ablation_cases(False, "c", ["magnus_lift=false"])
    assert label == "magnus_lift=false" and case.physics.magnus_lift is False
    assert _matches(2, "down on the axis", 2, "up on the axis") == "no (sense)"
    assert _matches(2, "up on the axis", 2, "up on the axis") == "yes"
    assert _matches(4, "up on the axis", 2, "up on the axis") == "no"
    assert _matches(4, "down on the axis", 4) == "yes"
