"""Particle–wall collision with a rough pipe wall (Sommerfeld & Huber 1999).

The model of docs/physics.md, section 5 "Particle–wall collisions"; where it departs from
the reference paper (Laín & Sommerfeld), section 7 "Departures from the reference paper"
lists the departure and its option.  Geometry: the pipe wall is the cylinder y² + z² = R²
(x along the axis, y up, z horizontal); at a particle centre (x, y, z) with
r = sqrt(y² + z²) the inward wall normal is n₀ = −(0, y, z)/r.  The centre touches the
wall when r = R − r_p.

One impact, in order (``make_wall_collision`` builds the kernel):

1. nominal impact angle α = arcsin(−v·n₀/|v|) and the impact-plane frame
   t₀ (tangential), b₀ = n₀ × t₀ (lateral)
2. in-plane roughness angle γ₁ from the shadow-effect pdf
   f_eff(γ; α) ∝ N(γ; 0, Δγ) sin(α + γ), α + γ > 0              [Sommerfeld 2003;
   Sommerfeld & Kussin 2004]; option: simple rejection of α + γ ≤ 0 (Sommerfeld & Huber 1999)
3. lateral roughness angle γ₂ ~ N(0, Δγ) (option: none)           [not stated in the paper]
4. virtual-wall normal n″ = cos γ₂ (cos γ₁ n₀ − sin γ₁ t₀) + sin γ₂ b₀
5. e_w = max(0.8, 1 − 0.01 α_c), μ_w = max(0.1, 0.4 − 0.015 α_c), α_c [deg] the
   effective angle α + γ₁ (option: nominal α)   [Sommerfeld & Huber 1999; angle: section 7]
6. hard-sphere impulse rebound on n″, sliding or sticking, with spin
                                               [Sommerfeld & Huber 1999; Crowe et al. 2012]
7. if the rebound does not leave the real wall (v′·n₀ ≤ 0), impact again with a
   new roughness angle, at most ``max_impacts`` times in all
8. if the particle still does not leave, or leaves with a wall-normal speed
   below ``v_min`` (e.g. ``minimum_bounce_speed`` = speed gained falling one
   diameter), the impact becomes a *contact*: the incoming state hits the
   smooth real wall with e = 0 and Coulomb friction μ_w(α); the particle keeps
   moving along the wall, sliding or, once the contact point sticks, rolling.
   Repeated each step while it is pressed on the wall, the normal impulse
   m |v_n| = F_n Δt makes this Coulomb friction μ F_n over the step
9. the normal component of the fluid velocity fluctuation seen is mirrored,
   u′_F → u′_F − 2 (u′_F·n₀) n₀
10. the centre is put back to r ≤ R − r_p (distance ≥ r_p from the wall,
    strictly inside the pipe) along its radial line.

Angles inside the kernels are in radians; the correlations take degrees, as
published.
"""

import math
from dataclasses import dataclass
from functools import lru_cache

from numba import njit

from .conf import JIT_FLAGS, KERNEL_FLAGS
from .random import next_normal, next_uniform  # Philox streams; normals by the ziggurat

# Wall-kernel status codes (returned; the tracker counts them).
WALL_NO_IMPACT = 0  # not moving towards the wall: only the position was corrected
WALL_REBOUND = 1  # bounced off the (rough) wall and leaves it
WALL_SLIDING = 2  # contact regime, the contact point slips (Coulomb friction)
WALL_ROLLING = 3  # contact regime, the contact point sticks (rolling without slip)

GRAVITY = 9.81  # m s-2, for minimum_bounce_speed's default
_PI = math.pi
_HALF_PI = 0.5 * math.pi
_SQRT_2PI = math.sqrt(2.0 * math.pi)
_DEG = 180.0 / math.pi
# Relative margin by which the centre is put inside r = R - r_p.
_PLACE_MARGIN = 1e-12
# Cap on the rejection loops of the roughness samplers (expected < 3 tries; never reached in practice).
_MAX_TRIES = 10000


@njit(**JIT_FLAGS)
def linear_with_floor(alpha_deg, value0, slope, floor):
    """max(floor, value0 − slope·α): the form of the Sommerfeld–Huber wall coefficients.

    alpha_deg : impact angle [deg];  slope [1/deg].
    """
    return max(floor, value0 - slope * alpha_deg)


