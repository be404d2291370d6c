"""The Lagrangian pass: geometry, interpolation, bookkeeping, momentum budget, determinism."""

import math

import numba
import numpy as np
import pytest

from particles import FieldTable, ParticleSpec, PhysicsOptions, TrackSettings, track
from particles.fields import F_EPS, F_K, F_UX, F_WX, F_WZ, YSTAR_VISCOUS
from particles.kernel import MAX_SEGMENTS, walk_segment
from rans import PipeMesh, locate_cell
from rans import kepsilon as ke

from .particle_support import AIR, periodic_pipe

def RS(nt):
    return np.sin(np.arange(nt + 1) * 2.0 * math.pi / nt)


def RC(nt):
    return np.cos(np.arange(nt + 1) * 2.0 * math.pi / nt)


BASE = ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 1.5)  # Tsuji-Morikawa base particles


# ------------------------------------------------------------------ geometry
def test_segment_walk_splits_by_time_fraction_into_the_right_cells():
    mesh = PipeMesh.build(0.0305, 0.1, axial_cells=10, radial_cells=8, azimuthal_cells=16)
    rng = np.random.default_rng(3)
    cells = np.empty(MAX_SEGMENTS, dtype=np.int64)
    fracs = np.empty(MAX_SEGMENTS)
    nr, nt = mesh.nr, mesh.nt
    rmax = 0.999 * mesh.radius
    for _ in range(2000):
        p0 = np.array([rng.uniform(0, 0.1), *(rmax * np.sqrt(rng.uniform()) * np.array(
            [math.sin(t := rng.uniform(0, 2 * math.pi)), math.cos(t)]))])
        p1 = np.array([rng.uniform(0, 0.1), *(rmax * np.sqrt(rng.uniform()) * np.array(
            [math.sin(t := rng.uniform(0, 2 * math.pi)), math.cos(t)]))])
        d = p1 - p0
        i, j, k = locate_cell(*p0, mesh.length, mesh.nx, mesh.r_edges, nt)
        n, end = walk_segment(*p0, *d, i, j, k, mesh.x_edges, mesh.r_edges, RS(nt), RC(nt), cells, fracs)
        assert end == 0
        assert fracs[:n].sum() == pytest.approx(1.0, abs=1e-12)
        s = 0.0
        for q in range(n):  # the midpoint of each piece lies in the cell it is credited to
            if fracs[q] > 1e-9:
                mid = p0 + (s + 0.5 * fracs[q]) * d
                ci, cj, ck = locate_cell(*mid, mesh.length, mesh.nx, mesh.r_edges, nt)
                assert cells[q] == (ci * nr + cj) * nt + ck
            s += fracs[q]


def test_segment_walk_stops_at_the_outlet_plane():
    mesh = PipeMesh.build(0.0305, 0.1, axial_cells=10, radial_cells=8, azimuthal_cells=16)
    cells = np.empty(MAX_SEGMENTS, dtype=np.int64)
    fracs = np.empty(MAX_SEGMENTS)
    n, end = walk_segment(0.095, 0.0, 0.001, 0.01, 0.0, 0.0, 9, 0, 0, mesh.x_edges, mesh.r_edges,
                          RS(mesh.nt), RC(mesh.nt), cells, fracs)
    assert end == 1 and fracs[:n].sum() == pytest.approx(0.5)


# ------------------------------------------------------------------ interpolation
def test_fields_are_continuous_through_the_axis_and_exact_at_cell_centres():
    mesh, gas = periodic_pipe()
    tab = FieldTable.from_gas(mesh, gas)
    j, k = 5, 7
    at = tab.at(0.5, mesh.y[j, k], mesh.z[j, k])
    assert at[F_UX] == pytest.approx(gas.ux[0, j, k], rel=1e-12)
    assert at[F_K] == pytest.approx(gas.k[0, j, k], rel=1e-12)
    a = tab.at(0.5, 1e-9, 0.0)
    b = tab.at(0.5, -1e-9, 0.0)
    c = tab.at(0.5, 0.0, 0.0)
    assert a[:F_WX] == pytest.approx(c[:F_WX], rel=1e-6) and b[:F_WX] == pytest.approx(c[:F_WX], rel=1e-6)
    assert c[F_UX] == pytest.approx(gas.ux[0, 0].mean(), rel=1e-12)


