"""The compiled tracking kernel: one parcel from the inlet to the outlet, batch by batch.

``make_tracker(options)`` builds, once per set of physics switches (memoised), the numba
functions of a Lagrangian pass.  Switches are compile-time constants of the closures, so
a scene that turns off Magnus lift, rotation or inter-particle collisions runs a kernel
that does not contain them.

Per particle step:

1. fields at x_n (interpolated at the end of the previous step): U, k, ε, ∇×U, ∇k;
   u_F = U + u′_F;
2. time step Δt = c · min(T_L, cell-crossing time, 0.1/f_coll) (``step_rule = "default"``;
   the crossing time uses the axial cell length and the *ring thickness*, never the arc
   length, so the small sectors at the axis do not force small steps) or
   c · min(τ_p, T_L, 1/f_coll) (``"paper"``), or the default with max(T_L, √(ν/ε)) in place of
   T_L (``"kolmogorov"``);
3. force coefficients frozen over the step: drag (Schiller–Naumann), reduced gravity g′,
   Saffman–Mei and Magnus lift.  Both lifts are linear in the slip, a_L = b × (u_F − u),
   so the velocity and position are advanced with the exact solution of
   du/dt = (u_F − u)/τ_p + b × (u_F − u) + g′ (an exponential decay combined with a rotation
   about b), stable for any Δt/τ_p: a lift does not outlive the slip that causes it.  The
   spin likewise relaxes toward ½ ∇×U with the torque's time scale τ_r;
4. a step that would end beyond the wall contact radius R − r_p is shortened to the
   straight-line contact time (if at least 5 % of the step remains; otherwise the centre
   is put on the contact radius), and the rough-wall collision follows;
5. the segment x_n → x_{n+1} is split between the cells it crosses by time fraction and
   sampled (occupancy, mass flux, velocity moments, spin moments, the exact fluid impulse
   J = m[(u^{n+1} − u^n) − g′Δt] and u′_F·J);
6. fields at x_{n+1}; the fluid velocity seen is updated by the Langevin model of
   Sommerfeld et al. (1993) with R_P = R_L(Δt) R_E(Δr), Δr = ∫(u_F − u_p)dt over the step, plus the
   (1 − R_L) T_L ∂⟨u′_i u′_j⟩/∂x_j drift correction (or (1 − R_P) T_L, ``drift_form``);
7. wall collision (collisions.wall, which also mirrors u′_n) and the stochastic
   inter-particle collision against a fictitious partner drawn from the previous pass's
   cell statistics (collisions.interparticle);
8. a parcel leaving through the outlet is counted EXITED; one crossing the inlet plane
   backwards is reflected (counted); one exceeding the residence-time or step cap is
   stopped and counted STUCK; a non-finite state is counted LOST (must never happen).

A batch is swept window by window (``TrackSettings.window_stations`` stations; a parcel is
suspended where a step ends beyond its window and resumed in the next), which keeps the
stations the batch works on in the cache and changes no trajectory (docs/numerics.md).

Collision velocity jumps are not part of J, so the momentum budget
Σ Ṅ J = Σ Ṅ m [u_out − u_in − g′ t_res − Δu_wall − Δu_pp − Δu_inlet] closes to round-off.
"""

from __future__ import annotations

import dataclasses
import math
import types
import warnings
import zlib
from dataclasses import dataclass, field
from functools import lru_cache

import numba
import numpy as np
from numba import njit, prange
from numba.core.errors import NumbaWarning

from collisions.conf import JIT_FLAGS, KERNEL_FLAGS, LOOP_FLAGS, inlined
from collisions.interparticle import InterparticleOptions, make_interparticle_collision
from collisions.random import (RNG_DRAW, RNG_PARCEL, RNG_PASS, RNG_SEED, RNG_STATE_SIZE, RNG_STREAM,
                               STREAM_COLLISION, STREAM_DISPERSION, STREAM_INJECTION, STREAM_WALL,
                               next_normal_pair, next_uniform_pair)
from collisions.wall import (WALL_REBOUND, WALL_ROLLING, WALL_SLIDING, WallOptions,
                             make_wall_collision)

from . import forces as fl
from .fields import F_DKX, F_EPS, F_K, F_UX, F_WX, NF, interpolate
from .layout import (A_BETA, A_J, A_MUV, A_PP, A_PPK, CS_APP, CS_COV, A_KSEEN, A_MU, A_MUU, A_NW, A_NWW, A_SK, A_VISITS, A_WM, A_WN, B_INLET, B_J,
                     B_MASS_IN, B_MASS_OUT, B_MASS_STUCK, B_MOM_IN, B_MOM_OUT, B_PP,
                     B_RESIDENCE, B_WALL, B_WEIGHT, NBUD, C_EXITED, C_INJECTED, C_INLET, C_LOST, C_PP,
                     C_REBOUNDS, C_ROLLING, C_SLIDING, C_STEPS, C_STUCK, C_VARIANT, CS_F, CS_N, CS_OK,
                     CS_RMS, CS_ST, CS_U, CS_WM, CS_WRMS, N_ANGLE_BINS, N_SPEED_BINS, NACC, NWALL,
                     P_DGAMMA, P_DP, P_GRAV, P_INJ_RMS, P_MAXSTEPS, P_MU, P_NDOT, P_RHO_F,
                     P_RHO_P, P_SPEEDMAX, P_STEP, P_TCAP, P_U0, P_VMIN, P_WINDOW, S_EXITED, S_LOST,
                     S_STUCK, W_ANGLE, W_COUNT, W_SPEED)

__all__ = ["PhysicsOptions", "kernel_options", "make_motion", "make_tracker", "make_window_tracker", "fold_batches",
           "walk_segment", "MAX_SEGMENTS"]

# The parallel super-batch driver calls the (cached) batch kernel inside prange; numba cannot
# cache such a parallel function ("dynamic globals"), so it is compiled once per process and
# option set (about 2–3 s); everything it calls is cached.  The warning says only that.
warnings.filterwarnings("ignore", message='Cannot cache compiled function "track_(superbatch|windows)"',
                        category=NumbaWarning)

C_T = 0.24  # T_L = C_T σ²/ε (Sommerfeld 2001)
C_L = 3.0  # L_E = C_L T_L σ
NSTATE = 19  # per-parcel final state columns, see make_tracker
# columns of a parcel's suspended state between two windows of the sweep (track_parcels)
SU_POS, SU_VEL, SU_OMEGA, SU_USEEN = 0, 3, 6, 9
SU_FIELDS = 12  # the NF interpolated fields at the parcel
SU_CELL = SU_FIELDS + NF  # its cell (i, j, k)
SU_T = SU_CELL + 3
SU_STEPS = SU_T + 1
SU_SPARE = SU_STEPS + 1  # (have_spare, spare): the normal kept for the next step
SU_INLET = SU_SPARE + 2  # injection position
SU_DRAWS = SU_INLET + 3  # draw counters of the dispersion, wall and collision streams
SU_ACTIVE = SU_DRAWS + 3  # 1: suspended, to be resumed in the next window
NSUSP = SU_ACTIVE + 1
MAX_SEGMENTS = 512  # cells one step may cross (a step crosses ~1; the rest goes to the last cell)
_WALL_REDO = 0.05  # shorten a wall-crossing step only if this fraction of it remains before contact
_DEG = 180.0 / math.pi


