"""Rough-wall particle–wall collision (collisions.wall), docs/physics.md"""

import math
from functools import lru_cache

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numba import njit
from scipy import integrate, stats

from collisions import random as cr
from collisions import tables
from collisions import wall as cw

G = 9.81
DEG = math.pi / 180

SMOOTH_MIRROR = cw.WallOptions(restitution=(1.0, 0.0, 1.0), friction=(0.0, 0.0, 0.0))
OPTION_SETS = [
    cw.WallOptions(),
    cw.WallOptions(impact_angle="nominal"),
    cw.WallOptions(shadow_effect="rejection"),
    cw.WallOptions(lateral_roughness=False),
    cw.WallOptions(rotation=False),
    cw.WallOptions(max_impacts=1),
]


def kinetic_energy_per_mass(vel, omega, r_p):
    """(v² + I ω²/m)/2 with I = (2/5) m r_p² [J/kg]."""
    return 0.5 * np.dot(vel, vel) + 0.2 * r_p**2 * np.dot(omega, omega)


def inward_normal(pos):
    r = math.hypot(pos[1], pos[2])
    return np.array([0.0, -pos[1] / r, -pos[2] / r])


def impact_state(R, rp_frac, theta, overshoot, alpha_deg, psi, speed, spin, spin_dir):
    """Particle at the wall (centre at (R - r_p)(1 + overshoot), angle theta) hitting it at alpha."""
    r_p = rp_frac * R
    r = (R - r_p) * (1.0 + overshoot)
    pos = np.array([0.3, r * math.cos(theta), r * math.sin(theta)])
    n0 = inward_normal(pos)
    ex = np.array([1.0, 0.0, 0.0])
    eth = np.cross(n0, ex)  # azimuthal, in the wall plane
    a = alpha_deg * DEG
    t = math.cos(psi) * ex + math.sin(psi) * eth
    vel = speed * (math.cos(a) * t - math.sin(a) * n0)
    d = np.asarray(spin_dir, float)
    d = d / max(np.linalg.norm(d), 1e-300)
    omega = spin / r_p * d
    return pos, vel, omega, r_p


def run_kernel(kernel, pos, vel, omega, uf, r_p, R, dgamma, v_min, seed):
    pos, vel, omega, uf = pos.copy(), vel.copy(), omega.copy(), uf.copy()
    dv = np.zeros(3)
    rng = cr.rng_state(seed, 0, 7, cr.STREAM_WALL)
    status = kernel(pos, vel, omega, uf, dv, r_p, R, dgamma, v_min, rng)
    return status, pos, vel, omega, uf, dv, rng


# ---------------------------------------------------------------------------------------------
# coefficients and small helpers
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("alpha,e,mu", [(0.0, 1.0, 0.4), (10.0, 0.9, 0.25), (20.0, 0.8, 0.1),
                                        (45.0, 0.8, 0.1), (5.0, 0.95, 0.325)])
def test_coefficients_vs_seed_formula(alpha, e, mu):
    """e_w = max(0.8, 1 − 0.01 α), μ_w = max(0.1, 0.4 − 0.015 α) (seed; docs/physics.md)."""
    for f in (cw.sommerfeld_huber_1999_restitution, cw.sommerfeld_huber_1999_restitution.py_func):
        assert f(alpha) == pytest.approx(e, abs=1e-14)
    for f in (cw.sommerfeld_huber_1999_friction, cw.sommerfeld_huber_1999_friction.py_func):
        assert f(alpha) == pytest.approx(mu, abs=1e-14)
    assert cw.linear_with_floor(alpha, 1.0, 0.01, 0.8) == cw.linear_with_floor.py_func(alpha, 1.0, 0.01, 0.8)


def test_minimum_bounce_speed_is_free_fall_over_one_diameter():
    d = 200e-6
    v = cw.minimum_bounce_speed(d)
    assert v == cw.minimum_bounce_speed.py_func(d)
    assert 0.5 * v**2 == pytest.approx(G * d, rel=1e-12)


@given(y=st.floats(-0.9, 0.9), z=st.floats(-0.9, 0.9), vy=st.floats(-5, 5), vz=st.floats(-5, 5))
@settings(max_examples=200, deadline=None)
def test_time_to_wall_lands_on_contact_circle(y, z, vy, vz):
    rc = 1.0
    if y * y + z * z >= rc * rc:
        assert cw.time_to_wall(y, z, vy, vz, rc) == 0.0
        return
    t = cw.time_to_wall(y, z, vy, vz, rc)
    assert t == pytest.approx(cw.time_to_wall.py_func(y, z, vy, vz, rc), rel=1e-13)  # fused multiply-adds
    if vy == 0.0 and vz == 0.0:
        assert t == math.inf
        return
    if vy * vy + vz * vz < 1e-100:  # speeds whose square underflows are outside the model
        return
    assert t >= 0.0
    assert math.hypot(y + vy * t, z + vz * t) == pytest.approx(rc, rel=1e-9)
    # no earlier contact: halfway there the centre is still inside
    assert math.hypot(y + vy * t / 2, z + vz * t / 2) < rc


def test_place_inside_vs_py_func_and_bounds():
    for f in (cw.place_inside, cw.place_inside.py_func):
        pos = np.array([1.0, 0.02, -0.03])
        r = f(pos, 1e-3, 0.02)
        assert math.hypot(pos[1], pos[2]) == pytest.approx(r) and r <= 0.02 - 1e-3
        pos2 = np.array([1.0, 0.001, 0.0])
        assert f(pos2, 1e-3, 0.02) == 0.001 and pos2[1] == 0.001  # already inside: untouched


# ---------------------------------------------------------------------------------------------
# hard-sphere rebound on a plane (§3.4, §9.2)
# ---------------------------------------------------------------------------------------------

unit_vectors = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: 0.1 < math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2))


@given(n=unit_vectors, v=st.tuples(*[st.floats(-20, 20)] * 3), w=st.tuples(*[st.floats(-3e4, 3e4)] * 3),
       e=st.floats(0, 1), mu=st.floats(0, 1), r_p=st.floats(1e-5, 1e-3))