@njit(**JIT_FLAGS)
def sommerfeld_huber_1999_restitution(alpha_deg):
    """Wall restitution e_w = max(0.8, 1 − 0.01 α) [-], α [deg].

    Glass beads on steel, fit to Sommerfeld & Huber (1999) as used by Laín & Sommerfeld
    (the reference paper, the unnumbered equation after its eq. 15). Floor reached at α = 20°.
    """
    return max(0.8, 1.0 - 0.01 * alpha_deg)


@njit(**JIT_FLAGS)
def sommerfeld_huber_1999_friction(alpha_deg):
    """Wall (kinetic) friction μ_w = max(0.1, 0.4 − 0.015 α) [-], α [deg].

    Source as ``sommerfeld_huber_1999_restitution``. Floor reached at α = 20°.
    """
    return max(0.1, 0.4 - 0.015 * alpha_deg)


@njit(**JIT_FLAGS)
def minimum_bounce_speed(diameter, gravity=GRAVITY):
    """Wall-normal speed gained falling one particle diameter, sqrt(2 g D_p) [m/s].

    diameter [m], gravity [m/s2]. Rebounds slower than this are treated as contact
    (sliding/rolling) instead of a bounce (docs/physics.md, section 5).
    """
    return math.sqrt(2.0 * gravity * diameter)


@njit(**KERNEL_FLAGS)
def roughness_angle_effective_pdf(alpha, dgamma, rng):
    """Roughness angle γ [rad] with the shadow-effect pdf (Sommerfeld 2003; Sommerfeld & Kussin 2004).

        f_eff(γ; α) ∝ N(γ; 0, Δγ) · sin(α + γ)   for 0 < α + γ < π,   0 otherwise

    alpha: nominal impact angle [rad], 0 ≤ α ≤ π/2; dgamma: Δγ [rad]; rng: int64[5] state of
    ``collisions.random`` (advanced).  Δγ ≤ 0 gives γ = 0.

    Exact rejection sampler with a tight envelope, efficient also for α → 0 and small Δγ,
    where drawing γ ~ N(0, Δγ) and accepting with probability sin(α + γ) accepts only a
    fraction ~ 0.4 Δγ.  With s = (α + γ)/Δγ, a = α/Δγ, z = s − a:
    target ∝ φ(z) sin(Δγ s) 1{s > 0}.  Proposal q(z) ∝ (|z| + a) φ(z), a mixture of a
    Rayleigh variate with random sign (weight 2) and a standard normal (weight a√(2π));
    accept with probability sin(Δγ s)/(Δγ (|z| + a)) ≤ 1, since sin x ≤ x and s ≤ |z| + a.
    Acceptance is ≳ 1/3 for all α, Δγ.
    """
    if dgamma <= 0.0:
        return 0.0
    a = alpha / dgamma
    p_rayleigh = 2.0 / (2.0 + a * _SQRT_2PI)
    for _ in range(_MAX_TRIES):
        u = next_uniform(rng)
        if u < p_rayleigh:
            z = math.sqrt(-2.0 * math.log(1.0 - next_uniform(rng)))
            if u < 0.5 * p_rayleigh:
                z = -z
        else:
            z = next_normal(rng)
        x = alpha + dgamma * z  # α + γ
        if x <= 0.0 or x >= _PI:
            continue
        if next_uniform(rng) * dgamma * (abs(z) + a) < math.sin(x):
            return dgamma * z
    return 0.0


@njit(**KERNEL_FLAGS)
def roughness_angle_simple(alpha, dgamma, rng):
    """Roughness angle γ ~ N(0, Δγ) [rad], redrawn while α + γ ≤ 0 (Sommerfeld & Huber 1999).

    The simple shadow effect (also redrawn if α + γ ≥ π, which needs a > 9σ draw).
    alpha, dgamma [rad]; rng advanced.
    """
    if dgamma <= 0.0:
        return 0.0
    for _ in range(_MAX_TRIES):
        g = dgamma * next_normal(rng)
        if 0.0 < alpha + g < _PI:
            return g
    return 0.0


