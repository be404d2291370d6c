"""Inter-particle collisions: binary hard-sphere kernel and the stochastic model of Sommerfeld (2001).

The model of docs/physics.md, section 6 "Inter-particle collisions".  Per real particle and
time step the stochastic model

1. builds a fictitious partner from the cell statistics of the previous pass:
   diameter D₂ (the caller draws it from the local size distribution, see
   ``sample_size_class``), velocity
       u₂ = ū₂ + R(St) u′₁ + σ₂ sqrt(1 − R²) ξ,  u′₁ = u₁ − ū₁,  ξ ~ N(0, 1) per component,
       R(St) = exp(−0.55 St^0.4),  St = τ_p/T_L                   (Sommerfeld 2001)
   (with ``InterparticleOptions(covariance="full")`` σ₂ ξ becomes L ξ, L the Cholesky factor
   of the cell's velocity covariance matrix)
   and angular velocity ω₂ = ω̄ (+ σ_ω ξ′ if the cell rms is given)
2. collides with probability P = 1 − exp(−f Δt),
       f = (π/4) (D₁ + D₂)² |u₁ − u₂| n_p                           [Sommerfeld 2001]
   (P is never clipped: the exponential form is the Poisson probability of at
   least one collision in Δt)
3. samples the impact point uniformly on the full collision disc (L = sqrt(U₁),
   ψ = 2π U₂, sin Φ = L) and applies the two-sphere impulse equations with
   restitution e = 0.9 and friction μ = 0.4 (static = dynamic; the reference paper of
   Laín & Sommerfeld) to the real particle only; the partner is discarded
                                                                   [Sommerfeld 2001]

Masses enter only through m₂/(m₁ + m₂) = D₂³/(D₁³ + D₂³) (one material), so no
density is needed.  Equation numbers of the papers are not quoted (not checked against the
originals); the references are listed in docs/physics.md.
"""

import math
from dataclasses import dataclass
from functools import lru_cache

from numba import njit

from .conf import JIT_FLAGS, KERNEL_FLAGS
from .random import next_normal_pair, next_uniform, next_uniform_pair

# Binary / stochastic collision status codes.
COLLISION_NONE = 0  # no collision (or spheres not approaching)
COLLISION_STICKING = 1  # non-sliding collision: tangential contact velocity brought to zero
COLLISION_SLIDING = 2  # sliding collision: Coulomb friction over the whole impact

# Layout of the ``partner`` diagnostic array written by the stochastic kernel.
PARTNER_VELOCITY = 0  # [0:3] partner velocity before the collision [m/s]
PARTNER_OMEGA = 3  # [3:6] partner angular velocity [rad/s]
PARTNER_NORMAL = 6  # [6:9] unit line of centres, real → partner (written on collision only)
PARTNER_SIZE = 9

_TWO_PI = 2.0 * math.pi
_QUARTER_PI = 0.25 * math.pi


@njit(**JIT_FLAGS)
def sommerfeld_2001_correlation(stokes):
    """Velocity correlation of colliding particles R(St) = exp(−0.55 St^0.4) [-].

    stokes: St = τ_p/T_L [-] (τ_p particle response time, T_L fluid Lagrangian
    integral time). Sommerfeld (2001), IJMF 27:1829–1858.
    R → 1 for St → 0 (tracers move with their neighbours), R → 0 for St → ∞.
    """
    return math.exp(-0.55 * stokes**0.4)


@njit(**JIT_FLAGS)
def kinetic_collision_frequency(d1, d2, number_density, relative_speed):
    """Collision frequency of one particle with a partner class, f = (π/4)(D₁ + D₂)² |g| n [1/s].

    d1, d2 [m]; number_density n [1/m3]; relative_speed |g| [m/s]. Kinetic theory of
    hard spheres; Sommerfeld (2001).
    """
    s = d1 + d2
    return _QUARTER_PI * s * s * relative_speed * number_density


