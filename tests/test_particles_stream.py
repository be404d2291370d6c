"""A pass streamed beside the gas march that feeds it equals the pass in the finished field."""

import dataclasses

import numba
import numpy as np
import pytest

from particles import FieldTable, ParticleSpec, PhysicsOptions, TrackSettings, track
from particles.fields import NT, axial_gradient, table_rows
from particles.layout import CS_ST
from particles.stream import StreamedPass
from particles.tracking import cell_stokes
from rans import PipeMesh, Sources, solve
from rans import kepsilon as ke

from .particle_support import AIR, D_PIPE

BASE = ParticleSpec(200e-6, 1020.0, 0.3, 10.0, 0.5, 1.5)  # Tsuji-Morikawa particles, light loading


def _mesh(nx=24, length=0.4):
    return PipeMesh.build(D_PIPE, length, mode="developing", axial_cells=nx, radial_cells=6,
                          azimuthal_cells=12, bulk_velocity=10.0)


def _solve(mesh, sources=None, on_station=None):
    return solve(mesh, AIR, 10.0, 1.0, ke.inlet_epsilon(1.0, D_PIPE), sources, on_station=on_station)


@pytest.fixture(scope="module")
def coupled():
    """A developing pipe, a collisional pass's statistics and the gas with its sources."""
    mesh = _mesh()
    gas0 = _solve(mesh)
    first = track(mesh, gas0, BASE, PhysicsOptions(), parcels=400, seed=5, pass_index=0)
    stats = first.cell_statistics(gas0)
    src = Sources(momentum=0.2 * np.stack([first.momentum_source(c) for c in range(3)]),
                  k=0.2 * first.k_source, epsilon=np.zeros(mesh.shape))  # relaxed, as the loop does
    return mesh, gas0, stats, src


@pytest.mark.parametrize("split", [(0, 37), (3, 9), (11, 12), (0, 1)])
def test_table_rows_split_anywhere_equal_the_whole_table(split):
    """Rows built from any split of the stations equal FieldTable.from_gas bit for bit, and the
    axial gradient equals numpy's on the whole field."""
    mesh = PipeMesh.build(0.08, 2.0, mode="developing", axial_cells=37, radial_cells=5, azimuthal_cells=8,
                          bulk_velocity=10.0)
    rng = np.random.default_rng(2)
    f = [rng.normal(size=mesh.shape) for _ in range(3)] + [rng.uniform(0.1, 1, size=mesh.shape) for _ in range(2)]
    j0, j1 = split
    assert np.array_equal(axial_gradient(f[0], mesh.x, j0, j1), np.gradient(f[0], mesh.x, axis=0)[j0:j1])
    gas = dataclasses.replace(_solve(_mesh(37, 2.0)), mesh=mesh, ux=f[0], uy=f[1], uz=f[2], k=f[3], epsilon=f[4])
    whole = FieldTable.from_gas(mesh, gas)
    tab = np.full(mesh.shape + (NT,), np.nan)
    axis = np.full((mesh.nx, NT), np.nan)
    for a, b in ((0, j0), (j0, j1), (j1, mesh.nx)):
        if b > a:
            table_rows(mesh.geometry(), mesh.x, *f, a, b, tab, axis)
    assert np.array_equal(tab, whole.values) and np.array_equal(axis, whole.axis)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("window", [1, 4])
def test_streamed_pass_equals_the_pass_in_the_finished_gas(coupled, threads, window):
    """Tracked while the march solves the gas it runs in, a four-way pass (partners' R(St) per
    cell from the streamed gas, two super-batches) gives the sums, variances and counts of the
    pass tracked afterwards, bit for bit, for one and two numba threads."""
    mesh, _, stats, src = coupled
    settings = TrackSettings(window_stations=window, batch_size=60, batches_per_superbatch=4)
    physics = PhysicsOptions(partner_correlation="cell")
    stream = StreamedPass(mesh, AIR, BASE, physics, parcels=600, seed=5, pass_index=1, stats=stats,
                          settings=settings, partner_stokes=True, threads=threads)
    gas = _solve(mesh, src, on_station=stream.station)
    stream.finish(gas)
    got = stream.result()
    cell_stats = stats.copy()
    cell_stats[:, CS_ST] = cell_stokes(stats, gas, BASE)
    old = numba.get_num_threads()
    try:
        numba.set_num_threads(threads)
        want = track(mesh, gas, BASE, physics, parcels=600, seed=5, pass_index=1, stats=cell_stats,
                     settings=settings)
    finally:
        numba.set_num_threads(old)
    assert want.batches == 10 and want.counts["particle_collisions"] > 0
    assert np.array_equal(got.total, want.total)
    assert np.array_equal(got.var, want.var, equal_nan=True)
    assert np.array_equal(got.cov, want.cov, equal_nan=True)
    assert got.counts == want.counts