@njit(**KERNEL_FLAGS)
def hard_sphere_wall_rebound(vel, omega, nx, ny, nz, r_p, e, mu, rotation):
    """Hard-sphere impact of a sphere on a plane wall with unit normal n (into the fluid).

    Vector form of the sliding / non-sliding impulse equations of Sommerfeld & Huber (1999) and
    Crowe et al. (2012).  With v_n = v·n < 0, G = v − r_p ω × n, G_t = G − (G·n) n:

        non-sliding if |G_t| ≤ (7/2) μ (1 + e) |v_n|:
            v′ = v − (1+e) v_n n − (2/7) G_t,        ω′ = ω + 5/(7 r_p) n × G_t
        sliding otherwise (t̂ = G_t/|G_t|):
            v′ = v − (1+e) v_n n − μ (1+e) |v_n| t̂,  ω′ = ω + 5 μ (1+e) |v_n|/(2 r_p) n × t̂

    vel [m/s], omega [rad/s]: float64[3], updated in place; n: unit normal; r_p [m];
    e, mu [-]; rotation: if False, ω is taken as zero and not updated (the tangential
    impulse still uses the sphere's inertia, I = (2/5) m r_p²; in the contact regime such a
    particle slides to rest at Coulomb deceleration instead of rolling).
    Returns True for a non-sliding (sticking) impact.  Does nothing (returns False)
    if v·n ≥ 0.
    """
    vx = vel[0]
    vy = vel[1]
    vz = vel[2]
    vn = vx * nx + vy * ny + vz * nz
    if vn >= 0.0:
        return False
    if rotation:
        wx = omega[0]
        wy = omega[1]
        wz = omega[2]
    else:
        wx = 0.0
        wy = 0.0
        wz = 0.0
    # G = v - r_p (ω × n)
    gx = vx - r_p * (wy * nz - wz * ny)
    gy = vy - r_p * (wz * nx - wx * nz)
    gz = vz - r_p * (wx * ny - wy * nx)
    gn = gx * nx + gy * ny + gz * nz
    gx -= gn * nx
    gy -= gn * ny
    gz -= gn * nz
    gt = math.sqrt(gx * gx + gy * gy + gz * gz)
    jn = -(1.0 + e) * vn  # (1+e)|v_n|: normal velocity change along n
    stick = gt <= 3.5 * mu * jn
    if stick:
        f = 2.0 / 7.0
    else:
        f = mu * jn / gt
    vel[0] = vx + jn * nx - f * gx
    vel[1] = vy + jn * ny - f * gy
    vel[2] = vz + jn * nz - f * gz
    if rotation:
        c = 2.5 * f / r_p  # 5/(7 r_p) when sticking, 5 μ (1+e)|v_n| /(2 r_p |G_t|) when sliding
        omega[0] = wx + c * (ny * gz - nz * gy)
        omega[1] = wy + c * (nz * gx - nx * gz)
        omega[2] = wz + c * (nx * gy - ny * gx)
    return stick


@njit(**JIT_FLAGS)
def time_to_wall(y, z, vy, vz, r_contact):
    """Time [s] until a centre at (y, z) [m] moving with (v_y, v_z) [m/s] reaches r = r_contact [m].

    Smallest t ≥ 0 with (y + v_y t)² + (z + v_z t)² = r_contact² (straight path); 0 if the
    centre is already at or beyond r_contact, +inf if it never gets there.  For the tracker:
    r_contact = R − r_p, so the wall kernel is called at the contact point.
    """
    c = y * y + z * z - r_contact * r_contact
    if c >= 0.0:
        return 0.0
    a = vy * vy + vz * vz
    if a <= 0.0:
        return math.inf
    b = 2.0 * (y * vy + z * vz)
    sq = math.sqrt(b * b - 4.0 * a * c)
    if b > 0.0:
        return 2.0 * c / (-b - sq)
    return (-b + sq) / (2.0 * a)


@njit(**KERNEL_FLAGS)
def place_inside(pos, r_p, pipe_radius):
    """Move the centre radially to r ≤ (R − r_p)(1 − 1e-12) if it is farther out (in place).

    pos [m] float64[3]; r_p, pipe_radius [m]. x is unchanged. Returns the new r [m].
    """
    y = pos[1]
    z = pos[2]
    r = math.sqrt(y * y + z * z)
    r_max = (pipe_radius - r_p) * (1.0 - _PLACE_MARGIN)
    if r > r_max:
        if r_max <= 0.0:
            pos[1] = 0.0
            pos[2] = 0.0
            return 0.0
        s = r_max / r
        pos[1] = y * s
        pos[2] = z * s
        return r_max
    return r