@njit(**JIT_FLAGS)
def collision_probability(frequency, dt):
    """P = 1 − exp(−f Δt) [-]: Poisson probability of at least one collision in Δt.

    frequency [1/s], dt [s]. Computed as −expm1(−f Δt) (accurate for
    small f Δt); never clipped.
    """
    return -math.expm1(-frequency * dt)


@njit(**JIT_FLAGS)
def mean_collision_frequency(d1, d2, number_density, sigma1, sigma2, correlation):
    """Mean collision frequency for Maxwellian fluctuations, ⟨f⟩ = (π/4)(D₁+D₂)² n ⟨|g|⟩ [1/s].

    Equal means; per-component rms sigma1, sigma2 [m/s] of the two classes; partner
    correlated with coefficient R as in the stochastic model (the partner's correlated
    part R u′₁ plus independent part σ₂ sqrt(1 − R²) ξ). Then g = u′₁ − u′₂ is Gaussian
    with per-component variance s² = (1 − R)² σ₁² + (1 − R²) σ₂² and
    ⟨|g|⟩ = s sqrt(8/π) (Maxwell distribution mean). For R = 0, σ₁ = σ₂ = σ:
    ⟨|g|⟩ = 4σ/√π. Useful for the step-size limit 0.1/f_coll.
    """
    s2 = (1.0 - correlation) ** 2 * sigma1 * sigma1 + (1.0 - correlation * correlation) * sigma2 * sigma2
    return kinetic_collision_frequency(d1, d2, number_density, math.sqrt(s2 * 8.0 / math.pi))


@njit(**KERNEL_FLAGS)
def sample_size_class(cumulative_weights, rng):
    """Index k of a size class drawn with probability ∝ its weight.

    cumulative_weights: float64[K], non-decreasing, last entry the total (> 0) — e.g. the
    running sum of the cell's number density per class. rng advanced by one draw.
    """
    k_max = cumulative_weights.shape[0] - 1
    u = next_uniform(rng) * cumulative_weights[k_max]
    lo = 0
    hi = k_max
    while lo < hi:
        mid = (lo + hi) // 2
        if cumulative_weights[mid] > u:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(**JIT_FLAGS)
def impact_normal(gx, gy, gz, u1, u2):
    """Unit line of centres n (real → partner) for an impact point uniform on the collision disc.

    g = u₁ − u₂ [m/s] (|g| > 0); u1, u2 uniforms in [0, 1). In the partner's rest frame,
    with ĝ = g/|g| and any orthonormal e₁, e₂ ⊥ ĝ: L = sqrt(u1) (pdf 2L on [0, 1]),
    ψ = 2π u2, sin Φ = L, n = cos Φ ĝ + sin Φ (cos ψ e₁ + sin ψ e₂); hence g·n = |g| cos Φ ≥ 0.
    Sommerfeld (2001) (L, Y, Z, Φ, Ψ construction), over the full disc.
    """
    g = math.sqrt(gx * gx + gy * gy + gz * gz)
    hx = gx / g
    hy = gy / g
    hz = gz / g
    # e1 = normalised (ĝ × a), a the coordinate axis least aligned with ĝ
    ax = abs(hx)
    ay = abs(hy)
    az = abs(hz)
    if ax <= ay and ax <= az:  # a = e_x
        e1x, e1y, e1z = 0.0, hz, -hy
    elif ay <= az:  # a = e_y
        e1x, e1y, e1z = -hz, 0.0, hx
    else:  # a = e_z
        e1x, e1y, e1z = hy, -hx, 0.0
    inv = 1.0 / math.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
    e1x *= inv
    e1y *= inv
    e1z *= inv
    e2x = hy * e1z - hz * e1y
    e2y = hz * e1x - hx * e1z
    e2z = hx * e1y - hy * e1x
    sin_phi = math.sqrt(u1)
    cos_phi = math.sqrt(1.0 - u1)
    psi = _TWO_PI * u2
    c = sin_phi * math.cos(psi)
    s = sin_phi * math.sin(psi)
    return (cos_phi * hx + c * e1x + s * e2x,
            cos_phi * hy + c * e1y + s * e2y,
            cos_phi * hz + c * e1z + s * e2z)


