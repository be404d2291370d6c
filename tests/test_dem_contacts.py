"""Contact physics of the DEM grains, each test against an independent number:

- normal restitution of a pair and of a grain on the tube wall against the e the dashpot was
  built from (mean over contact phases within 1 %, at the default stiffness, dt = t_c/30);
- a grain sliding along the tube bottom decelerates at μg and rolls from 5/7 of its speed
  (solid sphere, I = 2/5 m R²);
- momentum conservation of the pair forces (to the last bit);
- 1 and 2 numba threads give bit-identical trajectories;
- the Verlet list misses no contact: fast grains (3 m/s) follow the same trajectories as with a
  list rebuilt every step (no skin), to round-off;
- Janssen saturation of the wall stress in a column sliding down a vertical tube (slow).
"""

import math

import numba
import numpy as np
import pytest

from dem import FREE, CellGrid, ContactModel, Grains, contact_time, damping_ratio, dem_step
from dem.contacts import contact

D, RHO, K, E, MU = 1.4e-3, 937.0, 1000.0, 0.5, 0.5
RT = 3.5e-3
STEPS_PER_CONTACT = 30


def _model(mu=MU, e=E):
    return ContactModel(D, RHO, K, e, mu)


def _run(g, m, steps, dt, gravity=(0.0, 0.0, 0.0), grid=None, plate_x=np.nan, parallel=False):
    grid = grid or CellGrid(-0.01, 0.01, RT, D)
    work, gas = {}, np.zeros((len(g.status), 3))
    return dem_step(g, m, grid, gas, np.asarray(gravity, float), dt, 0.0, plate_x, work, nsteps=steps,
                    parallel=parallel)


def test_damping_ratio_vs_restitution_formula():
    z = damping_ratio(E)
    assert math.exp(-math.pi * z / math.sqrt(1 - z * z)) == pytest.approx(E, rel=1e-12)
    assert z == pytest.approx(0.2154, abs=1e-4)


PHASES = np.linspace(0.0, 1.0, 8, endpoint=False)


def test_pair_restitution_within_one_percent_of_e():
    """Head-on pair at 0.3 m/s; the contact starts at eight phases within a time step (the
    dashpot's jumps at the start and end of a contact make a single collision's e depend on
    the phase): the mean is within 1 % of e, each collision within 2.5 %."""
    m = _model()
    dt = m.t_contact / STEPS_PER_CONTACT
    v0, r = 0.15, 0.5 * D
    es = []
    for phase in PHASES:
        gap = 1e-7 + phase * 2 * v0 * dt
        g = Grains()
        g.append(np.array([[-r - gap / 2, 0, 0], [r + gap / 2, 0, 0]]), np.array([[v0, 0, 0], [-v0, 0, 0]]),
                 np.array([FREE, FREE], dtype=np.int8), np.arange(2))
        omax = _run(g, m, 4 * STEPS_PER_CONTACT, dt)
        es.append((g.vel[1, 0] - g.vel[0, 0]) / (2 * v0))
        # momentum to the last bit; the undamped bound of the overlap
        assert g.vel[0, 0] + g.vel[1, 0] == 0.0
        assert omax < 2 * v0 * math.sqrt(0.5 * m.mass / K)
    assert np.mean(es) == pytest.approx(E, rel=0.01)
    assert np.allclose(es, E, rtol=0.01, atol=0)


def test_wall_restitution_within_one_percent_of_e():
    """The wall's own restitution (0.8 here, the pairs' 0.5), so that a wall contact built with
    the pairs' dashpot would fail."""
    e_w = 0.8
    m = ContactModel(D, RHO, K, E, MU, wall_restitution=e_w)
    dt = m.t_contact / STEPS_PER_CONTACT
    v0, r = 0.2, 0.5 * D
    es = []
    for phase in PHASES:
        g = Grains()
        g.append(np.array([[0, 0, -(RT - r) + 1e-7 + phase * v0 * dt]]), np.array([[0, 0, -v0]]),
                 np.array([FREE], dtype=np.int8), np.arange(1))
        _run(g, m, 6 * STEPS_PER_CONTACT, dt)
        es.append(g.vel[0, 2] / v0)
    assert np.mean(es) == pytest.approx(e_w, rel=0.01)
    assert np.allclose(es, e_w, rtol=0.025, atol=0)
    assert contact_time(E, K, m.mass) == pytest.approx(math.sqrt(2) * m.t_contact, rel=1e-12)


