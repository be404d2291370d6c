"""Single-phase pipe flow of the k-epsilon solver against independent numbers:
Colebrook (fluids.friction), the log law, and the OpenFOAM v1912 k-epsilon solution in shared/data."""

import math

import numpy as np
import pytest
from fluids.friction import Colebrook

from rans import GasProperties, PipeMesh, SolverDivergence, Sources, solve
from rans.profiles import axis_value, vertical_profile

from .conftest import read_reference_csv

RHO, MU, D = 1.205, 1.81e-5, 0.0305
GAS = GasProperties(RHO, MU)


def periodic(Re, nr=20, nt=40, D=D, yplus=30.0):
    U = Re * MU / (RHO * D)
    m = PipeMesh.build(D, 1.0, "periodic", radial_cells=nr, azimuthal_cells=nt, first_cell_yplus=yplus,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    return m, solve(m, GAS, U, inlet_k=(0.05 * U) ** 2, tol=1e-8)


@pytest.mark.parametrize("Re,tol", [(2e4, 0.07), (1e5, 0.05), (1e6, 0.05)])
def test_friction_factor_vs_colebrook(Re, tol):
    m, f = periodic(Re)
    assert f.converged
    ratio = f.friction_factor[0] / Colebrook(Re, 0.0)
    assert abs(ratio - 1.0) < tol, ratio
    # standard k-epsilon with wall functions under-predicts slightly (OpenFOAM: -3.9 % at Re 2e4)
    assert ratio < 1.0
    # the wall cell sits at the y+ it was designed for
    assert np.all(np.abs(f.wall_yplus - 30.0) < 3.0)
    # global momentum balance: pressure force = wall shear force, exactly
    assert f.pressure_gradient[0] * math.pi * m.radius**2 == pytest.approx(
        f.wall_shear[0].mean() * 2 * math.pi * m.radius, rel=1e-6)


@pytest.mark.parametrize("Re", [1e5, 1e6])
def test_mean_velocity_vs_log_law(Re):
    """Launder & Spalding's (1974) log law with their constants written out here, u+ =
    ln(E y+)/κ, κ = 0.41, E = 9.8 (u+ = 2.44 ln y+ + 5.57), within 3 % over 30 < y+ < 0.15 Re_τ
    (the code's own constants changed would fail it)."""
    m, f = periodic(Re)
    u_tau = math.sqrt(f.wall_shear[0].mean() / RHO)
    nu = MU / RHO
    re_tau = u_tau * m.radius / nu
    yplus = (m.radius - m.r) * u_tau / nu
    uplus = f.ux[0].mean(axis=1) / u_tau
    sel = (yplus > 29.0) & (yplus < 0.15 * re_tau)
    assert sel.sum() >= 3
    dev = uplus[sel] / (np.log(9.8 * yplus[sel]) / 0.41) - 1.0
    assert np.abs(dev).max() < 0.03, dev


def test_fully_developed_profile_vs_openfoam_kepsilon():
    """Same model and constants as OpenFOAM v1912 (profile at x = 3.56 m of its developing run,
    which is fully developed there): within 1 % of U0.  The point y/R = +-0.9 of the reference
    is a linear interpolation across OpenFOAM's log-layer cell and lies 2 % below the log law
    (u+ = 15.4 at y+ = 56); it is checked against the log law instead (test above)."""
    rows = [r for r in read_reference_csv("openfoam_v1912_developing_pipe_kepsilon.csv") if r["kind"] == "profile_x3.56"]
    eta = np.array([float(r["y_over_R"]) for r in rows])
    u_ref = np.array([float(r["U_over_U0"]) for r in rows])
    U = 10.0
    m = PipeMesh.build(D, 1.0, "periodic", radial_cells=20, azimuthal_cells=40, bulk_velocity=U, density=RHO, viscosity=MU)
    f = solve(m, GAS, U, tol=1e-8)
    u = vertical_profile(m, f.ux[0], eta) / U
    keep = ~np.isclose(np.abs(eta), 0.9)
    assert np.abs(u - u_ref)[keep].max() < 0.01
    # the k-epsilon core is flatter than the DNS (U_c/U_b ~ 1.19)
    assert axis_value(m, f.ux[0]) / U == pytest.approx(1.19, abs=0.01)


def test_periodic_single_phase_has_exactly_zero_cross_flow():
    m, f = periodic(2e4, nr=10, nt=16)
    assert np.all(f.uy == 0.0) and np.all(f.uz == 0.0)


def test_axisymmetric_solution_is_the_same_in_every_sector():
    m, f = periodic(2e4, nr=10, nt=16)
    for a in (f.ux, f.k, f.epsilon):
        assert np.ptp(a[0], axis=1).max() <= 1e-9 * np.abs(a).max()


@pytest.fixture(scope="module")
def developing():
    U = 10.0
    m = PipeMesh.build(D, 4.0, "developing", axial_cells=400, radial_cells=20, azimuthal_cells=20,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    f = solve(m, GAS, U, inlet_k=1.0)
    mp = PipeMesh.build(D, 1.0, "periodic", radial_cells=20, azimuthal_cells=20, bulk_velocity=U, density=RHO, viscosity=MU)
    fp = solve(mp, GAS, U, tol=1e-8)
    return m, f, fp


def test_developing_centreline_vs_openfoam_kepsilon(developing):
    m, f, _ = developing
    rows = [r for r in read_reference_csv("openfoam_v1912_developing_pipe_kepsilon.csv") if r["kind"] == "centreline"]
    uc = np.array([axis_value(m, f.ux[i]) for i in range(m.nx)]) / 10.0
    for r in rows:
        x, ref = float(r["x"]), float(r["U_over_U0"])
        assert np.interp(x, m.x, uc) == pytest.approx(ref, abs=0.01), x
    # the entrance overshoot is there: a maximum near x = 0.75 m above the developed value
    assert uc.max() > uc[-1] + 0.01 and 0.5 < m.x[uc.argmax()] < 1.0


def test_developing_reaches_fully_developed_state(developing):
    m, f, fp = developing
    assert f.converged
    i = np.searchsorted(m.x, 3.56)
    w = (3.56 - m.x[i - 1]) / (m.x[i] - m.x[i - 1])
    u356 = (1 - w) * f.ux[i - 1] + w * f.ux[i]
    assert np.abs(u356 - fp.ux[0]).max() < 0.02 * 10.0
    g = f.pressure_gradient[m.x >= 2.0]
    assert np.abs(g / fp.pressure_gradient[0] - 1.0).max() < 0.01
    # mass flow is exactly conserved at every station
    flow = (f.ux * m.cell_area).sum(axis=(1, 2))
    np.testing.assert_allclose(flow, 10.0 * math.pi * m.radius**2, rtol=1e-10)
    # pressure relative to the outlet, decreasing downstream
    pbar = (f.p * m.cell_area).sum(axis=(1, 2)) / m.cell_area.sum()
    assert np.all(np.diff(pbar) < 0) and 0 < pbar[-1] < f.pressure_gradient[-1] * m.dx[-1]
    assert np.all(f.k > 0) and np.all(f.epsilon > 0)


def test_turbulence_sink_keeps_k_positive():
    """A particle-like k sink of 20x the local dissipation, applied in proportion to k (as the
    particle sink scales), is treated implicitly: k and epsilon stay positive."""
    U = 10.0
    m, f = periodic(2e4, nr=10, nt=16)
    s = Sources.zeros(m)
    s.k[...] = -20.0 * RHO * f.epsilon
    s.epsilon[...] = 1.8 * f.epsilon / f.k * s.k
    s.k_reference, s.epsilon_reference = f.k, f.epsilon
    g = solve(m, GAS, U, sources=s, initial=f, tol=1e-8)
    assert np.all(g.k > 0) and np.all(g.epsilon > 0)
    assert g.k.mean() < 0.5 * f.k.mean()


def test_closure_epsilon_source_of_a_sink_equals_the_referenced_explicit_one():
    """With c_eps3, a referenced k sink S_k gives the eps sink C_eps3 eps S_k/k_ref: the same
    linear sink as an explicit S_eps = C_eps3 (eps_ref/k_ref) S_k referred to eps_ref."""
    U = 10.0
    m, f = periodic(2e4, nr=10, nt=16)
    explicit = Sources.zeros(m)
    explicit.k[...] = -5.0 * RHO * f.epsilon
    explicit.epsilon[...] = 1.8 * f.epsilon / f.k * explicit.k
    explicit.k_reference, explicit.epsilon_reference = f.k, f.epsilon
    closure = Sources(explicit.momentum, explicit.k, np.zeros_like(explicit.k), k_reference=f.k, c_eps3=1.8)
    a = solve(m, GAS, U, sources=explicit, initial=f, tol=1e-9)
    b = solve(m, GAS, U, sources=closure, initial=f, tol=1e-9)
    assert a.k.mean() < 0.8 * f.k.mean()  # the sink acts
    np.testing.assert_allclose(b.k, a.k, rtol=1e-6)
    np.testing.assert_allclose(b.epsilon, a.epsilon, rtol=1e-6)
    np.testing.assert_allclose(closure.applied_epsilon(b.k, b.epsilon), 1.8 * b.epsilon / b.k * explicit.k * b.k / f.k,
                               rtol=1e-12)


def test_closure_epsilon_source_follows_the_solved_turbulence():
    """A positive S_k with c_eps3: the converged field carries S_eps = C_eps3 (eps/k) S_k with its
    own eps/k, i.e. solving again with that S_eps as a fixed explicit source gives the same field."""
    U = 10.0
    m, f = periodic(2e4, nr=10, nt=16)
    closure = Sources.zeros(m)
    closure.k[...] = 2.0 * RHO * f.epsilon
    closure.c_eps3 = 1.8
    b = solve(m, GAS, U, sources=closure, initial=f, tol=1e-10)
    assert b.k.mean() > 1.2 * f.k.mean()
    fixed = Sources.zeros(m)
    fixed.k[...] = closure.k
    fixed.epsilon[...] = closure.applied_epsilon(b.k, b.epsilon)
    np.testing.assert_allclose(fixed.epsilon, 1.8 * b.epsilon / b.k * closure.k, rtol=1e-12)
    c = solve(m, GAS, U, sources=fixed, initial=b, tol=1e-10)
    np.testing.assert_allclose(c.k, b.k, rtol=1e-5)
    np.testing.assert_allclose(c.epsilon, b.epsilon, rtol=1e-5)


def test_unsustainable_sink_stops_with_diagnosis_not_nan():
    """A fixed k sink 50x the dissipation has no positive steady solution: the solve stops naming k."""
    U = 10.0
    m, f = periodic(2e4, nr=10, nt=16)
    s = Sources.zeros(m)
    s.k[...] = -50.0 * RHO * f.epsilon
    with pytest.raises(SolverDivergence, match=r"\bk = .* at x = .*ring \d+, sector \d+"):
        solve(m, GAS, U, sources=s, initial=f, tol=1e-8)


def test_non_finite_source_is_rejected_before_solving():
    U = 10.0
    m = PipeMesh.build(D, 1.0, "periodic", radial_cells=8, azimuthal_cells=16, bulk_velocity=U, density=RHO, viscosity=MU)
    s = Sources.zeros(m)
    s.momentum[0, 0, 3, 5] = np.nan
    with pytest.raises(ValueError, match=r"momentum source .* not finite .* ring 3, sector 5"):
        solve(m, GAS, U, sources=s)


def test_wall_shear_coefficient_is_continuous_at_the_sublayer_switch():
    """The viscous law and the log law meet at y* = 11.53 (kappa 0.41, E 9.8): no jump in tau_w
    when k_P moves the wall cell across the switch (a 2 % jump at the often quoted 11.225 made a
    wall cell cycle between the two laws and a gas station never converge)."""
    from rans import kepsilon as ke

    y_p = 1e-3
    ystar = ke.YSTAR_LAMINAR * np.array([1 - 1e-7, 1 + 1e-7])
    k = (ystar * MU / (RHO * y_p)) ** 2 / math.sqrt(ke.C_MU)
    c, ys = ke.wall_shear_coefficient(k, y_p, RHO, MU)
    assert ys == pytest.approx(ystar, rel=1e-9)
    assert c[1] == pytest.approx(c[0], rel=1e-6)
    # the edge is where u+ = y+ meets the log law, independently: y = ln(E y)/kappa
    assert ke.YSTAR_LAMINAR == pytest.approx(math.log(ke.E_WALL * ke.YSTAR_LAMINAR) / ke.KAPPA, rel=1e-12)
    assert 11.5 < ke.YSTAR_LAMINAR < 11.56


@pytest.fixture
def plain_march(monkeypatch):
    """The retry chain of _march_station without its first, Anderson-accelerated attempt (the
    tests below count the plain attempts' iterations; the accelerated one has its own tests)."""
    from rans import solver as S

    monkeypatch.setattr(S, "ANDERSON_DEPTH", 0)


def test_a_diverging_station_is_retried_with_relaxation_and_keeps_the_fixed_point(monkeypatch, plain_march):
    """A station of the march whose outer iteration diverges is iterated again with implicit
    relaxation (rans.solver._march_station), and the relaxation used is recorded per station.
    k-eps relaxation alone keeps the field the march gives without the failure (to the
    tolerance); momentum relaxation changes the SIMPLEC interpolation weights, so the cross flow
    of that station moves by a few % of its maximum and u_x, k, eps by < 1e-5."""
    from rans import solver as S

    U = 10.0
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    plain = solve(m, GAS, U, tol=1e-9)
    assert np.all(plain.station_relaxation == 1.0)
    orig = S._StationSolver._iterate

    def run(diverges):
        def iterate(self, st, hist, c0, dx, src, laminar, relax_turb):
            if self.station == 5 and diverges(self, relax_turb):
                raise SolverDivergence("gas solve diverged: epsilon = inf (test)")
            return orig(self, st, hist, c0, dx, src, laminar, relax_turb)

        monkeypatch.setattr(S._StationSolver, "_iterate", iterate)
        return solve(m, GAS, U, tol=1e-9)

    def deviation(f, name):
        return np.abs(getattr(f, name) - getattr(plain, name)).max() / np.abs(getattr(plain, name)).max()

    turb = run(lambda s, r: r == 1.0)  # retried with k-eps relaxation 0.5
    assert turb.converged and turb.station_relaxation[5] == 0.5
    assert np.all(np.delete(turb.station_relaxation, 5) == 1.0)
    for name in ("ux", "uy", "uz", "k", "epsilon"):
        assert deviation(turb, name) < 1e-7, name

    mom = run(lambda s, r: s.alpha_u > 0.6)  # needs momentum relaxation 0.5 (k-eps 0.2)
    assert mom.converged and mom.station_relaxation[5] == 0.2
    for name in ("ux", "k", "epsilon"):
        assert deviation(mom, name) < 1e-5, name
    for name in ("uy", "uz"):
        assert deviation(mom, name) < 0.05, name

    assert not mom.station_coupled.any()

    # SIMPLEC diverges: the coupled cross-flow step takes the station (no relaxation)
    cpl = run(lambda s, r: not s.coupled)
    assert cpl.converged and cpl.station_coupled[5] and cpl.station_coupled.sum() == 1
    assert np.all(cpl.station_relaxation == 1.0)
    for name in ("ux", "k", "epsilon"):
        assert deviation(cpl, name) < 1e-4, name
    for name in ("uy", "uz"):
        assert deviation(cpl, name) < 0.05, name

    with pytest.raises(SolverDivergence, match="epsilon = inf"):
        run(lambda s, r: True)


def test_a_stalling_station_is_retried_with_the_coupled_cross_flow_step(monkeypatch, plain_march):
    """A station whose SIMPLEC iteration does not reach the tolerance within its iterations is
    iterated again with the coupled cross-flow step; the march then converges."""
    from rans import solver as S

    U = 10.0
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    orig = S._StationSolver._iterate

    def stalling(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        return ch if self.coupled or self.station != 7 else max(ch, 1e-3)

    monkeypatch.setattr(S._StationSolver, "_iterate", stalling)
    f = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    assert f.converged and f.station_coupled[7] and f.station_coupled.sum() == 1
    assert f.station_iterations[7] < 60

    def always(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        return ch if self.station != 7 else max(ch, 1e-3)

    monkeypatch.setattr(S._StationSolver, "_iterate", always)
    g = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    assert not g.converged and g.station_iterations[7] == 60
    assert np.flatnonzero(~g.station_converged).tolist() == [7]


def test_the_march_records_which_stations_converged_and_their_last_change():
    """GasField.station_converged / station_change: with three iterations per station the
    march stops short of a 1e-9 tolerance at the developing inlet stations; the change recorded
    for each (velocity / U_b, k-eps relative) is that of its last iteration, at or above the
    tolerance exactly where the station is reported unconverged."""
    U = 10.0
    tol = 1e-9
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    f = solve(m, GAS, U, tol=tol, station_iterations=(2, 3))
    assert f.station_converged.shape == (12,) and f.station_change.shape == (12, 2)
    assert not f.converged and not f.station_converged.all()
    assert f.converged == f.station_converged.all()
    worst = f.station_change.max(axis=1)
    assert np.all(np.isfinite(worst))
    assert np.all(worst[~f.station_converged] >= tol)
    assert np.all(worst[f.station_converged] < tol)
    full = solve(m, GAS, U, tol=tol)
    assert full.converged and full.station_converged.all() and np.all(full.station_change.max(axis=1) < tol)


def test_a_stalled_station_is_retried_with_k_eps_relaxation_and_keeps_the_fixed_point(monkeypatch, plain_march):
    """A station that stalls without relaxation (SIMPLEC and the coupled step) is iterated again
    with implicit k-eps relaxation 0.5 and no momentum relaxation, which keeps the fixed point:
    the march converges there to the field it gives without the stall (the near-wall
    oscillation of scene h's final pass, docs/history.md)."""
    from rans import solver as S

    U = 10.0
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    plain = solve(m, GAS, U, tol=1e-9)
    orig = S._StationSolver._iterate
    seen = []

    def stalls_unrelaxed(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        if self.station == 7:
            seen.append((relax_turb, self.alpha_u, self.coupled))
        return max(ch, 1e-3) if self.station == 7 and relax_turb == 1.0 else ch

    monkeypatch.setattr(S._StationSolver, "_iterate", stalls_unrelaxed)
    f = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    assert f.converged and f.station_converged.all()
    assert f.station_relaxation[7] == 0.5 and not f.station_coupled[7]
    assert np.all(np.delete(f.station_relaxation, 7) == 1.0)
    assert {a for a in seen} == {(1.0, 1.0, False), (1.0, 1.0, True), (0.5, 1.0, False)}  # never momentum relaxation
    for name in ("ux", "uy", "uz", "k", "epsilon"):
        dev = np.abs(getattr(f, name) - getattr(plain, name)).max() / np.abs(getattr(plain, name)).max()
        assert dev < 1e-7, name

    def stalls_always(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        if self.station == 7:
            seen.append((relax_turb, self.alpha_u, self.coupled))
        return max(ch, 1e-3) if self.station == 7 else ch

    seen.clear()
    monkeypatch.setattr(S._StationSolver, "_iterate", stalls_always)
    g = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    assert not g.converged and np.flatnonzero(~g.station_converged).tolist() == [7]
    assert all(a[1] == 1.0 for a in seen) and (0.5, 1.0, True) in seen  # k-eps relaxation with both steps, no more
    assert g.station_relaxation[7] == 1.0  # the unrelaxed attempt had the smallest (scaled) change


@pytest.mark.parametrize("rate, iterates_on", [(0.9, True), (0.995, False)])
def test_a_slowly_but_steadily_converging_station_iterates_on(monkeypatch, plain_march, rate, iterates_on):
    """A station whose change is still falling steadily when its iterations run out iterates on
    (no coupled retry) when that rate reaches the tolerance within STATION_EXTENSION times its
    iterations (here: 1e-3 * 0.9^n < 1e-9 at n = 132 < 4 x 60); at a rate that would need more
    (0.995: n = 2757) it is retried with the coupled step at the cap, as a stalled one."""
    from rans import solver as S

    U = 10.0
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    orig = S._StationSolver._iterate
    calls = {"simplec": 0}

    def slow(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        if self.station != 7 or self.coupled:
            return ch
        calls["simplec"] += 1
        return max(ch, 1e-3 * rate ** calls["simplec"])

    monkeypatch.setattr(S._StationSolver, "_iterate", slow)
    f = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    assert f.converged
    if iterates_on:
        assert not f.station_coupled.any()
        assert f.station_iterations[7] == calls["simplec"] == 132
    else:
        assert f.station_coupled[7] and calls["simplec"] == 60


def test_a_station_that_contracts_steadily_after_a_bump_iterates_on(monkeypatch, plain_march):
    """Scene g's case at test size: the change rises to 1e-2 at iteration 42 of 60, turns over
    and falls by 0.75 per iteration.  The chunk maxima (6.6e-3 vs 1e-2) would project ~560 more
    iterations (> 180 left), the straight fall of its last 15 ~40: it iterates on and converges
    with SIMPLEC (no coupled retry) at the iteration the profile crosses the tolerance."""
    from rans import solver as S

    U = 10.0
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    orig = S._StationSolver._iterate
    calls = {"simplec": 0}

    def profile(n):
        if n <= 42:
            return 1e-4 * 100.0 ** (n / 42.0)
        return 1e-2 * 0.9 ** min(n - 42, 5) * 0.75 ** max(n - 47, 0)

    def bump(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        if self.station != 7 or self.coupled:
            return ch
        calls["simplec"] += 1
        return max(ch, profile(calls["simplec"]))

    monkeypatch.setattr(S._StationSolver, "_iterate", bump)
    f = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    first_below = next(n for n in range(1, 400) if profile(n) < 1e-9)
    assert f.converged and not f.station_coupled.any()
    assert f.station_iterations[7] == calls["simplec"] == first_below


def test_importing_eulag_makes_blas_single_threaded_unless_the_user_chose():
    """rans/__init__.py: the dense block inversions of the march must not spread over OpenBLAS
    threads (3.7x slower at a 40 x 80 section on busy cores); a user's own setting stays."""
    import os
    import subprocess
    import sys

    code = "import eulag, os, numpy; print(os.environ['OPENBLAS_NUM_THREADS'])"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "1"
    env["OPENBLAS_NUM_THREADS"] = "2"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "2"


def test_a_station_that_diverges_while_iterating_on_keeps_the_state_where_its_iterations_ran_out(monkeypatch, plain_march):
    """Iterating on must not turn an unconverged station into a failed solve: an attempt that
    diverges after its cap ends as the state at the cap (returned unconverged, as before)."""
    from rans import solver as S

    U = 10.0
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    orig = S._StationSolver._iterate
    calls = {}

    def slow_then_diverging(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        if self.station != 7:
            return ch
        key = (self.coupled, self.alpha_u, relax_turb)
        calls[key] = calls.get(key, 0) + 1
        if calls[key] > 70:
            raise SolverDivergence("gas solve diverged: k = -1 (test)")
        return max(ch, 1e-3 * 0.9 ** calls[key])

    monkeypatch.setattr(S._StationSolver, "_iterate", slow_then_diverging)
    f = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    assert not f.converged and f.station_iterations[7] == 60
    # SIMPLEC, the coupled step, then both with k-eps relaxation 0.5 (which diverge before their cap)
    assert set(calls) == {(False, 1.0, 1.0), (True, 1.0, 1.0), (False, 1.0, 0.5), (True, 1.0, 0.5)}
    assert all(n == 71 for n in calls.values())


def test_a_station_that_drifts_past_every_attempt_iterates_on_as_the_last_resort(monkeypatch, plain_march):
    """Scene h's pass 9 at x = 0.9 m: the plain iteration drifts for ~300 iterations at a change
    that neither grows nor falls, then contracts; SIMPLEC, the coupled step and the k-eps
    relaxation all stall on it within their caps.  When no attempt converged, the first plain
    attempt iterates on from its cap (up to STATION_EXTENSION times it) and converges, to the
    field of the plain march."""
    from rans import solver as S

    U = 10.0
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=12, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    plain = solve(m, GAS, U, tol=1e-9)
    orig = S._StationSolver._iterate
    calls = {"plain": 0, "other": 0}

    def drifting(self, st, hist, c0, dx, src, laminar, relax_turb):
        ch = orig(self, st, hist, c0, dx, src, laminar, relax_turb)
        if self.station != 7:
            return ch
        if not self.coupled and relax_turb == 1.0:
            calls["plain"] += 1
            return ch if calls["plain"] > 100 else max(ch, 1e-3)  # a drift of 100 iterations
        calls["other"] += 1
        return max(ch, 1e-3)  # the retries stall

    monkeypatch.setattr(S._StationSolver, "_iterate", drifting)
    f = solve(m, GAS, U, tol=1e-9, station_iterations=(2, 60))
    assert f.converged and f.station_converged.all()
    assert f.station_iterations[7] == calls["plain"] == 101  # 60, then on from there
    assert calls["other"] > 0 and not f.station_coupled[7] and f.station_relaxation[7] == 1.0
    for name in ("ux", "uy", "uz", "k", "epsilon"):
        dev = np.abs(getattr(f, name) - getattr(plain, name)).max() / np.abs(getattr(plain, name)).max()
        assert dev < 1e-7, name


def test_only_a_steady_contraction_counts_as_still_converging():
    from rans.solver import _still_converging

    n = np.arange(200)
    assert _still_converging(list(1e-3 * 0.97 ** n), 50, 1e-6, 600)   # needs ~27 more
    assert not _still_converging(list(1e-3 * 0.995 ** n), 50, 1e-6, 600)  # needs ~1200 more
    # a wandering iteration: changes scattered over 1e-4..1e-3, whatever its last two values
    rng = np.random.default_rng(3)
    for _ in range(50):
        wander = list(10.0 ** rng.uniform(-4.0, -3.0, 200))
        assert not _still_converging(wander, 50, 1e-6, 600)
    # an oscillation about the fixed point, decaying 0.5 % per iteration (period 12)
    osc = list(1e-3 * 0.995 ** n * (1.05 + np.sin(2.0 * np.pi * n / 12.0)))
    assert not _still_converging(osc, 50, 1e-6, 600)


def test_a_steady_contraction_after_a_bump_counts_as_still_converging():
    """Scene g's station at x = 0.825 m (docs/history.md): the change rose to 0.16 at iteration 142
    of 200 and then fell by ~0.8, later 0.92, per iteration to 1.3e-5.  The largest change of
    the last 50 over that of the 50 before (there 6.5e-2 and 0.158: 626 more iterations; in
    this synthetic profile 7.4e-2 and 0.158: 743) projects more than the 600 left, yet at the
    rate of the last ones 20-30 suffice: the straight fall of log(change) says it is still
    converging."""
    from rans.solver import _still_converging

    n = np.arange(200)
    rise = 5e-3 * (0.158 / 5e-3) ** (n[:143] / 142.0)
    rate = np.select([n[143:] < 152, n[143:] < 185], [0.91, 0.8], 0.92)  # turning over, then steady
    fall = 0.158 * np.cumprod(rate)
    changes = np.concatenate([rise, fall])
    assert 1e-5 < changes[-1] < 1e-4
    now, before = changes[-50:].max(), changes[-100:-50].max()
    assert math.log(1e-6 / now) / (math.log(now / before) / 50) > 600  # the chunk maxima decline
    assert _still_converging(list(changes), 50, 1e-6, 600)
    assert not _still_converging(list(changes), 50, 1e-6, 10)  # but not if the ~20 needed are more than left


def _particle_like_momentum_source(m, f, scale):
    """A braking source concentrated in the bottom half, with a cross-flow part (N m-3)."""
    sec = m.geometry()
    ybot = np.clip(-sec.cy.reshape(m.shape[1:]) / m.radius, 0.0, None)
    s = Sources.zeros(m)
    s.momentum[0] = -scale * (0.2 + ybot**2)
    s.momentum[1] = 0.05 * scale * ybot
    s.momentum[2] = 0.02 * scale * np.sin(np.pi * sec.cz.reshape(m.shape[1:]) / m.radius)
    return s


@pytest.mark.parametrize("mode", ["periodic", "developing"])
def test_linearised_drag_keeps_the_solution_of_the_explicit_source(mode):
    """Sources.drag: S(U) = momentum + drag (U_ref - U).  With U_ref the solution of the explicit
    source, the linearised source has the same solution (the Rhie-Chow weights leave drag out),
    however large drag is (here up to 2e4 kg m-3 s-1 in the bottom cells)."""
    U = 10.0
    if mode == "periodic":
        m, f = periodic(2e4, nr=10, nt=16)
    else:
        m = PipeMesh.build(D, 0.3, "developing", axial_cells=20, radial_cells=10, azimuthal_cells=16,
                           bulk_velocity=U, density=RHO, viscosity=MU)
        f = None
    ref = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, tol=1e-9) if f is None else f
    s = _particle_like_momentum_source(m, ref, 20.0)
    a = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, sources=s, initial=f, tol=1e-10)
    sec = m.geometry()
    ybot = np.clip(-sec.cy.reshape(m.shape[1:]) / m.radius, 0.0, None)
    drag = np.broadcast_to(2.0e4 * ybot**4 + 10.0, m.shape).copy()  # kg m-3 s-1
    u_ref = np.stack([a.ux, a.uy, a.uz])
    lin = Sources(s.momentum, s.k, s.epsilon, drag=drag, velocity_reference=u_ref)
    b = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, sources=lin, initial=f, tol=1e-10)
    assert a.converged and b.converged
    np.testing.assert_allclose(b.ux, a.ux, rtol=0, atol=1e-6 * U)
    cross = max(np.abs(a.uy).max(), np.abs(a.uz).max())  # the cross flow: ~1e-4 U here
    np.testing.assert_allclose(b.uy, a.uy, rtol=0, atol=1e-4 * cross)
    np.testing.assert_allclose(b.uz, a.uz, rtol=0, atol=1e-4 * cross)
    if a.face_flux is not None:
        np.testing.assert_allclose(b.face_flux, a.face_flux, rtol=0, atol=1e-4 * np.abs(a.face_flux).max())
    np.testing.assert_allclose(b.pressure_gradient, a.pressure_gradient, rtol=1e-6)
    np.testing.assert_allclose(b.k, a.k, rtol=1e-5)
    np.testing.assert_allclose(lin.applied_momentum(b.ux, b.uy, b.uz), s.momentum, rtol=0, atol=1e-4 * 20.0)


def test_linear_drag_source_balances_the_pressure_gradient():
    """A pure linear drag S = -beta U (momentum 0, U_ref = 0, beta uniform) in fully developed
    flow: the section-mean momentum balance -dp/dx = 4 tau_w/D + beta U_b holds exactly."""
    U, beta = 10.0, 3.0  # beta U_b = 30 Pa/m, about the wall's 4 tau_w / D at Re 2e4
    m, f = periodic(2e4, nr=10, nt=16)
    lin = Sources(np.zeros((3,) + m.shape), np.zeros(m.shape), np.zeros(m.shape),
                  drag=np.full(m.shape, beta), velocity_reference=np.zeros((3,) + m.shape))
    g = solve(m, GAS, U, sources=lin, initial=f, tol=1e-10)
    assert g.converged
    wall = 4.0 * g.wall_shear[0].mean() / D
    assert g.pressure_gradient[0] == pytest.approx(wall + beta * U, rel=1e-6)
    assert g.pressure_gradient[0] > f.pressure_gradient[0] + 0.9 * beta * U  # the drag acts


def test_drag_source_without_its_reference_velocity_is_rejected():
    m = PipeMesh.build(D, 1.0, "periodic", radial_cells=8, azimuthal_cells=16, bulk_velocity=10.0,
                       density=RHO, viscosity=MU)
    s = Sources.zeros(m)
    with pytest.raises(ValueError, match="velocity_reference"):
        solve(m, GAS, 10.0, sources=Sources(s.momentum, s.k, s.epsilon, drag=np.ones(m.shape)))
    with pytest.raises(ValueError, match="negative"):
        solve(m, GAS, 10.0, sources=Sources(s.momentum, s.k, s.epsilon, drag=-np.ones(m.shape),
                                            velocity_reference=np.zeros((3,) + m.shape)))


@pytest.mark.parametrize("nr, nt", [(6, 8), (20, 40)])
def test_coupled_cross_flow_system_is_the_product_of_its_defining_operators(nr, nt):
    """rans.operators.CoupledCrossFlow (the coupled step's 3n system in a fixed pattern, C_p from
    a precomputed linear map of the momentum-interpolation weights) against the system built
    from its definition with scipy's sparse products: the same entries to round-off, the same
    momentum-interpolated face values and continuity rows."""
    import scipy.sparse as sp

    from rans.operators import CoupledCrossFlow

    mesh = PipeMesh.build(0.0305, 0.1, "periodic", radial_cells=nr, azimuthal_cells=nt)
    sec = mesh.geometry()
    rng = np.random.default_rng(nr)
    n, nf = sec.n, sec.nf
    diag, a_PN, a_NP = rng.uniform(1.0, 2.0, n), -rng.uniform(0.0, 0.3, nf), -rng.uniform(0.0, 0.3, nf)
    d = rng.uniform(0.1, 1.0, n)
    D = sp.diags
    K = RHO * sec.div @ D(sec.S)
    Q = -D(sec.nz) @ sec.I @ D(d) @ sec.Rz - D(sec.ny) @ sec.I @ D(d) @ sec.Ry + D(sec.interp(d))
    Cp = (-(K @ Q @ sec.Dn)).tolil()
    w = sec.wall[0]
    Cp[w, w] += 1e3 * np.abs(Cp.diagonal()).max()
    M = sec.matrix(diag, a_PN, a_NP)
    ref = sp.bmat([[M, None, D(sec.area) @ sec.Rz @ sec.Dn], [None, M, D(sec.area) @ sec.Ry @ sec.Dn],
                   [K @ D(sec.nz) @ sec.I, K @ D(sec.ny) @ sec.I, Cp]]).toarray()
    system = CoupledCrossFlow(sec, RHO)
    got = system.matrix(diag, a_PN, a_NP, d)
    assert got.has_sorted_indices and got.nnz == system.nnz
    np.testing.assert_allclose(got.toarray(), ref, rtol=0, atol=1e-13 * np.abs(ref).max())
    v = rng.normal(size=nf)
    np.testing.assert_allclose(system.interpolated(v, d), Q @ v, rtol=0, atol=1e-14 * np.abs(Q @ v).max())
    np.testing.assert_allclose(system.continuity(v), K @ v, rtol=0, atol=1e-14 * np.abs(K @ v).max())


def _sinks(m, ref, scale):
    """Particle-like sources of a developing solve: braking momentum with cross flow, and a
    k sink (referred to ref's k, with the C_eps3 closure)."""
    s = _particle_like_momentum_source(m, ref, 20.0 * scale)
    s.k[...] = -scale * RHO * ref.epsilon
    s.k_reference, s.c_eps3 = ref.k, 1.8
    return s


@pytest.fixture(scope="module")
def warm_start_case():
    U, tol = 10.0, 1e-8
    m = PipeMesh.build(D, 0.3, "developing", axial_cells=20, radial_cells=8, azimuthal_cells=12,
                       bulk_velocity=U, density=RHO, viscosity=MU)
    ref = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, tol=1e-9)
    a = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, sources=_sinks(m, ref, 1.0), tol=tol)
    return m, ref, a, U, tol


def test_a_warm_started_march_converges_to_the_cold_solution(warm_start_case):
    """solve(initial=...) in the developing mode: each station starts from the earlier field's
    state there; with sources 2 % stronger than that field's, the march converges to the field
    of a cold solve (from the upstream states) within the tolerance, not to the earlier field
    (which differs by ~1e5 tolerances)."""
    m, ref, a, U, tol = warm_start_case
    s = _sinks(m, ref, 1.02)
    cold = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, sources=s, tol=tol)
    warm = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, sources=s, tol=tol, initial=a)
    assert cold.converged and warm.converged
    assert np.abs(a.ux - cold.ux).max() > 1e4 * tol * U  # the earlier field is far from it
    for v in ("ux", "uy", "uz"):
        np.testing.assert_allclose(getattr(warm, v), getattr(cold, v), rtol=0, atol=2 * tol * U, err_msg=v)
    # k and eps contract more slowly: a converged station is within ~10 of its last changes
    np.testing.assert_allclose(warm.k, cold.k, rtol=20 * tol)
    np.testing.assert_allclose(warm.epsilon, cold.epsilon, rtol=20 * tol)
    np.testing.assert_allclose(warm.pressure_gradient, cold.pressure_gradient, rtol=5 * tol)
    assert warm.station_flux.shape == (m.nx, m.geometry().nf)


def test_a_march_warm_started_from_its_own_solution_stops_after_two_iterations(warm_start_case):
    """Started from the converged field of the same sources (its velocities, pressure, k, eps
    and cross-section face fluxes at each station), every station meets the tolerance at once:
    the minimum of two outer iterations."""
    m, ref, a, U, tol = warm_start_case
    again = solve(m, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, sources=_sinks(m, ref, 1.0), tol=tol, initial=a)
    assert again.converged
    assert again.station_iterations.max() <= 2, again.station_iterations
    np.testing.assert_allclose(again.ux, a.ux, rtol=0, atol=tol * U)
    np.testing.assert_allclose(again.k, a.k, rtol=10 * tol)
    with pytest.raises(ValueError, match="initial field has shape"):
        coarse = PipeMesh.build(D, 0.3, "developing", axial_cells=10, radial_cells=8, azimuthal_cells=12,
                                bulk_velocity=U, density=RHO, viscosity=MU)
        solve(coarse, GAS, U, inlet_k=0.4, inlet_epsilon=50.0, tol=tol, initial=a)


def test_a_station_without_retries_keeps_its_first_attempt():
    """_march_station(retries=False) iterates a stalled station once, to its cap, and returns it
    unconverged; with retries it goes on through the coupled step and the relaxations. A
    diverging attempt is retried either way."""
    from rans import solver as rs

    class Stalled:
        alpha_u, coupled, last_change = 1.0, False, (1.0, 1.0)

        def __init__(self):
            self.calls = 0

        def iterate(self, st, *args):
            self.calls += 1
            return 0.5  # a change that never falls

    class State:
        def copy(self):
            return State()

    counts = {}
    for retries in (False, True):
        s = Stalled()
        _, ok, *_ = rs._march_station(s, State(), None, None, None, None, True, 1.0, (2, 20), 1e-6, [],
                                      retries=retries)
        assert not ok
        counts[retries] = s.calls
    assert counts[False] == 20
    assert counts[True] > 3 * counts[False]

    class DivergesOnce(Stalled):
        def iterate(self, st, *args):
            self.calls += 1
            if self.calls == 1:
                raise rs.SolverDivergence("epsilon = inf (test)")
            return 0.0  # converged at once

    s = DivergesOnce()
    _, ok, *_ = rs._march_station(s, State(), None, None, None, None, True, 1.0, (2, 20), 1e-6, [],
                                  retries=False)
    assert ok and s.calls == 3  # a divergence is retried even without retries of stalls


def test_a_slow_steady_contraction_converges_with_the_final_solves_extension():
    """A station whose first attempt contracts by 0.996 per iteration from a change of 1e-3 needs
    ~1,700 iterations, more than STATION_EXTENSION (4) times its cap of 200: it is returned
    unconverged at its cap (_still_converging sees it will not arrive in time); with
    ``extension`` = FINAL_STATION_EXTENSION (the coupling loop's final solves) it iterates on
    while it is still converging and converges.  A station whose change stays level gets no
    more iterations from the larger extension.  With the retries, a station that drifts level
    for 500 iterations and then contracts by 0.996 is taken on by the last resort: unconverged
    at 4 x 200 iterations, converged with the larger extension.  An attempt that diverges
    while iterating on ends where its iterations last ran out, not at its first cap."""
    from rans import solver as rs

    class Contracting:
        alpha_u, coupled, last_change = 1.0, False, (1.0, 1.0)

        def __init__(self, rate):
            self.rate, self.calls = rate, 0

        def iterate(self, st, *args):
            self.calls += 1
            return 1e-3 * self.rate ** self.calls

    class State:
        def copy(self):
            return State()

    assert rs.FINAL_STATION_EXTENSION > rs.STATION_EXTENSION
    runs = {}
    for rate in (0.996, 1.0):
        for ext in (rs.STATION_EXTENSION, rs.FINAL_STATION_EXTENSION):
            s = Contracting(rate)
            _, ok, *_ = rs._march_station(s, State(), None, None, None, None, True, 1.0, (2, 200), 1e-6, [],
                                          retries=False, extension=ext)
            runs[rate, ext] = (ok, s.calls)
    assert runs[0.996, rs.STATION_EXTENSION] == (False, 200), runs
    ok, calls = runs[0.996, rs.FINAL_STATION_EXTENSION]
    assert ok and 1700 <= calls <= 1750, runs
    assert runs[1.0, rs.STATION_EXTENSION] == runs[1.0, rs.FINAL_STATION_EXTENSION] == (False, 200), runs

    class Counted:  # a state that knows how many iterations led to it
        n, change = 0, None

        def copy(self):
            c = Counted()
            c.n, c.change = self.n, self.change
            return c

    class DriftThenContract(Contracting):  # level for 500 iterations of any attempt, then 0.996
        def iterate(self, st, *args):
            self.calls += 1
            st.n += 1
            return 0.5 if st.n <= 500 else 1e-3 * self.rate ** (st.n - 500)

    for ext, converges in ((rs.STATION_EXTENSION, False), (rs.FINAL_STATION_EXTENSION, True)):
        s = DriftThenContract(0.996)
        state, ok, *_ = rs._march_station(s, Counted(), None, None, None, None, True, 1.0, (2, 200), 1e-6, [],
                                          extension=ext)
        assert ok == converges, (ext, s.calls, state.n)
    assert 2200 <= state.n <= 2300, state.n  # the first attempt's state carried on by the last resort

    class DivergesLate(Contracting):
        def iterate(self, st, *args):
            self.calls += 1
            if self.calls == 1500:
                raise rs.SolverDivergence("diverged while iterating on (test)")
            st.n += 1
            st.change = 1e-3 * self.rate ** self.calls
            return st.change

    s = DivergesLate(0.997)
    state, ok, it, *_ = rs._march_station(s, Counted(), None, None, None, None, True, 1.0, (2, 200), 1e-6, [],
                                          retries=False, extension=rs.FINAL_STATION_EXTENSION)
    assert not ok and it > 1400 and state.change < 2e-5, (it, state.change)


def test_an_attempt_on_a_limit_cycle_ends_before_its_cap_and_a_level_stall_does_not():
    """_march_station ends an attempt whose changes repeat with a period of 2 or more (k jumping
    up and down at the axis: 31, 0.97, 31, ...) after a few periods instead of at its cap of
    200 iterations, and does not iterate it on as a last resort; a level change (a slow drift)
    runs to the cap; rans.solver._cycling on
    its own: a decaying oscillation is not a cycle, a repeated pattern of period 11 is."""
    from rans import solver as rs

    class Cycling:
        alpha_u, coupled, last_change = 1.0, False, (1.0, 1.0)

        def __init__(self, values):
            self.values, self.calls = values, 0

        def iterate(self, st, *args):
            self.calls += 1
            return self.values[(self.calls - 1) % len(self.values)]

    class State:
        def copy(self):
            return State()

    for values, ends_early in (([31.0, 0.97], True), ([0.5], False)):
        s = Cycling(values)
        _, ok, *_ = rs._march_station(s, State(), None, None, None, None, True, 1.0, (2, 200), 1e-6, [],
                                      retries=False)
        assert not ok
        assert (s.calls < 20) if ends_early else (s.calls == 200)
    # with the retries every attempt cycles, and the last resort (iterating the first plain
    # attempt on, up to 4 x 200 iterations) is not taken: it would repeat the cycle
    s = Cycling([31.0, 0.97])
    _, ok, *_ = rs._march_station(s, State(), None, None, None, None, True, 1.0, (2, 200), 1e-6, [])
    assert not ok and s.calls < 150
    assert not rs._cycling([31.0 * 0.9**i if i % 2 == 0 else 0.97 * 0.9**i for i in range(40)], 1e-6)
    period = [18.0, 0.95, 0.78, 0.65, 0.52, 0.47, 0.39, 0.35, 0.31, 0.28, 0.72]
    assert rs._cycling([0.7, 0.3] + period * 3, 1e-6)
    assert not rs._cycling([0.7, 0.3] + period * 3, 1.0)  # above the tolerance only


def test_an_attempt_whose_changes_explode_is_a_divergence():
    """Two consecutive outer iterations that change the state by more than
    rans.solver.DIVERGED_CHANGE (after the fourth) end the attempt as a divergence, ~40
    iterations before the overflow would; every attempt diverging, the last one's divergence
    is raised."""
    from rans import solver as rs

    class Exploding:
        alpha_u, coupled, last_change = 1.0, False, (1.0, 1.0)
        calls = 0

        def iterate(self, st, *args):
            self.calls += 1
            return 1e9

    class State:
        def copy(self):
            return State()

    s = Exploding()
    s.x, s.station = 0.5, 3
    with pytest.raises(rs.SolverDivergence, match="changed the state by 1e\\+09"):
        rs._march_station(s, State(), None, None, None, None, True, 1.0, (2, 200), 1e-6, [])
    assert s.calls % 5 == 0 and s.calls <= 5 * 12
