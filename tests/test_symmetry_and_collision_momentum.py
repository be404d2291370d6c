"""Mirror-symmetric sampling and the momentum of the stochastic inter-particle collisions."""

import numpy as np
import pytest

from eulag.coupling import CouplingLoop
from eulag.runs import run
from particles import ParticleSpec, PhysicsOptions, track
from particles.layout import ACC_PARITY, A_MU, A_MUV, A_NW, A_PP, A_PPK, A_WM, NACC
from particles.symmetry import mirror_average_vector, mirror_cell_array, mirror_sectors

from .particle_support import periodic_pipe, uniform_field
from .test_coupling import small_case


def mirror_image(a, parity=1):
    """a∘mirror, the field seen in the mirror z → −z (sector axis last), with its parity."""
    return parity * np.take(a, mirror_sectors(a.shape[-1]), axis=-1)


def test_the_mirror_maps_each_sector_on_its_image_across_the_vertical_plane():
    nt = 40
    m = mirror_sectors(nt)
    theta = (np.arange(nt) + 0.5) * 2 * np.pi / nt
    # z = r cos θ changes sign, y = r sin θ does not
    np.testing.assert_allclose(np.cos(theta[m]), -np.cos(theta), atol=1e-15)
    np.testing.assert_allclose(np.sin(theta[m]), np.sin(theta), atol=1e-15)
    assert np.array_equal(m[m], np.arange(nt))
    with pytest.raises(ValueError, match="even number of azimuthal sectors"):
        mirror_sectors(15)


def test_parities_are_those_of_scalars_polar_and_axial_vectors():
    assert len(ACC_PARITY) == NACC
    assert ACC_PARITY[A_WM] == 1
    assert [ACC_PARITY[A_MU + c] for c in range(3)] == [1, 1, -1]  # polar vector: z odd
    assert [ACC_PARITY[A_NW + c] for c in range(3)] == [-1, -1, 1]  # axial vector: x, y odd
    assert [ACC_PARITY[A_PP + c] for c in range(3)] == [1, 1, -1]
    assert [ACC_PARITY[A_PPK + c] for c in range(3)] == [1, 1, -1]
    assert [ACC_PARITY[A_MUV + c] for c in range(3)] == [1, -1, -1]  # u_x u_y even; u_x u_z, u_y u_z odd


@pytest.fixture(scope="module")
def raw_and_symmetrised():
    mesh, gas = periodic_pipe(radial_cells=8, azimuthal_cells=16, length=0.3)
    spec = ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 5.0)
    first = track(mesh, gas, spec, PhysicsOptions(), parcels=2000, seed=5, pass_index=0)
    stats = first.cell_statistics(gas)
    raw = track(mesh, gas, spec, PhysicsOptions(), parcels=2000, seed=5, pass_index=1, stats=stats)
    return mesh, raw, raw.mirror_symmetrised()


def test_a_symmetrised_sample_is_mirror_symmetric_to_the_last_bit(raw_and_symmetrised):
    mesh, raw, sym = raw_and_symmetrised
    for c, parity in ((0, 1), (1, 1), (2, -1)):
        f = sym.momentum_source(c)
        assert np.array_equal(f, mirror_image(f, parity)), c
        v = sym.velocity(c)
        ok = np.isfinite(v)
        assert np.array_equal(v[ok], mirror_image(v, parity)[ok]), c
        g = sym.collision_force(c)
        assert np.array_equal(g, mirror_image(g, parity)), c
    assert np.array_equal(sym.concentration, mirror_image(sym.concentration))
    assert np.array_equal(sym.wall_collision_rate, mirror_image(sym.wall_collision_rate))
    # exact in the mean: the symmetrised field is the mean of the field and its image
    np.testing.assert_allclose(sym.concentration,
                               0.5 * (raw.concentration + mirror_image(raw.concentration)), rtol=1e-13)
    # half the variance: (v + v∘m)/4
    np.testing.assert_allclose(sym.concentration_stderr ** 2,
                               0.25 * (raw.concentration_stderr ** 2 + mirror_image(raw.concentration_stderr ** 2)),
                               rtol=1e-10, atol=1e-300)
    # the section totals (budget) keep x and y; z, odd under the mirror, is exactly zero
    # (as the sum of the symmetrised cells' z components is); the counts are untouched
    assert np.array_equal(sym.budget["fluid_impulse"][:2], raw.budget["fluid_impulse"][:2])
    assert sym.budget["fluid_impulse"][2] == 0.0 and raw.budget["fluid_impulse"][2] != 0.0
    assert sym.counts == raw.counts


def test_mirror_cell_array_keeps_a_symmetric_field_and_kills_an_antisymmetric_one():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 5, 12))
    even = mirror_cell_array(a, +1)
    odd = mirror_cell_array(a, -1)
    np.testing.assert_allclose(even + odd, a, rtol=1e-14, atol=1e-15)
    assert np.array_equal(mirror_cell_array(even, +1), even)
    assert np.array_equal(mirror_cell_array(even, -1), np.zeros_like(a))
    with pytest.raises(ValueError, match="allowed total, var, cov"):
        mirror_average_vector(np.zeros(10), (1, 1, 2), kind="mean")