@njit(**JIT_FLAGS)
def hard_sphere_pair_impulse(gx, gy, gz, sx, sy, sz, nx, ny, nz, e, mu):
    """Impulse per reduced mass J/m* on sphere 1 in a collision of two hard spheres.

    Vector form of the impulse equations of Sommerfeld (2001) and Crowe et al. (2012); the tests
    check the conservation of momentum and angular momentum and the exact normal restitution
    (docs/validation.md, "Particles").
    g = u₁ − u₂ [m/s]; s = r₁ ω₁ + r₂ ω₂ [m/s]; n unit line of centres from 1 to 2 with
    g_n = g·n > 0; e, mu [-].  G = g + s × n, G_t = G − (G·n) n:

        J/m* = −(1+e) g_n n + J_t/m*
        non-sliding if |G_t| ≤ (7/2) μ (1+e) g_n:  J_t/m* = −(2/7) G_t
        sliding otherwise:                         J_t/m* = −μ (1+e) g_n G_t/|G_t|

    Returns (Jx, Jy, Jz, Jtx, Jty, Jtz, status) per unit m* [m/s]; status
    COLLISION_NONE (g_n ≤ 0, zero impulse), COLLISION_STICKING or COLLISION_SLIDING.
    """
    gn = gx * nx + gy * ny + gz * nz
    if not gn > 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, COLLISION_NONE
    cx = gx + (sy * nz - sz * ny)
    cy = gy + (sz * nx - sx * nz)
    cz = gz + (sx * ny - sy * nx)
    cn = cx * nx + cy * ny + cz * nz
    cx -= cn * nx
    cy -= cn * ny
    cz -= cn * nz
    ct = math.sqrt(cx * cx + cy * cy + cz * cz)
    jn = (1.0 + e) * gn
    if ct <= 3.5 * mu * jn:
        f = 2.0 / 7.0
        status = COLLISION_STICKING
    else:
        f = mu * jn / ct
        status = COLLISION_SLIDING
    jtx = -f * cx
    jty = -f * cy
    jtz = -f * cz
    return -jn * nx + jtx, -jn * ny + jty, -jn * nz + jtz, jtx, jty, jtz, status


@njit(**KERNEL_FLAGS)
def hard_sphere_pair(u1, w1, d1, u2, w2, d2, n, e, mu):
    """Binary hard-sphere collision of two real spheres of one material (in place).

    u1, u2 [m/s], w1, w2 [rad/s]: float64[3], updated; d1, d2 diameters [m]; n float64[3]
    unit line of centres from sphere 1 to sphere 2; e, mu [-]. With m ∝ D³ and
    m* = m₁m₂/(m₁+m₂), J from ``hard_sphere_pair_impulse``:

        u₁′ = u₁ + J/m₁,  u₂′ = u₂ − J/m₂,
        ω₁′ = ω₁ + 5/(2 m₁ r₁) n × J_t,  ω₂′ = ω₂ + 5/(2 m₂ r₂) n × J_t

    Conserves linear and angular momentum; kinetic energy does not increase for e ≤ 1.
    Returns the status of ``hard_sphere_pair_impulse`` (no change if not approaching).
    """
    r1 = 0.5 * d1
    r2 = 0.5 * d2
    m1 = d1 * d1 * d1
    m2 = d2 * d2 * d2
    f1 = m2 / (m1 + m2)  # m*/m1
    f2 = m1 / (m1 + m2)  # m*/m2
    jx, jy, jz, tx, ty, tz, status = hard_sphere_pair_impulse(
        u1[0] - u2[0], u1[1] - u2[1], u1[2] - u2[2],
        r1 * w1[0] + r2 * w2[0], r1 * w1[1] + r2 * w2[1], r1 * w1[2] + r2 * w2[2],
        n[0], n[1], n[2], e, mu)
    if status == COLLISION_NONE:
        return status
    u1[0] += f1 * jx
    u1[1] += f1 * jy
    u1[2] += f1 * jz
    u2[0] -= f2 * jx
    u2[1] -= f2 * jy
    u2[2] -= f2 * jz
    cx = n[1] * tz - n[2] * ty
    cy = n[2] * tx - n[0] * tz
    cz = n[0] * ty - n[1] * tx
    c1 = 2.5 * f1 / r1
    c2 = 2.5 * f2 / r2
    w1[0] += c1 * cx
    w1[1] += c1 * cy
    w1[2] += c1 * cz
    w2[0] += c2 * cx
    w2[1] += c2 * cy
    w2[2] += c2 * cz
    return status


