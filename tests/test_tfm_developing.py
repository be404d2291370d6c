"""The developing two-fluid pipe (tfm.developing; ``numerics.mode = "developing"``): the paper's
inlet (eqs. 20–23), the solids mass flow carried from station to station, the gas-only limit
against Colebrook, the axial momentum balance of the marched equations, step-size convergence,
and checkpoint/resume.  Small meshes and short pipes (fast)."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

import eulag.two_fluid as tf
from eulag.two_fluid import problem_from_case, run_two_fluid, validate_two_fluid_case
from tfm.developing import axial_stations, inlet_state, march_pipe
from tfm.inlet import hinkle_1953_solids_velocity, inlet_solids_fraction
from tfm.section import _Solver

CASES = Path(__file__).resolve().parent.parent / "cases" / "two_fluid"


def small_case(nr=8, nt=16, length=0.3, **numerics):
    case = tomllib.loads((CASES / "ding_qs0.8.toml").read_text())
    case["numerics"].update(radial_cells=nr, azimuthal_cells=nt, mode="developing", **numerics)
    case["pipe"]["length"] = length
    return case


def test_stations_grow_geometrically_and_end_at_the_length():
    xs = axial_stations(1.0, 0.01, 1.5, 0.1)
    steps = np.diff(np.concatenate([[0.0], xs]))
    assert xs[-1] == 1.0
    assert steps[:4] == pytest.approx([0.01, 0.015, 0.0225, 0.03375])
    assert steps[:-1].max() <= 0.1 + 1e-12 and steps[-1] >= 0.25 * 0.1 - 1e-12
    with pytest.raises(ValueError, match="growth"):
        axial_stations(1.0, 0.01, 0.9, 0.1)


def test_max_step_below_first_step_is_one_clear_line():
    case = small_case(first_step_diameters=2.0, max_step_diameters=1.0)
    with pytest.raises(ValueError, match=r"^numerics.max_step_diameters = 1.0: allowed a number >= "
                                         r"numerics.first_step_diameters \(2.0\)$"):
        validate_two_fluid_case(case)


def test_inlet_is_the_papers_uniform_suspension_with_power_law_profiles():
    """Eqs. 20–23: α_s,inlet = 4 M_s/(ρ_s u_s π D²) with Hinkle's u_s; mean gas velocity
    U_g/(1 − α_s), mean solids velocity u_s (1/7-power profiles, zero-free at the wall cells)."""
    pb = problem_from_case(small_case())
    s = _Solver(pb)
    st = inlet_state(s)
    us = hinkle_1953_solids_velocity(pb.u_g, pb.d_s, pb.rho_s, pb.rho_g, pb.diameter)
    a = inlet_solids_fraction(pb.m_s, pb.rho_s, us, pb.diameter)
    assert a == pytest.approx(0.2458, abs=2e-4)      # Table 1 gives 0.245 for this row
    assert np.all(st.alpha == a)
    assert np.sum(st.us * s.A) / s.Atot == pytest.approx(us, rel=1e-12)
    assert np.sum(st.ug * s.A) / s.Atot == pytest.approx(pb.u_g / (1 - a), rel=1e-12)
    assert st.ug.max() > 1.1 * st.ug.min()           # a profile, not a plug
    # the 1/7-power shape (1 − r/R)^(1/7) of eqs. 20–21 in both phases, cell by cell
    shape = (1.0 - np.hypot(s.sec.cz, s.sec.cy) / (0.5 * pb.diameter)) ** (1.0 / 7.0)
    assert np.allclose(st.us / st.us.max(), shape / shape.max(), rtol=1e-12)
    assert np.allclose(st.ug / st.ug.max(), shape / shape.max(), rtol=1e-12)


@pytest.fixture(scope="module")
def march08():
    pb = problem_from_case(small_case())
    return pb, march_pipe(pb, 0.3)


def test_solids_mass_flow_is_carried_from_station_to_station(march08):
    pb, r = march08
    assert r.converged.all()
    assert np.max(np.abs(r.solids_mass_flow / pb.m_s - 1.0)) < 1e-4
    # the solids accelerate from the Hinkle velocity: the holdup falls below the inlet's
    assert r.holdup.min() < 0.95 * r.inlet["alpha_s"]


def test_marched_pressure_drop_is_wall_shear_plus_axial_momentum_change():
    """Summed over the section, drag and stresses cancel: G A = wall forces + the convected momentum
    change Σ ρ α u_up (u − u_up) A/Δx of both phases, at every station (from the solver's own wall
    coefficients at the converged state).  Over the pipe, the convected change is the physical
    momentum-flux change ∫ρ α u² dA (out − in) up to the in-plane convection of axial momentum by
    the drift flux, which the marching neglects (stated)."""
    pb = problem_from_case(small_case())
    s = _Solver(pb)
    rec = []

    def cb(i, x, st, row):
        c = s.closures(st)
        s.momentum(st, c)      # the wall coefficients at this state (conv still that of this station)
        w, arc = s.sec.wall, s.sec.wall_arc
        walls = np.sum(s.hg * st.ug[w] * arc) + np.sum(s.hs * st.us[w] * arc)
        cv = s.conv
        conv = np.sum(cv["cg"] * (st.ug - cv["ug"]) * s.A) + np.sum(cv["cs"] * (st.us - cv["us"]) * s.A)
        rec.append((st.G * s.Atot, walls, conv, cv["dx"]))

    r = march_pipe(pb, 0.3, solver=s, callback=cb)
    GA, walls, conv, dx = np.array(rec).T
    # the stored state is the relaxed iterate: the balance holds to the outer tolerance (a check
    # of the discretisation's conservation: the rows of the linear systems sum to it)
    assert np.max(np.abs(GA / (walls + conv) - 1.0)) < 5e-3
    st_in = inlet_state(_Solver(pb))

    def flux(st):
        return np.sum((pb.rho_g * (1 - st.alpha) * st.ug**2 + pb.rho_s * st.alpha * st.us**2) * s.A)

    physical = flux(r.state) - flux(st_in)
    print(f"convected {np.sum(conv * dx):.5g} N, physical {physical:.5g} N, walls {np.sum(walls * dx):.5g} N")
    # the physical check: the convected momentum the march books equals the change of the
    # momentum flux between the inlet and the last station
    assert np.sum(conv * dx) == pytest.approx(physical, rel=0.05)   # measured: 2.7 %
    assert np.sum(GA * dx) == pytest.approx(r.pressure_drop[-1] * s.Atot, rel=1e-12)  # bookkeeping


def test_gas_only_march_develops_to_colebrook():
    """Vanishing solids flow: from the 1/7-power inlet the marched −dp/dx settles, within 60 D, to
    the developed section's value, and that is Colebrook's smooth-pipe value (fluids.friction)
    within the 6 % of the developed section's own test (measured −4.2 %)."""
    from fluids.friction import Colebrook
    case = small_case(length=0.6)
    case["solids"]["mass_flow"] = 1e-6
    pb = problem_from_case(case)
    r = march_pipe(pb, 0.6)
    s = _Solver(pb)
    st, ok, _ = s.run(s.initial_state())
    assert ok and r.converged.all()
    assert r.G[-1] == pytest.approx(st.G, rel=0.01)
    re = pb.rho_g * pb.u_g * pb.diameter / pb.mu_g
    assert r.G[-1] == pytest.approx(Colebrook(re, 0.0) / pb.diameter * 0.5 * pb.rho_g * pb.u_g**2, rel=0.06)