def test_ring_search_from_any_hint_gives_the_binary_search_result():
    """The tracker finds the ring by stepping from the previous ring: the cell and every field
    must equal those of the binary search (rans.locate_cell), bit for bit, for any hint."""
    from particles.fields import NF, interpolate

    mesh, gas = periodic_pipe()
    tab = FieldTable.from_gas(mesh, gas)
    rng = np.random.default_rng(3)
    n = 400
    r = mesh.radius * np.concatenate([np.sqrt(rng.random(n - 4)), [0.0, 1.0, 1.0 + 1e-6, 1.1]])
    ne = len(mesh.r_edges) + len(mesh.r)
    r[:ne] = np.concatenate([mesh.r_edges, mesh.r])  # exactly on ring edges and centres (th = 0)
    th = 2 * np.pi * rng.random(n)
    th[:ne] = 0.0
    x = np.where(rng.random(n) < 0.05, -1e-3, rng.random(n) * mesh.length)
    x[ne:ne + 5] = mesh.length * np.array([1.0, 1.0 + 1e-9, 1.001, 0.0, 0.5])  # at and beyond the ends
    args = (tab.values, tab.axis, tab.x_centres, tab.r_centres, tab.r_edges, tab.length, tab.radius, tab.nu)
    ref, got = np.empty(NF), np.empty(NF)
    for p in range(n):
        y, z = (0.0, r[p]) if th[p] == 0.0 else (r[p] * np.sin(th[p]), r[p] * np.cos(th[p]))
        cell = interpolate(x[p], y, z, *args, ref)
        assert cell == locate_cell(x[p], y, z, mesh.length, mesh.nx, mesh.r_edges, mesh.nt)
        for hint in range(mesh.nr):
            assert interpolate(x[p], y, z, *args, got, hint) == cell
            np.testing.assert_array_equal(got, ref)


def test_wall_cell_fields_follow_the_log_law_not_a_linear_ramp():
    mesh, gas = periodic_pipe()
    tab = FieldTable.from_gas(mesh, gas)
    k_sector = 10
    theta = mesh.theta[k_sector]
    u_p, k_p, eps_p = gas.ux[0, -1, k_sector], gas.k[0, -1, k_sector], gas.epsilon[0, -1, k_sector]
    y_p = mesh.radius - mesh.r[-1]
    nu = AIR.kinematic_viscosity
    u_star = ke.C_MU**0.25 * math.sqrt(k_p)
    for y in (0.8 * y_p, 0.5 * y_p):
        r = mesh.radius - y
        f = tab.at(0.5, r * math.sin(theta), r * math.cos(theta))
        expected = u_p * math.log(ke.E_WALL * u_star * y / nu) / math.log(ke.E_WALL * u_star * y_p / nu)
        assert u_star * y / nu > YSTAR_VISCOUS
        assert f[F_UX] == pytest.approx(expected, rel=1e-9)
        assert f[F_K] == pytest.approx(k_p, rel=1e-12)
        assert f[F_EPS] == pytest.approx(eps_p * y_p / y, rel=1e-12)
        # |curl U| = dU/dy = u_P / (y ln(E y*_P)) (azimuthal vorticity at the wall)
        dudy = u_p / (y * math.log(ke.E_WALL * u_star * y_p / nu))
        assert math.hypot(f[F_WX + 1], f[F_WZ]) == pytest.approx(dudy, rel=1e-9)
        assert f[F_UX] > u_p * (y / y_p)  # well above a linear interpolation to zero
    # in the viscous sublayer (y* < 11.53) the profile is u+ = y+ and eps keeps its edge value
    y = 0.5 * YSTAR_VISCOUS * nu / u_star
    r = mesh.radius - y
    f = tab.at(0.5, r * math.sin(theta), r * math.cos(theta))
    assert f[F_UX] == pytest.approx(u_p * (u_star * y / nu) / math.log(ke.E_WALL * u_star * y_p / nu)
                                    * ke.KAPPA, rel=1e-9)
    assert f[F_EPS] == pytest.approx(eps_p * y_p / (2.0 * y), rel=1e-12)


