"""Inter-particle collisions (collisions.interparticle): binary hard spheres and Sommerfeld (2001)."""

import math
from functools import lru_cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit
from scipy import integrate, stats

from collisions import interparticle as ci
from collisions import random as cr

RHO = 2500.0  # kg/m3, only for the momentum bookkeeping of the tests


def mass(d):
    return RHO * math.pi * d**3 / 6


def inertia(d):
    return mass(d) * d**2 / 10


vec = st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-20, 20))
direction = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2) > 0.1)


def pair_invariants(u1, w1, d1, u2, w2, d2, n):
    """Linear momentum, angular momentum about the origin (sphere 1 at 0, sphere 2 at (r1+r2) n), KE."""
    m1, m2 = mass(d1), mass(d2)
    x2 = 0.5 * (d1 + d2) * n
    p = m1 * u1 + m2 * u2
    L = m2 * np.cross(x2, u2) + inertia(d1) * w1 + inertia(d2) * w2
    ke = 0.5 * (m1 * u1 @ u1 + m2 * u2 @ u2 + inertia(d1) * w1 @ w1 + inertia(d2) * w2 @ w2)
    return p, L, ke


# ---------------------------------------------------------------------------------------------
# binary collision of two real particles (§4.2)
# ---------------------------------------------------------------------------------------------

@given(u1=vec, u2=vec, s1=vec, s2=vec, n=direction, d1=st.floats(1e-5, 1e-3), d2=st.floats(1e-5, 1e-3),
       e=st.floats(0, 1), mu=st.floats(0, 1))
@settings(max_examples=400, deadline=None)
def test_binary_pair_conserves_momentum_and_angular_momentum_energy_not_increasing(u1, u2, s1, s2, n, d1, d2, e,
                                                                                   mu):
    u1, u2 = np.array(u1, float), np.array(u2, float)
    w1, w2 = np.array(s1) / (0.5 * d1), np.array(s2) / (0.5 * d2)  # spins with |r ω| ≤ 35 m/s
    n = np.array(n) / np.linalg.norm(n)
    gn = (u1 - u2) @ n
    if abs(gn) < 1e-6:
        return
    if gn < 0:
        n = -n
        gn = -gn
    p0, L0, ke0 = pair_invariants(u1, w1, d1, u2, w2, d2, n)
    a = [u1.copy(), w1.copy(), u2.copy(), w2.copy()]
    status = ci.hard_sphere_pair(a[0], a[1], d1, a[2], a[3], d2, n, e, mu)
    assert status in (ci.COLLISION_STICKING, ci.COLLISION_SLIDING)
    p1, L1, ke1 = pair_invariants(a[0], a[1], d1, a[2], a[3], d2, n)
    scale_p = mass(d1) * np.linalg.norm(u1) + mass(d2) * np.linalg.norm(u2) + mass(max(d1, d2)) * 1e-3
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-12 * scale_p)
    scale_L = (np.linalg.norm(L0) + scale_p * (d1 + d2))
    np.testing.assert_allclose(L1, L0, rtol=0, atol=1e-12 * scale_L)
    assert ke1 <= ke0 * (1 + 1e-12)
    # normal restitution exact
    assert (a[0] - a[2]) @ n == pytest.approx(-e * gn, rel=1e-9, abs=1e-9 * (gn + 1))

    def slip(v1, om1, v2, om2):
        G = v1 - v2 + np.cross(0.5 * d1 * om1 + 0.5 * d2 * om2, n)
        return G - (G @ n) * n

    G0 = slip(u1, w1, u2, w2)
    G1 = slip(*a)
    if status == ci.COLLISION_STICKING:
        assert np.linalg.norm(G1) <= 1e-9 * (np.linalg.norm(G0) + gn)
    else:
        assert np.linalg.norm(G1 - G0) == pytest.approx(3.5 * mu * (1 + e) * gn, rel=1e-9)
    # compiled vs py_func
    b = [u1.copy(), w1.copy(), u2.copy(), w2.copy()]
    assert ci.hard_sphere_pair.py_func(b[0], b[1], d1, b[2], b[3], d2, n, e, mu) == status
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-9)