@njit(**KERNEL_FLAGS)
def chi3_tail_radius(k, rng):
    """Radius r = |ξ| of a 3-D standard normal vector conditioned on |ξ| > k (k > 0).

    Density ∝ r² exp(−r²/2) on r > k. With t = (r² − k²)/2 ≥ 0 the density is
    ∝ sqrt(k² + 2t) e^(−t) ≤ (k + sqrt(2t)) e^(−t): proposal = mixture of Exp(1)
    (weight k) and Gamma(3/2, 1) (weight sqrt(π/2)), accepted with probability
    sqrt(k² + 2t)/(k + sqrt(2t)) ≥ 1/√2.  rng advanced (≥ 2 draws).
    """
    w_exp = k / (k + math.sqrt(0.5 * math.pi))
    t = 0.0
    for _ in range(1000):
        u, v = next_uniform_pair(rng)
        t = -math.log(1.0 - v)
        if u >= w_exp:  # Gamma(3/2, 1) = Exp(1) + z²/2
            z, _ = next_normal_pair(rng)
            t += 0.5 * z * z
        if next_uniform(rng) * (k + math.sqrt(2.0 * t)) < math.sqrt(k * k + 2.0 * t):
            break
    return math.sqrt(k * k + 2.0 * t)


@njit(**JIT_FLAGS)
def chi3_tail_probability(k):
    """P(|ξ| > k) for a 3-D standard normal vector: erfc(k/√2) + sqrt(2/π) k exp(−k²/2)."""
    return math.erfc(k / math.sqrt(2.0)) + math.sqrt(2.0 / math.pi) * k * math.exp(-0.5 * k * k)


@dataclass(frozen=True)
class InterparticleOptions:
    """Compile-time constants of the stochastic collision kernel.

    restitution : e [-] (reference paper: 0.9);  friction : μ [-], static = dynamic (reference
        paper: 0.4).
    rotation : include spin in the contact velocity and update ω (docs/physics.md, section 6);
        if False, both spins are taken as zero and ω is not touched.
    majorant_radius : K of the exact thinning (see ``make_interparticle_collision``); any
        K > 0 gives the same statistics, K = 5 makes the tail branch rare (1.5e-5) and the
        majorant tight. A numerical parameter, exposed for the tests.
    covariance : "components" (Sommerfeld 2001: each Cartesian component of the partner's
        fluctuation drawn with its own rms, independently of the others) or "full" (drawn with
        the cell's whole velocity covariance matrix, through its Cholesky factor, so that the
        partner does not depend on the frame: in a wall cell at 45° the particles' wall-normal
        and along-wall fluctuations differ, which shows in y and z only as a covariance).
    """

    restitution: float = 0.9
    friction: float = 0.4
    rotation: bool = True
    majorant_radius: float = 5.0
    covariance: str = "components"

    def __post_init__(self):
        if not 0.0 <= float(self.restitution) <= 1.0:
            raise ValueError("restitution must lie in [0, 1]")
        if not float(self.friction) >= 0.0:
            raise ValueError("friction must be >= 0")
        if not float(self.majorant_radius) > 0.0:
            raise ValueError("majorant_radius must be > 0")
        if self.covariance not in ("components", "full"):
            raise ValueError(f"covariance = {self.covariance!r}: allowed components, full")
        object.__setattr__(self, "restitution", float(self.restitution))
        object.__setattr__(self, "friction", float(self.friction))
        object.__setattr__(self, "majorant_radius", float(self.majorant_radius))