@settings(max_examples=300, deadline=None)
def test_rebound_restitution_slip_spin_and_energy(n, v, w, e, mu, r_p):
    """v_n′ = −e v_n; sticking: zero slip after; sliding: |ΔG_t| = (7/2) μ (1+e) |v_n|; ω·n kept; KE ↓."""
    n = np.array(n) / np.linalg.norm(n)
    vel = np.array(v, float)
    omega = np.array(w, float)
    vn = vel @ n
    if vn >= -1e-6:
        vel = vel - (vn + 1.0) * n  # make it approach the wall
        vn = vel @ n
    v0, w0 = vel.copy(), omega.copy()
    stick = cw.hard_sphere_wall_rebound(vel, omega, n[0], n[1], n[2], r_p, e, mu, True)
    assert vel @ n == pytest.approx(-e * vn, rel=1e-9, abs=1e-9)
    assert omega @ n == pytest.approx(w0 @ n, rel=1e-9, abs=1e-6)

    def slip(vv, ww):
        G_ = vv - r_p * np.cross(ww, n)
        return G_ - (G_ @ n) * n

    scale = np.linalg.norm(slip(v0, w0)) + abs(vn)
    if stick:
        assert np.linalg.norm(slip(vel, omega)) <= 1e-9 * scale
    else:
        assert np.linalg.norm(slip(vel, omega) - slip(v0, w0)) == pytest.approx(
            3.5 * mu * (1 + e) * abs(vn), rel=1e-9, abs=1e-9 * scale)
        # friction never reverses the slip
        assert slip(vel, omega) @ slip(v0, w0) >= -1e-9 * scale**2
    assert kinetic_energy_per_mass(vel, omega, r_p) <= kinetic_energy_per_mass(v0, w0, r_p) * (1 + 1e-12) + 1e-12
    # compiled vs py_func: the same rebound to round-off (the kernels compile with fused
    # multiply-adds, collisions.conf), and the same regime unless the slip sits at the sticking
    # limit |G_t| = (7/2) μ (1 + e) |v_n| to round-off
    v1, w1 = v0.copy(), w0.copy()
    stick_py = cw.hard_sphere_wall_rebound.py_func(v1, w1, n[0], n[1], n[2], r_p, e, mu, True)
    np.testing.assert_allclose(v1, vel, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(w1, omega, rtol=1e-13, atol=1e-9)
    limit = 3.5 * mu * (1 + e) * abs(vn)
    g_t = np.linalg.norm(slip(v0, w0))
    assert stick_py == stick or abs(g_t - limit) <= 1e-12 * (abs(vn) + g_t), (g_t, limit)


@pytest.mark.parametrize("u,v,wz,e,mu", [(3.0, -1.0, 0.0, 0.9, 0.4),  # non-sliding
                                         (10.0, -0.5, 0.0, 0.9, 0.4),  # sliding
                                         (2.0, -1.0, -5000.0, 0.8, 0.3),
                                         (-4.0, -2.0, 8000.0, 0.7, 0.1)])
def test_rebound_vs_2d_component_form(u, v, wz, e, mu):
    """Wall below (n = +e_y), spin ω_z: docs/physics.md 2-D component equations."""
    Dp = 2e-4
    vel = np.array([u, v, 0.0])
    omega = np.array([0.0, 0.0, wz])
    cw.hard_sphere_wall_rebound(vel, omega, 0.0, 1.0, 0.0, Dp / 2, e, mu, True)
    slip = u + Dp / 2 * wz
    if abs(slip) <= 3.5 * mu * (1 + e) * abs(v):
        ue = 5 / 7 * u - 1 / 7 * Dp * wz
        we = 2 / 7 * wz - 10 / (7 * Dp) * u
    else:
        eps = math.copysign(1.0, slip)
        ue = u - mu * (1 + e) * abs(v) * eps
        we = wz - 5 * mu * (1 + e) * eps * abs(v) / Dp
    np.testing.assert_allclose(vel, [ue, -e * v, 0.0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(omega, [0.0, 0.0, we], rtol=1e-12, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# roughness-angle sampling (§3.2)
# ---------------------------------------------------------------------------------------------

@njit
def _sample_gammas(effective, alpha, dgamma, n, seed):
    out = np.empty(n)
    rng = cr.rng_state(seed, 0, 0, cr.STREAM_WALL)
    for i in range(n):
        if effective:
            out[i] = cw.roughness_angle_effective_pdf(alpha, dgamma, rng)
        else:
            out[i] = cw.roughness_angle_simple(alpha, dgamma, rng)
    return out, rng[cr.RNG_DRAW]


def _feff_cdf(alpha, dgamma, weighted):
    g = np.linspace(-alpha, min(math.pi - alpha, 9 * dgamma), 40001)
    pdf = np.exp(-0.5 * (g / dgamma) ** 2) * (np.sin(alpha + g) if weighted else 1.0)
    cdf = integrate.cumulative_trapezoid(pdf, g, initial=0.0)
    cdf /= cdf[-1]
    return lambda x: np.interp(x, g, cdf), g, pdf / np.trapezoid(pdf, g)


@pytest.mark.parametrize("alpha_deg", [2.0, 10.0, 45.0])
@pytest.mark.parametrize("dgamma_deg", [1.0, 5.0, 10.0])
def test_shadow_effect_pdf_vs_analytic_feff(alpha_deg, dgamma_deg):
    """Histogram/KS of γ against f_eff ∝ N(γ; 0, Δγ) sin(α + γ), γ > −α (docs/physics.md)."""
    a, dg = alpha_deg * DEG, dgamma_deg * DEG
    n = 100_000
    gam, draws = _sample_gammas(True, a, dg, n, 11)
    assert gam.min() > -a
    cdf, g, pdf = _feff_cdf(a, dg, True)
    assert stats.kstest(gam, cdf).pvalue > 1e-3
    assert gam.mean() == pytest.approx(np.trapezoid(g * pdf, g), abs=5 * gam.std() / math.sqrt(n))
    assert draws / n < 6.0  # efficient sampler: a few draws per angle even at small α and Δγ


@pytest.mark.parametrize("alpha_deg", [2.0, 10.0])
def test_simple_shadow_is_truncated_normal(alpha_deg):
    a, dg = alpha_deg * DEG, 5 * DEG
    gam, _ = _sample_gammas(False, a, dg, 100_000, 12)
    cdf, _, _ = _feff_cdf(a, dg, False)
    assert gam.min() > -a
    assert stats.kstest(gam, cdf).pvalue > 1e-3


def test_effective_impact_angle_exceeds_nominal_at_small_angles():
    """⟨α + γ⟩ > α for small α: grazing particles see steeper facets (§3.2)."""
    for alpha_deg in (0.5, 2.0, 5.0):
        gam, _ = _sample_gammas(True, alpha_deg * DEG, 5 * DEG, 50_000, 13)
        assert gam.mean() > 2.0 * DEG
    # steep impacts: small shift, to first order Δγ² cot α (sin(α+γ) ≈ sin α + γ cos α)
    gam, _ = _sample_gammas(True, 45 * DEG, 5 * DEG, 50_000, 13)
    assert gam.mean() == pytest.approx((5 * DEG) ** 2, rel=0.15)


def test_samplers_vs_py_func():
    for f in (cw.roughness_angle_effective_pdf, cw.roughness_angle_simple):
        r1 = cr.rng_state(3, 1, 2, cr.STREAM_WALL)
        r2 = r1.copy()
        a = [f(0.01, 0.1, r1) for _ in range(20)]
        b = [f.py_func(0.01, 0.1, r2) for _ in range(20)]
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
        assert np.array_equal(r1, r2)
        assert f(0.3, 0.0, r1) == 0.0  # smooth wall


# ---------------------------------------------------------------------------------------------
# the wall-collision kernel: properties over random impacts
# ---------------------------------------------------------------------------------------------

impacts = st.fixed_dictionaries({
    "R": st.floats(0.005, 0.1),
    "rp_frac": st.floats(1e-4, 0.05),
    "theta": st.floats(0, 2 * math.pi),
    "overshoot": st.floats(-1e-9, 0.1),
    "alpha_deg": st.one_of(st.floats(1e-6, 1.0), st.floats(1.0, 90.0), st.floats(89.0, 90.0)),
    "psi": st.floats(0, 2 * math.pi),
    "speed": st.floats(1e-3, 50.0),
    "spin": st.floats(-20.0, 20.0),
    "spin_dir": st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)),
})


@given(imp=impacts, dgamma_deg=st.one_of(st.just(0.0), st.floats(0.0, 20.0)), contact=st.booleans(),
       opt=st.sampled_from(range(len(OPTION_SETS))), uf=st.tuples(*[st.floats(-3, 3)] * 3),
       seed=st.integers(0, 2**40))
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_wall_collision_properties_over_random_impacts(imp, dgamma_deg, contact, opt, uf, seed):
    """After a wall collision: v·n₀ ≥ 0 (into the pipe); KE (translation + rotation) never
    increases; the centre is ≥ r_p from the wall and strictly inside; dv = v′ − v; u′_F,n mirrored."""
    pos, vel, omega, r_p = impact_state(**imp)
    R = imp["R"]
    kernel = cw.make_wall_collision(OPTION_SETS[opt])
    v_min = cw.minimum_bounce_speed(2 * r_p) if contact else 0.0
    uf = np.array(uf, float)
    n0 = inward_normal(pos)
    status, p1, v1, w1, uf1, dv, _ = run_kernel(kernel, pos, vel, omega, uf, r_p, R, dgamma_deg * DEG, v_min, seed)
    assert status in (cw.WALL_REBOUND, cw.WALL_SLIDING, cw.WALL_ROLLING)
    assert np.all(np.isfinite(v1)) and np.all(np.isfinite(w1)) and np.all(np.isfinite(p1))
    speed = np.linalg.norm(vel)
    vn1 = v1 @ n0
    assert vn1 >= -1e-12 * speed
    if status == cw.WALL_REBOUND:
        assert vn1 >= v_min and vn1 > 0.0
    else:
        assert abs(vn1) <= 1e-12 * speed
    if OPTION_SETS[opt].rotation:
        ke0 = kinetic_energy_per_mass(vel, omega, r_p)
    else:
        ke0 = kinetic_energy_per_mass(vel, np.zeros(3), r_p)
        np.testing.assert_array_equal(w1, omega)
        w1 = np.zeros(3)
    assert kinetic_energy_per_mass(v1, w1, r_p) <= ke0 * (1 + 1e-12)
    r1 = math.hypot(p1[1], p1[2])
    assert r1 <= R - r_p and r1 < R
    assert p1[0] == pos[0]
    np.testing.assert_allclose(dv, v1 - vel, rtol=0, atol=1e-12 * speed)
    np.testing.assert_allclose(uf1, uf - 2 * (uf @ n0) * n0, rtol=0, atol=1e-12)


@given(imp=impacts, seed=st.integers(0, 2**40))
@settings(max_examples=300, deadline=None)
def test_smooth_elastic_frictionless_is_mirror_reflection(imp, seed):
    """e = 1, μ = 0, Δγ = 0: v′ = v − 2 (v·n₀) n₀ exactly; ω unchanged."""
    pos, vel, omega, r_p = impact_state(**imp)
    kernel = cw.make_wall_collision(SMOOTH_MIRROR)
    n0 = inward_normal(pos)
    status, _, v1, w1, _, _, rng = run_kernel(kernel, pos, vel, omega, np.zeros(3), r_p, imp["R"], 0.0, 0.0, seed)
    assert status == cw.WALL_REBOUND
    np.testing.assert_allclose(v1, vel - 2 * (vel @ n0) * n0, rtol=0, atol=1e-13 * np.linalg.norm(vel))
    np.testing.assert_array_equal(w1, omega)
    assert rng[cr.RNG_DRAW] == 0  # a smooth wall draws no random numbers


def test_not_approaching_only_puts_particle_back():
    R, r_p = 0.015, 1e-4
    pos = np.array([0.0, 0.0, R * 1.01])  # outside, moving inward (away from the wall)
    vel = np.array([5.0, 0.1, -1.0])
    status, p1, v1, _, _, dv, _ = run_kernel(cw.wall_collision, pos, vel, np.zeros(3), np.zeros(3), r_p, R,
                                             5 * DEG, 0.0, 1)
    assert status == cw.WALL_NO_IMPACT
    np.testing.assert_array_equal(v1, vel)
    assert np.all(dv == 0) and math.hypot(p1[1], p1[2]) <= R - r_p


@pytest.mark.parametrize("opt", range(len(OPTION_SETS)))
def test_wall_kernel_vs_py_func(opt):
    kernel = cw.make_wall_collision(OPTION_SETS[opt])
    rs = np.random.default_rng(opt)
    for k in range(5):
        pos, vel, omega, r_p = impact_state(0.02, 0.01, rs.uniform(0, 6.28), rs.uniform(0, 0.01),
                                            rs.uniform(0.1, 60), rs.uniform(0, 6.28), rs.uniform(0.1, 20),
                                            rs.uniform(-5, 5), rs.normal(size=3))
        uf = rs.normal(size=3)
        a = run_kernel(kernel, pos, vel, omega, uf, r_p, 0.02, 7 * DEG, 0.05, k)
        b = run_kernel(kernel.py_func, pos, vel, omega, uf, r_p, 0.02, 7 * DEG, 0.05, k)
        assert a[0] == b[0]
        for x, y in zip(a[1:], b[1:]):
            np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)


def test_extreme_roughness_terminates_inside():
    """Non-physical Δγ = 80° at grazing incidence: bounded work, inside, finite."""
    R = 0.01
    for seed in range(200):
        pos, vel, omega, r_p = impact_state(R, 0.01, 1.0, 0.0, 0.01, 0.3, 10.0, 1.0, (0, 0, 1))
        status, p1, v1, w1, _, _, rng = run_kernel(cw.wall_collision, pos, vel, omega, np.zeros(3), r_p, R,
                                                   80 * DEG, 0.0, seed)
        assert np.all(np.isfinite(v1)) and math.hypot(p1[1], p1[2]) < R - r_p
        assert v1 @ inward_normal(pos) >= 0.0
        assert rng[cr.RNG_DRAW] < 10 * 10_000


# ---------------------------------------------------------------------------------------------
# rough-wall statistics (Sommerfeld & Huber 1999)
# ---------------------------------------------------------------------------------------------

def closed_form_rebound_angle(alpha_deg, e, mu):
    """Non-rotating sphere, smooth wall: tan β from the 2-D impulse equations (docs/physics.md).

    u = V cos α, v = −V sin α. Non-sliding if cot α ≤ (7/2) μ (1+e): u′ = 5u/7, v′ = e V sin α;
    sliding: u′ = u − μ(1+e) V sin α.  Written out here independently of the kernel.
    """
    a = math.radians(alpha_deg)
    if 1.0 / math.tan(a) <= 3.5 * mu * (1 + e):
        return math.degrees(math.atan(e * math.tan(a) * 7.0 / 5.0)), "non-sliding"
    return math.degrees(math.atan(e * math.tan(a) / (1.0 - mu * (1 + e) * math.tan(a)))), "sliding"


def _rebound_angle(options, alpha_deg):
    out = np.empty(1)
    tables.make_rebound_sampler(options)(alpha_deg, 0.0, 1, 1, out, np.empty(1))
    return out[0]


def test_rebound_sampler_vs_py_func():
    sampler = tables.make_rebound_sampler(cw.WallOptions())
    a, b = np.empty(5), np.empty(5)
    ra, rb = np.empty(5), np.empty(5)
    sampler(3.0, 5.0, 5, 2, a, ra)
    sampler.py_func(3.0, 5.0, 5, 2, b, rb)
    np.testing.assert_allclose(a, b, rtol=1e-12)
    np.testing.assert_allclose(ra, rb, rtol=1e-12)


@pytest.mark.parametrize("alpha_deg", [1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0])
def test_smooth_rebound_angle_vs_closed_form_with_seed_coefficients(alpha_deg):
    e = max(0.8, 1 - 0.01 * alpha_deg)
    mu = max(0.1, 0.4 - 0.015 * alpha_deg)
    expected, regime = closed_form_rebound_angle(alpha_deg, e, mu)
    assert regime == "sliding"  # with these coefficients every impact up to 45° slides
    assert _rebound_angle(cw.WallOptions(), alpha_deg) == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize("alpha_deg", [2.0, 10.0, 20.0, 21.0, 30.0, 60.0, 89.0])
def test_smooth_rebound_angle_vs_closed_form_sliding_and_non_sliding(alpha_deg):
    """Constant e = 0.9, μ = 0.4: sliding below α* = atan(1/(3.5·0.4·1.9)) = 20.6°, non-sliding above."""
    opts = cw.WallOptions(restitution=(0.9, 0.0, 0.9), friction=(0.4, 0.0, 0.4))
    expected, regime = closed_form_rebound_angle(alpha_deg, 0.9, 0.4)
    assert regime == ("sliding" if alpha_deg < 20.6 else "non-sliding")
    assert _rebound_angle(opts, alpha_deg) == pytest.approx(expected, rel=1e-10)


def test_rough_wall_rebound_table_grazing_particles_thrown_away(capsys):
    """Mean rebound angle vs impact angle 1°–45° for Δγ = 0, 5°, 10° (printed); at small impact
    angles the mean rebound angle exceeds the impact angle and grows with Δγ."""
    n = 20_000
    mean, sem = tables.rebound_angle_table(samples=n, seed=3)
    with capsys.disabled():
        print("\n" + tables.format_table(tables.IMPACT_ANGLES_DEG, tables.ROUGHNESS_STD_DEG, mean, sem))
    alphas = np.array(tables.IMPACT_ANGLES_DEG)
    assert list(tables.ROUGHNESS_STD_DEG) == [0.0, 5.0, 10.0]
    small = alphas <= 10.0
    # smooth wall: deterministic closed form (friction makes β slightly exceed α at small α)
    for a, b in zip(alphas, mean[:, 0]):
        e, mu = max(0.8, 1 - 0.01 * a), max(0.1, 0.4 - 0.015 * a)
        assert b == pytest.approx(closed_form_rebound_angle(a, e, mu)[0], rel=1e-10)
    # rough walls: thrown away from the wall, more so for larger Δγ (margins >> 10 standard errors)
    assert np.all(mean[small, 1] > alphas[small] + 3.0)
    assert np.all(mean[small, 1] > mean[small, 0] + 3.0)
    assert np.all(mean[small, 2] > mean[small, 1] + 5.0)
    assert np.all(sem[small, 1:] < 0.1)


def test_impact_angle_sensitivity_effective_vs_nominal():
    """§3.1/§12.1: evaluating e_w, μ_w at α + γ₁ instead of α. At grazing impacts the effective
    angle is larger, so friction (and restitution) are lower: the rebound keeps more speed. The
    effect on the mean rebound angle stays within a few degrees (printed by collisions.tables)."""
    sens = tables.impact_angle_sensitivity(impact_angles_deg=(1.0, 5.0, 45.0), samples=20_000, seed=4)
    beta_eff, speed_eff = sens["effective"]
    beta_nom, speed_nom = sens["nominal"]
    assert speed_eff[0] > speed_nom[0]  # grazing: less friction at the steeper effective angle
    assert np.all(np.abs(beta_eff - beta_nom) < 3.0)
    assert np.all(np.abs(speed_eff - speed_nom) < 0.05)


def _facet_rebound(alpha, gamma, e, mu):
    """Rebound (v_t′, v_n′) in the real wall's frame of a non-rotating sphere of unit speed hitting,
    at angle α to the real wall, a flat facet tilted by γ (angle α + γ to the facet); numpy arrays.

    In the facet's frame (tangent t′ along the motion, normal n′ into the fluid) the sphere comes in
    with u = cos(α + γ), v = −sin(α + γ) and leaves with v′ = e sin(α + γ) and, from the 2-D impulse
    equations (Sommerfeld & Huber 1999; Crowe et al. 2012), u′ = 5u/7 if non-sliding,
    |u| ≤ (7/2) μ (1 + e) |v| (the contact point stops slipping: u − (2/7) u), else
    u′ = u − sgn(u) μ (1 + e) |v|.  Rotated back by γ: t′ = cos γ t₀ + sin γ n₀,
    n′ = −sin γ t₀ + cos γ n₀.  Written out here independently of the kernel.
    """
    a = alpha + gamma
    u, v_in = np.cos(a), np.sin(a)
    stick = np.abs(u) <= 3.5 * mu * (1 + e) * v_in
    u1 = np.where(stick, u - 2.0 / 7.0 * u, u - np.sign(u) * mu * (1 + e) * v_in)
    v1 = e * v_in
    return u1 * np.cos(gamma) - v1 * np.sin(gamma), u1 * np.sin(gamma) + v1 * np.cos(gamma), stick


@lru_cache(maxsize=None)
def _make_rough_impacts(options):
    kernel = cw.make_wall_collision(options)

    @njit
    def run(alpha, dgamma, n, seed, vt, vn, vb, status):
        """n impacts at angle alpha [rad], speed 10 m/s, no spin, on the pipe bottom (n₀ = +e_y,
        t₀ = +e_x); one rng key per impact.  Fills v_t′, v_n′, the lateral v_z′ and the status."""
        R, r_p, V = 0.015, 1e-4, 10.0
        pos = np.empty(3)
        vel = np.empty(3)
        omega = np.empty(3)
        uf = np.zeros(3)
        dv = np.zeros(3)
        for i in range(n):
            pos[0] = 0.0
            pos[1] = -(R - r_p)
            pos[2] = 0.0
            vel[0] = V * math.cos(alpha)
            vel[1] = -V * math.sin(alpha)
            vel[2] = 0.0
            omega[:] = 0.0
            rng = cr.rng_state(seed, 0, i, cr.STREAM_WALL)
            status[i] = kernel(pos, vel, omega, uf, dv, r_p, R, dgamma, 0.0, rng)
            vt[i] = vel[0] / V
            vn[i] = vel[1] / V
            vb[i] = vel[2] / V

    return run


@pytest.mark.parametrize("alpha_deg,dgamma_deg,shadow,angle", [
    (5.0, 5.0, "weighted", "effective"),  # grazing: shadow effect strong, 4 % of impacts end in contact
    (15.0, 10.0, "weighted", "effective"),  # e_w, μ_w across their 20° kink
    (55.0, 10.0, "weighted", "effective"),  # 44 % of the facets non-sliding
    (5.0, 5.0, "rejection", "effective"),
    (15.0, 10.0, "weighted", "nominal"),
])
def test_rough_wall_rebound_statistics_vs_quadrature_over_facet_angle(alpha_deg, dgamma_deg, shadow, angle):
    """Rough wall, in-plane roughness only, one impact per call (lateral_roughness off,
    max_impacts = 1, v_min = 0, no spin before impact): the mean and standard deviation of the
    rebound angle β = atan2(v_n′, v_t′), the mean velocity ratios v_n′/|v_n| and v_t′/v_t and the
    fraction of contacts from 2·10⁵ kernel calls equal the integrals over the roughness angle γ of
    the rebound from a single flat facet tilted by γ (``_facet_rebound``) with the facet pdf
    f(γ) ∝ N(γ; 0, Δγ) sin(α + γ) (shadow effect "weighted": Sommerfeld 2003; Sommerfeld & Kussin
    2004) or ∝ N(γ; 0, Δγ) (shadow effect "rejection": Sommerfeld & Huber 1999), 0 < α + γ < π,
    and e_w = max(0.8, 1 − 0.01 α_c), μ_w = max(0.1, 0.4 − 0.015 α_c) (the seed paper's fits to
    Sommerfeld & Huber 1999, α_c in degrees; docs/physics.md) at α_c = α + γ ("effective")
    or α ("nominal").  A facet whose rebound still points into the real wall (v_n′ ≤ 0) gives, with
    max_impacts = 1, the contact regime, written out exactly: the incoming sphere on the smooth
    wall with e = 0 and μ_w(α), sliding to u′ = cos α − μ_w sin α or, if cos α ≤ (7/2) μ_w sin α,
    rolling at 5/7 cos α; β = 0 (with more impacts per call the next facet's pdf depends on the
    first rebound, no longer a single integral).  Within 4 Monte-Carlo standard errors (computed
    from the samples)."""
    options = cw.WallOptions(shadow_effect=shadow, impact_angle=angle, lateral_roughness=False, max_impacts=1)
    a, dg = alpha_deg * DEG, dgamma_deg * DEG
    n = 200_000
    vt, vn, vb, status = np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.int64)
    _make_rough_impacts(options)(a, dg, n, 21, vt, vn, vb, status)
    assert np.all(np.isin(status, [cw.WALL_REBOUND, cw.WALL_SLIDING, cw.WALL_ROLLING]))
    assert np.all(vb == 0.0)  # in-plane problem

    # quadrature over the facet angle (fine trapezoid; the integrand jumps at the contact boundary)
    g = np.linspace(-a, min(math.pi - a, 12 * dg), 400_001)
    f = np.exp(-0.5 * (g / dg) ** 2) * (np.sin(a + g) if shadow == "weighted" else 1.0)
    f /= np.trapezoid(f, g)
    a_c = np.degrees(a + g) if angle == "effective" else np.full_like(g, alpha_deg)
    qt, qn, _ = _facet_rebound(a, g, np.maximum(0.8, 1 - 0.01 * a_c), np.maximum(0.1, 0.4 - 0.015 * a_c))
    contact = qn <= 0.0
    mu_a = max(0.1, 0.4 - 0.015 * alpha_deg)
    slide = math.cos(a) - mu_a * math.sin(a)
    qt = np.where(contact, 5 / 7 * math.cos(a) if math.cos(a) <= 3.5 * mu_a * math.sin(a) else slide, qt)
    qn = np.where(contact, 0.0, qn)
    q_beta = np.degrees(np.arctan2(qn, qt))

    def expect(x):
        return np.trapezoid(x * f, g)

    beta = np.degrees(np.arctan2(vn, vt))
    m_beta = expect(q_beta)
    s_beta = math.sqrt(expect((q_beta - m_beta) ** 2))
    m4 = np.mean((beta - beta.mean()) ** 4)  # standard error of the standard deviation: delta method
    rn, rt = vn / math.sin(a), vt / math.cos(a)
    p_contact = expect(contact)
    checks = {  # name: (Monte Carlo, quadrature, standard error)
        "mean beta [deg]": (beta.mean(), m_beta, beta.std() / math.sqrt(n)),
        "std beta [deg]": (beta.std(), s_beta, math.sqrt((m4 - beta.var() ** 2) / (4 * n * beta.var()))),
        "v_n'/|v_n|": (rn.mean(), expect(qn) / math.sin(a), rn.std() / math.sqrt(n)),
        "v_t'/v_t": (rt.mean(), expect(qt) / math.cos(a), rt.std() / math.sqrt(n)),
        "P(contact)": (np.mean(status != cw.WALL_REBOUND), p_contact, math.sqrt(p_contact * (1 - p_contact) / n)),
    }
    for name, (mc, quad, se) in checks.items():
        print(f"{alpha_deg:4.0f} {dgamma_deg:4.0f} {shadow:9s} {angle:9s} {name:16s} MC {mc:.5f} quad {quad:.5f} "
              f"SE {se:.5f} ({(mc - quad) / se:+.2f} SE)")
    for name, (mc, quad, se) in checks.items():
        assert abs(mc - quad) < 4.0 * se, (name, mc, quad, se)