def test_a_mirror_symmetric_coupled_case_gives_mirror_symmetric_fields():
    """Sources sampled symmetrically → gas and particle fields symmetric to round-off."""
    ds = run(small_case(**{"numerics.max_passes": 3, "numerics.average_passes": 1}))
    assert ds.attrs["case_numerics_mirror_symmetry"] == "true"
    for name, parity in (("gas_ux", 1), ("gas_uy", 1), ("gas_uz", -1), ("gas_k", 1), ("gas_p", 1),
                         ("particle_concentration", 1), ("particle_uz", -1), ("source_uy", 1),
                         ("source_uz", -1), ("particle_collision_force_y", 1)):
        f = ds[name].values
        img = mirror_image(f, parity)
        ok = np.isfinite(f)
        scale = np.nanmax(np.abs(f)) + 1e-300
        assert np.max(np.abs(f[ok] - img[ok])) <= 1e-9 * scale, name


def test_four_way_datasets_carry_the_per_cell_collision_force():
    ds = run(small_case(**{"numerics.max_passes": 3, "numerics.average_passes": 1}))
    for c in "xyz":
        v = ds[f"particle_collision_force_{c}"]
        assert v.attrs["units"] == "N m-3" and v.dims == ("x", "r", "theta")
        assert f"particle_collision_force_{c}_stderr" in ds
        # the cell values integrate to the pipe total, which the parcel budget gives independently
        total = float((v * ds.cell_area).sum() * float(ds.attrs["case_pipe_length"]) / ds.sizes["x"])
        assert total == pytest.approx(float(ds[f"particle_collision_force_total_{c}"]), rel=1e-9,
                                      abs=1e-12)
    two = run(small_case(**{"numerics.max_passes": 2, "numerics.average_passes": 1,
                            "physics.coupling": "two-way"}))
    assert "particle_collision_force_x" not in two


def test_returned_partner_momentum_makes_the_net_collision_force_vanish_in_uniform_gas():
    """Uniform gas (10 m/s, k = 1 m²/s²) in a 0.3 m pipe, 200 µm particles at loading 2.2 with a
    rough wall (Δγ = 5°), gravity: the rebounds skew the particles' vertical velocities, and
    the Gaussian fictitious partners then take momentum out of the particles on balance.
    Statistics relaxed as the coupling loop relaxes them (weight 0.3), eight passes; with the
    partners' momentum returned, the net collision force of the last pass is zero within
    3 standard errors in x, y and z (its error: that pass's batch spread and that of the
    pass the returned acceleration came from, ~√2 the pass's own)."""
    last = _uniform_passes("returned", 8)[-1]
    net, se = last.collision_force_total
    inflow = last.budget["momentum_in"][0]
    assert np.all(np.abs(net) <= 3.0 * np.sqrt(2.0) * se), (net / inflow, se / inflow)
    # the section sum of the per-cell force variables is the same total
    np.testing.assert_allclose([(last.collision_force(c) * last.mesh.volume).sum() for c in range(3)],
                               net, rtol=1e-9, atol=1e-12 * abs(inflow))


def _half_forces(samples):
    """Vertical collision force on the particles in the lower and upper half of the pipe,
    averaged over ``samples``, each over the momentum inflow, with standard errors:
    (lower, se_lower, upper, se_upper)."""
    lo_v, hi_v, lo_s, hi_s = [], [], [], []
    for s in samples:
        vol = s.mesh.volume
        f = np.nan_to_num(s.collision_force(1) * vol)
        e = np.nan_to_num(s.collision_force_stderr(1) * vol)
        lower = np.broadcast_to(s.mesh.y, f.shape) < 0.0
        inflow = s.budget["momentum_in"][0]
        lo_v.append(f[lower].sum() / inflow)
        hi_v.append(f[~lower].sum() / inflow)
        lo_s.append(np.sqrt((e[lower] ** 2).sum()) / inflow)
        hi_s.append(np.sqrt((e[~lower] ** 2).sum()) / inflow)
    n = len(samples)
    return (np.mean(lo_v), np.sqrt(np.sum(np.square(lo_s))) / n,
            np.mean(hi_v), np.sqrt(np.sum(np.square(hi_s))) / n)


def test_discarded_partners_push_the_lower_half_down_and_returned_ones_do_not():
    """The cross-section part of the fictitious partners' momentum error (uniform gas, rough
    wall, gravity; the last three of eight passes): with the partners' impulse discarded the
    skewed vertical velocities of rebounding particles make the collisions pull the lower
    half's particles down and push the upper half's up, each by several standard errors; with
    it returned both halves are zero within 3 standard errors."""
    lo, se_lo, hi, se_hi = _half_forces(_uniform_passes("discarded", 8, parcels=6000)[-3:])
    diff, se_diff = lo - hi, np.hypot(se_lo, se_hi)
    assert lo < 0.0 < hi and diff < -4.0 * se_diff, (lo, se_lo, hi, se_hi)
    lo, se_lo, hi, se_hi = _half_forces(_uniform_passes("returned", 8, parcels=6000)[-3:])
    # each pass's returned acceleration carries the previous passes' noise: sqrt 2 on the error
    assert abs(lo) < 3.0 * np.sqrt(2.0) * se_lo and abs(hi) < 3.0 * np.sqrt(2.0) * se_hi, (lo, se_lo, hi, se_hi)