@njit(**KERNEL_FLAGS)
def _upper_speed(vel, mean_own, mean_partner, b, big_k):
    """Upper bound of |a| + max_i b_i · K over 0 ≤ R ≤ 1 (``make_interparticle_collision``).

    a = (1 − R)(u₁ − ū₂) + R (ū₁ − ū₂), so |a| ≤ max(|u₁ − ū₂|, |ū₁ − ū₂|); b_i = σ₂,i sqrt(1 − R²)
    ≤ σ₂,i ≤ b, the largest rms (with the full covariance: the square root of its trace).  Inflated by a relative 1e-9 and an absolute 1e-12 of the velocity scale, which
    covers the round-off of both this bound and the exact Q = −expm1(−c s) ≤ c s.
    NaN inputs give NaN (the caller then takes the exact path).
    """
    px = vel[0] - mean_partner[0]
    py = vel[1] - mean_partner[1]
    pz = vel[2] - mean_partner[2]
    qx = mean_own[0] - mean_partner[0]
    qy = mean_own[1] - mean_partner[1]
    qz = mean_own[2] - mean_partner[2]
    a2 = max(px * px + py * py + pz * pz, qx * qx + qy * qy + qz * qz)
    scale = (abs(vel[0]) + abs(vel[1]) + abs(vel[2]) + abs(mean_own[0]) + abs(mean_own[1])
             + abs(mean_own[2]) + abs(mean_partner[0]) + abs(mean_partner[1]) + abs(mean_partner[2]))
    return (math.sqrt(a2) + b * big_k) * (1.0 + 1e-9) + 1e-12 * scale