def test_pair_impulse_vs_py_func():
    for args in ((1.0, -0.5, 0.2, 0.3, 0.0, -0.1, 0.6, 0.8, 0.0, 0.9, 0.4),  # sliding
                 (1.0, 0.01, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.9, 0.4),  # sticking
                 (-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.9, 0.4)):  # receding
        a = ci.hard_sphere_pair_impulse(*args)
        b = ci.hard_sphere_pair_impulse.py_func(*args)
        assert a[6] == b[6]
        np.testing.assert_allclose(a[:6], b[:6], rtol=1e-14, atol=1e-15)
    assert [ci.hard_sphere_pair_impulse(*x)[6] for x in (
        (1.0, -0.5, 0.2, 0.3, 0.0, -0.1, 0.6, 0.8, 0.0, 0.9, 0.4),
        (1.0, 0.01, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.9, 0.4),
        (-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.9, 0.4))] == [
        ci.COLLISION_SLIDING, ci.COLLISION_STICKING, ci.COLLISION_NONE]


def test_binary_pair_not_approaching_is_unchanged():
    u1, w1, u2, w2 = np.array([1.0, 0, 0]), np.zeros(3), np.array([2.0, 0, 0]), np.zeros(3)
    assert ci.hard_sphere_pair(u1, w1, 1e-4, u2, w2, 1e-4, np.array([1.0, 0, 0]), 0.9, 0.4) == ci.COLLISION_NONE
    assert u1[0] == 1.0 and u2[0] == 2.0


def test_head_on_equal_spheres_vs_textbook():
    """Equal spheres, head-on, e: u₁′ = ((1−e)u₁ + (1+e)u₂)/2."""
    e = 0.9
    u1, u2 = np.array([3.0, 0, 0]), np.array([-1.0, 0, 0])
    w = np.zeros(3)
    ci.hard_sphere_pair(u1, w.copy(), 1e-4, u2, w.copy(), 1e-4, np.array([1.0, 0, 0]), e, 0.4)
    assert u1[0] == pytest.approx(((1 - e) * 3 + (1 + e) * -1) / 2)
    assert u2[0] == pytest.approx(((1 - e) * -1 + (1 + e) * 3) / 2)


# ---------------------------------------------------------------------------------------------
# the fictitious partner path (§4.1)
# ---------------------------------------------------------------------------------------------

OPTS = [ci.InterparticleOptions(), ci.InterparticleOptions(rotation=False),
        ci.InterparticleOptions(restitution=1.0, friction=0.0), ci.InterparticleOptions(covariance="full")]


@given(vel=vec, w=vec, mean_own=vec, mean_partner=vec, rms=st.tuples(*[st.floats(0, 3)] * 3),
       wmean=vec, wrms=st.tuples(*[st.floats(0, 10)] * 3), d1=st.floats(1e-5, 1e-3), d2=st.floats(1e-5, 1e-3),
       stokes=st.floats(0, 100), seed=st.integers(0, 2**40), opt=st.sampled_from(range(len(OPTS))))
@settings(max_examples=300, deadline=None)
def test_fictitious_partner_path_is_binary_collision_with_sampled_partner(vel, w, mean_own, mean_partner, rms, wmean,
                                                                          wrms, d1, d2, stokes, seed, opt):
    """On a collision the real particle's new state is the binary collision with the partner the
    kernel reports (velocity, spin, line of centres); that pair conserves momentum and its KE does
    not increase. (The partner's distribution is checked against the direct algorithm below.)"""
    kernel = ci.make_interparticle_collision(OPTS[opt])
    rotation = OPTS[opt].rotation
    vel = np.array(vel, float)
    omega = np.array(w) / d1 / 20  # |r ω| ≲ 0.5 m/s
    mean_own, mean_partner, rms = map(np.asarray, (mean_own, mean_partner, rms))
    wmean, wrms = np.array(wmean) * 50.0, np.array(wrms)
    rng = cr.rng_state(seed, 2, 9, cr.STREAM_COLLISION)
    v1, w1, dv, partner = vel.copy(), omega.copy(), np.zeros(3), np.full(ci.PARTNER_SIZE, np.nan)
    status = kernel(v1, w1, d1, mean_own, d2, mean_partner, rms, np.zeros(3), wmean, wrms, 1e15,
                    stokes, 10.0, rng, dv, partner)
    if status == ci.COLLISION_NONE:
        # c |g| ≥ 50 makes P = 1 unless g = 0: only a vanishing relative velocity avoids the collision
        assert np.all(np.isnan(partner))
        np.testing.assert_array_equal(v1, vel)
        return
    u2 = partner[:3]
    R = math.exp(-0.55 * stokes**0.4)
    # the partner's deterministic part: |u2 − ū₂ − R u′₁| is a fluctuation of rms σ₂ sqrt(1 − R²) per component
    dev = u2 - mean_partner - R * (vel - mean_own)
    bound = rms * math.sqrt(max(0.0, 1 - R * R)) * 12 + 1e-9 * (1 + np.abs(vel) + np.abs(mean_partner))
    assert np.all(np.abs(dev) <= bound)
    n = partner[6:9]
    assert n @ (vel - u2) >= 0.0 and np.linalg.norm(n) == pytest.approx(1.0)
    w2 = partner[3:6]
    if rotation and np.all(wrms == 0):
        np.testing.assert_array_equal(w2, wmean)
    a = [vel.copy(), omega.copy() if rotation else np.zeros(3), u2.copy(), w2.copy()]
    ref = ci.hard_sphere_pair(a[0], a[1], d1, a[2], a[3], d2, n, OPTS[opt].restitution, OPTS[opt].friction)
    assert ref == status
    np.testing.assert_allclose(v1, a[0], rtol=1e-12, atol=1e-12)
    if rotation:
        np.testing.assert_allclose(w1, a[1], rtol=1e-12, atol=1e-9)
    else:
        np.testing.assert_array_equal(w1, omega)
    np.testing.assert_allclose(dv, v1 - vel, rtol=0, atol=1e-12)
    p0, _, ke0 = pair_invariants(vel, omega if rotation else np.zeros(3), d1, u2, w2, d2, n)
    p1, _, ke1 = pair_invariants(v1, a[1], d1, a[2], a[3], d2, n)
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-12 * (mass(d1) + mass(d2)) * 100)
    assert ke1 <= ke0 * (1 + 1e-12)