@dataclass(frozen=True)
class PhysicsOptions:
    """Compile-time switches of the tracking kernel (one compiled kernel per combination).

    saffman_mei_lift, magnus_lift, rotation, langevin, drift_correction, gravity,
    inter_particle_collisions : bool — terms of docs/physics.md–§4 (magnus needs rotation).
    drift_form : "particle" | "lagrangian" (default) | "response" — the drift correction's factor
        (1 − R_P) T_L (the particle's correlation, crossing trajectories included), (1 − R_L) T_L
        (the fluid's Lagrangian correlation alone: the mean-pressure-gradient drift of the fluid
        seen acting over the step, as in Minier & Peirano 2001), or (1 − R_L) T_L/(1 + St) with
        St = τ_p/T_L (the particle's response to the fluid, Bocksell & Loth 2006, Dehbi 2008: the
        correction cancels a spurious drift that comes from the particle moving with the fluid
        across the gradient of σ, which a particle that does not follow the fluid does not
        have); the three agree for tracers.
    magnus_model : "lun-liu" | "oesterle-bui-dinh".
    step_rule : "default" | "paper" | "kolmogorov" (the default rule with the T_L of the step
        bounded below by the Kolmogorov time sqrt(ν/ε): it binds where k²/(νε) < 39, where the
        particles' sink or the inlet's decay has left a turbulence whose T_L = C_T σ²/ε is far
        below any eddy's time; the Langevin model keeps its T_L).
    partner_correlation : "particle" | "cell" — where the Stokes number St = τ_p/T_L of the
        fictitious partner's correlation R(St) is taken: at the real particle (its step's τ_p,
        T_L of the gas at its position: in the wall cell ε follows the wall function, so R
        varies across the cell) or once per cell (the statistics' ``layout.CS_ST``,
        ``tracking.cell_stokes``).  With the partner drawn
        about the cell mean, a per-particle R that varies together with u₁ − ū₁ inside a cell
        makes the collisions' net momentum non-zero.
    partner_momentum : "discarded" | "returned" — what becomes of the momentum the fictitious
        partners would have received.  "discarded" (Sommerfeld 2001): only the real particle
        is updated, so the collisions conserve momentum only while the partners' Gaussian
        velocity law matches the cell's particles; with skewed rebound velocities near a
        rough wall they do not (the collision force per cell is then up to several times the
        gas source).  "returned": each cell's particles receive, spread over their residence
        time, the acceleration a = −F_jump/c of the previous pass's statistics (``layout.CS_APP``:
        the net collision force per unit volume F_jump over the particle concentration c), so
        the net collision impulse per cell vanishes in the mean at the coupled steady state.
    wall_cell : "log-law" | "wall-ring" — the gas fields a particle sees inside the
        wall-function cell: the log-law reconstruction of U, ∇ × U and ε from the wall-ring
        values (docs/physics.md, section 3), or the wall-ring values held out to the wall
        (``fields.interpolate``, ``wall_law``).  The reference paper does not say which.
    wall : collisions.WallOptions;  interparticle : collisions.InterparticleOptions.
    """

    saffman_mei_lift: bool = True
    magnus_lift: bool = True
    magnus_model: str = "lun-liu"
    rotation: bool = True
    langevin: bool = True
    drift_correction: bool = True
    drift_form: str = "lagrangian"
    gravity: bool = True
    inter_particle_collisions: bool = True
    step_rule: str = "default"
    partner_correlation: str = "particle"
    partner_momentum: str = "discarded"
    wall_cell: str = "log-law"
    wall: WallOptions = field(default_factory=WallOptions)
    interparticle: InterparticleOptions = field(default_factory=InterparticleOptions)

    def __post_init__(self):
        if self.magnus_lift and not self.rotation:
            raise ValueError("magnus_lift needs rotation")
        if self.magnus_model not in ("lun-liu", "oesterle-bui-dinh"):
            raise ValueError(f"magnus_model = {self.magnus_model!r}: allowed lun-liu, oesterle-bui-dinh")
        if self.drift_form not in ("particle", "lagrangian", "response"):
            raise ValueError(f"drift_form = {self.drift_form!r}: allowed particle, lagrangian, response")
        if self.step_rule not in ("default", "paper", "kolmogorov"):
            raise ValueError(f"step_rule = {self.step_rule!r}: allowed default, paper, kolmogorov")
        if self.partner_correlation not in ("particle", "cell"):
            raise ValueError(f"partner_correlation = {self.partner_correlation!r}: allowed particle, cell")
        if self.partner_momentum not in ("discarded", "returned"):
            raise ValueError(f"partner_momentum = {self.partner_momentum!r}: allowed discarded, returned")
        if self.wall_cell not in ("log-law", "wall-ring"):
            raise ValueError(f"wall_cell = {self.wall_cell!r}: allowed log-law, wall-ring")
        if self.wall.rotation != self.rotation:
            object.__setattr__(self, "wall", WallOptions(**{**self.wall.__dict__, "rotation": self.rotation}))
        if self.interparticle.rotation != self.rotation:
            object.__setattr__(self, "interparticle",
                               InterparticleOptions(**{**self.interparticle.__dict__,
                                                       "rotation": self.rotation}))


# ---------------------------------------------------------------------------- geometry
@njit(**KERNEL_FLAGS)
def walk_segment(p0x, p0y, p0z, dx, dy, dz, i, j, k, x_edges, r_edges, ray_sin, ray_cos, seg_cell,
                 seg_frac):
    """Split the straight segment p0 → p0 + d between the cells it crosses.

    (i, j, k): the cell holding p0; ray_sin, ray_cos (nt+1,): sin and cos of the sector edges.  Writes (flat cell index, fraction of the segment) into
    seg_cell/seg_frac and returns (n_segments, end) with end = 0 inside the pipe, 1 through
    the outlet plane, 2 through the inlet plane (the fractions then sum to the part inside).
    Faces: axial planes, ring circles (exact quadratic roots), sector rays (half-lines).
    """
    nx = x_edges.shape[0] - 1
    nr = r_edges.shape[0] - 1
    nt = ray_sin.shape[0] - 1
    a = dy * dy + dz * dz
    b = p0y * dy + p0z * dz
    c = p0y * p0y + p0z * p0z
    s = 0.0
    n = 0
    entry = -1
    end = 0
    while True:
        s_exit = 1.0
        face = -1
        if dx > 0.0 and entry != 1:
            t = (x_edges[i + 1] - p0x) / dx
            if t < s_exit:
                s_exit = t
                face = 0
        elif dx < 0.0 and entry != 0:
            t = (x_edges[i] - p0x) / dx
            if t < s_exit:
                s_exit = t
                face = 1
        if a > 0.0:
            ro = r_edges[j + 1]
            disc = b * b - a * (c - ro * ro)
            if disc > 0.0:
                t = (-b + math.sqrt(disc)) / a
                if s < t < s_exit:
                    s_exit = t
                    face = 2
            if j > 0 and entry != 2:
                ri = r_edges[j]
                disc = b * b - a * (c - ri * ri)
                if disc > 0.0:
                    t = (-b - math.sqrt(disc)) / a
                    if s < t < s_exit:
                        s_exit = t
                        face = 3
        for side in range(2):
            if (side == 0 and entry == 5) or (side == 1 and entry == 4):
                continue
            sp = ray_sin[k + 1 - side]
            cp = ray_cos[k + 1 - side]
            den = dz * sp - dy * cp
            if den != 0.0:
                t = (p0y * cp - p0z * sp) / den
                if s < t < s_exit and (p0y + t * dy) * sp + (p0z + t * dz) * cp > 0.0:
                    s_exit = t
                    face = 4 + side
        if s_exit < s:
            s_exit = s
        seg_cell[n] = (i * nr + j) * nt + k
        seg_frac[n] = s_exit - s
        n += 1
        if face < 0:
            break
        s = s_exit
        entry = face
        if face == 0:
            i += 1
            if i >= nx:
                end = 1
                break
        elif face == 1:
            i -= 1
            if i < 0:
                end = 2
                break
        elif face == 2:
            if j + 1 < nr:
                j += 1
        elif face == 3:
            j -= 1
        elif face == 4:
            k += 1
            if k >= nt:
                k -= nt
        else:
            k -= 1
            if k < 0:
                k += nt
        if n >= seg_cell.shape[0]:
            seg_frac[n - 1] += 1.0 - s  # pathological: the rest stays in the last cell
            break
    return n, end