# ---------------------------------------------------------------------------------------------
# contact regime: resting, sliding and rolling on the pipe bottom (§12.11)
# ---------------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def _make_bottom_tracker(options):
    kernel = cw.make_wall_collision(options)

    @njit
    def track(v0x, w0z, dgamma, tau_p, dt, n_steps, r_p, R, seed, vx_hist, status_hist, height_hist, theta0=0.0,
              z_hist=np.empty(0)):
        """Gravity (−y) and Stokes drag in still air (exact exponential step; tau_p = 0: no drag),
        wall kernel on contact. Start at rest on the wall, theta0 [rad] from the bottom towards +z."""
        rc = (R - r_p) * (1 - 1e-12)
        pos = np.array([0.0, -rc * math.cos(theta0), rc * math.sin(theta0)])
        vel = np.array([v0x, 0.0, 0.0])
        omega = np.array([0.0, 0.0, w0z])
        uf = np.zeros(3)
        dv = np.zeros(3)
        rng = cr.rng_state(seed, 0, 0, cr.STREAM_WALL)
        v_min = cw.minimum_bounce_speed(2 * r_p)
        g = np.array([0.0, -9.81, 0.0])
        a = math.exp(-dt / tau_p) if tau_p > 0 else 1.0
        calls = 0
        for k in range(n_steps):
            for c in range(3):
                vt = g[c] * tau_p if tau_p > 0 else 0.0
                if tau_p > 0:
                    pos[c] += vt * dt + (vel[c] - vt) * tau_p * (1 - a)
                    vel[c] = vt + (vel[c] - vt) * a
                else:
                    pos[c] += vel[c] * dt + 0.5 * g[c] * dt * dt
                    vel[c] += g[c] * dt
            status = -1
            if pos[1] ** 2 + pos[2] ** 2 >= (R - r_p) ** 2:
                status = kernel(pos, vel, omega, uf, dv, r_p, R, dgamma, v_min, rng)
                calls += 1
            vx_hist[k] = vel[0]
            status_hist[k] = status
            height_hist[k] = (R - r_p) - math.sqrt(pos[1] ** 2 + pos[2] ** 2)
            if z_hist.shape[0] > k:
                z_hist[k] = pos[2]
        return calls, vel, omega, pos

    return track