@njit
def _direct_reference(vel, mean_own, d1, d2, mean_partner, chol, n_p, stokes, dt, n, seed, out_u2):
    """The stochastic model written the plain way (docs/physics.md steps 3–4): draw ξ, form u₂ with
    the fluctuation chol @ ξ (diag(rms) for the per-component draw), collide if Y < 1 − exp(−f Δt).
    Returns the number of collisions; partner velocities in out_u2."""
    R = math.exp(-0.55 * stokes**0.4)
    s = math.sqrt(1.0 - R * R)
    hits = 0
    rng = cr.rng_state(seed, 0, 0, cr.STREAM_INJECTION)
    for i in range(n):
        z0, z1 = cr.next_normal_pair(rng)
        z2, _ = cr.next_normal_pair(rng)
        y = cr.next_uniform(rng)
        u2 = np.empty(3)
        for k in range(3):
            u2[k] = (mean_partner[k] + R * (vel[k] - mean_own[k])
                     + s * (chol[k, 0] * z0 + chol[k, 1] * z1 + chol[k, 2] * z2))
        g = math.sqrt(((vel - u2) ** 2).sum())
        f = math.pi / 4 * (d1 + d2) ** 2 * g * n_p
        if y < 1.0 - math.exp(-f * dt):
            out_u2[hits] = u2
            hits += 1
    return hits


@lru_cache(maxsize=None)
def _make_kernel_sampler(majorant_radius, covariance="components"):
    kernel = ci.make_interparticle_collision(ci.InterparticleOptions(majorant_radius=majorant_radius,
                                                                     covariance=covariance))

    @njit
    def run(vel, mean_own, d1, d2, mean_partner, rms, cov, n_p, stokes, dt, n, seed, out_u2, out_v):
        zero = np.zeros(3)
        partner = np.zeros(ci.PARTNER_SIZE)
        dv = np.zeros(3)
        v = np.empty(3)
        w = np.zeros(3)
        rng = cr.rng_state(seed, 0, 0, cr.STREAM_COLLISION)
        hits = 0
        for i in range(n):
            v[:] = vel
            rng[cr.RNG_PARCEL] = i
            rng[cr.RNG_DRAW] = 0
            if kernel(v, w, d1, mean_own, d2, mean_partner, rms, cov, zero, zero, n_p, stokes, dt, rng, dv, partner):
                out_u2[hits] = partner[:3]
                out_v[hits] = v
                hits += 1
        return hits

    return run