def test_sliding_grain_decelerates_at_mu_g_and_rolls_at_five_sevenths():
    """On the wall's own friction coefficient (0.3 here, the pairs' 0.5)."""
    mu_w = 0.3
    m = ContactModel(D, RHO, K, E, MU, wall_friction=mu_w)
    dt = m.t_contact / STEPS_PER_CONTACT
    g9, v0, r = 9.81, 0.1, 0.5 * D
    z0 = -(RT - r) - m.mass * g9 / K  # resting on the tube bottom at the static overlap
    g = Grains()
    g.append(np.array([[0.0, 0, z0]]), np.array([[v0, 0, 0]]), np.array([FREE], dtype=np.int8), np.arange(1))
    grid = CellGrid(-0.05, 0.05, RT, D)
    t_roll = 2 * v0 / (7 * mu_w * g9)  # sliding phase of a solid sphere
    n1 = int(0.5 * t_roll / dt)
    _run(g, m, n1, dt, (0, 0, -g9), grid)
    decel = (v0 - g.vel[0, 0]) / (n1 * dt)
    assert decel == pytest.approx(mu_w * g9, rel=0.01)
    _run(g, m, int(1.5 * t_roll / dt), dt, (0, 0, -g9), grid)
    assert g.vel[0, 0] == pytest.approx(5 / 7 * v0, rel=0.005)
    # rolling without slipping: v = −ω_y R ... sign: contact point at −R ẑ, v_c = v + ω × (−R ẑ)
    assert g.vel[0, 0] + g.omg[0, 1] * (-r) == pytest.approx(0.0, abs=1e-3 * v0)


@pytest.mark.parametrize("fraction,grows", [(0.9, False), (1.1, True)])
def test_viscous_tangential_force_stable_below_the_stated_limit(fraction, grows):
    """The kick–drift–kick step's eigenvalue analysis (eulag.slug.tangential_damping_pair_limit) puts the
    stability limit of the viscous tangential force of a pair at dt γ_t 7/m = 1: below it a small
    slip decays during the contact, above it the slip grows step by step."""
    from eulag.slug import tangential_damping_pair_limit

    r = 0.5 * D
    m = ContactModel(D, RHO, K, E, MU, tangential_ratio=fraction * tangential_damping_pair_limit(E, STEPS_PER_CONTACT))
    dt = m.t_contact / STEPS_PER_CONTACT
    s0 = 1e-9  # small enough for the viscous branch throughout (μ F_n ≫ γ_t |v_t|)
    g = Grains()
    g.append(np.array([[-r, 0, 0], [r + 1e-9, 0, 0]]), np.array([[0.005, s0 / 2, 0], [-0.005, -s0 / 2, 0]]),
             np.array([FREE, FREE], dtype=np.int8), np.arange(2))
    slip = []
    for _ in range(20):
        _run(g, m, 1, dt)
        assert g.pos[1, 0] - g.pos[0, 0] < D  # still in contact (the contact lasts 30 steps)
        slip.append(abs(g.vel[0, 1] + r * g.omg[0, 2] - g.vel[1, 1] + r * g.omg[1, 2]))
    assert (slip[19] > slip[9]) == grows