@njit(**KERNEL_FLAGS)
def _key_rng(rng, seed, pass_, parcel, stream):
    """Reset a random-stream state int64[5] to the key (seed, pass, parcel, stream), draw 0."""
    rng[RNG_SEED] = seed
    rng[RNG_PASS] = pass_
    rng[RNG_PARCEL] = parcel
    rng[RNG_STREAM] = stream
    rng[RNG_DRAW] = 0


# ---------------------------------------------------------------------------- motion
@lru_cache(maxsize=None)
def make_motion(options=PhysicsOptions()):
    """Build ``advance``, the single-step integrator with frozen forces (see module docstring).

        tau_p = advance(pos, vel, omega, uf, vort, dt, prm, impulse)

    pos, vel, omega float64[3] (in/out) [m, m/s, rad/s]; uf float64[3] fluid velocity seen
    U + u′ [m/s]; vort float64[3] ∇×U at the particle [1/s]; dt [s]; prm runtime parameters
    (layout.P_*); impulse float64[3] (out) the fluid impulse J = m[(u^{n+1} − u^n) − g′Δt]
    [kg m/s].  Returns the drag response time τ_p [s] used in the step.
    """
    saffman = options.saffman_mei_lift
    magnus = options.magnus_lift
    lun_liu = options.magnus_model == "lun-liu"
    rotation = options.rotation
    gravity = options.gravity

    @njit(**KERNEL_FLAGS)
    def advance(pos, vel, omega, uf, vort, dt, prm, impulse):
        rho_f = prm[P_RHO_F]
        mu = prm[P_MU]
        rho_p = prm[P_RHO_P]
        d = prm[P_DP]
        m = rho_p * math.pi * d * d * d / 6.0
        rx = uf[0] - vel[0]
        ry = uf[1] - vel[1]
        rz = uf[2] - vel[2]
        slip = math.sqrt(rx * rx + ry * ry + rz * rz)
        re_p = rho_f * d * slip / mu
        ln_re = fl._log0(re_p)  # one logarithm for the drag's and the lift's powers of Re_p
        tau = fl.response_time(rho_p, d, mu, fl.schiller_naumann_drag_factor_ln(re_p, ln_re))
        gy = -prm[P_GRAV] if gravity else 0.0
        # lift accelerations are linear in the slip: a_L = b x (u_F - u) with
        # b = c_M Omega - c_S omega_F (Saffman: c_S (u_rel x omega_F); Magnus: c_M (Omega x u_rel))
        bx = 0.0
        by = 0.0
        bz = 0.0
        wfx = vort[0]
        wfy = vort[1]
        wfz = vort[2]
        if saffman:
            wf = math.sqrt(wfx * wfx + wfy * wfy + wfz * wfz)
            if wf > 0.0 and re_p > 0.0:
                re_s = rho_f * d * d * wf / mu
                c = 0.125 * math.pi * rho_f * d * d * d * fl.saffman_mei_lift_coefficient(re_p, re_s) / m
                bx -= c * wfx
                by -= c * wfy
                bz -= c * wfz
        om_slip = -1.0  # |Ω| = |½ ∇×U − ω| at the start of the step, shared with the spin update
        if magnus:
            ox = 0.5 * wfx - omega[0]
            oy = 0.5 * wfy - omega[1]
            oz = 0.5 * wfz - omega[2]
            om = math.sqrt(ox * ox + oy * oy + oz * oz)
            om_slip = om
            if om > 0.0 and re_p > 0.0:
                re_r = rho_f * d * d * om / mu
                if lun_liu:
                    clr = fl.lun_liu_1997_lift_coefficient_ln(re_p, re_r, ln_re)
                else:
                    clr = fl.oesterle_bui_dinh_1998_lift_coefficient(re_p, re_r)
                c = 0.125 * math.pi * rho_f * d * d * clr * slip / (om * m)
                bx += c * ox
                by += c * oy
                bz += c * oz
        # exact solution of dw/dt = -w/tau - b x w + g', w = u - u_F (u_F, tau, b frozen):
        # w(t) = w_inf + exp(-t/tau) R(t) (w0 - w_inf), R the rotation by -|b| t about b
        a = 1.0 / tau
        bb = bx * bx + by * by + bz * bz
        # w_inf solves (a I + [b]x) w = g' = (0, gy, 0)
        den = a * (a * a + bb)
        bg = by * gy
        wix = (bg * bx - a * (-bz * gy)) / den
        wiy = (a * a * gy + bg * by) / den
        wiz = (bg * bz - a * (bx * gy)) / den
        v0x = vel[0] - uf[0] - wix
        v0y = vel[1] - uf[1] - wiy
        v0z = vel[2] - uf[2] - wiz
        e1 = -math.expm1(-dt * a)  # 1 - exp(-dt/tau), accurate for small dt/tau
        ee = 1.0 - e1
        beta = math.sqrt(bb)
        if beta * dt > 1e-14:
            hx = bx / beta
            hy = by / beta
            hz = bz / beta
            pd = hx * v0x + hy * v0y + hz * v0z
            px = pd * hx
            py = pd * hy
            pz = pd * hz
            qx = v0x - px
            qy = v0y - py
            qz = v0z - pz
            cx = hy * v0z - hz * v0y
            cy = hz * v0x - hx * v0z
            cz = hx * v0y - hy * v0x
            co = math.cos(beta * dt)
            si = math.sin(beta * dt)
            nrm = a * a + bb
            ic = (a * (1.0 - ee * co) + beta * ee * si) / nrm
            is_ = (beta * (1.0 - ee * co) - a * ee * si) / nrm
            ip = e1 * tau
            w1x = wix + ee * (px + qx * co - cx * si)
            w1y = wiy + ee * (py + qy * co - cy * si)
            w1z = wiz + ee * (pz + qz * co - cz * si)
            sx = px * ip + qx * ic - cx * is_
            sy = py * ip + qy * ic - cy * is_
            sz = pz * ip + qz * ic - cz * is_
        else:
            w1x = wix + ee * v0x
            w1y = wiy + ee * v0y
            w1z = wiz + ee * v0z
            ip = e1 * tau
            sx = v0x * ip
            sy = v0y * ip
            sz = v0z * ip
        pos[0] += (uf[0] + wix) * dt + sx
        pos[1] += (uf[1] + wiy) * dt + sy
        pos[2] += (uf[2] + wiz) * dt + sz
        n0 = uf[0] + w1x
        n1 = uf[1] + w1y
        n2 = uf[2] + w1z
        impulse[0] = m * (n0 - vel[0])
        impulse[1] = m * (n1 - vel[1] - gy * dt)
        impulse[2] = m * (n2 - vel[2])
        vel[0] = n0
        vel[1] = n1
        vel[2] = n2
        if rotation:
            ox = 0.5 * vort[0] - omega[0]
            oy = 0.5 * vort[1] - omega[1]
            oz = 0.5 * vort[2] - omega[2]
            om = om_slip if om_slip >= 0.0 else math.sqrt(ox * ox + oy * oy + oz * oz)
            re_r = rho_f * d * d * om / mu
            tau_r = fl.rotational_response_time(rho_p, d, mu, fl.torque_factor(re_r))
            er = -math.expm1(-dt / tau_r)
            omega[0] += ox * er
            omega[1] += oy * er
            omega[2] += oz * er
        return tau

    return advance


