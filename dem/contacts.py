"""Soft-sphere contact laws of the grains (Cundall & Strack 1979, as used by Strauß, McNamara &
Herrmann, "Plug conveying in a horizontal tube", §2.2).

Normal force: Hooke spring plus a viscous dashpot,

    F_n = k_n δ − γ_n v_n                               [N]

with δ [m] the overlap and v_n [m/s] the normal relative velocity (negative when approaching).
The dashpot is set from the normal coefficient of restitution e (linear spring–dashpot, the
contact ends when δ returns to zero):

    ζ = −ln e / sqrt(π² + ln² e),   γ_n = 2 ζ sqrt(m_eff k_n),   e = exp(−π ζ / sqrt(1 − ζ²))

(e = 0.5 → ζ = 0.2154).  m_eff = m/2 for two equal grains and m for a grain on the (fixed)
wall.  The force is not clipped at zero: clipping would change the restitution (e = 0.55 for
ζ = 0.2154, measured) and makes it depend more on where in a step the contact starts; a
small attraction at the very end of a damped contact is the price (it is what the formula for
e assumes).  The dashpot jumps at the start and end of a contact, so a measured e depends on
the phase of the contact within a time step: at dt = t_c/30, −2.1 %…+1.2 % at the wall, ±0.5 %
for a pair, the average over phases within 0.5 % of e (tests/test_dem_contacts.py).

Tangential force: the smaller of Coulomb friction and a viscous force, opposite to the sliding
velocity of the contact point,

    F_t = −min(μ max(F_n, 0), γ_t |v_t|) v̂_t            [N]

with no tangential spring (SMH §2.2: "the viscous damping is used when the relative surface
velocity is small").  γ_t is not given by the paper; the default takes γ_t = γ_n.  A sliding
grain therefore decelerates at μg and rolls without slipping from 5/7 of its initial speed
on (solid sphere, I = (2/5) m R²), whatever γ_t (tests/test_dem_contacts.py).

The tube wall (a cylinder along x) and an optional flat end plate use the same laws.

References: Cundall, P. A. & Strack, O. D. L. (1979) Géotechnique 29:47–65,
doi:10.1680/geot.1979.29.1.47.  Strauß, McNamara & Herrmann, Granular Matter (2006),
doi:10.1007/s10035-006-0009-0.
"""

import math

from numba import njit

from .conf import JIT_FLAGS


def damping_ratio(restitution):
    """Damping ratio ζ [-] of a linear spring–dashpot with normal restitution e [-] (0 < e ≤ 1).

    ζ = −ln e / sqrt(π² + ln² e).

    Examples
    --------
    >>> round(damping_ratio(0.5), 4)
    0.2154
    """
    if not 0.0 < restitution <= 1.0:
        raise ValueError(f"restitution = {restitution}: allowed 0 < e <= 1")
    le = math.log(restitution)
    return -le / math.sqrt(math.pi ** 2 + le ** 2)


def dashpot_coefficient(restitution, stiffness, m_eff):
    """Normal dashpot γ_n [kg/s] = 2 ζ(e) sqrt(m_eff [kg] · k_n [N/m])."""
    return 2.0 * damping_ratio(restitution) * math.sqrt(m_eff * stiffness)


def contact_time(restitution, stiffness, m_eff):
    """Duration [s] of a linear spring–dashpot contact: π / (ω0 sqrt(1 − ζ²)), ω0 = sqrt(k_n/m_eff)."""
    z = damping_ratio(restitution)
    return math.pi / (math.sqrt(stiffness / m_eff) * math.sqrt(1.0 - z * z))


def max_overlap(speed, stiffness, m_eff):
    """Undamped upper bound of the overlap [m] of an impact at normal speed [m/s]: v sqrt(m_eff/k_n)."""
    return speed * math.sqrt(m_eff / stiffness)


@njit(**JIT_FLAGS)
def contact(nx, ny, nz, delta, vrx, vry, vrz, wsx, wsy, wsz, radius, k_n, g_n, g_t, mu):
    """Force on grain i and torque on grain i from one contact (pair or wall).

    n = (nx, ny, nz) is the unit normal pointing from the partner (grain j or wall) to grain i;
    delta [m] the overlap; vr [m/s] = v_i − v_j (v_j = 0 for the wall); ws [1/s] = ω_i + ω_j
    (ω_i alone for the wall); radius [m] the grain radius (lever arm of the contact point).

    The contact point of i is at x_i − R n, so its velocity relative to the partner's is
    v_c = vr − R (ws × n).  Returns (fx, fy, fz, tx, ty, tz, fn) with fn the normal force [N].

    Written so that swapping i and j (n → −n, vr → −vr) negates the force exactly in floating
    point: the pair sums conserve momentum to the last bit.
    """
    vn = vrx * nx + vry * ny + vrz * nz
    fn = k_n * delta - g_n * vn
    # ws × n
    cx = wsy * nz - wsz * ny
    cy = wsz * nx - wsx * nz
    cz = wsx * ny - wsy * nx
    vcx = vrx - radius * cx
    vcy = vry - radius * cy
    vcz = vrz - radius * cz
    vtx = vcx - vn * nx
    vty = vcy - vn * ny
    vtz = vcz - vn * nz
    vt = math.sqrt(vtx * vtx + vty * vty + vtz * vtz)
    ftx = 0.0
    fty = 0.0
    ftz = 0.0
    if vt > 0.0:
        coulomb = mu * fn if fn > 0.0 else 0.0
        viscous = g_t * vt
        ft = coulomb if coulomb < viscous else viscous
        s = -ft / vt
        ftx = s * vtx
        fty = s * vty
        ftz = s * vtz
    # torque (−R n) × F_t
    tx = -radius * (ny * ftz - nz * fty)
    ty = -radius * (nz * ftx - nx * ftz)
    tz = -radius * (nx * fty - ny * ftx)
    return fn * nx + ftx, fn * ny + fty, fn * nz + ftz, tx, ty, tz, fn