@pytest.mark.parametrize("dgamma_deg", [0.0, 5.0, 10.0])
@pytest.mark.parametrize("tau_p", [0.0, 0.05])
def test_particle_at_rest_on_bottom_stays_at_rest(dgamma_deg, tau_p):
    """Released at rest on the pipe bottom in still air: no bouncing, it stays at rest."""
    R, r_p, dt, n = 0.015, 1e-4, 1e-4, 5000
    vx, status, h = np.empty(n), np.empty(n, np.int64), np.empty(n)
    calls, vel, omega, pos = _make_bottom_tracker(cw.WallOptions())(0.0, 0.0, dgamma_deg * DEG, tau_p, dt, n, r_p,
                                                                     R, 5, vx, status, h)
    assert calls <= n  # at most one kernel call per step
    assert not np.any(status == cw.WALL_REBOUND)
    assert np.all(np.isin(status, [-1, cw.WALL_SLIDING, cw.WALL_ROLLING]))
    assert np.linalg.norm(vel) <= G * dt * (1 + 1e-9)  # at most one step of gravity
    assert h.max() <= 2 * G * dt * dt and h.min() >= 0.0  # never leaves the wall, never outside
    assert abs(vx).max() < 1e-12


def test_sliding_sphere_decelerates_by_coulomb_friction_then_rolls_at_five_sevenths():
    """Smooth wall, no drag, launched along the bottom with v0 and no spin: the contact regime
    gives dv/dt = −μ g until rolling sets in at t* = 2 v0/(7 μ g), then v = 5 v0/7, ω = −v/r_p
    (classical sliding-to-rolling sphere; μ = μ_w(α → 0) = 0.4)."""
    R, r_p, dt, n, v0 = 0.015, 1e-4, 1e-5, 20000, 1.0
    vx, status, h = np.empty(n), np.empty(n, np.int64), np.empty(n)
    calls, vel, omega, pos = _make_bottom_tracker(cw.WallOptions())(v0, 0.0, 0.0, 0.0, dt, n, r_p, R, 1, vx,
                                                                     status, h)
    assert calls == n
    mu = 0.4
    t_star = 2 * v0 / (7 * mu * G)
    t = dt * (np.arange(n) + 1)
    sliding = t < 0.9 * t_star
    np.testing.assert_allclose(vx[sliding], v0 - mu * G * t[sliding], rtol=2e-3)
    assert np.all(status[sliding] == cw.WALL_SLIDING)
    assert np.all(status[t > 1.1 * t_star] == cw.WALL_ROLLING)
    assert vel[0] == pytest.approx(5 / 7 * v0, rel=2e-3)
    assert omega[2] == pytest.approx(-vel[0] / r_p, rel=1e-6)
    assert h.max() <= 2 * G * dt * dt


