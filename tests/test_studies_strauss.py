"""eulag study strauss: the plan holds the paper's runs; the quick mode runs end to end through
the run layer and writes its table (Markdown + CSV), figures and README section (keeping the
hand-written text around it); --report reuses the records without running; bad options exit 2
with one line; the regime classifier (SMH Fig. 3) on synthetic datasets.

Quick-mode numbers are not results: the tests check the machinery, never specific values.
"""

import csv
import json
import math

import numpy as np
import pytest
import xarray as xr

from eulag import slug, studies
from eulag.cli import main
from eulag.studies import strauss
from tests.slug_support import killed_after_checkpoint


def study(*argv):
    return main(["study", "strauss", *[str(a) for a in argv]])


def rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# ---------------------------------------------------------------------------- plan
def test_registered_and_the_full_plan():
    assert "strauss" in studies.STUDIES
    plan = studies.strauss_cases(False)
    default = plan["strauss__vs-1.0__feed-2.49"]
    assert set(default[0]) >= {"default", "curves", "mass-flux", "viscosity", "friction"}
    assert default[2].data["numerics"]["end_time_s"] == 4.0
    curves = [(i["feed"], i["vs"]) for n, (g, i, c) in plan.items() if "curves" in g]
    assert sorted(curves) == sorted((f, v) for f in (2.49, 9.95) for v in strauss.VELOCITIES)
    assert min(v for _, v in curves) <= 0.2 and max(v for _, v in curves) >= 5.0
    for n, (g, i, c) in plan.items():
        d = c.data
        assert d["gas"]["superficial_velocity_m_s"] == i["vs"] and d["feed"]["mass_flow_kg_h"] == i["feed"]
        assert d["gas"]["viscosity_Pa_s"] == pytest.approx(i["eta_cP"] * 1e-3)
        assert d["grains"]["friction"] == d["grains"]["wall_friction"] == i["mu"]
        slug.validate_slug_case(d)
    assert {i["eta_cP"] for n, (g, i, c) in plan.items() if "viscosity" in g} == {0.045, 0.0673, 0.085}
    vertical = plan["strauss_vertical__vs-1.0__feed-2.49"][2].data
    assert vertical["tube"]["orientation"] == "vertical"
    assert vertical["numerics"]["end_time_s"] == 12.0  # the tube fills until t ≈ 5.7 s
    assert strauss.window_of(vertical)[0] == 6.0
    assert not any("long" in g for g, _, _ in plan.values())
    long = studies.strauss_cases(False, long=True)
    assert long["strauss__vs-1.0__feed-2.49__t-22.5"][2].data["numerics"]["end_time_s"] == 22.5
    short = studies.strauss_cases(False, ["curves"], feeds=(2.49,), velocities=(0.2, 5.0), window=1.5)
    assert sorted(short) == ["strauss__vs-0.2__feed-2.49__t-1.5", "strauss__vs-5.0__feed-2.49__t-1.5"]


# ---------------------------------------------------------------------------- regime
def _synthetic(phi, u, n_tube, outflow=None, periodic=False, dt=0.01):
    """A slug dataset with the given porosity and grain velocity (time, x) on the paper's tube."""
    case = slug.validate_slug_case(json.loads(json.dumps(strauss._load("strauss_horizontal").data)))
    case["tube"]["periodic"] = periodic
    nt, nx = phi.shape
    t = (np.arange(nt) + 1) * dt
    x = (np.arange(nx) + 0.5) * 0.525 / nx
    outflow = np.zeros(nt) if outflow is None else outflow
    return xr.Dataset({"porosity": (("time", "x"), phi), "grain_velocity": (("time", "x"), u),
                       "grains_in_tube": ("time", np.full(nt, float(n_tube))), "outflow_count": ("time", outflow)},
                      coords={"time": t, "x": x},
                      attrs={"case": json.dumps(case), "feed_speed_m_s": 0.0446})


def test_a_resting_packing_is_resting_bulk():
    """The first 60 slices a packing of porosity 0.5 pushed at the feed speed, the rest empty."""
    phi = np.ones((100, 150))
    phi[:, :60] = 0.5
    u = np.where(phi < 0.6, 0.0446 * 0.86, 0.0)  # compacted below the feed porosity: slower than v_feed
    r = strauss.classify_regime(_synthetic(phi, u, 2000), t_min=0.5)
    assert r["regime"] == "resting bulk"
    assert r["dense_share"] == pytest.approx(1.0) and r["moving_share"] == 0.0
    assert r["outflow_per_feed"] == 0.0