def test_cancelled_stream_stops_and_a_differing_gas_is_refused(coupled):
    mesh, gas0, stats, src = coupled
    stream = StreamedPass(mesh, AIR, BASE, PhysicsOptions(), parcels=200, seed=5, pass_index=1, stats=stats)
    for i in range(5):
        stream.station(i, gas0.ux[i], gas0.uy[i], gas0.uz[i], gas0.k[i], gas0.epsilon[i])
    stream.cancel(wait=True)
    assert stream.result() is None
    stream = StreamedPass(mesh, AIR, BASE, PhysicsOptions(), parcels=200, seed=5, pass_index=1, stats=stats)
    _solve(mesh, src, on_station=stream.station)
    stream.finish(gas0)  # not the field that was streamed
    with pytest.raises(RuntimeError, match="streamed gas differs"):
        stream.result()


def test_windows_are_swept_before_the_march_ends(coupled):
    """Fed half of the stations, the pass sweeps the windows they cover and waits; fed the rest,
    it ends with the pass of the finished field."""
    import time

    mesh, gas0, stats, _ = coupled
    settings = TrackSettings(window_stations=2, batch_size=100)
    stream = StreamedPass(mesh, AIR, BASE, PhysicsOptions(), parcels=400, seed=5, pass_index=1, stats=stats,
                          settings=settings)
    half = mesh.nx // 2
    for i in range(half):
        stream.station(i, gas0.ux[i], gas0.uy[i], gas0.uz[i], gas0.k[i], gas0.epsilon[i])
    t0 = time.perf_counter()
    while stream.windows_beside_march < (half - 1 - 3) // 2 and time.perf_counter() - t0 < 60:
        time.sleep(0.01)
    assert stream.windows_beside_march == (half - 1 - 3) // 2  # rows half-1 built, 3 beyond a window
    for i in range(half, mesh.nx):
        stream.station(i, gas0.ux[i], gas0.uy[i], gas0.uz[i], gas0.k[i], gas0.epsilon[i])
    stream.finish(gas0)
    want = track(mesh, gas0, BASE, PhysicsOptions(), parcels=400, seed=5, pass_index=1, stats=stats,
                 settings=settings)
    assert np.array_equal(stream.result().total, want.total)


def test_a_parcel_ahead_of_the_march_voids_the_pass(coupled, monkeypatch):
    """With windows swept before the rows their parcels read exist (a negative margin), the
    parcels meet the NaN of the rows not yet built and the pass says so instead of summing them."""
    import time

    import particles.stream as stream_mod

    mesh, gas0, stats, _ = coupled
    monkeypatch.setattr(stream_mod, "ROW_MARGIN", -3)
    stream = StreamedPass(mesh, AIR, BASE, PhysicsOptions(), parcels=200, seed=5, pass_index=1, stats=stats,
                          settings=TrackSettings(window_stations=4, batch_size=50))
    for i in range(mesh.nx // 2):
        stream.station(i, gas0.ux[i], gas0.uy[i], gas0.uz[i], gas0.k[i], gas0.epsilon[i])
    t0 = time.perf_counter()
    while stream._thread.is_alive() and time.perf_counter() - t0 < 60:
        time.sleep(0.01)
    for i in range(mesh.nx // 2, mesh.nx):
        stream.station(i, gas0.ux[i], gas0.uy[i], gas0.uz[i], gas0.k[i], gas0.epsilon[i])
    stream.finish(gas0)
    with pytest.raises(stream_mod.StreamOvershoot, match="was lost|march had delivered|non-finite"):
        stream.result()


def test_result_before_finish_or_cancel_is_refused(coupled):
    mesh, _, stats, _ = coupled
    stream = StreamedPass(mesh, AIR, BASE, PhysicsOptions(), parcels=50, seed=5, pass_index=1, stats=stats)
    with pytest.raises(RuntimeError, match="before finish"):
        stream.result()
    stream.cancel(wait=True)