@pytest.mark.parametrize("majorant_radius", [5.0, 1.0, 0.3])
@pytest.mark.parametrize("stokes,p_scale", [(1e8, 0.02), (0.5, 0.2), (0.05, 1.0)])
def test_thinned_kernel_vs_direct_algorithm(majorant_radius, stokes, p_scale):
    """Exact thinning: collision probability and the partner-velocity distribution given a
    collision equal those of the direct algorithm (binomial 5σ; KS per component). Small K makes
    the tail branch (|ξ| > K) frequent, so both branches are exercised. Anisotropic rms, unequal
    sizes and class means, a real particle off the mean."""
    vel = np.array([10.6, -0.4, 0.25])
    mean_own = np.array([10.0, -0.1, 0.0])
    mean_partner = np.array([9.5, -0.2, 0.05])
    rms = np.array([0.6, 0.3, 0.4])
    d1, d2, n_p = 100e-6, 150e-6, 1e10
    f_scale = math.pi / 4 * (d1 + d2) ** 2 * n_p * 1.0
    dt = p_scale / f_scale
    n = 200_000
    ref_u2 = np.empty((n, 3))
    hits_ref = _direct_reference(vel, mean_own, d1, d2, mean_partner, np.diag(rms), n_p, stokes, dt, n, 1, ref_u2)
    k_u2, k_v = np.empty((n, 3)), np.empty((n, 3))
    hits = _make_kernel_sampler(majorant_radius)(vel, mean_own, d1, d2, mean_partner, rms, np.zeros(3), n_p, stokes,
                                                 dt, n, 2, k_u2, k_v)
    p = hits_ref / n
    assert abs(hits - hits_ref) < 5 * math.sqrt(2 * n * p * (1 - p))
    for c in range(3):
        assert stats.ks_2samp(k_u2[:hits, c], ref_u2[:hits_ref, c]).pvalue > 1e-3, c
    g_k = np.linalg.norm(vel - k_u2[:hits], axis=1)
    g_r = np.linalg.norm(vel - ref_u2[:hits_ref], axis=1)
    assert stats.ks_2samp(g_k, g_r).pvalue > 1e-3


@pytest.mark.parametrize("majorant_radius", [5.0, 0.3])
@pytest.mark.parametrize("stokes,p_scale", [(1e8, 0.2), (0.05, 1.0)])
def test_thinned_kernel_with_the_full_covariance_vs_direct_algorithm(majorant_radius, stokes, p_scale):
    """The full-covariance partner (physics.partner_covariance = "full"), every covariance
    non-zero: collision probability and the partner velocity given a collision equal those of
    the direct algorithm with the covariance's Cholesky factor (binomial 5σ; KS per component and
    along two diagonals, which a dropped or misplaced covariance would shift)."""
    vel = np.array([10.6, -0.4, 0.25])
    mean_own = np.array([10.0, -0.1, 0.0])
    mean_partner = np.array([9.5, -0.2, 0.05])
    sigma = np.array([[0.36, 0.09, -0.06], [0.09, 0.25, 0.12], [-0.06, 0.12, 0.30]])
    rms = np.sqrt(np.diag(sigma)).copy()
    cov = np.array([sigma[0, 1], sigma[0, 2], sigma[1, 2]])
    d1, d2, n_p = 100e-6, 150e-6, 1e10
    dt = p_scale / (math.pi / 4 * (d1 + d2) ** 2 * n_p)
    n = 200_000
    ref_u2, k_u2, k_v = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    hits_ref = _direct_reference(vel, mean_own, d1, d2, mean_partner, np.linalg.cholesky(sigma), n_p, stokes, dt, n,
                                 1, ref_u2)
    hits = _make_kernel_sampler(majorant_radius, "full")(vel, mean_own, d1, d2, mean_partner, rms, cov, n_p, stokes,
                                                         dt, n, 2, k_u2, k_v)
    p = hits_ref / n
    assert abs(hits - hits_ref) < 5 * math.sqrt(2 * n * p * (1 - p))
    a, b = k_u2[:hits], ref_u2[:hits_ref]
    for proj in (np.eye(3), np.array([[1.0, 1.0, 0.0], [0.0, 1.0, -1.0]])):
        for row in proj:
            assert stats.ks_2samp(a @ row, b @ row).pvalue > 1e-3, row
    # the components' draw would miss the correlation: the partners' (u_y, u_z) correlate
    assert np.corrcoef(a[:, 1], a[:, 2])[0, 1] > 0.2