@pytest.mark.parametrize("fraction,grows", [(0.9, False), (1.1, True)])
def test_packing_limit_of_the_viscous_tangential_force(fraction, grows):
    """Two grains pressed by a gas force against an end plate on the tube bottom: the step is
    stable below the pair limit divided by the configuration's λ_max / (7 γ_t/m)
    (dem.stability.damping_factor, an eigenvalue computation independent of the step) and not
    above it: a 1e-9 m/s perturbation decays, or grows step by step against an unperturbed copy."""
    from dem.stability import damping_factor
    from eulag.slug import tangential_damping_pair_limit

    r, x0, nc = 0.5 * D, -0.009, 2
    pos = np.array([[x0 + r + k * D * (1 - 1e-3), -(RT - r) + 1e-7, 0.0] for k in range(nc)])
    m = ContactModel(D, RHO, K, E, 1e6)  # μ large: every contact stays in the viscous branch
    dt = m.t_contact / STEPS_PER_CONTACT
    g = Grains()
    g.append(pos, np.zeros_like(pos), np.full(nc, FREE, np.int8), np.arange(nc))
    grid = CellGrid(-0.01, 0.01, RT, D)
    gas = np.zeros((nc, 3))
    gas[:, 0] = -5 * m.mass * 9.81
    grav = np.array([0.0, -9.81, 0.0])
    dem_step(g, m, grid, gas, grav, dt, 0.0, x0, {}, nsteps=3000)  # settle against the plate
    factor = damping_factor(g.pos[:nc], D, RT, plate_x=x0)
    assert 1.2 < factor < 2.5  # pair, wall and plate contacts together
    ratio = fraction * tangential_damping_pair_limit(E, STEPS_PER_CONTACT) / factor
    m.gt_pp, m.gt_pw = ratio * m.gn_pp, ratio * m.gn_pw
    ref = Grains.from_state(g.state())
    rng = np.random.default_rng(0)
    g.vel[:nc] += 1e-9 * rng.standard_normal((nc, 3))
    g.omg[:nc] += 1e-9 / r * rng.standard_normal((nc, 3))

    def gap():
        dv, dw = g.vel[:nc] - ref.vel[:nc], g.omg[:nc] - ref.omg[:nc]
        return math.sqrt((dv ** 2).sum() + r * r * (dw ** 2).sum())

    start, w1, w2 = gap(), {}, {}
    for _ in range(4):
        dem_step(g, m, grid, gas, grav, dt, 0.0, x0, w1, nsteps=25)
        dem_step(ref, m, grid, gas, grav, dt, 0.0, x0, w2, nsteps=25)
    assert (gap() > 10 * start) == grows and (gap() < start) == (not grows)


def test_contact_force_antisymmetric_bitwise():
    rng = np.random.default_rng(1)
    for _ in range(100):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        vr, ws = rng.normal(size=3), rng.normal(size=3) * 100
        a = contact(*n, 1e-5, *vr, *ws, 7e-4, K, 0.01, 0.01, MU)
        b = contact(*(-n), 1e-5, *(-vr), *ws, 7e-4, K, 0.01, 0.01, MU)
        assert all(a[k] == -b[k] for k in range(3))
        assert all(a[k] == b[k] for k in range(3, 7))
        # the kernel agrees with its Python version
        c = contact.py_func(*n, 1e-5, *vr, *ws, 7e-4, K, 0.01, 0.01, MU)
        assert np.allclose(a, c, rtol=1e-13, atol=0)


def _random_column(n, length, seed):
    """n grains on a loose lattice in a tube segment with random velocities (numpy seeded)."""
    rng = np.random.default_rng(seed)
    r = 0.5 * D
    pts = []
    a = 1.05 * D
    for x in np.arange(r, length - r, a):
        for y in np.arange(-RT + r, RT - r + 1e-12, a):
            for z in np.arange(-RT + r, RT - r + 1e-12, a):
                if y * y + z * z < (RT - r) ** 2:
                    pts.append((x, y, z))
    pts = np.array(pts[:n])
    return pts, rng.normal(scale=0.05, size=pts.shape)


def test_one_and_two_threads_bit_identical():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    m = _model()
    dt = m.t_contact / STEPS_PER_CONTACT
    pos, vel = _random_column(400, 0.03, 3)
    out = []
    for nt in (1, 2):
        numba.set_num_threads(nt)
        try:
            g = Grains()
            g.append(pos, vel, np.full(len(pos), FREE, dtype=np.int8), np.arange(len(pos)))
            _run(g, m, 300, dt, (0, 0, -9.81), CellGrid(0.0, 0.03, RT, D, periodic=True), parallel=True)
            out.append(np.concatenate([g.pos[: g.n].ravel(), g.vel[: g.n].ravel(), g.omg[: g.n].ravel()]))
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    assert np.array_equal(out[0], out[1])
    # and the serial kernels give the same bits
    g = Grains()
    g.append(pos, vel, np.full(len(pos), FREE, dtype=np.int8), np.arange(len(pos)))
    _run(g, m, 300, dt, (0, 0, -9.81), CellGrid(0.0, 0.03, RT, D, periodic=True), parallel=False)
    assert np.array_equal(out[0], np.concatenate([g.pos[: g.n].ravel(), g.vel[: g.n].ravel(), g.omg[: g.n].ravel()]))