# ---------------------------------------------------------------------------- tracker
def _with_globals(fn, **names):
    """Copy of the closure ``fn`` whose global namespace also holds ``names``.

    Sub-kernels (numba dispatchers) reach the tracking kernels as globals rather than closure
    cells: numba's on-disk cache key hashes the closure cells, and a pickled dispatcher differs
    from process to process, which would defeat the cache.  The cells keep the plain option
    values (and ``repr(options)``), so each option set still gets its own cache entry.
    """
    g = dict(fn.__globals__)
    g.update(names)
    new = types.FunctionType(fn.__code__, g, fn.__name__, fn.__defaults__, fn.__closure__)
    new.__qualname__ = fn.__qualname__
    new.__module__ = fn.__module__
    new.__doc__ = fn.__doc__
    return new


def tracker_variant(options):
    """The number a kernel compiled for ``options`` writes into every batch's C_VARIANT counter
    (CRC-32 of ``repr(options)``; ``track_superbatch.eulag_variant``): the driver compares it, so
    a kernel for another option set — served by a numba cache that concurrent processes
    corrupted — cannot go unnoticed."""
    return float(zlib.crc32(repr(options).encode()))


def kernel_options(options):
    """``options`` with the switches its kernel does not read set to their defaults: the
    partners' correlation and momentum and the collision options without inter-particle
    collisions, the drift's form without the drift correction (or without the Langevin model,
    which carries it), the Magnus model without Magnus lift.  Option sets that differ only in
    those compile to the same code and share one kernel (one compilation, one cache entry); a
    two-way run and a four-way run's ablations then do not each compile their own."""
    default = PhysicsOptions()
    changes = {}
    if not options.inter_particle_collisions:
        changes.update(partner_correlation=default.partner_correlation,
                       partner_momentum=default.partner_momentum,
                       interparticle=InterparticleOptions(rotation=options.rotation))
    if not options.langevin:
        changes["drift_correction"] = default.drift_correction
    if not (options.langevin and options.drift_correction):
        changes["drift_form"] = default.drift_form
    if not options.magnus_lift:
        changes["magnus_model"] = default.magnus_model
    if all(getattr(options, k) == v for k, v in changes.items()):
        return options
    return dataclasses.replace(options, **changes)


def _trackers(options):
    """:func:`_build_trackers` for the kernel's options (:func:`kernel_options`)."""
    return _build_trackers(kernel_options(options))