def _moving_slug(speed, nt=100, nx=150):
    """One slug of 15 slices moving at ``speed`` over a resting layer of porosity 0.9."""
    phi = np.full((nt, nx), 0.9)
    u = np.zeros((nt, nx))
    for k in range(nt):
        i0 = int((0.05 + speed * (k + 1) * 0.01) / 0.0035) % (nx - 15)
        phi[k, i0:i0 + 15] = 0.5
        u[k, i0:i0 + 15] = speed
    return phi, u


def test_a_moving_slug_is_slugs_and_a_creeping_one_is_not():
    phi, u = _moving_slug(0.35)
    r = strauss.classify_regime(_synthetic(phi, u, 1500), t_min=0.0)
    assert r["regime"] == "slugs"
    assert r["dense_share"] < 0.5 and r["moving_share"] == pytest.approx(1.0)  # a resting layer holds more
    assert r["moving_share_all"] < 0.5
    assert r["dense_velocity_m_s"] == pytest.approx(0.35)
    # the same slug no faster than the feed pushes it: the gas does not move it
    phi, u = _moving_slug(0.05)
    assert strauss.classify_regime(_synthetic(phi, u, 1500), t_min=0.0)["regime"] == "resting bulk"


def test_an_empty_tube_and_outflow_per_feed():
    nt = 100
    phi = np.full((nt, 150), 0.98)
    u = np.full((nt, 150), 1.5)
    # the feed (2.49 kg/h: 514 grains/s) leaves at the outlet
    m_p = 937.0 * math.pi * 1.4e-3 ** 3 / 6
    rate = 2.49 / 3600 / m_p
    outflow = rate * (np.arange(nt) + 1) * 0.01
    r = strauss.classify_regime(_synthetic(phi, u, 40, outflow=outflow), t_min=0.5)
    assert r["regime"] == "nearly empty tube" and r["dense_share"] == 0.0
    assert r["outflow_per_feed"] == pytest.approx(1.0, rel=1e-9)
    # a run continued from a saved state at t = 13.25 s counts its outflow from there: a window
    # from its first record measures the outflow over 13.25 s to its end, not over 0 to its end
    later = _synthetic(phi, u, 40, outflow=outflow)
    later = later.assign_coords(time=later.time.values + 13.25)
    assert strauss.classify_regime(later)["outflow_per_feed"] == pytest.approx(1.0, rel=1e-9)
    assert strauss.classify_regime(later, t_min=13.75)["outflow_per_feed"] == pytest.approx(1.0, rel=1e-9)
    # t_max ends a window: the feed's rate leaves for 0.5 s, then three times it
    k = np.arange(nt) + 1
    burst = later.assign(outflow_count=("time", rate * 0.01 * np.where(k <= 50, k, 50 + 3 * (k - 50))))
    assert strauss.classify_regime(burst, t_max=13.75)["outflow_per_feed"] == pytest.approx(1.0, rel=1e-9)
    assert strauss.classify_regime(burst, t_min=13.76)["outflow_per_feed"] == pytest.approx(3.0, rel=1e-9)
    assert strauss.classify_regime(burst)["outflow_per_feed"] == pytest.approx(2.0, rel=1e-9)
    # a few dense slices at the inlet, pushed by the feed, do not make slugs: the dispersed grains
    # hold and carry most of the solids
    phi[:, :3] = 0.55
    u[:, :3] = 0.04
    assert strauss.classify_regime(_synthetic(phi, u, 40), t_min=0.0)["regime"] == "nearly empty tube"
    # no grains at all
    none = _synthetic(np.ones((10, 150)), np.zeros((10, 150)), 0)
    assert strauss.classify_regime(none)["regime"] == "nearly empty tube"