def test_wall_ring_option_holds_the_ring_values_out_to_the_wall():
    """physics.wall_cell_fields = "wall-ring": between the wall-ring centre and the wall the
    particle sees the ring's own U, k, eps and curl U (no reconstruction), and no grad k; inside
    the ring centre both options interpolate alike."""
    mesh, gas = periodic_pipe()
    tab = FieldTable.from_gas(mesh, gas)
    k_sector = 10
    theta = mesh.theta[k_sector]
    ring = tab.values[0, -1, k_sector]
    y_p = mesh.radius - mesh.r[-1]
    for y in (0.8 * y_p, 0.3 * y_p, 1e-6 * y_p):
        r = mesh.radius - y
        f = tab.at(0.5, r * math.sin(theta), r * math.cos(theta), wall_law=False)
        np.testing.assert_allclose(f[:F_WZ + 1], ring, rtol=1e-12, atol=1e-12 * np.abs(ring).max())
        assert np.all(f[F_WZ + 1:] == 0.0)
        g = tab.at(0.5, r * math.sin(theta), r * math.cos(theta))
        assert g[F_UX] < f[F_UX] and g[F_EPS] > f[F_EPS]  # the log law falls, eps rises towards the wall
    r = 0.5 * (mesh.r[-2] + mesh.r[-1])
    a = tab.at(0.5, r * math.sin(theta), r * math.cos(theta), wall_law=False)
    np.testing.assert_array_equal(a, tab.at(0.5, r * math.sin(theta), r * math.cos(theta)))


def test_wall_ring_option_reaches_the_tracker():
    """The tracker compiled for "wall-ring" is another kernel: the pass runs, its sources
    differ from the log-law pass's (the particles visit the wall cell), the bookkeeping closes,
    and an unknown value is refused."""
    mesh, gas = periodic_pipe()
    a = track(mesh, gas, BASE, PhysicsOptions(inter_particle_collisions=False), parcels=500, seed=3,
              pass_index=0)
    b = track(mesh, gas, BASE, PhysicsOptions(inter_particle_collisions=False, wall_cell="wall-ring"),
              parcels=500, seed=3, pass_index=0)
    for s in (a, b):
        assert s.counts["lost"] == 0 and s.counts["injected"] == s.counts["exited"] + s.counts["stuck"]
    assert not np.array_equal(a.momentum_source(0), b.momentum_source(0))
    with pytest.raises(ValueError, match="wall_cell"):
        PhysicsOptions(wall_cell="cell")


# ------------------------------------------------------------------ passes
@pytest.fixture(scope="module")
def base_passes():
    mesh, gas = periodic_pipe()
    first = track(mesh, gas, BASE, PhysicsOptions(), parcels=3000, seed=7, pass_index=0)
    stats = first.cell_statistics(gas)
    second = track(mesh, gas, BASE, PhysicsOptions(), parcels=3000, seed=7, pass_index=1,
                   stats=stats, keep_states=True)
    return mesh, gas, first, second, stats


def test_every_parcel_is_accounted_for(base_passes):
    *_, first, second, _ = base_passes
    for s in (first, second):
        c = s.counts
        assert c["lost"] == 0
        assert c["injected"] == c["exited"] + c["stuck"] == 3000
    assert second.counts["particle_collisions"] > 0 and first.counts["particle_collisions"] == 0
    assert second.counts["wall_rebounds"] > 0


@pytest.mark.parametrize("which", ["one-way pass (no collision statistics)", "four-way pass"])
def test_momentum_budget_closes_to_round_off(base_passes, which):
    """Σ cells of the source = −(out − in − net weight − wall − inter-particle − inlet impulses)."""
    mesh, _, first, second, _ = base_passes
    s = first if which.startswith("one") else second
    b = s.budget
    cell_sum = -np.array([s.momentum_source(c) * mesh.volume for c in range(3)]).reshape(3, -1).sum(axis=1)
    balance = (b["momentum_out"] - b["momentum_in"] - b["weight"] - b["wall_collisions"]
               - b["particle_collisions"] - b["inlet_reflections"])
    scale = np.abs(b["momentum_in"]).max()
    assert cell_sum == pytest.approx(b["fluid_impulse"], abs=1e-12 * scale)
    assert cell_sum == pytest.approx(balance, abs=1e-11 * scale)
    if which == "four-way pass":
        assert np.abs(b["particle_collisions"]).max() > 1e-6 * scale  # counted, and not negligible
    assert b["mass_out"] + b["mass_stuck"] == pytest.approx(b["mass_in"], rel=1e-13)


def test_axial_mass_flux_carries_the_particle_mass_flow(base_passes):
    mesh, gas, first, *_ = base_passes
    mdot = BASE.mass_loading * AIR.density * 10.0 * math.pi * mesh.radius**2
    flow = np.sum(first.mass_flux * mesh.cell_area[None])
    assert flow == pytest.approx(mdot, rel=1e-3)


def test_injection_is_uniform_over_the_section(base_passes):
    mesh, *_, second, _ = base_passes
    st = second.states
    r2 = (st[:, 17] ** 2 + st[:, 18] ** 2) / (mesh.radius - 0.5 * BASE.diameter) ** 2
    assert np.all(st[:, 16] == 0.0)
    assert r2.mean() == pytest.approx(0.5, abs=4 * math.sqrt(1 / 12 / st.shape[0]))