@lru_cache(maxsize=None)
def _build_trackers(options):
    """(track_batch, track_superbatch, track_windows) for ``options``: make_tracker,
    make_window_tracker."""
    advance = make_motion(options)
    wall_collision = make_wall_collision(options.wall)
    pp_collision = make_interparticle_collision(options.interparticle)
    langevin = options.langevin
    drift = options.drift_correction
    drift_lagrangian = options.drift_form in ("lagrangian", "response")
    drift_response = options.drift_form == "response"
    pp = options.inter_particle_collisions
    full_cov = pp and options.interparticle.covariance == "full"
    paper_rule = options.step_rule == "paper"
    kolmogorov_rule = options.step_rule == "kolmogorov"
    cell_corr = options.partner_correlation == "cell"
    returned = pp and options.partner_momentum == "returned"
    rotation = options.rotation
    gravity = options.gravity
    wall_law = options.wall_cell == "log-law"

    key = repr(options)  # a closure cell: numba's cache key then differs per option set
    variant = tracker_variant(options)  # written by every batch, checked by the driver

    def track_parcels(first, count, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                      x_centres, tab, axis, stats, prm, out, state, dvals, fvals, pos, vel, omega,
                      useen, uf, imp, dv, partner, seg_cell, seg_frac, mean_own, rms, cov, wmean, wrms,
                      saved, ray_sin, ray_cos, rng_inj, rng_disp, rng_wall, rng_pp, susp, w_first, w_last):
        if len(key) == 0:  # never true; keeps ``key`` in the closure (cache key)
            return
        nx = x_edges.shape[0] - 1
        nr = r_edges.shape[0] - 1
        ncell = nx * nr * nt
        off_wall = ncell * NACC
        off_angle = off_wall + nx * nt * NWALL
        off_speed = off_angle + N_ANGLE_BINS
        off_bud = off_speed + N_SPEED_BINS
        off_cnt = off_bud + NBUD
        out[off_cnt + C_VARIANT] = variant
        rho_p = prm[P_RHO_P]
        d = prm[P_DP]
        r_p = 0.5 * d
        m = rho_p * math.pi * d * d * d / 6.0
        ndot = prm[P_NDOT]
        w_m = ndot * m
        gred = prm[P_GRAV] if gravity else 0.0
        c_step = prm[P_STEP]
        t_cap = prm[P_TCAP]
        max_steps = prm[P_MAXSTEPS]
        r_contact = radius - r_p
        dxc = length / nx
        speed_max = prm[P_SPEEDMAX]
        two_pi = 2.0 * math.pi
        # the sweep: every parcel is tracked through window 0 (the first ``per`` stations), then
        # every parcel still in the pipe through window 1, ...; a parcel whose step ends beyond
        # its window is suspended (susp) and resumed there in the next window.  The parcel's
        # trajectory is the same as if tracked in one go (the suspended state is everything a
        # step carries over); the sampled sums differ only in their order (round-off).  Between
        # them the parcels of a batch then read and write the same few stations' fields, cell
        # statistics and accumulators, which stay in the cache.
        per = int(prm[P_WINDOW])
        if per <= 0 or per >= nx:
            per = nx
        nwin = (nx + per - 1) // per
        # windows w_first … w_last − 1 of the sweep (all: 0, nwin); a later call resumes the
        # suspended parcels (susp) where this one stopped (track_windows)
        for item in range(w_first * count, min(w_last, nwin) * count):
            win = item // count
            q = item - win * count
            pid = first + q
            x_hi = x_edges[min((win + 1) * per, nx)] if win + 1 < nwin else np.inf
            if win > 0:
                if susp[q, SU_ACTIVE] == 0.0:
                    continue
                # ---- resume the parcel where its previous window left it
                for c in range(3):
                    pos[c] = susp[q, SU_POS + c]
                    vel[c] = susp[q, SU_VEL + c]
                    omega[c] = susp[q, SU_OMEGA + c]
                    useen[c] = susp[q, SU_USEEN + c]
                for c in range(NF):
                    fvals[c] = susp[q, SU_FIELDS + c]
                ci = int(susp[q, SU_CELL])
                cj = int(susp[q, SU_CELL + 1])
                ck = int(susp[q, SU_CELL + 2])
                t = susp[q, SU_T]
                steps = int(susp[q, SU_STEPS])
                have_spare = susp[q, SU_SPARE] != 0.0
                spare = susp[q, SU_SPARE + 1]
                x_in = susp[q, SU_INLET]
                y_in = susp[q, SU_INLET + 1]
                z_in = susp[q, SU_INLET + 2]
                _key_rng(rng_disp, seed, pass_, pid, STREAM_DISPERSION)
                _key_rng(rng_wall, seed, pass_, pid, STREAM_WALL)
                _key_rng(rng_pp, seed, pass_, pid, STREAM_COLLISION)
                rng_disp[RNG_DRAW] = np.int64(susp[q, SU_DRAWS])
                rng_wall[RNG_DRAW] = np.int64(susp[q, SU_DRAWS + 1])
                rng_pp[RNG_DRAW] = np.int64(susp[q, SU_DRAWS + 2])
                status = 0
                susp[q, SU_ACTIVE] = 0.0
            else:
                if susp.shape[0] > 0:  # a parcel that ends in window 0 is not resumed later
                    susp[q, SU_ACTIVE] = 0.0
                _key_rng(rng_inj, seed, pass_, pid, STREAM_INJECTION)
                _key_rng(rng_disp, seed, pass_, pid, STREAM_DISPERSION)
                _key_rng(rng_wall, seed, pass_, pid, STREAM_WALL)
                _key_rng(rng_pp, seed, pass_, pid, STREAM_COLLISION)
                # ---- injection: uniform over the section, Gaussian velocity (seed)
                u1, u2 = next_uniform_pair(rng_inj)
                rr = r_contact * math.sqrt(u1)
                th = two_pi * u2
                pos[0] = 0.0
                pos[1] = rr * math.sin(th)
                pos[2] = rr * math.cos(th)
                x_in = pos[0]
                y_in = pos[1]
                z_in = pos[2]
                g0, g1 = next_normal_pair(rng_inj)
                g2, g3 = next_normal_pair(rng_inj)
                vel[0] = prm[P_U0] + prm[P_INJ_RMS] * g0
                vel[1] = prm[P_INJ_RMS] * g1
                vel[2] = prm[P_INJ_RMS] * g2
                omega[:] = 0.0
                ci, cj, ck = interpolate(pos[0], pos[1], pos[2], tab, axis, x_centres, rc, r_edges, length,
                                             radius, nu, fvals, -1, wall_law)
                if langevin:
                    sig = math.sqrt(2.0 * fvals[F_K] / 3.0)
                    g4, g5 = next_normal_pair(rng_inj)
                    useen[0] = sig * g3
                    useen[1] = sig * g4
                    useen[2] = sig * g5
                else:
                    useen[:] = 0.0
                out[off_cnt + C_INJECTED] += 1.0
                for c in range(3):
                    out[off_bud + B_MOM_IN + c] += w_m * vel[c]
                out[off_bud + B_MASS_IN] += w_m
                t = 0.0
                steps = 0
                status = 0
                have_spare = False
                spare = 0.0
            suspended = False
            while True:
                # ---- fields at x_n (fvals), time step
                kk = fvals[F_K]
                eps = fvals[F_EPS]
                sig2 = 2.0 * kk / 3.0
                t_l = C_T * sig2 / eps
                for c in range(3):
                    uf[c] = fvals[F_UX + c] + useen[c]
                if ci < 0:
                    status = S_LOST
                    break
                cell = (ci * nr + cj) * nt + ck
                fcoll = 0.0
                if pp:
                    if stats[cell, CS_OK] > 0.0:
                        fcoll = stats[cell, CS_F]
                if paper_rule:
                    rx = uf[0] - vel[0]
                    ry = uf[1] - vel[1]
                    rz = uf[2] - vel[2]
                    re_p = prm[P_RHO_F] * d * math.sqrt(rx * rx + ry * ry + rz * rz) / prm[P_MU]
                    tau_p = fl.response_time(rho_p, d, prm[P_MU], fl.schiller_naumann_drag_factor(re_p))
                    lim = min(tau_p, t_l)
                    if fcoll > 0.0:
                        lim = min(lim, 1.0 / fcoll)
                else:
                    vperp = math.sqrt(vel[1] * vel[1] + vel[2] * vel[2])
                    lim = t_l
                    if kolmogorov_rule:  # no eddy turns over faster than τ_η = √(ν/ε) [s] (Pope 2000, eq. 6.1)
                        # μ/(ρ_F ε), not nu/eps: under arcp a division by eps alone would share its
                        # reciprocal with T_L's and change T_L by round-off in live turbulence too
                        lim = max(t_l, math.sqrt(prm[P_MU] / (prm[P_RHO_F] * eps)))
                    if abs(vel[0]) > 0.0:
                        lim = min(lim, dxc / abs(vel[0]))
                    if vperp > 0.0:
                        lim = min(lim, (r_edges[cj + 1] - r_edges[cj]) / vperp)
                    if fcoll > 0.0:
                        lim = min(lim, 0.1 / fcoll)
                dt = c_step * lim
                if dt > t_cap - t:
                    dt = max(t_cap - t, 1e-300)
                # ---- advance with frozen forces
                for c in range(3):
                    saved[c] = pos[c]
                    saved[3 + c] = vel[c]
                wsx = omega[0]
                wsy = omega[1]
                wsz = omega[2]
                tau_step = _ADVANCE(pos, vel, omega, uf, fvals[F_WX:F_WX + 3], dt, prm, imp)
                # separation from the fluid element over the step, Δr = ∫(u_F − u_p)dt
                drx = uf[0] * dt - (pos[0] - saved[0])
                dry = uf[1] * dt - (pos[1] - saved[1])
                drz = uf[2] * dt - (pos[2] - saved[2])
                hit_wall = False
                r1 = math.sqrt(pos[1] * pos[1] + pos[2] * pos[2])
                if r1 > r_contact:
                    hit_wall = True
                    # straight-line contact time of the chord
                    ey = pos[1] - saved[1]
                    ez = pos[2] - saved[2]
                    aa = ey * ey + ez * ez
                    bb = saved[1] * ey + saved[2] * ez
                    cc = saved[1] * saved[1] + saved[2] * saved[2] - r_contact * r_contact
                    sw = 1.0
                    if cc < 0.0 and aa > 0.0:
                        sw = (-bb + math.sqrt(max(bb * bb - aa * cc, 0.0))) / aa
                    if _WALL_REDO <= sw < 1.0:
                        dt *= sw
                        for c in range(3):
                            pos[c] = saved[c]
                            vel[c] = saved[3 + c]
                        if rotation:
                            omega[0] = wsx
                            omega[1] = wsy
                            omega[2] = wsz
                        tau_step = _ADVANCE_CALL(pos, vel, omega, uf, fvals[F_WX:F_WX + 3], dt, prm, imp)
                        r1 = math.sqrt(pos[1] * pos[1] + pos[2] * pos[2])
                    if r1 > r_contact:
                        f = r_contact / r1
                        pos[1] *= f
                        pos[2] *= f
                # ---- sample the segment (split by time fraction between cells)
                dxs = pos[0] - saved[0]
                dys = pos[1] - saved[1]
                dzs = pos[2] - saved[2]
                nseg, end = _WALK(saved[0], saved[1], saved[2], dxs, dys, dzs, ci, cj, ck,
                                 x_edges, r_edges, ray_sin, ray_cos, seg_cell, seg_frac)
                inside = 0.0
                imp0 = imp[0]  # in locals: the stores into ``out`` below could alias the arrays
                imp1 = imp[1]
                imp2 = imp[2]
                om0 = omega[0]
                om1 = omega[1]
                om2 = omega[2]
                uj = useen[0] * imp0 + useen[1] * imp1 + useen[2] * imp2
                kseen = 0.5 * (useen[0] * useen[0] + useen[1] * useen[1] + useen[2] * useen[2])
                wdt = ndot * dt
                ux = dxs / dt
                uy = dys / dt
                uz = dzs / dt
                last = seg_cell[0]
                kick0 = 0.0
                kick1 = 0.0
                kick2 = 0.0
                for s_ in range(nseg):
                    f = seg_frac[s_]
                    if f <= 0.0:
                        continue
                    cc_ = seg_cell[s_]
                    last = cc_
                    inside += f
                    base = cc_ * NACC
                    wn = wdt * f
                    wmf = wn * m
                    out[base + A_WN] += wn
                    out[base + A_WM] += wmf
                    out[base + A_MU] += w_m * f * dxs
                    out[base + A_MU + 1] += w_m * f * dys
                    out[base + A_MU + 2] += w_m * f * dzs
                    out[base + A_MUU] += wmf * ux * ux
                    out[base + A_MUU + 1] += wmf * uy * uy
                    out[base + A_MUU + 2] += wmf * uz * uz
                    if full_cov:
                        out[base + A_MUV] += wmf * ux * uy
                        out[base + A_MUV + 1] += wmf * ux * uz
                        out[base + A_MUV + 2] += wmf * uy * uz
                    out[base + A_J] += ndot * f * imp0
                    out[base + A_J + 1] += ndot * f * imp1
                    out[base + A_J + 2] += ndot * f * imp2
                    out[base + A_SK] += ndot * f * uj
                    if rotation:
                        out[base + A_NW] += wn * om0
                        out[base + A_NW + 1] += wn * om1
                        out[base + A_NW + 2] += wn * om2
                        out[base + A_NWW] += wn * om0 * om0
                        out[base + A_NWW + 1] += wn * om1 * om1
                        out[base + A_NWW + 2] += wn * om2 * om2
                    out[base + A_VISITS] += 1.0
                    out[base + A_KSEEN] += wn * kseen
                    out[base + A_BETA] += wmf / tau_step
                    if returned:  # the partners' momentum, returned over the residence time
                        a0 = stats[cc_, CS_APP]
                        a1 = stats[cc_, CS_APP + 1]
                        a2 = stats[cc_, CS_APP + 2]
                        if a0 != 0.0 or a1 != 0.0 or a2 != 0.0:
                            kick0 += f * a0
                            kick1 += f * a1
                            kick2 += f * a2
                            out[base + A_PPK] += wmf * a0
                            out[base + A_PPK + 1] += wmf * a1
                            out[base + A_PPK + 2] += wmf * a2
                            out[base + A_PP] += wmf * a0
                            out[base + A_PP + 1] += wmf * a1
                            out[base + A_PP + 2] += wmf * a2
                if inside < 1.0:  # the part beyond the inlet/outlet plane: its impulse stays in the pipe
                    base = last * NACC
                    rest = 1.0 - inside
                    out[base + A_J] += ndot * rest * imp0
                    out[base + A_J + 1] += ndot * rest * imp1
                    out[base + A_J + 2] += ndot * rest * imp2
                    out[base + A_SK] += ndot * rest * uj
                    out[base + A_BETA] += w_m * rest * dt / tau_step
                for c in range(3):
                    out[off_bud + B_J + c] += ndot * imp[c]
                if returned:  # a velocity jump outside J, like the collisions'
                    vel[0] += kick0 * dt
                    vel[1] += kick1 * dt
                    vel[2] += kick2 * dt
                    out[off_bud + B_PP] += w_m * kick0 * dt
                    out[off_bud + B_PP + 1] += w_m * kick1 * dt
                    out[off_bud + B_PP + 2] += w_m * kick2 * dt
                out[off_bud + B_WEIGHT + 1] -= w_m * gred * dt
                t += dt
                steps += 1
                if end == 1:
                    status = S_EXITED
                    break
                if end == 2:  # reflected at the inlet plane (a symmetry plane for the particles)
                    pos[0] = -pos[0]
                    out[off_bud + B_INLET] += -2.0 * w_m * vel[0]
                    vel[0] = -vel[0]
                    useen[0] = -useen[0]
                    out[off_cnt + C_INLET] += 1.0
                    if pos[0] > length:
                        pos[0] = length
                # ---- fields at x_{n+1}; Langevin update of the fluid velocity seen
                ni, nj, nk = _INTERPOLATE(pos[0], pos[1], pos[2], tab, axis, x_centres, rc, r_edges, length,
                                          radius, nu, dvals, cj, wall_law)  # ring search from the last ring
                if langevin:
                    src = dvals  # k, eps and grad k at the new position
                    sig2n = 2.0 * src[F_K] / 3.0
                    sign = math.sqrt(sig2n)
                    t_ln = C_T * sig2n / src[F_EPS]
                    dr2 = drx * drx + dry * dry + drz * drz
                    z0, z1 = next_normal_pair(rng_disp)
                    if have_spare:  # three normals per step from three pairs every two steps
                        z2 = spare
                        have_spare = False
                    else:
                        z2, spare = next_normal_pair(rng_disp)
                        have_spare = True
                    # R_P,i = R_L R_E,i with R_L = exp(-dt/T_L), R_E,i = (f - g) dr_i^2/dr^2 + g,
                    # f = exp(-dr/L_E), g = (1 - dr/(2 L_E)) f: one exponential for R_L f
                    if dr2 > 0.0:
                        dr = math.sqrt(dr2)
                        h = 0.5 * dr / (C_L * t_ln * sign)  # dr / (2 L_E)
                        rlf = math.exp(-dt / t_ln - 2.0 * h)
                        gr = (1.0 - h) * rlf
                        fg = h * rlf / dr2
                        re0 = fg * drx * drx + gr
                        re1 = fg * dry * dry + gr
                        re2 = fg * drz * drz + gr
                    else:
                        re0 = math.exp(-dt / t_ln)
                        re1 = re0
                        re2 = re0
                    if drift and drift_lagrangian:
                        drift_time = -math.expm1(-dt / t_ln) * t_ln  # (1 - R_L) T_L
                        if drift_response:  # times T_L/(T_L + tau_p) = 1/(1 + St)
                            drift_time *= t_ln / (t_ln + tau_step)
                    for c in range(3):
                        rp = re0 if c == 0 else (re1 if c == 1 else re2)
                        zc = z0 if c == 0 else (z1 if c == 1 else z2)
                        un = rp * useen[c] + sign * math.sqrt(max(0.0, 1.0 - rp * rp)) * zc
                        if drift:
                            if drift_lagrangian:
                                un += drift_time * (2.0 / 3.0) * src[F_DKX + c]
                            else:
                                un += (1.0 - rp) * t_ln * (2.0 / 3.0) * src[F_DKX + c]
                        useen[c] = un
                fvals, dvals = dvals, fvals  # the fields at x_{n+1} become those of the next step
                ci = ni
                cj = nj
                ck = nk
                # ---- wall collision
                if hit_wall:
                    vmag = math.sqrt(vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2])
                    rw = math.sqrt(pos[1] * pos[1] + pos[2] * pos[2])
                    vn = -(vel[1] * pos[1] + vel[2] * pos[2]) / rw if rw > 0.0 else 0.0
                    dv[:] = 0.0
                    code = _WALL(pos, vel, omega, useen, dv, r_p, radius, prm[P_DGAMMA],
                                          prm[P_VMIN], rng_wall)
                    if code == WALL_REBOUND:
                        out[off_cnt + C_REBOUNDS] += 1.0
                    elif code == WALL_SLIDING:
                        out[off_cnt + C_SLIDING] += 1.0
                    elif code == WALL_ROLLING:
                        out[off_cnt + C_ROLLING] += 1.0
                    if code == WALL_REBOUND:
                        alpha = math.asin(min(1.0, max(0.0, -vn / vmag))) * _DEG if vmag > 0.0 else 0.0
                        wi = min(int(pos[0] / dxc), nx - 1)
                        thw = math.atan2(pos[1], pos[2])
                        if thw < 0.0:
                            thw += two_pi
                        wk = min(int(thw / two_pi * nt), nt - 1)
                        wb = off_wall + (wi * nt + wk) * NWALL
                        out[wb + W_COUNT] += ndot
                        out[wb + W_ANGLE] += ndot * alpha
                        out[wb + W_SPEED] += ndot * vmag
                        out[off_angle + min(int(alpha), N_ANGLE_BINS - 1)] += ndot
                        out[off_speed + min(int(vmag / speed_max * N_SPEED_BINS), N_SPEED_BINS - 1)] += ndot
                    for c in range(3):
                        out[off_bud + B_WALL + c] += w_m * dv[c]
                    ci, cj, ck = interpolate(pos[0], pos[1], pos[2], tab, axis, x_centres, rc, r_edges, length,
                                             radius, nu, fvals, r_edges.shape[0] - 2, wall_law)  # from the wall ring
                # ---- inter-particle collision with a fictitious partner (previous pass's statistics)
                if pp:
                    if ci >= 0:
                        cell = (ci * nr + cj) * nt + ck
                        if stats[cell, CS_OK] > 0.0:
                            for c in range(3):
                                mean_own[c] = stats[cell, CS_U + c]
                                rms[c] = stats[cell, CS_RMS + c]
                                if full_cov:  # read by the partner draw only then
                                    cov[c] = stats[cell, CS_COV + c]
                                wmean[c] = stats[cell, CS_WM + c]
                                wrms[c] = stats[cell, CS_WRMS + c]
                            if cell_corr:
                                st_pp = stats[cell, CS_ST]
                            else:
                                st_pp = tau_step / (C_T * (2.0 * fvals[F_K] / 3.0) / fvals[F_EPS])
                            dv[:] = 0.0
                            code = _PP(vel, omega, d, mean_own, d, mean_own, rms, cov, wmean, wrms,
                                       stats[cell, CS_N], st_pp, dt, rng_pp, dv, partner)
                            if code > 0:
                                out[off_cnt + C_PP] += 1.0
                                for c in range(3):
                                    out[off_bud + B_PP + c] += w_m * dv[c]
                                    out[cell * NACC + A_PP + c] += w_m * dv[c]
                # ---- fates
                if not (math.isfinite(pos[0]) and math.isfinite(pos[1]) and math.isfinite(pos[2])
                        and math.isfinite(vel[0]) and math.isfinite(vel[1]) and math.isfinite(vel[2])):
                    status = S_LOST
                    break
                if t >= t_cap or steps >= max_steps:
                    status = S_STUCK
                    break
                if pos[0] >= x_hi:  # beyond this window: on in the next
                    suspended = True
                    break
            if suspended:
                for c in range(3):
                    susp[q, SU_POS + c] = pos[c]
                    susp[q, SU_VEL + c] = vel[c]
                    susp[q, SU_OMEGA + c] = omega[c]
                    susp[q, SU_USEEN + c] = useen[c]
                for c in range(NF):
                    susp[q, SU_FIELDS + c] = fvals[c]
                susp[q, SU_CELL] = ci
                susp[q, SU_CELL + 1] = cj
                susp[q, SU_CELL + 2] = ck
                susp[q, SU_T] = t
                susp[q, SU_STEPS] = steps
                susp[q, SU_SPARE] = 1.0 if have_spare else 0.0
                susp[q, SU_SPARE + 1] = spare
                susp[q, SU_INLET] = x_in
                susp[q, SU_INLET + 1] = y_in
                susp[q, SU_INLET + 2] = z_in
                susp[q, SU_DRAWS] = rng_disp[RNG_DRAW]
                susp[q, SU_DRAWS + 1] = rng_wall[RNG_DRAW]
                susp[q, SU_DRAWS + 2] = rng_pp[RNG_DRAW]
                susp[q, SU_ACTIVE] = 1.0
                continue
            # ---- bookkeeping of the fate
            out[off_cnt + C_STEPS] += steps
            out[off_bud + B_RESIDENCE] += w_m * t
            if status == S_EXITED:
                out[off_cnt + C_EXITED] += 1.0
                out[off_bud + B_MASS_OUT] += w_m
            elif status == S_STUCK:
                out[off_cnt + C_STUCK] += 1.0
                out[off_bud + B_MASS_STUCK] += w_m
            else:
                out[off_cnt + C_LOST] += 1.0
            if status != S_LOST:
                for c in range(3):
                    out[off_bud + B_MOM_OUT + c] += w_m * vel[c]
            for c in range(3):
                state[q, c] = pos[c]
                state[q, 3 + c] = vel[c]
                state[q, 6 + c] = omega[c]
                state[q, 9 + c] = useen[c]
            state[q, 12] = t
            state[q, 13] = steps
            state[q, 14] = status
            state[q, 15] = d
            state[q, 16] = x_in
            state[q, 17] = y_in
            state[q, 18] = z_in

    # the parcel loop runs without the numba runtime's reference counting (KERNEL_FLAGS): array
    # arguments of the sub-kernel calls then cost no reference counts; the calls made every step
    # (motion, segment walk, field interpolation, stochastic collision) are inlined, the rare
    # ones (injection, the wall path, the shortened step before a wall contact) stay calls
    # (collisions/conf.py, ``inlined``); fused multiply-adds and reused reciprocals (LOOP_FLAGS)
    track_parcels = njit(**LOOP_FLAGS)(_with_globals(
        track_parcels, _ADVANCE=inlined(advance), _ADVANCE_CALL=advance, _WALK=inlined(walk_segment),
        _INTERPOLATE=inlined(interpolate), _WALL=wall_collision, _PP=inlined(pp_collision)))

    def track_batch_windows(first, count, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                            x_centres, tab, axis, stats, prm, out, state, susp, w_first, w_last):
        if len(key) == 0:
            return
        ray = np.arange(nt + 1) * (2.0 * math.pi / nt)
        rngs = np.zeros((4, RNG_STATE_SIZE), dtype=np.int64)
        _TRACK_PARCELS(first, count, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                       x_centres, tab, axis, stats, prm, out, state, np.empty(NF), np.empty(NF),
                       np.empty(3), np.empty(3), np.zeros(3), np.zeros(3), np.empty(3), np.empty(3),
                       np.zeros(3), np.empty(9), np.empty(MAX_SEGMENTS, dtype=np.int64),
                       np.empty(MAX_SEGMENTS), np.empty(3), np.empty(3), np.zeros(3), np.empty(3), np.empty(3),
                       np.empty(6), np.sin(ray), np.cos(ray), rngs[0], rngs[1], rngs[2], rngs[3],
                       susp, w_first, w_last)

    track_batch_windows = njit(**JIT_FLAGS)(_with_globals(track_batch_windows, _TRACK_PARCELS=track_parcels))

    def track_batch(first, count, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                    x_centres, tab, axis, stats, prm, out, state):
        if len(key) == 0:
            return
        windowed = 0.0 < prm[P_WINDOW] < x_edges.shape[0] - 1  # more than one window
        n_susp = count if windowed else 0  # suspended parcel states
        susp = np.empty((n_susp, NSUSP))
        _TRACK_BATCH_WINDOWS(first, count, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                             x_centres, tab, axis, stats, prm, out, state, susp, 0, x_edges.shape[0])

    track_batch = njit(**JIT_FLAGS)(_with_globals(track_batch, _TRACK_BATCH_WINDOWS=track_batch_windows))

    def track_windows(starts, counts, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                      x_centres, tab, axis, stats, prm, scratch, states, susp, w_first, w_last):
        # windows w_first … w_last − 1 of every batch of a super-batch, batch b into scratch[b]
        # (zeroed by the caller before window 0) and its parcels' rows of states and susp
        if len(key) == 0:
            return
        for s in prange(starts.shape[0]):
            lo = starts[s] - starts[0]
            hi = lo + counts[s]
            _TRACK_BATCH_WINDOWS(starts[s], counts[s], seed, pass_, x_edges, r_edges, rc, nt, length,
                                 radius, nu, x_centres, tab, axis, stats, prm, scratch[s], states[lo:hi],
                                 susp[lo:hi], w_first, w_last)

    # nogil: a super-batch streamed window by window runs beside the gas solve that feeds it
    # its fields (particles.stream)
    track_windows = njit(parallel=True, nogil=True, **JIT_FLAGS)(
        _with_globals(track_windows, _TRACK_BATCH_WINDOWS=track_batch_windows))

    def track_superbatch(starts, counts, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                         x_centres, tab, axis, stats, prm, totals, squares, cross, n_acc_cells,
                         states):
        if len(key) == 0:
            return
        nb = starts.shape[0]
        size = totals.shape[0]
        width = min(numba.get_num_threads(), nb)
        scratch = np.empty((width, size))
        for b0 in range(0, nb, width):
            nin = min(width, nb - b0)
            for s in prange(nin):
                scratch[s, :] = 0.0
                _TRACK_BATCH(starts[b0 + s], counts[b0 + s], seed, pass_, x_edges, r_edges, rc, nt,
                             length, radius, nu, x_centres, tab, axis, stats, prm, scratch[s],
                             states[starts[b0 + s] - starts[0]:starts[b0 + s] - starts[0] + counts[b0 + s]])
            fold_batches(scratch, nin, totals, squares, cross, n_acc_cells)

    track_superbatch = njit(parallel=True, nogil=True, **JIT_FLAGS)(
        _with_globals(track_superbatch, _TRACK_BATCH=track_batch))
    # what the compiled code must report (options equal to these reuse this memoised pair,
    # though their repr may differ: 1.0 against np.float64(1.0))
    track_superbatch.eulag_variant = variant
    track_windows.eulag_variant = variant
    return track_batch, track_superbatch, track_windows