@dataclass(frozen=True)
class WallOptions:
    """Switches and coefficients of the rough-wall model (compile-time constants of the kernel).

    restitution, friction : (value at 0°, slope [1/deg], floor) of e_w, μ_w = max(floor,
        value − slope·α) — default Sommerfeld & Huber (1999) as in the reference paper.
    impact_angle : angle of e_w, μ_w: "effective" (α + γ₁, default) or "nominal" (α).
    shadow_effect : "weighted" (the sin(α + γ)-weighted effective pdf, default) or
        "rejection" (only reject α + γ ≤ 0).
    lateral_roughness : also tilt the wall laterally by γ₂ ~ N(0, Δγ) (default).
    rotation : track the particle spin (else ω is zero in the impulse and not updated).
    max_impacts : cap on rough impacts per call before the contact regime takes over.

    docs/physics.md, section 7, compares these defaults with the reference paper's forms.

    impact_angle, shadow_effect and lateral_roughness carry the names and values of the
    [walls] section of eulag.config; rotation is [physics] rotation.
    """

    restitution: tuple = (1.0, 0.01, 0.8)
    friction: tuple = (0.4, 0.015, 0.1)
    impact_angle: str = "effective"
    shadow_effect: str = "weighted"
    lateral_roughness: bool = True
    rotation: bool = True
    max_impacts: int = 10

    def __post_init__(self):
        for name in ("restitution", "friction"):
            v = getattr(self, name)
            if len(v) != 3 or not all(math.isfinite(float(c)) for c in v):
                raise ValueError(f"{name} must be (value, slope_per_deg, floor), got {v!r}")
            object.__setattr__(self, name, tuple(float(c) for c in v))
        e0, _, efloor = self.restitution
        if not (0.0 <= efloor <= 1.0 and 0.0 <= e0 <= 1.0):
            raise ValueError("restitution value and floor must lie in [0, 1]")
        if self.friction[0] < 0.0 or self.friction[2] < 0.0:
            raise ValueError("friction value and floor must be >= 0")
        if self.impact_angle not in ("effective", "nominal"):
            raise ValueError("impact_angle must be 'effective' or 'nominal'")
        if self.shadow_effect not in ("weighted", "rejection"):
            raise ValueError("shadow_effect must be 'weighted' or 'rejection'")
        if int(self.max_impacts) < 1:
            raise ValueError("max_impacts must be >= 1")