def test_standard_errors_come_from_the_batch_spread(base_passes):
    *_, first, _, _ = base_passes
    assert first.batches >= 8
    se = first.concentration_stderr
    c = first.concentration
    filled = first.visits > 50
    rel = se[filled] / c[filled]
    assert np.all(np.isfinite(rel)) and np.median(rel) < 0.5 and np.all(rel > 0.0)


def test_same_sources_bit_for_bit_with_one_and_two_threads(base_passes):
    mesh, gas, _, second, stats = base_passes
    old = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = track(mesh, gas, BASE, PhysicsOptions(), parcels=3000, seed=7, pass_index=1, stats=stats)
    finally:
        numba.set_num_threads(old)
    assert numba.config.NUMBA_NUM_THREADS >= 2
    assert np.array_equal(one.total, second.total)
    assert np.array_equal(one.var, second.var, equal_nan=True)


def test_a_pass_draws_fresh_noise_and_a_seed_reproduces(base_passes):
    mesh, gas, first, *_ = base_passes
    again = track(mesh, gas, BASE, PhysicsOptions(), parcels=3000, seed=7, pass_index=0)
    other = track(mesh, gas, BASE, PhysicsOptions(), parcels=3000, seed=7, pass_index=5)
    assert np.array_equal(again.total, first.total)
    assert not np.array_equal(other.total, first.total)


@pytest.mark.parametrize("u_inject", [10.0, 7.0])
def test_drag_coefficient_is_the_momentum_source_per_unit_slip(u_inject):
    """Sample.drag_coefficient β = (1/V) Σ Ṅ m δt/τ_p.  Drag only, uniform gas at 10 m/s
    (negligible turbulence): particles injected at the gas velocity keep zero slip, so
    β = c/τ_p0 (Stokes, the concentration c over the response time) to round-off; injected
    at 7 m/s, the source on the gas is −β (U − ū_p) per cell (each step's impulse is m/τ_p times its mean
    slip times δt; the cell mixes steps of slightly different τ_p)."""
    from .particle_support import uniform_field

    drag_only = PhysicsOptions(saffman_mei_lift=False, magnus_lift=False, rotation=False, gravity=False,
                        inter_particle_collisions=False)
    mesh = PipeMesh.build(0.0305, 0.5, mode="developing", axial_cells=20, radial_cells=6, azimuthal_cells=8,
                          bulk_velocity=10.0)
    gas = uniform_field(mesh, ux=10.0, k=1e-24, epsilon=1e-24)
    spec = ParticleSpec(200e-6, 1020.0, 1.0, u_inject, 1e-9)
    s = track(mesh, gas, spec, drag_only, parcels=400, seed=3)
    assert s.counts["lost"] == 0 and s.counts["exited"] == 400
    # the outlet cell also holds the impulse beyond the plane; the wall ring sees the log law
    inner = (slice(0, -1), slice(0, -1))
    beta = s.drag_coefficient[inner]
    tau0 = spec.density * spec.diameter**2 / (18.0 * AIR.viscosity)
    if u_inject == 10.0:
        np.testing.assert_allclose(beta, s.concentration[inner] / tau0, rtol=1e-6)  # f - 1 ~ slip^0.687
    else:
        slip = 10.0 - s.velocity(0)[inner]
        assert slip.min() > 1.0  # still slipping at the outlet
        assert np.all(beta > 1.2 * s.concentration[inner] / tau0)  # Schiller-Naumann: f > 1
        np.testing.assert_allclose(s.momentum_source(0)[inner], -beta * slip, rtol=1e-3)  # the gas loses it