def test_verlet_list_misses_no_contact():
    """Grains at 3 m/s (up to 10 µm per step, the skin's half 140 µm passed within tens of steps)
    in a periodic segment: the trajectories with the default skin equal those of a list rebuilt
    every step (skin 0: exactly the pairs in contact, as a cell search would find them) to
    round-off; a contact missed for a single step would move the grains by micrometres."""
    m = _model()
    dt = m.t_contact / STEPS_PER_CONTACT
    pos, _ = _random_column(300, 0.02, 5)
    vel = np.random.default_rng(7).normal(scale=1.7, size=pos.shape)  # |v| ~ 3 m/s
    out = []
    for skin in (0.2, 0.0):
        g = Grains()
        g.append(pos, vel, np.full(len(pos), FREE, dtype=np.int8), np.arange(len(pos)))
        omax = _run(g, m, 400, dt, (0, 0, -9.81), CellGrid(0.0, 0.02, RT, D, periodic=True, skin=skin))
        out.append(g.pos[: g.n].copy())
    assert omax > 0.0  # there were contacts
    moved = np.abs(out[0] - pos).max()
    assert moved > 1e-3  # grains travelled many skins
    assert np.abs(out[0] - out[1]).max() < 1e-10

    # the rebuild rule's bound: two grains head-on from a gap just beyond the list's reach close
    # it by twice their own travel, so the list must be rebuilt once a grain has moved half the
    # skin (a rule of a whole skin lets them pass through each other)
    skin = 0.2
    gap = 1.05 * skin * D
    pair = np.array([[-0.5 * (D + gap), 0.0, 0.0], [0.5 * (D + gap), 0.0, 0.0]])
    finals = []
    for s in (skin, 0.0):
        g = Grains()
        g.append(pair, np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]]), np.full(2, FREE, dtype=np.int8),
                 np.arange(2))
        _run(g, m, 300, dt, grid=CellGrid(-0.01, 0.01, RT, D, skin=s))
        finals.append(g.vel[:2, 0].copy())
    assert finals[1] == pytest.approx([-0.5 * E, 0.5 * E], rel=0.02)  # rebounded with restitution e
    assert np.abs(finals[0] - finals[1]).max() < 1e-12


def test_listed_forces_equal_a_brute_force_sum_over_all_pairs():
    """The force and torque on every grain after a step equal the sum of dem.contacts.contact over
    all pairs and the wall, evaluated independently of any neighbour search (O(N²)), at the
    positions and predicted velocities the step used."""
    m = _model()
    dt = m.t_contact / STEPS_PER_CONTACT
    pos, _ = _random_column(250, 0.02, 11)
    rng = np.random.default_rng(3)
    pos = pos + rng.normal(scale=0.06 * D, size=pos.shape)  # overlaps of a few per cent of d
    vel = rng.normal(scale=0.5, size=pos.shape)
    g = Grains()
    g.append(pos, vel, np.full(len(pos), FREE, dtype=np.int8), np.arange(len(pos)))
    g.omg[: g.n] = rng.normal(scale=50.0, size=pos.shape)
    grid = CellGrid(-0.01, 0.03, RT, D)
    work, gas = {}, np.zeros((len(g.status), 3))
    dem_step(g, m, grid, gas, np.zeros(3), dt, 0.0, np.nan, work, nsteps=3)
    n, r = g.n, 0.5 * D
    p, vp, wp = g.pos[:n], work["vp"][:n], work["wp"][:n]
    f_ref, t_ref = np.zeros((n, 3)), np.zeros((n, 3))
    for i in range(n):
        for j in range(n):
            d = p[i] - p[j]
            dist = math.sqrt(d @ d)
            if i == j or dist >= D:
                continue
            out = contact(*(d / dist), D - dist, *(vp[i] - vp[j]), *(wp[i] + wp[j]), r, m.k_n, m.gn_pp, m.gt_pp,
                          m.mu_pp)
            f_ref[i] += out[:3]
            t_ref[i] += out[3:6]
        rr = math.hypot(p[i, 1], p[i, 2])
        if rr + r > RT:
            out = contact(0.0, -p[i, 1] / rr, -p[i, 2] / rr, rr + r - RT, *vp[i], *wp[i], r, m.k_n, m.gn_pw, m.gt_pw,
                          m.mu_pw)
            f_ref[i] += out[:3]
            t_ref[i] += out[3:6]
    assert np.count_nonzero(np.abs(f_ref).sum(axis=1)) > 80  # a third of the grains are in contact
    scale = np.abs(f_ref).max()
    assert np.abs(g.force[:n] - f_ref).max() < 1e-12 * scale
    assert np.abs(g.torque[:n] - t_ref).max() < 1e-12 * np.abs(t_ref).max()