# ---------------------------------------------------------------------------- the study
def test_quick_runs_end_to_end_and_report_reuses_the_records(tmp_path, capsys):
    out = tmp_path / "strauss"
    out.mkdir()
    (out / "README.md").write_text("# Hand-written\n\nA table of runs made by hand: 736 Pa/m.\n")
    assert study("--quick", "--quiet", "-o", out) == 0
    readme = (out / "README.md").read_text()
    assert readme.startswith("# Hand-written") and "736 Pa/m" in readme
    assert readme.count(strauss.BEGIN) == 1 and readme.count(strauss.END) == 1
    assert "Quick mode" in readme and "not results" in readme and "wall time of this invocation" in readme
    assert "Against the paper" in readme and "0.3 (§3.2, Fig. 10)" in readme
    table = rows(out / "strauss.csv")
    plan = studies.strauss_cases(True)
    assert [r["run"] for r in table] == list(plan)
    for r in table:
        assert r["status"] == "yes" and int(r["lost"]) == 0
        assert math.isfinite(float(r["dp"])) and float(r["grains"]) >= 0
        assert r["regime"] in strauss.REGIMES
    for fig in ("fig3_characteristic_curves", "fig5_mass_flux", "fig6_viscosity", "fig7_friction",
                "spacetime_strauss__vs-1.0__feed-2.49__quick", "slug_profiles_strauss__vs-1.0__feed-2.49__quick"):
        assert f"]({fig}.png)" in readme
    for ln in readme.splitlines():  # every figure the README shows exists
        if ln.startswith("!["):
            target = out / ln[ln.index("(") + 1: ln.rindex(")")]
            assert target.is_file() and target.stat().st_size > 1000, target
    assert len(list(out.glob("*.record.json"))) == len(plan)

    # --report without the datasets: from the records, nothing run; the section replaced, not added
    for nc in out.glob("*.nc"):
        nc.unlink()
    capsys.readouterr()
    assert study("--quick", "--report", "-o", out) == 0
    err = capsys.readouterr().err
    assert "running" not in err and "reported from its record" in err
    assert not any(out.glob("*.nc"))
    assert rows(out / "strauss.csv") == table
    readme2 = (out / "README.md").read_text()
    assert readme2.count(strauss.BEGIN) == 1 and readme2.startswith("# Hand-written")
    assert "--report" in readme2