@pytest.mark.parametrize("component", [1, 2])
def test_a_cross_flow_gives_the_gas_the_in_plane_source_of_its_own_component(component):
    """Drag only in a uniform gas with a cross flow of 1 m/s in y (component 1) or z (2) besides
    10 m/s axially: per cell the source on the gas in that component is −β (U_c − ū_p,c), the
    gas losing what it gives the particles, and the other in-plane component has none. A sign
    or a y/z swap between the kernel's accumulators and the gas's components fails here."""
    from .particle_support import uniform_field

    drag_only = PhysicsOptions(saffman_mei_lift=False, magnus_lift=False, rotation=False, gravity=False,
                               inter_particle_collisions=False, langevin=False, drift_correction=False)
    mesh = PipeMesh.build(0.0305, 0.1, mode="developing", axial_cells=5, radial_cells=6, azimuthal_cells=8,
                          bulk_velocity=10.0)
    gas = uniform_field(mesh, ux=10.0, k=1e-24, epsilon=1e-24)
    (gas.uy if component == 1 else gas.uz)[:] = 1.0
    s = track(mesh, gas, ParticleSpec(50e-6, 1020.0, 1.0, 10.0, 1e-9), drag_only, parcels=2000, seed=3)
    inner = (slice(1, -1), slice(0, -1))  # past the first station, off the wall ring
    c = s.concentration[inner]
    full = c > 0.5 * c.mean()  # the cells the particles have not left
    assert full.sum() > 0.8 * full.size
    beta = s.drag_coefficient[inner][full]
    slip = 1.0 - s.velocity(component)[inner][full]
    assert slip.min() > 0.2  # the particles have not caught up with the cross flow
    np.testing.assert_allclose(s.momentum_source(component)[inner][full], -beta * slip, rtol=1e-2)
    other = 3 - component
    assert (np.abs(s.momentum_source(other)[inner][full]).max()
            < 1e-3 * np.abs(s.momentum_source(component)[inner][full]).min())


def test_partners_about_the_cell_mean_need_one_correlation_per_cell():
    """1 µm tracers in fully developed pipe flow, collision statistics from a pass through the
    same gas: partners drawn like the particles conserve momentum on average, so the net
    axial velocity the collisions give a particle per collision must vanish within the batch
    standard error. With R(St) taken at each particle (T_L of the log-law wall cell, ∝ y)
    it does not: 1 − R is largest where the tracers are slowest, and each collision pulls a
    tracer towards the cell mean by ~(1 − R)(ū − u₁) — the mechanism of the tracers'
    +1.8 of their momentum inflow in the stability study (docs/history.md). Measured:
    +20.4 ± 2.3 mm/s per collision against −0.1 ± 1.9 mm/s with R per cell."""
    from particles.layout import B_PP

    mesh, gas = periodic_pipe()
    spec = ParticleSpec(1e-6, 1020.0, 0.2, 10.0)
    first = track(mesh, gas, spec, PhysicsOptions(), parcels=1000, seed=3, pass_index=0)
    stats = first.cell_statistics(gas)
    w_m = first.budget["mass_in"] / 1000  # kg/s carried by one parcel
    per_collision = {}
    for where in ("particle", "cell"):
        s = track(mesh, gas, spec, PhysicsOptions(partner_correlation=where), parcels=1000, seed=3,
                  pass_index=1, stats=stats)
        n = s.counts["particle_collisions"]
        assert n > 30000 and s.counts["lost"] == 0
        se = math.sqrt(s.var[s._lay.budget + B_PP])
        per_collision[where] = (s.budget["particle_collisions"][0] / (w_m * n), se / (w_m * n), n)
    # R per cell is of the size of R per particle (read from the statistics: with R = 0, i.e. a
    # wrong or infinite St, the collisions quadruple: 235736 against ~61000, scratch runs)
    assert per_collision["cell"][2] == pytest.approx(per_collision["particle"][2], rel=0.1)
    mean, se, _ = per_collision["cell"]
    assert abs(mean) < 3.0 * se, per_collision
    mean, se, _ = per_collision["particle"]
    assert mean > 5.0 * se and mean > 0.01, per_collision  # m/s


def test_residence_cap_stops_and_counts_parcels():
    mesh, gas = periodic_pipe()
    s = track(mesh, gas, BASE, PhysicsOptions(inter_particle_collisions=False), parcels=200, seed=1,
              settings=TrackSettings(residence_cap=0.02))
    assert s.counts["stuck"] == 200 and s.counts["lost"] == 0
    b = s.budget
    assert b["mass_stuck"] == pytest.approx(b["mass_in"], rel=1e-13)


def test_a_kernel_compiled_for_other_options_is_refused(monkeypatch):
    """numba's on-disk cache, written by two processes at once, once served a four-way pass the
    kernel without collisions (same results as two-way, no error).  Every batch now reports the
    option set it was compiled for, and the driver refuses a mismatch."""
    import particles.tracking as tr

    mesh, gas = periodic_pipe()
    two_way = PhysicsOptions(inter_particle_collisions=False)
    inputs = tr.prepare_pass(mesh, gas, BASE, two_way, parcels=20, seed=1)
    tr.run_superbatch(inputs, 0)  # the right kernel passes
    right = tr.make_tracker(two_way)[1]
    # another option set's kernel: the wall-ring one, which test_wall_ring_option_reaches_the_tracker
    # compiles as well (one compile of ~15 s cold for both)
    other = tr.make_tracker(PhysicsOptions(inter_particle_collisions=False, wall_cell="wall-ring"))[1]

    class CorruptEntry:  # another option set's code, filed under this one's key
        eulag_variant = right.eulag_variant

        def __call__(self, *args):
            return other(*args)

    monkeypatch.setattr(tr, "make_tracker", lambda options: (None, CorruptEntry()))
    with pytest.raises(RuntimeError, match="compiled for other physics options"):
        tr.run_superbatch(inputs, 0)