def test_sphere_rolling_in_pipe_bottom_has_rolling_pendulum_period():
    """Released at rest 5° up the curved wall, no drag: it rolls to and fro in contact (no bounce)
    with the period of a sphere rolling without slip in a cylinder, 2π sqrt(7 (R − r_p)/(5 g))
    (a sliding, frictionless sphere would give 2π sqrt((R − r_p)/g), 15 % shorter)."""
    R, r_p, dt, n = 0.015, 1e-4, 1e-4, 20000
    vx, status, h, z = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n)
    _make_bottom_tracker(cw.WallOptions())(0.0, 0.0, 0.0, 0.0, dt, n, r_p, R, 1, vx, status, h, 5 * DEG, z)
    assert np.all(status == cw.WALL_ROLLING)
    t = dt * (np.arange(n) + 1)
    up = np.where((z[:-1] < 0) & (z[1:] >= 0))[0]
    assert len(up) >= 6
    period = np.diff(t[up]).mean()
    assert period == pytest.approx(2 * math.pi * math.sqrt(7 * (R - r_p) / (5 * G)), rel=3e-3)
    # amplitude decays only slowly (impulse contact dissipates O(Δt) per step)
    assert abs(z[-3000:]).max() > 0.8 * abs(z[:3000]).max()
    assert h.min() >= 0.0 and h.max() <= 2 * G * dt * dt