@lru_cache(maxsize=None)
def make_tracker(options=PhysicsOptions()):
    """Build ``track_batch`` and ``track_superbatch`` for ``options`` (memoised).

        track_batch(first, count, seed, pass_, x_edges, r_edges, rc, nt, length, radius, nu,
                    x_centres, tab, axis, stats, prm, out, state)

    tracks parcels first … first+count−1 (global ids key their random streams) and adds
    their samples to the flat vector ``out`` (layout.Layout); ``state`` (count, 16) receives
    the final parcel state (NSTATE columns) [pos(3), vel(3), omega(3), u′(3), t_res, steps,
    status, diameter, injection position(3)].

        track_superbatch(starts, counts, ..., totals, squares, cross, ncell, states)

    tracks the batches of one super-batch, in parallel (numba threads), each into its own
    scratch vector, and folds them *in batch order* into totals (Σ_b s_b), squares
    (Σ_b s_b²) and cross (Σ_b s_b · s_b[mass weight], cell accumulators only), so the result
    does not depend on the thread count; ``states`` (parcels of the super-batch, NSTATE)
    receives the final parcel states.
    """
    return _trackers(options)[:2]


def make_window_tracker(options=PhysicsOptions()):
    """``track_windows`` for ``options`` (memoised with :func:`make_tracker`):

        track_windows(starts, counts, ..., stats, prm, scratch, states, susp, w_first, w_last)

    sweeps windows w_first … w_last − 1 of every batch of a super-batch (in parallel over the
    batches), batch b into ``scratch[b]`` (zero it before window 0) and its parcels' rows of
    ``states`` and ``susp`` (parcels, NSUSP: the parcels suspended between two calls).  Called
    for consecutive window ranges that cover the sweep, then folded with :func:`fold_batches`,
    it gives the super-batch's sums bit for bit as ``track_superbatch`` does, whatever the
    ranges: a batch's operations and their order are the same (particles.stream).
    """
    return _trackers(options)[2]


@njit(**KERNEL_FLAGS)
def fold_batches(scratch, nin, totals, squares, cross, n_acc_cells):
    """Fold batches 0 … nin−1 of ``scratch`` into totals (Σ s_b), squares (Σ s_b²) and cross
    (Σ s_b · s_b[mass weight], the n_acc_cells cell accumulators) in batch order, so the sums
    do not depend on the thread count."""
    size = totals.shape[0]
    for s in range(nin):
        for a in range(size):
            v = scratch[s, a]
            totals[a] += v
            squares[a] += v * v
        for c in range(n_acc_cells):
            wm = scratch[s, c * NACC + A_WM]
            if wm != 0.0:
                for a in range(NACC):
                    cross[c * NACC + a] += scratch[s, c * NACC + a] * wm