def test_chi3_tail_radius_vs_scipy_conditional_chi():
    for k in (0.3, 1.0, 3.0, 5.0):
        rng = cr.rng_state(9, 0, 0, cr.STREAM_COLLISION)
        r = np.array([ci.chi3_tail_radius(k, rng) for _ in range(20_000)])
        assert r.min() > k
        chi = stats.chi(3)
        sf_k = chi.sf(k)
        assert ci.chi3_tail_probability(k) == pytest.approx(sf_k, rel=1e-10)
        assert ci.chi3_tail_probability.py_func(k) == pytest.approx(sf_k, rel=1e-10)
        assert stats.kstest(r, lambda x: 1 - chi.sf(x) / sf_k).pvalue > 1e-3
    r1, r2 = cr.rng_state(1, 0, 0, 3), cr.rng_state(1, 0, 0, 3)
    assert [ci.chi3_tail_radius(2.0, r1) for _ in range(5)] == pytest.approx(
        [ci.chi3_tail_radius.py_func(2.0, r2) for _ in range(5)], rel=1e-13)


@pytest.mark.parametrize("opt", range(len(OPTS)))
def test_stochastic_kernel_vs_py_func(opt):
    kernel = ci.make_interparticle_collision(OPTS[opt])
    rs = np.random.default_rng(opt)
    for k in range(10):
        args = dict(d_p=1e-4, mean_own=np.array([10.0, 0, 0]), d_partner=2e-4, mean_partner=np.array([9.0, 0.1, 0]),
                    rms_partner=np.array([0.5, 0.3, 0.3]), cov_partner=np.array([0.05, -0.02, 0.04]),
                    omega_mean=np.array([0, 0, -100.0]),
                    omega_rms=np.array([50.0, 50.0, 50.0]), number_density=1e11, stokes=rs.uniform(0, 5),
                    dt=1e-3)
        vel = np.array([10.0, 0, 0]) + rs.normal(size=3)
        om = rs.normal(size=3) * 1e3
        out = []
        for fn in (kernel, kernel.py_func):
            v, w, dv, part = vel.copy(), om.copy(), np.zeros(3), np.zeros(ci.PARTNER_SIZE)
            rng = cr.rng_state(4, 1, k, cr.STREAM_COLLISION)
            res = fn(v, w, args["d_p"], args["mean_own"], args["d_partner"], args["mean_partner"],
                     args["rms_partner"], args["cov_partner"], args["omega_mean"], args["omega_rms"],
                     args["number_density"],
                     args["stokes"], args["dt"], rng, dv, part)
            out.append((res, v, w, dv, part, rng))
        (ra, *xa), (rb, *xb) = out
        assert ra == rb
        for x, y in zip(xa, xb):
            np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)


def test_empty_cell_or_zero_step_never_collides():
    v, w, dv, part = np.ones(3), np.zeros(3), np.zeros(3), np.zeros(ci.PARTNER_SIZE)
    rng = cr.rng_state(1, 0, 0, cr.STREAM_COLLISION)
    z = np.zeros(3)
    for n_p, dt in ((0.0, 1.0), (1e12, 0.0)):
        assert ci.interparticle_collision(v, w, 1e-4, z, 1e-4, z, np.ones(3), z, z, z, n_p, 1.0, dt, rng, dv,
                                          part) == ci.COLLISION_NONE
    assert rng[cr.RNG_DRAW] == 0


# ---------------------------------------------------------------------------------------------
# model functions and the impact-point sampling
# ---------------------------------------------------------------------------------------------

def test_correlation_function_vs_sommerfeld_2001():
    for fn in (ci.sommerfeld_2001_correlation, ci.sommerfeld_2001_correlation.py_func):
        assert fn(0.0) == 1.0
        assert fn(1.0) == pytest.approx(math.exp(-0.55))
        assert fn(10.0) == pytest.approx(math.exp(-0.55 * 10**0.4))
    s = np.logspace(-6, 3, 50)
    r = np.array([ci.sommerfeld_2001_correlation(x) for x in s])
    assert np.all(np.diff(r) < 0) and r[0] > 0.99 and r[-1] < 2e-4  # R(1000) = 1.6e-4