def test_pressure_drop_converges_with_the_axial_step():
    """Scaling every step (first step, growth − 1, largest step) by 2, 1 and 1/2: the changes of
    Δp shrink as the march's order says (here 8 x 16 over 0.3 m: 4148.6, 4180.8, 4199.9 Pa, the
    differences 32.2 and 19.1 Pa, ratio 0.59; first order would halve them, the steps' growth
    term converges faster), and the last is < 0.5 % of Δp (on the 16 x 32 mesh over 2.4 m:
    9.015, 9.025, 9.031 kPa)."""
    pb = problem_from_case(small_case())
    D = pb.diameter
    dps = [march_pipe(pb, 0.3, first_step=f * 0.25 * D, growth=1 + f * 0.08, max_step=f * 2.5 * D).pressure_drop[-1]
           for f in (2.0, 1.0, 0.5)]
    ratio = (dps[2] - dps[1]) / (dps[1] - dps[0])
    assert 0.4 < ratio < 0.75, (dps, ratio)
    assert dps[2] == pytest.approx(dps[1], rel=5e-3)


def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path, monkeypatch):
    case = small_case(nr=6, nt=12, length=0.1)
    whole = run_two_fluid(case, tmp_path / "whole.nc")
    assert whole.attrs["converged"] == "true" and whole.sizes["x"] > 12
    assert float(whole.pressure_drop) == pytest.approx(float(whole.pressure[-1]) * -1, rel=1e-12)
    real, calls = tf._station_fields, []

    def crash(st, c):
        calls.append(1)
        if len(calls) > 12:
            raise KeyboardInterrupt("killed")
        return real(st, c)

    out = tmp_path / "cut.nc"
    monkeypatch.setattr(tf, "_station_fields", crash)
    with pytest.raises(KeyboardInterrupt):
        run_two_fluid(case, out)
    monkeypatch.setattr(tf, "_station_fields", real)
    assert not out.exists() and tf.checkpoint_path(out).is_file()
    with np.load(tf.checkpoint_path(out)) as z:
        before = float(z["time_total"])  # the killed session's wall time
    again = run_two_fluid(case, out, resume=True)
    assert again.attrs["time_total"] > before > 0
    assert not tf.checkpoint_path(out).exists()
    for v in ("gas_ux", "solids_ux", "solids_fraction", "pressure_gradient", "pressure_drop", "gas_k"):
        np.testing.assert_array_equal(again[v].values, whole[v].values)


def test_a_torn_checkpoint_counts_as_none(tmp_path):
    case = small_case(nr=6, nt=12, length=0.03)
    out = tmp_path / "tf.nc"
    tf.checkpoint_path(out).write_bytes(b"PK\x03\x04 torn")
    ds = run_two_fluid(case, out, resume=True)
    fresh = run_two_fluid(case, tmp_path / "fresh.nc")
    assert ds.attrs["converged"] == "true"
    np.testing.assert_array_equal(ds["pressure_gradient"].values, fresh["pressure_gradient"].values)


def test_a_station_that_loses_solids_is_reported_unconverged(tmp_path):
    """Without friction and with α_max just above the inlet α_s, the packing cap (α_max − 0.02)
    binds at the first stations and removes solids: those stations must not count as converged
    (measured: 0.5 % and 0.7 % of M_s lost at stations 1 and 2)."""
    case = small_case(nr=6, nt=12, length=0.05, max_iterations=60)
    case["friction"].update(model="none", alpha_min=0.1, alpha_max=0.268)
    ds = run_two_fluid(case, tmp_path / "cap.nc")
    assert ds.attrs["converged"] == "false"
    assert ds.attrs["stop_reason"].startswith("not converged: 2 of ")
    assert "first: station 1," in ds.attrs["stop_reason"]
    assert ds["station_converged"].values[:2].tolist() == [0, 0]
    assert ds["solids_mass_flow_x"].values[1] < 0.995 * 0.194