@pytest.mark.parametrize("argv, message", [
    (["--quick", "--frobnicate"], "unrecognized arguments"),
    (["--quick", "--only", "curves,spirals"], "unknown groups spirals"),
    (["--only", "long"], "allowed only with --long"),
    (["--quick", "--long"], "not with --quick"),
    (["--feeds", "2.49,-1"], "--feeds 2.49,-1: allowed a comma-separated list of positive numbers"),
    (["--velocities", "fast"], "--velocities fast"),
    (["--window", "0"], "--window 0"),
    (["--quick", "--parcels", "100"], "unrecognized arguments"),
    (["--from-state", "no_such_state.npz"], "--from-state no_such_state.npz: initial.state = 'no_such_state.npz': no such file"),
])
def test_bad_option_exits_2_with_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert study(*argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("eulag: error:") and message in err[0]
    assert not any(tmp_path.rglob("*.nc"))


def test_from_state_continues_the_horizontal_runs(tmp_path, monkeypatch):
    """--from-state: the state of the horizontal case (here after 0.005 s) starts only the
    horizontal runs (every feed rate), each ending the window after the state's time, with its
    statistics over the window's second half; a state of another tube stops with one line."""
    case = slug.validate_slug_case({"model": "dem-darcy", "numerics": {
        "end_time_s": 0.01, "output_interval_s": 0.005, "checkpoint_interval_s": 0.005}})
    killed_after_checkpoint(case, tmp_path / "fill.nc", monkeypatch)
    state = slug.save_state(tmp_path / "fill.nc.checkpoint", tmp_path / "state.npz")
    plan = strauss.study_cases(False, from_state=state)
    assert plan and all(i["orientation"] == "horizontal" for g, i, c in plan.values())
    assert {i["feed"] for g, i, c in plan.values()} == set(strauss.FEEDS) | set(strauss.MASS_FLUX_FEEDS)
    for name, (g, i, c) in plan.items():
        assert "__from-0.005__t-3.0" in name and c.data["numerics"]["end_time_s"] == pytest.approx(3.005)
        assert strauss.window_of(c.data)[0] == pytest.approx(1.505)
    assert {i["eta_cP"] for g, i, c in plan.values()} == set(strauss.VISCOSITIES_CP)
    other = slug.validate_slug_case({"model": "dem-darcy", "tube": {"length_m": 0.07}, "numerics": {
        "cells_x": 20, "end_time_s": 0.01, "output_interval_s": 0.005, "checkpoint_interval_s": 0.005}})
    killed_after_checkpoint(other, tmp_path / "short.nc", monkeypatch)
    monkeypatch.chdir(tmp_path)
    assert study("--from-state", "short.nc.checkpoint", "-o", "out") == 2
    assert study("--from-state", "state.npz", "--only", "vertical", "-o", "out") == 2  # nothing to continue


# ---------------------------------------------------------------------------- against the paper
def test_the_comparison_takes_each_velocity_the_papers_way():
    """SMH give two velocities: the slug velocity of §3 (0.42 m/s) and the maximal granular
    velocity in a slug (0.3 m/s, §3.2 / Fig. 10), and set the vertical plugs' 0.17 m/s beside
    the latter (§4) without saying which it is: the vertical plugs are judged by both.  Each row
    takes its own measure and its own band (± 30 %)."""
    from types import SimpleNamespace

    plan = {"h": (("long",), {"end_s": 22.5}, None), "v": (("vertical",), {"end_s": 10.0}, None)}
    base = {"pressure_drop_Pa": 400.0, "pressure_drop_per_length_Pa_m": 760.0, "grains_in_tube": 3000.0,
            "slug_min_porosity": 0.48, "slug_length_m": 0.035, "slug_grains": 460.0, "grains_lost": 0,
            "max_overlap_per_d": 0.009, "t_from_s": 6.0}
    h = dict(base, slug_velocity_m_s=0.50, slug_max_grain_velocity_m_s=0.40)
    v = dict(base, pressure_drop_Pa=1600.0, slug_velocity_m_s=0.28, slug_max_grain_velocity_m_s=0.215, t_from_s=5.0)
    records = {"h": SimpleNamespace(ok=True, metrics=h), "v": SimpleNamespace(ok=True, metrics=v)}
    rows = {r["quantity"]: r for r in strauss.comparison(plan, records)}
    centres = rows["slug velocity: the slug centres' speed [m/s]"]
    granular = rows["slug velocity: the maximal granular velocity in the slug [m/s]"]
    assert centres["here"].startswith("0.500") and centres["verdict"] == "within"  # 0.42 ± 30 %
    assert granular["here"].startswith("0.400") and granular["verdict"] == "outside"  # 0.3 ± 30 %: ≤ 0.39
    plug = rows["vertical plug velocity: the maximal granular velocity in the plug [m/s]"]
    assert plug["here"].startswith("0.215") and plug["verdict"] == "within"  # 0.17 ± 30 %: ≤ 0.221
    centres = rows["vertical plug velocity: the plug centres' speed [m/s]"]
    assert centres["here"] == "0.280" and centres["verdict"] == "outside"
    assert rows["vertical / horizontal maximal granular velocity"]["here"] == f"{0.215 / 0.40:.2f}"
    v["slug_max_grain_velocity_m_s"] = 0.23
    rows = {r["quantity"]: r for r in strauss.comparison(plan, records)}
    assert rows["vertical plug velocity: the maximal granular velocity in the plug [m/s]"]["verdict"] == "outside"
    # a run still filling over its window (outflow well below the feed) is listed, not judged
    h["outflow_per_feed"], v["outflow_per_feed"] = 0.09, 1.02
    rows = {r["quantity"]: r for r in strauss.comparison(plan, records)}
    assert rows["slug velocity: the slug centres' speed [m/s]"]["verdict"] == \
        "not judged: tube still filling (outflow / feed 0.09)"
    assert rows["vertical plug velocity: the maximal granular velocity in the plug [m/s]"]["verdict"] == "outside"
    assert rows["vertical Δp / horizontal Δp"]["verdict"].startswith("not judged")
    assert rows["vertical / horizontal maximal granular velocity"]["verdict"] == "—"


def test_the_development_table_gives_the_papers_measure_where_the_record_has_it():
    """SMH Fig. 10 is the maximal granular velocity along the tube: its row follows the slug
    centres' when the record holds it, and is left out for records written before it."""
    from types import SimpleNamespace

    dev = [{"x0": 0.0, "x1": 0.05, "records": 10, "velocity": 0.28, "max_velocity": 0.11, "min_porosity": 0.55,
            "grains": 180.0},
           {"x0": 0.05, "x1": 0.1, "records": 10, "velocity": 0.45, "max_velocity": math.nan, "min_porosity": 0.5,
            "grains": 260.0}]
    plan = {"h": (("long",), {"end_s": 22.5}, None)}
    metrics = {"pressure_drop_Pa": 400.0, "t_from_s": 6.0, "development": dev}
    text = "\n".join(strauss._development_text(plan, {"h": SimpleNamespace(ok=True, metrics=metrics)}))
    assert "| max granular velocity [m/s] | 0.11 | — |" in text
    assert "| slug velocity (centres) [m/s] | 0.28 | 0.45 |" in text
    old = [{k: v for k, v in d.items() if k != "max_velocity"} for d in dev]
    text = "\n".join(strauss._development_text(plan, {"h": SimpleNamespace(ok=True, metrics=dict(metrics, development=old))}))
    assert "max granular velocity" not in text and "| min porosity | 0.550 | 0.500 |" in text


def test_the_comparison_judges_the_layers_of_the_cross_section():
    """Fig. 19 / §4: horizontal slugs sheared with the uppermost layer fastest (rank correlation
    ≥ 0.8); vertical plugs at one velocity (wall minus axis layer below 10 % of the mean); runs
    without the records say so instead of a verdict."""
    from types import SimpleNamespace

    plan = {"h": (("long",), {"end_s": 22.5}, None), "v": (("vertical",), {"end_s": 10.0}, None)}
    base = {"pressure_drop_Pa": 400.0, "pressure_drop_per_length_Pa_m": 760.0, "grains_in_tube": 3000.0,
            "grains_lost": 0, "max_overlap_per_d": 0.009, "t_from_s": 6.0}

    def layers(shear, mean, rho):
        return {"coordinate": "height", "records_slug": 40, "records_between": 400,
                "slug": {"layers": 8, "shear_m_s": shear, "mean_velocity_m_s": mean,
                         "rank_correlation_with_layer": rho}, "between": {"layers": 3}}

    h = dict(base, layers=layers(0.18, 0.35, 0.98))
    v = dict(base, layers=layers(-0.074, 0.236, -1.0))
    records = {"h": SimpleNamespace(ok=True, metrics=h), "v": SimpleNamespace(ok=True, metrics=v)}
    rows = {r["quantity"]: r for r in strauss.comparison(plan, records)}
    hr = rows["layers in a slug at half the length: uppermost minus lowest [m/s]"]
    vr = rows["vertical: radial layers in a plug, wall minus axis layer [m/s]"]
    assert hr["verdict"] == "within" and hr["here"].startswith("+0.180 (+51 % of the mean 0.350)")
    assert vr["verdict"] == "outside" and vr["here"].startswith("-0.074 (-31 %")
    v["layers"] = layers(-0.01, 0.236, -0.4)
    h["layers"] = layers(0.05, 0.35, 0.3)
    rows = {r["quantity"]: r for r in strauss.comparison(plan, records)}
    assert rows["vertical: radial layers in a plug, wall minus axis layer [m/s]"]["verdict"] == "within"
    assert rows["layers in a slug at half the length: uppermost minus lowest [m/s]"]["verdict"] == "outside"
    del h["layers"]
    rows = {r["quantity"]: r for r in strauss.comparison(plan, records)}
    row = rows["layers in a slug at half the length: uppermost minus lowest [m/s]"]
    assert row["verdict"] == "—" and row["here"].startswith("no records of the cross-section")


def test_a_slug_runs_record_is_judged_again_by_todays_rules(tmp_path):
    """A record stored as converged (before the overlap rule) whose largest overlap is beyond
    numerics.overlap_limit, or with grains lost, reads as not converged, as its dataset would."""
    from eulag import runs
    from eulag.config import CASES_DIR

    case = runs.load_case(CASES_DIR / "slug" / "periodic_slug.toml")
    path = tmp_path / "p.record.json"
    for metrics, status, words in (({"max_overlap_per_d": 0.03, "grains_lost": 0}, "converged", None),
                                   ({"max_overlap_per_d": 0.09, "grains_lost": 0}, "not converged", "9 % of d"),
                                   ({"max_overlap_per_d": 0.01, "grains_lost": 2}, "not converged", "2 grains lost"),
                                   ({"max_overlap_per_d": 0.01, "grains_lost": 0, "porosity_clipped_cells": 7},
                                    "not converged", "in 7 node-steps"),
                                   ({"max_overlap_per_d": 0.01, "grains_lost": 0, "porosity_clipped_cells": 0},
                                    "converged", None)):
        studies.write_record(path, case, studies.RunRecord("p", case, tmp_path / "p.nc", "converged",
                                                           metrics=metrics))
        rec = studies.read_record(path, case)
        assert rec.status == status and (words is None or words in rec.message), (metrics, rec.message)