def test_frequency_probability_helpers_vs_py_func():
    assert ci.kinetic_collision_frequency(1e-4, 2e-4, 1e10, 2.0) == pytest.approx(math.pi / 4 * 9e-8 * 2e10)
    assert ci.kinetic_collision_frequency.py_func(1e-4, 2e-4, 1e10, 2.0) == ci.kinetic_collision_frequency(
        1e-4, 2e-4, 1e10, 2.0)
    for fdt in (1e-12, 1e-3, 0.5, 3.0, 50.0):
        assert ci.collision_probability(fdt, 1.0) == pytest.approx(1 - math.exp(-fdt), rel=1e-12)
        assert ci.collision_probability.py_func(fdt, 1.0) == ci.collision_probability(fdt, 1.0)
    # <|g|> = 4σ/√π for two independent Maxwellian classes of rms σ (docs/physics.md)
    s = 0.7
    assert ci.mean_collision_frequency(1e-4, 1e-4, 1e10, s, s, 0.0) == pytest.approx(
        math.pi / 4 * 4e-8 * 1e10 * 4 * s / math.sqrt(math.pi), rel=1e-12)
    assert ci.mean_collision_frequency.py_func(1e-4, 1e-4, 1e10, s, s, 0.3) == pytest.approx(
        ci.mean_collision_frequency(1e-4, 1e-4, 1e10, s, s, 0.3), rel=1e-14)


@njit
def _impact_normals(gx, gy, gz, n, seed):
    out = np.empty((n, 3))
    rng = cr.rng_state(seed, 0, 0, cr.STREAM_COLLISION)
    for i in range(n):
        u1, u2 = cr.next_uniform_pair(rng)
        out[i, 0], out[i, 1], out[i, 2] = ci.impact_normal(gx, gy, gz, u1, u2)
    return out