@pytest.mark.parametrize("dgamma_deg", [0.0, 10.0])
def test_particle_released_on_the_wall_comes_to_rest_at_the_bottom_with_drag(dgamma_deg):
    R, r_p, dt, n = 0.015, 1e-4, 1e-4, 20000
    vx, status, h, z = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n)
    _, vel, _, pos = _make_bottom_tracker(cw.WallOptions())(0.0, 0.0, dgamma_deg * DEG, 0.05, dt, n, r_p, R, 1, vx,
                                                             status, h, 10 * DEG, z)
    assert not np.any(status == cw.WALL_REBOUND)
    assert np.linalg.norm(vel) < 1e-3 and abs(pos[2]) < 1e-5
    assert h.min() >= 0.0


def test_no_micro_bounces_on_rough_wall_for_slow_sliding_particle():
    """Slow particle (0.02 m/s) on a rough wall: rebounds slower than the free-fall speed over one
    diameter are contacts, so the particle never hops higher than about one diameter."""
    R, r_p, dt, n = 0.015, 1e-4, 1e-4, 5000
    vx, status, h = np.empty(n), np.empty(n, np.int64), np.empty(n)
    _make_bottom_tracker(cw.WallOptions())(0.02, 0.0, 5 * DEG, 0.05, dt, n, r_p, R, 2, vx, status, h)
    assert h.max() < 2.5 * r_p
    assert h.min() >= 0.0