def _uniform_passes(mode, passes, parcels=3000):
    from eulag.coupling import _relax_statistics
    from rans import PipeMesh

    mesh = PipeMesh.build(0.0305, 0.3, mode="periodic", radial_cells=8, azimuthal_cells=16,
                          bulk_velocity=10.0)
    gas = uniform_field(mesh, ux=10.0, k=1.0, epsilon=30.0)
    spec = ParticleSpec(200e-6, 1020.0, 2.2, 10.0, 0.5, 5.0)
    opt = PhysicsOptions(partner_momentum=mode)
    s = track(mesh, gas, spec, opt, parcels=parcels, seed=11, pass_index=0)
    stats = s.cell_statistics(gas)
    out = []
    for p in range(1, passes + 1):
        s = track(mesh, gas, spec, opt, parcels=parcels, seed=11, pass_index=p, stats=stats)
        s = s.mirror_symmetrised()
        out.append(s)
        new = s.cell_statistics(gas)
        stats = new if p == 1 else _relax_statistics(stats, new, 0.3)
    return out


def _toy_passes(relax, passes=20000, alpha=0.3, seed=3, first=0, scale=1.0, skip=100):
    """A cell whose mass W and collision jump per unit mass r = F_jump/W change together from
    pass to pass (dense passes collide less per unit mass than sparse ones): W = 2, r = -1 or
    W = 0.5, r = -3, each with probability 1/2.  Each pass runs with the returned acceleration
    a of the statistics and leaves the net force F_net = W (r + a); the statistics of the pass
    carry a_new = -r.  ``relax(new, alpha)`` gives the next statistics.  The ``first`` passes
    have ``scale`` times the mass (a cell that fills or empties while the flow develops).  Mean
    F_net after the first ``skip`` passes."""
    from particles.layout import CS_APP, CS_N, CS_OK, NCS

    rng = np.random.default_rng(seed)
    a, nets = 0.0, []
    for n in range(passes):
        w, r = (2.0, -1.0) if rng.random() < 0.5 else (0.5, -3.0)
        w *= scale if n < first else 1.0
        nets.append(w * (r + a))
        new = np.zeros((1, NCS))
        new[0, CS_N], new[0, CS_OK], new[0, CS_APP] = w, 1.0, -r
        a = relax(new, alpha)[0, CS_APP]
    return float(np.mean(nets[skip:]))


def test_the_returned_acceleration_drives_the_mean_net_force_to_zero():
    """The coupling loop's relaxation of the returned acceleration is an integral controller on
    the net collision force (eulag.coupling: CouplingLoop._next_statistics, _relax_statistics):
    with the cell's mass and its jump rate per unit mass fluctuating together, the mean net
    force still vanishes.  The plain blend of a_new = -F_jump/W (the comparison) settles where
    the mean of r + a vanishes, a = 2, and leaves the net force (2 (2 - 1) + 0.5 (2 - 3)) / 2 =
    0.75 per pass."""
    from types import SimpleNamespace

    from eulag.coupling import CouplingLoop

    def plain(new, alpha, state={}):  # noqa: B006 - the toy's statistics between passes
        old = state.get("stats")
        out = new.copy() if old is None else (1 - alpha) * old + alpha * new
        state["stats"] = out
        return out

    def controller(weight=0.3):
        loop = SimpleNamespace(stats=None, two_way=True, pass_index=0, stats_n_ref=None, stats_n_count=None,
                               statistics_weight=lambda: weight)

        def controlled(new, alpha):
            loop.pass_index += 1
            loop.stats = CouplingLoop._next_statistics(loop, new)
            return loop.stats
        return controlled

    assert _toy_passes(plain) == pytest.approx(0.75, abs=0.03)
    # the reference mass is a running mean over STATS_REFERENCE_PASSES = 20 passes: what is
    # left is its own small correlation with the last passes (3 % of the plain blend's here,
    # where the cell's mass changes fourfold from pass to pass)
    assert abs(_toy_passes(controller())) < 0.03
    # the base gain is capped (coupling.RETURNED_GAIN_MAX), so a larger relaxation keeps it unbiased
    assert abs(_toy_passes(controller(0.6))) < 0.03
    # a cell whose loading was 20x or 1/20 in the first 200 passes: the reference forgets it
    for scale in (20.0, 0.05):
        assert abs(_toy_passes(controller(), passes=400, first=200, scale=scale, skip=250)) < 0.04, scale