@pytest.mark.parametrize("g", [(3.0, 0.0, 0.0), (0.0, 0.0, -2.0), (1.0, -2.0, 0.5), (1e-3, 1e-3, 1e-3)])
def test_impact_point_uniform_on_full_disc(g):
    """L = sin Φ has pdf 2L on [0, 1] and ψ is uniform on [0, 2π) about ĝ, in any global
    orientation (no quadrant bias, docs/physics.md step 5)."""
    n = 200_000
    g = np.array(g)
    gh = g / np.linalg.norm(g)
    nn = _impact_normals(*g, n, 5)
    np.testing.assert_allclose(np.linalg.norm(nn, axis=1), 1.0, atol=1e-12)
    cos_phi = nn @ gh
    assert cos_phi.min() >= 0.0
    L = np.sqrt(np.clip(1 - cos_phi**2, 0, 1))
    assert stats.kstest(L, lambda x: np.clip(x, 0, 1) ** 2).pvalue > 1e-3
    # azimuth about ĝ in a basis built here, independently of the kernel's
    a = np.array([0.0, 1.0, 0.0]) if abs(gh[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    b1 = np.cross(gh, a)
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(gh, b1)
    psi = np.mod(np.arctan2(nn @ b2, nn @ b1), 2 * np.pi)
    assert stats.kstest(psi, stats.uniform(0, 2 * np.pi).cdf).pvalue > 1e-3
    lateral = nn - np.outer(cos_phi, gh)
    assert np.linalg.norm(lateral.mean(axis=0)) < 5 * math.sqrt(0.5 / n)
    # compiled vs py_func
    assert ci.impact_normal.py_func(*g, 0.3, 0.7) == pytest.approx(ci.impact_normal(*g, 0.3, 0.7), abs=1e-15)


def test_size_class_sampling_vs_weights():
    w = np.array([0.1, 0.0, 2.0, 0.5, 1.4])
    cum = np.cumsum(w)
    rng = cr.rng_state(3, 0, 0, cr.STREAM_COLLISION)
    k = np.array([ci.sample_size_class(cum, rng) for _ in range(40_000)])
    counts = np.bincount(k, minlength=len(w))
    assert counts[1] == 0
    nz = w > 0
    assert stats.chisquare(counts[nz], w[nz] / w.sum() * len(k)).pvalue > 1e-3
    rng2 = cr.rng_state(3, 0, 0, cr.STREAM_COLLISION)
    assert [ci.sample_size_class.py_func(cum, rng2) for _ in range(50)] == list(k[:50])


# ---------------------------------------------------------------------------------------------
# collision frequency vs kinetic theory (§4.1, §9.3)
# ---------------------------------------------------------------------------------------------

D = 100e-6  # m
SIGMA = 0.5  # m/s, rms of each velocity component
N_P = 1e10  # 1/m3
MEAN = np.array([10.0, -0.2, 0.1])


@lru_cache(maxsize=None)
def _make_frequency_experiment():
    kernel = ci.make_interparticle_collision(ci.InterparticleOptions())

    @njit
    def run(stokes, dt, n, seed):
        """n particles with Maxwellian velocities (mean MEAN, rms SIGMA) in a uniform cell whose
        statistics are the same; one kernel call each; returns the number of collisions."""
        mean = np.array([10.0, -0.2, 0.1])
        rms = np.array([SIGMA, SIGMA, SIGMA])
        zero = np.zeros(3)
        vel = np.empty(3)
        omega = np.zeros(3)
        dv = np.zeros(3)
        partner = np.zeros(ci.PARTNER_SIZE)
        src = cr.rng_state(seed, 0, 0, cr.STREAM_INJECTION)
        rng = cr.rng_state(seed, 0, 0, cr.STREAM_COLLISION)
        hits = 0
        for i in range(n):
            a, b = cr.next_normal_pair(src)
            c, _ = cr.next_normal_pair(src)
            vel[0] = mean[0] + SIGMA * a
            vel[1] = mean[1] + SIGMA * b
            vel[2] = mean[2] + SIGMA * c
            omega[:] = 0.0
            rng[cr.RNG_PARCEL] = i
            rng[cr.RNG_DRAW] = 0
            status = kernel(vel, omega, D, mean, D, mean, rms, zero, zero, zero, N_P, stokes, dt, rng, dv, partner)
            if status != ci.COLLISION_NONE:
                hits += 1
        return hits

    return run


def _maxwell_expectation(fun, scale):
    """E[fun(|g|)] for |g| Maxwell-distributed with per-component std `scale` (scipy)."""
    dist = stats.maxwell(scale=scale)
    return integrate.quad(lambda x: fun(x) * dist.pdf(x), 0, 12 * scale, limit=200)[0]


def test_collision_frequency_vs_kinetic_theory_uncorrelated():
    """Uncorrelated Maxwellian partners (St → ∞): measured frequency = (π/4)(2D)² n ⟨|g|⟩ within 2 %,
    ⟨|g|⟩ the mean of a Maxwell distribution with per-component std σ√2 (scipy); ≥ 5·10^4 events."""
    f_kin = math.pi / 4 * (2 * D) ** 2 * N_P * stats.maxwell(scale=SIGMA * math.sqrt(2)).mean()
    # f Δt ≈ 0.004: the one-event-per-step bias (≈ f Δt/2) is 0.2 %; 5·10^4 events: 0.45 % standard error
    dt = 0.004 / f_kin
    n = 12_500_000
    hits = _make_frequency_experiment()(1e8, dt, n, 1)
    assert hits >= 10_000
    f_measured = hits / (n * dt)
    assert f_measured == pytest.approx(f_kin, rel=0.02)
    print(f"\ncollision frequency: measured {f_measured:.5g} 1/s, kinetic theory {f_kin:.5g} 1/s, "
          f"ratio {f_measured / f_kin:.4f}, events {hits}")


def test_collision_probability_not_clipped_at_large_steps():
    """f Δt ≈ 1: the event fraction equals the Poisson expectation E[1 − exp(−f Δt)] (quadrature),
    not E[min(f Δt, 1)] (what clipping a linear P would give)."""
    f_kin = math.pi / 4 * (2 * D) ** 2 * N_P * stats.maxwell(scale=SIGMA * math.sqrt(2)).mean()
    dt = 1.0 / f_kin
    c = math.pi / 4 * (2 * D) ** 2 * N_P * dt
    n = 300_000
    hits = _make_frequency_experiment()(1e8, dt, n, 2)
    expected = _maxwell_expectation(lambda g: -np.expm1(-c * g), SIGMA * math.sqrt(2))
    clipped = _maxwell_expectation(lambda g: min(c * g, 1.0), SIGMA * math.sqrt(2))
    frac = hits / n
    assert frac == pytest.approx(expected, rel=0.01)
    assert abs(clipped - expected) > 0.1


def test_collision_frequency_falls_to_zero_with_full_correlation():
    """Correlated partner: g has per-component variance 2σ²(1 − R) (derived here), so the event
    fraction is E[1 − exp(−c |g|)] over a Maxwell distribution of scale σ sqrt(2(1 − R)); it falls
    toward zero as St → 0 (R → 1)."""
    f_kin = math.pi / 4 * (2 * D) ** 2 * N_P * stats.maxwell(scale=SIGMA * math.sqrt(2)).mean()
    dt = 0.05 / f_kin
    c = math.pi / 4 * (2 * D) ** 2 * N_P * dt
    n = 1_000_000
    run = _make_frequency_experiment()
    ratios = []
    for stokes in (100.0, 1.0, 1e-2, 1e-4, 1e-8):
        R = math.exp(-0.55 * stokes**0.4)
        hits = run(stokes, dt, n, 3)
        expected = _maxwell_expectation(lambda g: -np.expm1(-c * g), SIGMA * math.sqrt(2 * (1 - R)))
        assert hits / n == pytest.approx(expected, rel=0.03, abs=3 * math.sqrt(expected / n))
        ratios.append(hits / (n * dt) / f_kin)
    assert all(a > b for a, b in zip(ratios, ratios[1:]))
    assert ratios[0] > 0.95 and ratios[-1] < 0.03


# ---------------------------------------------------------------------------------------------
# the partner's velocity covariance (physics.partner_covariance)
# ---------------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def _make_variance_experiment(covariance):
    kernel = ci.make_interparticle_collision(ci.InterparticleOptions(covariance=covariance, rotation=False))

    @njit
    def run(chol, rms, cov, n, seed):
        """n particles with zero-mean Gaussian velocities of Cholesky factor ``chol``, each colliding
        (or not) once with the partners of a cell with that rms and covariance (uncorrelated,
        St → ∞); per particle the change of v vᵀ (xx, yy, zz, xy, xz, yz)."""
        zero = np.zeros(3)
        vel = np.empty(3)
        omega = np.zeros(3)
        dv = np.zeros(3)
        partner = np.zeros(ci.PARTNER_SIZE)
        out = np.zeros((n, 6))
        src = cr.rng_state(seed, 0, 0, cr.STREAM_INJECTION)
        rng = cr.rng_state(seed, 0, 0, cr.STREAM_COLLISION)
        for i in range(n):
            a, b = cr.next_normal_pair(src)
            c, _ = cr.next_normal_pair(src)
            for k in range(3):
                vel[k] = chol[k, 0] * a + chol[k, 1] * b + chol[k, 2] * c
            v0 = vel.copy()
            rng[cr.RNG_PARCEL] = i
            rng[cr.RNG_DRAW] = 0
            kernel(vel, omega, D, zero, D, zero, rms, cov, zero, zero, 2e10, 1e12, 1e-3, rng, dv, partner)
            for k, (p, q) in enumerate(((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))):
                out[i, k] = vel[p] * vel[q] - v0[p] * v0[q]
        return out

    return run


def _wall_normal_variance_rate(covariance, turn, n=120000):
    """Mean change of the squared velocity normal to a wall, per collision test, for particles
    whose velocity has rms 0.5 (axial), 1.2 (wall-normal) and 0.65 m/s (along the wall), in a
    cell whose wall normal is y (turn = 0) or lies at 45° between y and z (turn = 45°)."""
    t = math.radians(turn)
    q = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(t), -math.sin(t)], [0.0, math.sin(t), math.cos(t)]])
    sigma = q @ np.diag([0.5**2, 1.2**2, 0.65**2]) @ q.T
    out = _make_variance_experiment(covariance)(np.linalg.cholesky(sigma), np.sqrt(np.diag(sigma)).copy(),
                                                np.array([sigma[0, 1], sigma[0, 2], sigma[1, 2]]), n, 11)
    nrm = q[:, 1]
    m = np.array([[0, 3, 4], [3, 1, 5], [4, 5, 2]])
    per = sum(out[:, m[p, r]] * nrm[p] * nrm[r] for p in range(3) for r in range(3))
    return per.mean(), per.std() / math.sqrt(n)


def test_partners_with_the_full_covariance_act_alike_in_any_frame():
    """The same particles, their wall-normal axis along y or at 45° between y and z: collisions
    with partners drawn with the cell's full covariance change the wall-normal variance alike
    (within 4 standard errors); partners drawn per Cartesian component are more isotropic than
    the particles at 45° (the y-z covariance dropped) and drain it faster there."""
    full0, se0 = _wall_normal_variance_rate("full", 0.0)
    full45, se45 = _wall_normal_variance_rate("full", 45.0)
    assert full0 < -20.0 * se0  # the collisions drain the largest variance
    assert abs(full45 - full0) < 4.0 * math.hypot(se0, se45), (full0, full45)
    comp0, sc0 = _wall_normal_variance_rate("components", 0.0)
    comp45, sc45 = _wall_normal_variance_rate("components", 45.0)
    assert comp45 < comp0 - 8.0 * math.hypot(sc0, sc45), (comp0, comp45)