@lru_cache(maxsize=None)
def make_interparticle_collision(options=InterparticleOptions()):
    """Build the stochastic inter-particle collision kernel (memoised per option set).

    Called once per real particle and time step from the particle step kernel:

        status = interparticle_collision(vel, omega, d_p, mean_own, d_partner, mean_partner,
                                         rms_partner, cov_partner, omega_mean, omega_rms,
                                         number_density, stokes, dt, rng, dv, partner)

    vel       float64[3] real-particle velocity [m/s]            (in/out)
    omega     float64[3] real-particle angular velocity [rad/s]  (in/out)
    d_p       real-particle diameter [m]
    mean_own  float64[3] cell mean velocity of the real particle's size class [m/s]
    d_partner partner diameter [m] (drawn by the caller; monodisperse: d_p)
    mean_partner, rms_partner  float64[3] cell mean and rms velocity (per component) of the
              partner's size class [m/s] (monodisperse: same class as mean_own)
    cov_partner float64[3] its velocity covariances xy, xz, yz [m²/s²] (read only with
              ``covariance = "full"``)
    omega_mean, omega_rms  float64[3] cell mean and rms angular velocity [rad/s] (zeros if
              not stored)
    number_density  n_p of real particles in the cell [1/m3] (of the partner class if the
              caller draws from a per-class pdf, else the total)
    stokes    St = τ_p/T_L [-] (R = exp(−0.55 St^0.4)): of the real particle, or of its cell
              (the tracker's ``partner_correlation``; docs/physics.md, section 6)
    dt        time step [s]
    rng       int64[5] state of ``collisions.random`` (stream STREAM_COLLISION; advanced)
    dv        float64[3] collision velocity jump accumulator [m/s] (+= v_after − v_before)
    partner   float64[9] diagnostics, written on a collision only: [0:3] partner velocity,
              [3:6] partner spin, [6:9] unit line of centres (real → partner)

    Returns COLLISION_NONE (0), COLLISION_STICKING (1) or COLLISION_SLIDING (2).
    For the step-size limit use ``mean_collision_frequency`` (the kernel does not compute f
    on most calls, see below).

    Exact thinning.  The model draws ξ ~ N(0, I), forms g = a − b∘ξ with
    a = u₁ − ū₂ − R (u₁ − ū₁), b = σ₂ sqrt(1 − R²), and collides if Y < P(ξ) = 1 − exp(−c|g|),
    c = (π/4)(D₁ + D₂)² n Δt, Y ~ U(0, 1) (with the full covariance g = a − sqrt(1 − R²) L ξ,
    and max b below is sqrt(1 − R²) sqrt(trace), ≥ |L ξ|/|ξ| for a semi-definite matrix).
    Since P(ξ) ≤ Q = 1 − exp(−c(|a| + max b · K))
    whenever |ξ| ≤ K, the kernel draws Y first: if Y < Q it samples ξ and decides exactly;
    if Y ≥ Q a collision needs |ξ| > K, an event of probability p_K = P(χ₃ > K) decided by a
    second uniform, after which ξ is drawn from the tail (``chi3_tail_radius``, uniform
    direction) and the decision is again Y < P(ξ).  The joint law of (collision, partner)
    is exactly that of the direct algorithm; a typical step (P ~ 0.01) costs one random
    block instead of three normals.  Y is compared first with c · s_up, an upper bound of
    c(|a| + max b · K) that does not need R (``_upper_speed``): when Y clears it, Y ≥ Q is
    certain and R(St), |a| and Q are not evaluated — the decisions and draws are those of the
    full test, bit for bit.
    """
    e = options.restitution
    mu = options.friction
    rotation = options.rotation
    big_k = options.majorant_radius
    p_tail = float(chi3_tail_probability(big_k))
    full = options.covariance == "full"

    @njit(**KERNEL_FLAGS)
    def interparticle_collision(vel, omega, d_p, mean_own, d_partner, mean_partner, rms_partner, cov_partner,
                                omega_mean, omega_rms, number_density, stokes, dt, rng, dv, partner):
        if not (number_density > 0.0 and dt > 0.0):
            return COLLISION_NONE
        c = kinetic_collision_frequency(d_p, d_partner, number_density, dt)  # f/|g| * dt
        y, w = next_uniform_pair(rng)
        # Most steps end here: y >= Q.  Q ≤ c (|a| + max b · K) ≤ c · s_up with s_up free of R
        # (|a| ≤ max(|u1 − ū2|, |ū1 − ū2|) for 0 ≤ R ≤ 1 by convexity, b ≤ σ2), so when y clears
        # c · s_up (with a margin far above round-off) the decision y < Q is known to be false
        # without evaluating R(St) — the same decision and the same draws as the full test.
        if full:
            # with the whole covariance matrix its Cholesky factor L (below) takes the place of
            # the rms: |L ξ| ≤ ‖L‖_F |ξ| = sqrt(trace) |ξ| the majorant's bound
            sxx = rms_partner[0] * rms_partner[0]
            syy = rms_partner[1] * rms_partner[1]
            szz = rms_partner[2] * rms_partner[2]
            bound = math.sqrt(sxx + syy + szz)
        else:
            bound = max(abs(rms_partner[0]), abs(rms_partner[1]), abs(rms_partner[2]))
        if y >= c * _upper_speed(vel, mean_own, mean_partner, bound, big_k):
            if not w < p_tail:
                return COLLISION_NONE
        if full:
            # the Cholesky factor L of the covariance matrix (semi-definite: a pivot that round-off
            # or the blend of two passes leaves at or below zero makes its column zero), only for
            # the steps the majorant's test above does not settle
            l00 = math.sqrt(sxx) if sxx > 0.0 else 0.0
            l10 = cov_partner[0] / l00 if l00 > 0.0 else 0.0
            l20 = cov_partner[1] / l00 if l00 > 0.0 else 0.0
            d11 = syy - l10 * l10
            l11 = math.sqrt(d11) if d11 > 0.0 else 0.0
            l21 = (cov_partner[2] - l20 * l10) / l11 if l11 > 0.0 else 0.0
            d22 = szz - l20 * l20 - l21 * l21
            l22 = math.sqrt(d22) if d22 > 0.0 else 0.0
        corr = sommerfeld_2001_correlation(stokes)
        ind = math.sqrt(max(0.0, 1.0 - corr * corr))
        # partner velocity u2 = mean_partner + corr (vel - mean_own) + b xi;  g = vel - u2 = a - b xi
        ax = vel[0] - mean_partner[0] - corr * (vel[0] - mean_own[0])
        ay = vel[1] - mean_partner[1] - corr * (vel[1] - mean_own[1])
        az = vel[2] - mean_partner[2] - corr * (vel[2] - mean_own[2])
        bx = abs(rms_partner[0]) * ind
        by = abs(rms_partner[1]) * ind
        bz = abs(rms_partner[2]) * ind
        q = collision_probability(c, math.sqrt(ax * ax + ay * ay + az * az) + bound * ind * big_k)
        if y < q:
            x0, x1 = next_normal_pair(rng)
            x2, _ = next_normal_pair(rng)
        elif w < p_tail:
            r = chi3_tail_radius(big_k, rng)
            u1, u2 = next_uniform_pair(rng)
            cz = 2.0 * u1 - 1.0
            sz = math.sqrt(max(0.0, 1.0 - cz * cz))
            phi = _TWO_PI * u2
            x0 = r * sz * math.cos(phi)
            x1 = r * sz * math.sin(phi)
            x2 = r * cz
        else:
            return COLLISION_NONE
        if full:  # the fluctuation sqrt(1 − R²) L ξ
            gx = ax - ind * (l00 * x0)
            gy = ay - ind * (l10 * x0 + l11 * x1)
            gz = az - ind * (l20 * x0 + l21 * x1 + l22 * x2)
        else:
            gx = ax - bx * x0
            gy = ay - by * x1
            gz = az - bz * x2
        g = math.sqrt(gx * gx + gy * gy + gz * gz)
        if not y < collision_probability(c, g):
            return COLLISION_NONE
        partner[0] = vel[0] - gx
        partner[1] = vel[1] - gy
        partner[2] = vel[2] - gz
        # impact point on the full collision disc → line of centres
        p1, p2 = next_uniform_pair(rng)
        nx, ny, nz = impact_normal(gx, gy, gz, p1, p2)
        partner[6] = nx
        partner[7] = ny
        partner[8] = nz
        r1 = 0.5 * d_p
        r2 = 0.5 * d_partner
        if rotation:
            w2x = omega_mean[0]
            w2y = omega_mean[1]
            w2z = omega_mean[2]
            if omega_rms[0] != 0.0 or omega_rms[1] != 0.0 or omega_rms[2] != 0.0:
                a0, a1 = next_normal_pair(rng)
                a2, _ = next_normal_pair(rng)
                w2x += omega_rms[0] * a0
                w2y += omega_rms[1] * a1
                w2z += omega_rms[2] * a2
            sx = r1 * omega[0] + r2 * w2x
            sy = r1 * omega[1] + r2 * w2y
            sz_ = r1 * omega[2] + r2 * w2z
        else:
            w2x = 0.0
            w2y = 0.0
            w2z = 0.0
            sx = 0.0
            sy = 0.0
            sz_ = 0.0
        partner[3] = w2x
        partner[4] = w2y
        partner[5] = w2z
        jx, jy, jz, tx, ty, tz, status = hard_sphere_pair_impulse(gx, gy, gz, sx, sy, sz_,
                                                                  nx, ny, nz, e, mu)
        m1 = d_p * d_p * d_p
        m2 = d_partner * d_partner * d_partner
        f1 = m2 / (m1 + m2)  # m*/m1
        vel[0] += f1 * jx
        vel[1] += f1 * jy
        vel[2] += f1 * jz
        dv[0] += f1 * jx
        dv[1] += f1 * jy
        dv[2] += f1 * jz
        if rotation:
            c1 = 2.5 * f1 / r1
            omega[0] += c1 * (ny * tz - nz * ty)
            omega[1] += c1 * (nz * tx - nx * tz)
            omega[2] += c1 * (nx * ty - ny * tx)
        return status

    return interparticle_collision


interparticle_collision = make_interparticle_collision(InterparticleOptions())
"""Default kernel (e = 0.9, μ = 0.4, with spin); see ``make_interparticle_collision``."""