@pytest.mark.slow
def test_janssen_wall_stress_saturates_in_a_sliding_vertical_column():
    """Janssen (1895) in a vertical tube: a column (relaxed packing of solids fraction 0.43,
    6.7 cm once settled, gravity along −x) sliding down the wall on a plate drawn down at
    2 cm/s.  Where the wall friction is fully mobilised the vertical stress saturates below a
    depth of a few λ = D/(4 μ_eff K_J): the wall normal force per unit length rises from the
    free surface and levels off, and at saturation the wall friction per length carries the
    weight per length w, so Coulomb's bound |F_t| ≤ μ F_n makes the level at least w/μ.
    Hydrostatics (no wall friction) would give a wall force growing linearly with depth.

    The column slides because the contact law has no tangential spring (the paper's): a column
    at rest holds no friction and creeps until its plate carries it, so Janssen's state of a
    mobilised wall friction is that of a column sliding along the wall, as a plug does.  Measured
    (seeds 5–7, 2–5 cm/s): the level is 1.76–1.85 w/μ (the wall friction carries the weight at
    about 0.55 μ F_n on average: grains at the wall partly roll), reached within 5–15 mm."""
    from dem.feed import relaxed_packing

    m = _model()
    dt = m.t_contact / STEPS_PER_CONTACT
    length = 0.084
    n = int(round(0.43 * math.pi * RT**2 * length / m.volume))
    pos = relaxed_packing(n, length, RT, D, RHO, K, seed=5)
    pos[:, 0] += 0.5 * D  # whole column above the plate at x = 0
    g = Grains()
    g.append(pos, np.zeros_like(pos), np.full(n, FREE, dtype=np.int8), np.arange(n))
    grid = CellGrid(-0.05, length + 0.01, RT, D)
    work, gas, gravity = {}, np.zeros((n, 3)), np.array([-9.81, 0.0, 0.0])
    dem_step(g, m, grid, gas, gravity, dt, 0.0, 0.0, work, nsteps=int(0.1 / dt))  # settle on the plate
    v_plate, chunk, plate = 0.02, 10, 0.0
    chunks = int(0.15 / (chunk * dt))
    wall, samples = np.zeros(n), 0
    for c in range(chunks):  # the plate drawn down; the wall force averaged over the second half
        dem_step(g, m, grid, gas, gravity, dt, 0.0, plate, work, nsteps=chunk)
        plate -= v_plate * chunk * dt
        if c >= chunks // 2:
            wall += work["wall_fn"][:n]
            samples += 1
    wall /= samples
    x = g.pos[:n, 0]
    assert -1.2 * v_plate < g.vel[:n, 0].mean() < -0.5 * v_plate  # the column slides with the plate
    top = np.sort(x)[-20:].mean()
    h = top - x  # depth below the free surface
    height = top - x.min()
    w = n * m.mass * 9.81 / height  # weight per length

    def per_length(lo, hi):
        return wall[(h >= lo) & (h < hi)].sum() / (hi - lo)

    middle = per_length(height / 3, 2 * height / 3)
    deep = per_length(2 * height / 3, height - 0.005)  # the last 5 mm touch the plate
    # saturation: the deep third as the middle one (linear growth: 5/3 of it), and the wall
    # force near the surface (5-15 mm) already half the deep level (linear: about a fifth)
    assert deep < 1.3 * middle, (deep / middle)
    assert per_length(0.005, 0.015) > 0.5 * deep, (per_length(0.005, 0.015) / deep)
    # Coulomb's bound at saturation, and a level of the same order (hydrostatics: without
    # bound at depth)
    assert w / MU <= deep < 3.0 * w / MU, (deep / (w / MU))