@lru_cache(maxsize=None)
def make_wall_collision(options=WallOptions()):
    """Build the wall-collision kernel for ``options`` (memoised; one compiled kernel per option set).

    The kernel, ``@njit``, to be called from the particle step when the centre reaches
    r ≥ R − r_p (see ``time_to_wall``):

        status = wall_collision(pos, vel, omega, u_fluid, dv, r_p, pipe_radius, dgamma, v_min, rng)

    pos      float64[3] particle centre [m]             (in/out: put back inside, r ≤ R − r_p)
    vel      float64[3] particle velocity [m/s]         (in/out)
    omega    float64[3] particle angular velocity [rad/s] (in/out)
    u_fluid  float64[3] fluid velocity fluctuation seen [m/s] (in/out: normal part mirrored)
    dv       float64[3] collision velocity jump accumulator [m/s] (in/out: += v_after − v_before;
             the tracker excludes it from the gas momentum source, docs/physics.md section 2)
    r_p [m] particle radius, pipe_radius [m], dgamma [rad] roughness std Δγ (0: smooth),
    v_min [m/s] minimum rebound wall-normal speed (``minimum_bounce_speed``; 0: always bounce),
    rng      int64[5] state of ``collisions.random`` (stream STREAM_WALL; advanced)

    Returns WALL_NO_IMPACT (0), WALL_REBOUND (1), WALL_SLIDING (2) or WALL_ROLLING (3).
    Afterwards v·n₀ ≥ 0 (≥ v_min and > 0 for a rebound, 0 up to round-off for contact), the
    translational + rotational kinetic energy has not increased, and r ≤ R − r_p < R.
    """
    e0, e_slope, e_floor = options.restitution
    mu0, mu_slope, mu_floor = options.friction
    effective_angle = options.impact_angle == "effective"
    shadow_pdf = options.shadow_effect == "weighted"
    lateral = options.lateral_roughness
    rotation = options.rotation
    max_impacts = int(options.max_impacts)

    @njit(**KERNEL_FLAGS)
    def wall_collision(pos, vel, omega, u_fluid, dv, r_p, pipe_radius, dgamma, v_min, rng):
        y = pos[1]
        z = pos[2]
        r = math.sqrt(y * y + z * z)
        if r <= 0.0:
            return WALL_NO_IMPACT
        # inward normal of the real wall, n0 = -e_r (no axial component)
        n0y = -y / r
        n0z = -z / r
        vx0 = vel[0]
        vy0 = vel[1]
        vz0 = vel[2]
        vn0 = vy0 * n0y + vz0 * n0z
        if not vn0 < 0.0:  # moving away or along the wall (or NaN): no impact
            place_inside(pos, r_p, pipe_radius)
            return WALL_NO_IMPACT
        wx0 = omega[0]
        wy0 = omega[1]
        wz0 = omega[2]

        left_wall = False
        for _ in range(max_impacts):
            vx = vel[0]
            vy = vel[1]
            vz = vel[2]
            vn = vy * n0y + vz * n0z
            speed = math.sqrt(vx * vx + vy * vy + vz * vz)
            alpha = math.asin(min(1.0, -vn / speed))
            # tangential direction in the impact plane, t0 = v_t/|v_t| (pipe axis for a normal impact)
            tx = vx
            ty = vy - vn * n0y
            tz = vz - vn * n0z
            vt = math.sqrt(tx * tx + ty * ty + tz * tz)
            if vt > 1e-12 * speed:
                tx /= vt
                ty /= vt
                tz /= vt
            else:
                tx = 1.0
                ty = 0.0
                tz = 0.0
            # in-plane tilt: n' = cos g1 n0 - sin g1 t0, so the effective angle is alpha + g1
            if shadow_pdf:
                g1 = roughness_angle_effective_pdf(alpha, dgamma, rng)
            else:
                g1 = roughness_angle_simple(alpha, dgamma, rng)
            c1 = math.cos(g1)
            s1 = math.sin(g1)
            nx = -s1 * tx
            ny = c1 * n0y - s1 * ty
            nz = c1 * n0z - s1 * tz
            if lateral and dgamma > 0.0:
                g2 = 0.0
                for _k in range(100):
                    g2 = dgamma * next_normal(rng)
                    if abs(g2) < _HALF_PI:
                        break
                # b0 = n0 x t0 (n0 has no x component)
                bx = n0y * tz - n0z * ty
                by = n0z * tx
                bz = -n0y * tx
                c2 = math.cos(g2)
                s2 = math.sin(g2)
                nx = c2 * nx + s2 * bx
                ny = c2 * ny + s2 * by
                nz = c2 * nz + s2 * bz
            if effective_angle:
                a_deg = (alpha + g1) * _DEG
            else:
                a_deg = alpha * _DEG
            e = max(e_floor, e0 - e_slope * a_deg)
            mu = max(mu_floor, mu0 - mu_slope * a_deg)
            hard_sphere_wall_rebound(vel, omega, nx, ny, nz, r_p, e, mu, rotation)
            if vel[1] * n0y + vel[2] * n0z > 0.0:
                left_wall = True
                break

        if left_wall and vel[1] * n0y + vel[2] * n0z >= v_min:
            status = WALL_REBOUND
        else:
            # contact regime: the incoming state meets the smooth real wall with e = 0 and
            # Coulomb friction; the particle stays on the wall, sliding or rolling.
            vel[0] = vx0
            vel[1] = vy0
            vel[2] = vz0
            if rotation:
                omega[0] = wx0
                omega[1] = wy0
                omega[2] = wz0
            speed0 = math.sqrt(vx0 * vx0 + vy0 * vy0 + vz0 * vz0)
            a_deg = math.asin(min(1.0, -vn0 / speed0)) * _DEG
            mu = max(mu_floor, mu0 - mu_slope * a_deg)
            stick = hard_sphere_wall_rebound(vel, omega, 0.0, n0y, n0z, r_p, 0.0, mu, rotation)
            # remove the round-off normal component left by the impulse
            vn = vel[1] * n0y + vel[2] * n0z
            vel[1] -= vn * n0y
            vel[2] -= vn * n0z
            status = WALL_ROLLING if stick else WALL_SLIDING

        # fluid velocity fluctuation seen: mirror its wall-normal component
        # (docs/physics.md, section 4)
        un = u_fluid[1] * n0y + u_fluid[2] * n0z
        u_fluid[1] -= 2.0 * un * n0y
        u_fluid[2] -= 2.0 * un * n0z

        dv[0] += vel[0] - vx0
        dv[1] += vel[1] - vy0
        dv[2] += vel[2] - vz0
        place_inside(pos, r_p, pipe_radius)
        return status

    return wall_collision


wall_collision = make_wall_collision(WallOptions())
"""Default kernel (the defaults of docs/physics.md, section 7); see ``make_wall_collision``."""