# ---------------------------------------------------------------------------------------------
# 10^6 random impacts, near grazing and near normal, rough and smooth
# ---------------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def _make_mass_impacts():
    kernel = cw.make_wall_collision(cw.WallOptions())

    @njit
    def run(n, seed):
        R = 0.015
        pos = np.empty(3)
        vel = np.empty(3)
        omega = np.empty(3)
        uf = np.empty(3)
        dv = np.zeros(3)
        bad_pos = 0
        bad_nan = 0
        bad_dir = 0
        bad_energy = 0
        for i in range(n):
            src = cr.rng_state(seed, 1, i, cr.STREAM_INJECTION)
            case = i % 4
            grazing = case < 2
            dgamma = 10.0 * DEG if case % 2 == 0 else 0.0
            u0, u1 = cr.next_uniform_pair(src)
            u2, u3 = cr.next_uniform_pair(src)
            u4, u5 = cr.next_uniform_pair(src)
            z0, z1 = cr.next_normal_pair(src)
            z2, z3 = cr.next_normal_pair(src)
            r_p = R * (1e-3 + 0.03 * u0)
            theta = 2 * math.pi * u1
            r = (R - r_p) * (1.0 + 1e-3 * u2 - 1e-9)  # at contact, sometimes overshooting
            alpha = (0.5 * u3 if grazing else 89.5 + 0.5 * u3) * DEG
            psi = 2 * math.pi * u4
            speed = 30.0 * u5 + 1e-3
            cy = math.cos(theta)
            sz = math.sin(theta)
            pos[0] = 0.0
            pos[1] = r * cy
            pos[2] = r * sz
            # n0 = (0, -cy, -sz); in-plane directions e_x and e_theta = (0, -sz, cy)
            tx = math.cos(psi)
            tt = math.sin(psi)
            ca = math.cos(alpha)
            sa = math.sin(alpha)
            vel[0] = speed * ca * tx
            vel[1] = speed * (ca * tt * (-sz) + sa * cy)
            vel[2] = speed * (ca * tt * cy + sa * sz)
            omega[0] = z0 * 5.0 / r_p
            omega[1] = z1 * 5.0 / r_p
            omega[2] = z2 * 5.0 / r_p
            uf[0] = z3
            uf[1] = 0.0
            uf[2] = 0.0
            ke0 = 0.5 * (vel[0] ** 2 + vel[1] ** 2 + vel[2] ** 2) + 0.2 * r_p * r_p * (
                omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2)
            rng = cr.rng_state(seed, 0, i, cr.STREAM_WALL)
            kernel(pos, vel, omega, uf, dv, r_p, R, dgamma, cw.minimum_bounce_speed(2 * r_p), rng)
            ke1 = 0.5 * (vel[0] ** 2 + vel[1] ** 2 + vel[2] ** 2) + 0.2 * r_p * r_p * (
                omega[0] ** 2 + omega[1] ** 2 + omega[2] ** 2)
            ok = True
            for c in range(3):
                if not (math.isfinite(pos[c]) and math.isfinite(vel[c]) and math.isfinite(omega[c])):
                    ok = False
            if not ok:
                bad_nan += 1
            rr = math.sqrt(pos[1] ** 2 + pos[2] ** 2)
            if not (rr <= R - r_p and rr < R):
                bad_pos += 1
            if vel[1] * (-cy) + vel[2] * (-sz) < -1e-12 * speed:
                bad_dir += 1
            if ke1 > ke0 * (1 + 1e-12):
                bad_energy += 1
        return bad_pos, bad_nan, bad_dir, bad_energy

    return run