def test_numba_cache_entries_written_at_once_keep_their_own_data(tmp_path, monkeypatch):
    """Two writers of one numba cache index (two processes compiling two variants of a kernel)
    must not end with one key pointing at the other's data: jitcache serialises them."""
    import threading
    import time

    import jitcache  # noqa: F401 - installs the lock
    from numba.core import caching

    cls = caching.IndexDataCacheFile
    assert cls._eulag_serialised
    real_load = cls._load_index

    def slow_load(self):  # widen the read-modify-write window of save()
        out = real_load(self)
        time.sleep(0.2)
        return out

    monkeypatch.setattr(cls, "_load_index", slow_load)
    stamp = (1.0, 1)

    def write(key):
        cls(str(tmp_path), "kernel", stamp).save(key, f"code of {key}")

    threads = [threading.Thread(target=write, args=(k,)) for k in ("with collisions", "without")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    reader = cls(str(tmp_path), "kernel", stamp)
    assert reader.load("with collisions") == "code of with collisions"
    assert reader.load("without") == "code of without"


def test_statistics_of_another_layout_are_refused():
    """The kernel reads the statistics' rows unchecked: an array of another shape (a v0.1.0
    layout without CS_ST, say) is refused before tracking."""
    from particles.layout import NCS

    mesh, gas = periodic_pipe()
    stats = np.zeros((mesh.nx * mesh.nr * mesh.nt, NCS - 1))
    with pytest.raises(ValueError, match=r"stats: shape .* the tracker reads"):
        track(mesh, gas, BASE, PhysicsOptions(), parcels=10, stats=stats)


def test_windowed_sweep_follows_the_same_trajectories():
    """Tracking a batch window by window (parcels suspended at a window's end and resumed in the
    next) gives every parcel the trajectory of tracking it in one go: the same final states bit
    for bit, the same counts, sums equal to round-off (only their order differs)."""
    mesh = PipeMesh.build(0.0305, 0.3, radial_cells=8, azimuthal_cells=16, axial_cells=30)
    from rans import solve
    gas = solve(mesh, AIR, 10.0, 1.0, ke.inlet_epsilon(1.0, 0.0305))
    stats = track(mesh, gas, BASE, PhysicsOptions(), parcels=300, seed=3,
                  pass_index=0).cell_statistics(gas)
    runs = [track(mesh, gas, BASE, PhysicsOptions(), parcels=300, seed=3, pass_index=1, stats=stats,
                  settings=TrackSettings(window_stations=w), keep_states=True) for w in (0, 3, 1)]
    assert runs[0].counts["particle_collisions"] > 0 and runs[0].counts["wall_rebounds"] > 0
    for other in runs[1:]:
        assert np.array_equal(runs[0].states, other.states)
        assert runs[0].counts == other.counts
        np.testing.assert_allclose(other.total, runs[0].total, rtol=0,
                                   atol=1e-13 * np.abs(runs[0].total).max())


def test_loop_flags_keep_the_finiteness_checks():
    """The parcel loop's fast-math flags (collisions.conf.LOOP_FLAGS) must leave NaN and inf
    testable: a non-finite parcel state is counted lost by the loop's math.isfinite checks,
    which LLVM's nnan/ninf flags would fold to True.  A division by zero gives inf/NaN under
    the loop's numpy error model instead of raising."""
    import math

    from numba import njit

    from collisions.conf import LOOP_FLAGS

    @njit(**{**LOOP_FLAGS, "cache": False})
    def finite_ratio(a, b):
        q = a / b
        return math.isfinite(q), q

    assert finite_ratio(1.0, 4.0) == (True, 0.25)
    ok, q = finite_ratio(1.0, 0.0)
    assert not ok and q == math.inf
    ok, q = finite_ratio(0.0, 0.0)
    assert not ok and math.isnan(q)


def test_kolmogorov_step_rule_acts_only_where_the_turbulence_has_died_out():
    """``step_rule = "kolmogorov"`` bounds the T_L of the step below by the Kolmogorov time
    √(ν/ε), which exceeds T_L = C_T (2k/3)/ε only where k²/(νε) < 39.  In the developed pipe's
    live turbulence the pass is the default rule's, bit for bit.  With k a hundredth of it (a
    turbulence put out, as the particles' sink does in the dense scenes; k²/(νε) < 39) the
    default rule's steps shrink with T_L, the bounded rule takes far fewer, and the two passes
    (independent seeds) agree cell by cell within their standard errors."""
    import dataclasses

    mesh, gas = periodic_pipe(10, 20)
    nu = AIR.viscosity / AIR.density
    # cell values; in the wall cell the kernel's log-law epsilon is up to ~3 times the cell's,
    # so the particles see k^2/(nu eps) above 39 only if the cells are above ~117
    assert (gas.k ** 2 / (nu * gas.epsilon)).min() > 117.0
    one_way = PhysicsOptions(inter_particle_collisions=False)
    kolmo = dataclasses.replace(one_way, step_rule="kolmogorov")
    a = track(mesh, gas, BASE, one_way, parcels=2000, seed=3)
    b = track(mesh, gas, BASE, kolmo, parcels=2000, seed=3)
    np.testing.assert_array_equal(a.visits, b.visits)
    np.testing.assert_array_equal(a.concentration, b.concentration)
    for c in range(3):
        np.testing.assert_array_equal(a.momentum_source(c), b.momentum_source(c))
    np.testing.assert_array_equal(a.k_source, b.k_source)

    dead = dataclasses.replace(gas, k=gas.k * 1e-2)
    assert (dead.k ** 2 / (nu * dead.epsilon)).max() < 39.0
    d = track(mesh, dead, BASE, one_way, parcels=400, seed=3)
    q = track(mesh, dead, BASE, kolmo, parcels=400, seed=4)
    assert q.visits.sum() < 0.2 * d.visits.sum(), (q.visits.sum(), d.visits.sum())
    z = (q.concentration - d.concentration) / np.hypot(q.concentration_stderr, d.concentration_stderr)
    assert np.sqrt(np.mean(z[np.isfinite(z)] ** 2)) < 1.5
    va, vb = (q.momentum_source(0) * q.volume).sum(), (d.momentum_source(0) * d.volume).sum()
    se = math.hypot(np.sqrt(((q.momentum_source_stderr(0) * q.volume) ** 2).sum()),
                    np.sqrt(((d.momentum_source_stderr(0) * d.volume) ** 2).sum()))
    assert abs(va - vb) < 4.0 * se, (va, vb, se)


def test_cache_keys_of_the_compiled_packages_hold_their_sources_digest(tmp_path):
    """numba keys a cached function by its own bytecode and file only; the kernels assembled from
    other files (the tracker from the motion, wall and collision kernels) would be served stale
    after an edit of one of those.  jitcache adds a digest of every source file of the compiled
    packages to their functions' cache stamps, and the digest follows any edit of any of them."""
    import shutil

    from numba import njit
    from numba.core.caching import Cache, FunctionCache

    import jitcache as jit
    from collisions.interparticle import sommerfeld_2001_correlation
    from particles.kernel import fold_batches

    # the digest: every .py file of every compiled package, and nothing else
    root = tmp_path / "tree"
    src = jit.Path(jit.__file__).resolve().parents[1]
    for pkg in jit.PROJECT_PACKAGES:
        shutil.copytree(src / pkg, root / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    base = jit.source_digest(root)
    assert base == jit.source_digest(src)
    (root / "collisions" / "notes.txt").write_text("not a source file")
    assert jit.source_digest(root) == base
    f = root / "collisions" / "interparticle.py"
    f.write_text(f.read_text().replace("exp(-0.55 * stokes**0.4)", "exp(-0.56 * stokes**0.4)"))
    assert jit.source_digest(root) != base

    # the keys: the project's functions (module-level and closures) carry it, others do not
    def foreign(x):
        return x + 1.0

    digest = Cache._eulag_digest  # the sources' digest when the guard was installed
    for fn, ours in ((sommerfeld_2001_correlation.py_func, True), (fold_batches.py_func, True),
                     (njit(foreign).py_func, False)):
        stamp = FunctionCache(fn)._cache_file._source_stamp
        assert (isinstance(stamp, tuple) and len(stamp) == 2 and stamp[1] == digest) == ours, (fn, stamp)


def test_every_compiled_function_states_the_flags_numba_would_inherit():
    """numba compiles a function whose fastmath, error_model or nrt is unset with those of the
    first jitted caller and keeps that compilation: the helpers called from the fast-math
    tracking loop then depended on who called them first (a four-way pass moved by 1e-15 to
    4e-11 with the process's history).  Every numba function of the compiled packages states
    them (jitcache.JIT_FLAGS), and the cache key holds each function's options."""
    import importlib
    import pkgutil

    from numba.core.dispatcher import Dispatcher

    import jitcache
    from particles.kernel import make_motion, make_tracker

    found = []
    for pkg in jitcache.PROJECT_PACKAGES:
        for info in pkgutil.iter_modules(importlib.import_module(pkg).__path__):
            mod = importlib.import_module(f"{pkg}.{info.name}")
            found += [(f"{pkg}.{info.name}.{k}", v) for k, v in vars(mod).items() if isinstance(v, Dispatcher)]
    found += [("make_motion()", make_motion(PhysicsOptions()))]
    found += [(f"make_tracker()[{i}]", d) for i, d in enumerate(make_tracker(PhysicsOptions()))]
    assert len(found) > 80, len(found)
    unset = [name for name, d in found
             if not {"fastmath", "error_model", "_nrt"} <= set(d.targetoptions)]
    assert not unset, unset
    keys = {jitcache._options_key(d.targetoptions) for _, d in found}
    assert len(keys) > 2  # plain, kernel (no reference counting), loop (fast-math), parallel, ...


def test_option_sets_that_compile_to_the_same_code_share_one_kernel():
    """Switches the kernel does not read (the partners' law without inter-particle collisions,
    the drift's form without the drift correction, the Magnus model without Magnus lift) do
    not make a kernel of their own: one compilation serves them all.  Switches it reads do."""
    import dataclasses

    from collisions import InterparticleOptions
    from particles.kernel import kernel_options, make_tracker, make_window_tracker

    two_way = PhysicsOptions(inter_particle_collisions=False)
    variants = [dataclasses.replace(two_way, partner_momentum="returned"),
                dataclasses.replace(two_way, partner_correlation="cell",
                                    interparticle=InterparticleOptions(restitution=0.5, covariance="full")),
                dataclasses.replace(two_way, drift_correction=False, drift_form="particle"),
                dataclasses.replace(two_way, magnus_lift=False, magnus_model="oesterle-bui-dinh")]
    for v in variants[:2]:
        assert kernel_options(v) == two_way
        assert make_tracker(v)[1] is make_tracker(two_way)[1]
        assert make_window_tracker(v) is make_window_tracker(two_way)
    assert kernel_options(variants[2]) == dataclasses.replace(two_way, drift_correction=False)
    assert kernel_options(variants[3]) == dataclasses.replace(two_way, magnus_lift=False)
    assert kernel_options(PhysicsOptions(langevin=False, drift_correction=False, drift_form="response")) == \
        PhysicsOptions(langevin=False)
    # every switch the kernel reads keeps its own kernel
    four_way = PhysicsOptions()
    read = [dataclasses.replace(four_way, partner_momentum="returned"),
            dataclasses.replace(four_way, partner_correlation="cell"),
            dataclasses.replace(four_way, interparticle=InterparticleOptions(covariance="full")),
            dataclasses.replace(four_way, drift_form="particle"),
            dataclasses.replace(four_way, magnus_model="oesterle-bui-dinh"),
            dataclasses.replace(four_way, step_rule="kolmogorov"),
            dataclasses.replace(four_way, wall_cell="wall-ring"),
            two_way]
    for v in read:
        assert kernel_options(v) == v
        assert make_tracker(v)[1] is not make_tracker(four_way)[1]


def test_cache_keys_hold_numba_s_compile_settings(monkeypatch):
    """A kernel compiled with NUMBA_OPT=0 or bounds checks (a debugging session) is not served
    from the cache to a run with numba's defaults: the settings are part of the key."""
    from numba import types
    from numba.core import config
    from numba.core.caching import FunctionCache

    from collisions.interparticle import sommerfeld_2001_correlation as fn

    cache = FunctionCache(fn.py_func)
    codegen = fn.targetctx.codegen()
    sig = (types.float64,)
    default = cache._index_key(sig, codegen)
    assert cache._index_key(sig, codegen) == default
    monkeypatch.setattr(config, "OPT", 0)
    assert cache._index_key(sig, codegen) != default
    monkeypatch.undo()
    monkeypatch.setattr(config, "BOUNDSCHECK", 1)
    assert cache._index_key(sig, codegen) != default