def test_million_random_impacts_stay_inside_and_finite():
    """10^6 impacts: grazing (α < 0.5°) and normal (α > 89.5°), Δγ = 10° and smooth, random spin,
    radii and overshoots: none outside the pipe, none NaN, none into the wall, none gaining energy."""
    bad_pos, bad_nan, bad_dir, bad_energy = _make_mass_impacts()(1_000_000, 17)
    assert (bad_pos, bad_nan, bad_dir, bad_energy) == (0, 0, 0, 0)


# ---------------------------------------------------------------------------------------------
# isotropy of the wall model about the pipe axis
# ---------------------------------------------------------------------------------------------

def _local(v, pos):
    """Components of v in the impact point's frame (axial, inward normal, azimuthal n0 × e_x)."""
    n0 = inward_normal(pos)
    ex = np.array([1.0, 0.0, 0.0])
    return np.array([v @ ex, v @ n0, v @ np.cross(n0, ex)])


@pytest.mark.parametrize("opt", [cw.WallOptions(), cw.WallOptions(shadow_effect="rejection", impact_angle="nominal",
                                                                  lateral_roughness=False)])
def test_an_impact_turned_about_the_pipe_axis_rebounds_turned(opt):
    """The same impact (same random stream) at any azimuth of the wall gives the same rebound in
    the impact point's frame, to round-off: nothing in the wall model prefers the bottom, the top
    or a side of the pipe (the gravity acts only between collisions)."""
    kernel = cw.make_wall_collision(opt)
    R, r_frac, dgamma = 0.01525, 100e-6 / 0.01525, 10.0 * DEG
    v_min = cw.minimum_bounce_speed(200e-6)
    for seed in range(60):
        alpha, psi, spin = 0.5 + 0.3 * seed, 0.05 * (seed % 7 - 3), 0.2 * (seed % 5 - 2)
        out = []
        for theta in (math.pi, 0.0, 0.5 * math.pi, 0.7, -2.2):
            pos, vel, omega, r_p = impact_state(R, r_frac, theta, 1e-4, alpha, psi, 10.0, spin, (0.3, 1.0, -0.5))
            # the spin given in the local frame, so that the impacts are the same one turned
            n0 = inward_normal(pos)
            ex = np.array([1.0, 0.0, 0.0])
            omega = spin / r_p * (0.3 * ex + 1.0 * n0 - 0.5 * np.cross(n0, ex)) / math.sqrt(1.34)
            status, p, v, w, uf, dv, _ = run_kernel(kernel, pos, vel, omega, np.zeros(3), r_p, R, dgamma, v_min,
                                                    seed)
            out.append(np.concatenate([[status], _local(v, p), _local(w, p) * r_p]))
        out = np.array(out)
        assert np.all(out[:, 0] == out[0, 0])
        assert np.abs(out[:, 1:] - out[0, 1:]).max() < 1e-9 * 10.0, (seed, out)


def test_an_impact_mirrored_in_its_plane_rebounds_mirrored_on_average():
    """An impact with the lateral (azimuthal) velocity reversed rebounds with the lateral velocity
    and the spin's normal component reversed, and the axial and normal ones the same, on average
    over the roughness (the lateral roughness angle is drawn per impact, not mirrored)."""
    kernel = cw.make_wall_collision(cw.WallOptions())
    R, r_frac, dgamma = 0.01525, 100e-6 / 0.01525, 5.0 * DEG
    v_min = cw.minimum_bounce_speed(200e-6)
    res = {1: [], -1: []}
    for sign in (1, -1):
        for seed in range(3000):
            pos, vel, omega, r_p = impact_state(R, r_frac, math.pi, 1e-4, 3.0, sign * 0.4, 10.0, 0.0, (1.0, 0.0, 0.0))
            _, p, v, w, *_ = run_kernel(kernel, pos, vel, omega, np.zeros(3), r_p, R, dgamma, v_min, seed)
            res[sign].append(np.concatenate([_local(v, p), _local(w, p) * r_p]))
    a, b = np.array(res[1]), np.array(res[-1])
    parity = np.array([1, 1, -1, -1, -1, 1])  # velocity: azimuthal odd; spin (axial vector): axial, normal odd
    diff = a.mean(axis=0) - parity * b.mean(axis=0)
    se = np.sqrt(a.var(axis=0) / len(a) + b.var(axis=0) / len(b))
    assert np.all(np.abs(diff) < 4.0 * se + 1e-12), (diff, se)
    assert abs(a[:, 2].mean()) > 10.0 * se[2]  # the lateral velocity is there to be mirrored
