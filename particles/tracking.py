"""One Lagrangian pass: inject, track and sample parcels through a converged gas field.

``track(mesh, gas, spec, physics, parcels=..., seed=..., pass_index=...)`` → :class:`Sample`.

Parcels are tracked in fixed-size batches (sizes fixed by the parcel count and
``batch_size``, never by the thread count); batches are grouped into super-batches of
``batches_per_superbatch``; each super-batch folds its batches in order and the super-batches
are summed in order, so the same seed gives the same numbers, bit for bit, for any number of
threads (and the same super-batches can go to Dask workers unchanged).

Every parcel stands for a particle number flow rate Ṅ = ṁ_p / (m_p · parcels) with the
particle mass flow ṁ_p = η ρ_F U_0 π R² (mass loading η).  Sampled quantities are
rate-weighted sums over trajectory segments divided by the cell volume; the spread of the
batch sums gives a standard error for each of them (``Sample.*_stderr``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from collisions.interparticle import mean_collision_frequency
from collisions.wall import minimum_bounce_speed

from .fields import FieldTable
from .kernel import C_T, NSTATE, PhysicsOptions, make_tracker
from .layout import (A_BETA, A_J, A_KSEEN, A_PP, A_PPK, CS_APP, CS_COV, A_MU, A_MUU, A_MUV, A_NW, A_NWW, A_SK, A_VISITS, A_WM, A_WN, B_INLET, B_J,
                     B_MASS_IN, B_MASS_OUT, B_MASS_STUCK, B_MOM_IN, B_MOM_OUT, B_PP, B_RESIDENCE,
                     B_WALL, B_WEIGHT, C_EXITED, C_INJECTED, C_INLET, C_LOST, C_PP, C_REBOUNDS,
                     C_ROLLING, C_SLIDING, C_STEPS, C_STUCK, C_VARIANT, CS_F, CS_N, CS_OK, CS_RMS, CS_ST, CS_U,
                     CS_WM, CS_WRMS, N_ANGLE_BINS, N_SPEED_BINS, NACC, NCNT, NCS, NPRM, NWALL, P_DGAMMA,
                     P_DP, P_GRAV, P_INJ_RMS, P_MAXSTEPS, P_MIN_VISITS, P_MU, P_NDOT, P_RHO_F, P_WINDOW,
                     P_RHO_P, P_SPEEDMAX, P_STEP, P_TCAP, P_U0, P_VMIN, W_ANGLE, W_COUNT, W_SPEED,
                     Layout)
from .symmetry import mirror_average_vector

__all__ = ["ParticleSpec", "TrackSettings", "Sample", "track", "batch_plan", "GRAVITY", "PassInputs",
           "prepare_pass", "run_superbatch", "fold_superbatches", "make_sample", "cell_stokes",
           "stokes_of_cells"]

GRAVITY = 9.81  # m s-2
C_EPS3 = 1.8  # S_eps = C_eps3 (eps/k) S_k (seed)


@dataclass(frozen=True)
class ParticleSpec:
    """The dispersed phase and its injection (monodisperse spheres).

    diameter [m], density [kg m-3], mass_loading η = ṁ_p/ṁ_gas [-], injection_velocity U_0
    (mean axial injection velocity, also the gas bulk velocity of ṁ_gas) [m s-1],
    injection_rms [m s-1] per component, roughness_angle_std_deg Δγ [deg].
    """

    diameter: float
    density: float
    mass_loading: float
    injection_velocity: float
    injection_rms: float = 0.5
    roughness_angle_std_deg: float = 0.0

    @property
    def mass(self):
        return self.density * math.pi * self.diameter**3 / 6.0


def cell_stokes(stats, gas, spec):
    """Stokes number St = τ_p/T_L of each cell, (ncell,), for the partners' correlation
    R(St) = exp(−0.55 St^0.4) (Sommerfeld 2001) taken once per cell.

    ``stats``: (ncell, NCS) cell statistics (their mean velocity gives the cell-mean slip of
    τ_p, Schiller–Naumann); T_L = C_T (2/3) k/ε from the gas cell-centre values.
    """
    return stokes_of_cells(stats, gas.ux.ravel(), gas.uy.ravel(), gas.uz.ravel(), gas.k.ravel(),
                           gas.epsilon.ravel(), gas.gas, spec)


def stokes_of_cells(stats, ux, uy, uz, k, eps, gas_props, spec):
    """:func:`cell_stokes` for the rows of ``stats`` and the gas values of the same cells (flat
    arrays); elementwise, so any subset of cells gets the numbers of the whole pipe."""
    mu = gas_props.viscosity
    rho = gas_props.density
    d = spec.diameter
    slip = np.sqrt((ux - stats[:, CS_U]) ** 2 + (uy - stats[:, CS_U + 1]) ** 2 + (uz - stats[:, CS_U + 2]) ** 2)
    re_p = rho * d * slip / mu  # drag factor f_d of Schiller & Naumann, Newton above 1000
    f_d = np.where(re_p > 1000.0, 0.44 * re_p / 24.0, 1.0 + 0.15 * re_p**0.687)
    tau_p = spec.density * d * d / (18.0 * mu * f_d)
    t_l = C_T * (2.0 / 3.0) * k / eps
    return tau_p / t_l


@dataclass(frozen=True)
class TrackSettings:
    """Numerical settings of a pass.

    step_factor c of Δt = c · min(...) [-]; batch_size parcels per batch (at least
    ``min_batches`` batches are formed, for the standard errors); batches_per_superbatch;
    residence_cap [s] (None: 50 L/U_0) and max_steps per parcel; min_visits: samples a cell
    needs before its statistics drive collisions; window_stations: the stations of one window
    of the tracking sweep (``kernel.track_parcels``: every parcel of a batch is tracked through
    the first window, then through the next, ...; 0 = the whole pipe at once, parcel after
    parcel).  The window changes only the order of the sampled sums (round-off), not a
    trajectory; small windows keep the fields and accumulators the batch works on in the cache
    (4 stations of the studies' 20 x 40 section: about 1.4 MB).
    """

    step_factor: float = 0.5
    batch_size: int = 4096
    min_batches: int = 8
    batches_per_superbatch: int = 8
    residence_cap: float | None = None
    max_steps: int = 2_000_000
    min_visits: int = 10
    window_stations: int = 4


def batch_plan(parcels, settings=TrackSettings()):
    """(starts, counts) of the batches, and the super-batch boundaries (list of slices)."""
    parcels = int(parcels)
    nb = max(min(settings.min_batches, parcels), -(-parcels // settings.batch_size))
    counts = np.full(nb, parcels // nb, dtype=np.int64)
    counts[: parcels % nb] += 1
    starts = np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64)
    per = settings.batches_per_superbatch
    supers = [slice(b, min(b + per, nb)) for b in range(0, nb, per)]
    return starts, counts, supers


@dataclass
class Sample:
    """Result of one Lagrangian pass (or the average of several, :meth:`average`).

    ``total`` is the flat result vector (layout.Layout), ``var`` the variance of each entry
    from the batch spread and ``cov`` its covariance with the cell mass weight (cell part
    only, for ratio statistics).  Derived fields are (nx, nr, nt) arrays in SI units.
    """

    mesh: object
    spec: ParticleSpec
    parcels: int
    batches: int
    total: np.ndarray
    var: np.ndarray
    cov: np.ndarray
    wall_time: float = 0.0
    passes: int = 1
    states: np.ndarray = field(default=None, repr=False)
    _lay: Layout = field(default=None, repr=False)

    def __post_init__(self):
        nx, nr, nt = self.mesh.shape
        self._lay = Layout(nx * nr * nt, nx * nt)

    # ---------------------------------------------------------------- raw parts
    def _cells(self, arr, a):
        nx, nr, nt = self.mesh.shape
        return arr[: nx * nr * nt * NACC].reshape(nx, nr, nt, NACC)[..., a]

    def _acc(self, a):
        return self._cells(self.total, a)

    def _sum_stderr(self, a):
        return np.sqrt(np.maximum(self._cells(self.var, a), 0.0))

    def _ratio(self, a, w=A_WM):
        num = self._acc(a)
        den = self._acc(w)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), np.nan)

    def _ratio_stderr(self, a):
        """Delta-method standard error of total[a]/total[WM] from the batch (co)variances."""
        r = self._ratio(a)
        w = self._acc(A_WM)
        va = self._cells(self.var, a)
        vw = self._cells(self.var, A_WM)
        cw = self._cells(self.cov, a)
        with np.errstate(invalid="ignore", divide="ignore"):
            v = (va - 2.0 * r * cw + r * r * vw) / np.where(w > 0.0, w * w, np.nan)
        return np.sqrt(np.maximum(v, 0.0))

    @property
    def volume(self):
        return self.mesh.volume

    # ---------------------------------------------------------------- cell fields
    @property
    def number_density(self):
        """Particle number concentration [m-3]."""
        return self._acc(A_WN) / self.volume

    @property
    def concentration(self):
        """Particle mass concentration [kg m-3]."""
        return self._acc(A_WM) / self.volume

    @property
    def concentration_stderr(self):
        return self._sum_stderr(A_WM) / self.volume

    @property
    def mass_flux(self):
        """Axial particle mass flux [kg m-2 s-1]."""
        return self._acc(A_MU) / self.volume

    @property
    def mass_flux_stderr(self):
        return self._sum_stderr(A_MU) / self.volume

    def velocity(self, c):
        """Mass-weighted mean particle velocity component c (0 x, 1 y, 2 z) [m s-1]; NaN if empty."""
        return self._ratio(A_MU + c)

    def velocity_stderr(self, c):
        return self._ratio_stderr(A_MU + c)

    def velocity_rms(self, c):
        """Rms of particle velocity component c about its cell mean [m s-1]; NaN if empty."""
        mean = self.velocity(c)
        return np.sqrt(np.maximum(self._ratio(A_MUU + c) - mean * mean, 0.0))

    def velocity_covariance(self, a, b):
        """Covariance of particle velocity components a < b about the cell means [m2 s-2]; NaN if
        empty, zero where the pass did not accumulate the products (they are accumulated with
        ``physics.partner_covariance = "full"`` only)."""
        i = {(0, 1): 0, (0, 2): 1, (1, 2): 2}[(a, b)]
        have = self._acc(A_MUV) != 0.0
        for j in (1, 2):
            have = have | (self._acc(A_MUV + j) != 0.0)
        cov = self._ratio(A_MUV + i) - self.velocity(a) * self.velocity(b)
        return np.where(have | np.isnan(cov), cov, 0.0)

    def velocity_rms_stderr(self, c):
        rms = self.velocity_rms(c)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(rms > 0.0, self._ratio_stderr(A_MUU + c) / (2.0 * np.where(rms > 0, rms, 1.0)),
                            np.nan)

    def momentum_source(self, c):
        """Momentum source on the gas, component c [N m-3] (as computed, not relaxed)."""
        return -self._acc(A_J + c) / self.volume

    def momentum_source_stderr(self, c):
        return self._sum_stderr(A_J + c) / self.volume

    @property
    def drag_coefficient(self):
        """β = (1/V) Σ Ṅ m δt/τ_p [kg m-3 s-1]: how the momentum source falls as the gas
        velocity the particles see rises, −∂S/∂U at fixed particle velocities (τ_p with the
        drag factor of each step); the coupling loop applies the source linearised with it."""
        return self._acc(A_BETA) / self.volume

    @property
    def k_source(self):
        """Turbulence source S_k = −(1/V) Σ Ṅ u′_F·J [W m-3]."""
        return -self._acc(A_SK) / self.volume

    @property
    def k_source_stderr(self):
        return self._sum_stderr(A_SK) / self.volume

    @property
    def seen_k(self):
        """Mean turbulent energy ½⟨|u′_F|²⟩ of the fluid velocity the particles see [m2 s-2]
        (number-weighted; NaN in unvisited cells)."""
        return self._ratio(A_KSEEN, A_WN)

    def collision_force(self, c):
        """Net force of the inter-particle collisions on the particles, component c [N m-3]:
        the collision velocity jumps (and, with partner_momentum = "returned", the returned
        partner momentum) per unit time and volume.  Real collisions exchange momentum between
        particles of one cell, so a momentum-conserving model gives zero in the mean."""
        return self._acc(A_PP + c) / self.volume

    def collision_force_stderr(self, c):
        return self._sum_stderr(A_PP + c) / self.volume

    def collision_jump_force(self, c):
        """The part of :meth:`collision_force` from the stochastic collisions' velocity jumps
        alone, without the returned partner momentum [N m-3]."""
        return (self._acc(A_PP + c) - self._acc(A_PPK + c)) / self.volume

    @property
    def collision_force_total(self):
        """Pipe integral of :meth:`collision_force` (x, y, z) [N] and its standard error from the
        batch spread of the section totals: (total, stderr), each float64[3]."""
        o = self._lay.budget + B_PP
        return self.total[o:o + 3].copy(), np.sqrt(np.maximum(self.var[o:o + 3], 0.0))

    def mirror_symmetrised(self):
        """This sample averaged with its mirror image z → −z (:mod:`particles.symmetry`):
        exact in the mean for a mirror-symmetric case, half the variance, symmetric fields to
        the last bit."""
        shape = self.mesh.shape
        return Sample(mesh=self.mesh, spec=self.spec, parcels=self.parcels, batches=self.batches,
                      total=mirror_average_vector(self.total, shape, "total"),
                      var=mirror_average_vector(self.var, shape, "var"),
                      cov=mirror_average_vector(self.cov, shape, "cov"),
                      wall_time=self.wall_time, passes=self.passes, states=self.states)

    def epsilon_source(self, k, epsilon, c_eps3=C_EPS3):
        """S_ε = C_ε3 (ε/k) S_k [W m-3 s-1] with the gas k, ε (nx, nr, nt); C_ε3 = 1.8 (seed)."""
        return c_eps3 * epsilon / k * self.k_source

    @property
    def visits(self):
        return self._acc(A_VISITS)

    def spin(self, c):
        """Mean particle angular velocity component c [rad s-1]."""
        return self._ratio(A_NW + c, A_WN)

    def spin_rms(self, c):
        mean = self.spin(c)
        return np.sqrt(np.maximum(self._ratio(A_NWW + c, A_WN) - mean * mean, 0.0))

    # ---------------------------------------------------------------- wall
    def _wall(self, arr, a):
        nx, _, nt = self.mesh.shape
        o = self._lay.wall
        return arr[o: o + nx * nt * NWALL].reshape(nx, nt, NWALL)[..., a]

    @property
    def wall_face_area(self):
        return np.outer(self.mesh.dx, np.full(self.mesh.nt, self.mesh.radius * self.mesh.dtheta))

    @property
    def wall_collision_rate(self):
        """Particle–wall impacts (rebounds) per wall area and time, (nx, nt) [m-2 s-1]."""
        return self._wall(self.total, W_COUNT) / self.wall_face_area

    @property
    def wall_collision_rate_stderr(self):
        return np.sqrt(np.maximum(self._wall(self.var, W_COUNT), 0.0)) / self.wall_face_area

    @property
    def wall_impact_angle_mean(self):
        """Rate-weighted mean nominal impact angle per wall face [deg] (NaN: no impacts)."""
        n = self._wall(self.total, W_COUNT)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, self._wall(self.total, W_ANGLE) / n, np.nan)

    @property
    def wall_impact_speed_mean(self):
        n = self._wall(self.total, W_COUNT)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, self._wall(self.total, W_SPEED) / n, np.nan)

    def _hist(self, off, n):
        h = self.total[off: off + n]
        s = h.sum()
        return h / s if s > 0 else np.zeros(n)

    @property
    def impact_angle_pdf(self):
        """(bin edges [deg], probability per bin) of the nominal wall-impact angle."""
        return np.linspace(0.0, 90.0, N_ANGLE_BINS + 1), self._hist(self._lay.angle, N_ANGLE_BINS)

    @property
    def impact_speed_pdf(self):
        """(bin edges [m s-1], probability per bin) of the wall-impact speed (last bin open)."""
        edges = np.linspace(0.0, 2.0 * self.spec.injection_velocity, N_SPEED_BINS + 1)
        return edges, self._hist(self._lay.speed, N_SPEED_BINS)

    # ---------------------------------------------------------------- bookkeeping
    @property
    def budget(self):
        """Rate-weighted totals [N or kg s-1 or kg]: momentum in/out, weight, collisions, impulse."""
        b = self.total[self._lay.budget:]
        v = lambda o: b[o: o + 3].copy()  # noqa: E731
        return {"momentum_in": v(B_MOM_IN), "momentum_out": v(B_MOM_OUT), "weight": v(B_WEIGHT),
                "wall_collisions": v(B_WALL), "particle_collisions": v(B_PP),
                "inlet_reflections": v(B_INLET), "fluid_impulse": v(B_J),
                "mass_in": b[B_MASS_IN], "mass_out": b[B_MASS_OUT], "mass_stuck": b[B_MASS_STUCK],
                "mean_residence_time": b[B_RESIDENCE] / b[B_MASS_IN] if b[B_MASS_IN] > 0 else np.nan}

    @property
    def counts(self):
        """Parcel fates and event counts (summed over the passes averaged)."""
        c = self.total[self._lay.counts:] * self.passes
        names = {C_INJECTED: "injected", C_EXITED: "exited", C_STUCK: "stuck", C_LOST: "lost",
                 C_STEPS: "steps", C_REBOUNDS: "wall_rebounds", C_SLIDING: "wall_sliding",
                 C_ROLLING: "wall_rolling", C_PP: "particle_collisions", C_INLET: "inlet_reflections"}
        return {n: int(round(c[i])) for i, n in names.items()}

    def cell_statistics(self, gas=None, min_visits=10):
        """Per-cell statistics (ncell, NCS) the next pass's collision model uses.

        Number density, mean and rms velocity (and the velocity covariances where the pass
        accumulated them, ``CS_COV``), mean and rms spin, the acceleration that
        returns the fictitious partners' momentum to the cell's particles (``CS_APP``: minus
        the collision jumps' net force over the particles' mass in the cell), the mean collision frequency
        (docs/physics.md, for the step limit; with the Sommerfeld correlation R(St), St = τ_p/T_L
        from the cell-mean slip and the gas k, ε when ``gas`` is given), that Stokes number
        (``cell_stokes``, ``CS_ST``; inf without ``gas``, i.e. uncorrelated partners; with
        ``partner_correlation = "cell"`` the partners' R takes it, and the coupling loop
        recomputes it with the gas of the next pass), and a flag for cells with at least
        ``min_visits`` samples.
        """
        nx, nr, nt = self.mesh.shape
        st = np.zeros((nx, nr, nt, NCS))
        ok = (self.visits >= min_visits) & (self._acc(A_WM) > 0.0)
        st[..., CS_N] = np.where(ok, self.number_density, 0.0)
        for c in range(3):
            st[..., CS_U + c] = np.where(ok, self.velocity(c), 0.0)
            st[..., CS_RMS + c] = np.where(ok, self.velocity_rms(c), 0.0)
            st[..., CS_WM + c] = np.where(ok, self.spin(c), 0.0)
            st[..., CS_WRMS + c] = np.where(ok, self.spin_rms(c), 0.0)
        for i, (a, b) in enumerate(((0, 1), (0, 2), (1, 2))):
            st[..., CS_COV + i] = np.where(ok, self.velocity_covariance(a, b), 0.0)
        sigma = np.sqrt(np.mean(st[..., CS_RMS:CS_RMS + 3] ** 2, axis=-1))
        d = self.spec.diameter
        if gas is not None:
            st[..., CS_ST] = cell_stokes(st.reshape(-1, NCS), gas, self.spec).reshape(nx, nr, nt)
            corr = np.exp(-0.55 * st[..., CS_ST] ** 0.4)
        else:  # no gas: uncorrelated partners (R = 0, St = inf)
            st[..., CS_ST] = np.inf
            corr = np.zeros((nx, nr, nt))
        freq = np.empty((nx, nr, nt))
        flat_n, flat_s, flat_c = st[..., CS_N].ravel(), sigma.ravel(), corr.ravel()
        fr = freq.ravel()
        for i in range(fr.size):
            fr[i] = mean_collision_frequency(d, d, flat_n[i], flat_s[i], flat_s[i], flat_c[i])
        st[..., CS_F] = freq
        st[..., CS_OK] = ok.astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            for c in range(3):  # a = −F_jump/c (PhysicsOptions.partner_momentum = "returned")
                acc = -(self._acc(A_PP + c) - self._acc(A_PPK + c)) / self._acc(A_WM)
                st[..., CS_APP + c] = np.where(ok, acc, 0.0)
        return np.ascontiguousarray(st.reshape(nx * nr * nt, NCS))

    # ---------------------------------------------------------------- averaging
    @classmethod
    def average(cls, samples):
        """Mean of several passes' samples; variances combine as Σ var / n²."""
        samples = list(samples)
        n = len(samples)
        s0 = samples[0]
        tot = sum(s.total for s in samples) / n
        var = sum(s.var for s in samples) / n**2
        cov = sum(s.cov for s in samples) / n**2
        return cls(mesh=s0.mesh, spec=s0.spec, parcels=sum(s.parcels for s in samples),
                   batches=sum(s.batches for s in samples), total=tot, var=var, cov=cov,
                   wall_time=sum(s.wall_time for s in samples), passes=n)


def parameters(spec, gas_props, mesh, settings=TrackSettings(), parcels=1, gravity=True):
    """Runtime parameter vector (layout.P_*) of a pass."""
    prm = np.zeros(NPRM)
    area = math.pi * mesh.radius**2
    mdot_p = spec.mass_loading * gas_props.density * spec.injection_velocity * area
    prm[P_RHO_F] = gas_props.density
    prm[P_MU] = gas_props.viscosity
    prm[P_RHO_P] = spec.density
    prm[P_DP] = spec.diameter
    prm[P_NDOT] = mdot_p / (spec.mass * parcels)
    prm[P_U0] = spec.injection_velocity
    prm[P_INJ_RMS] = spec.injection_rms
    prm[P_GRAV] = GRAVITY * (1.0 - gas_props.density / spec.density) if gravity else 0.0
    prm[P_DGAMMA] = math.radians(spec.roughness_angle_std_deg)
    prm[P_VMIN] = minimum_bounce_speed(spec.diameter, GRAVITY)
    prm[P_STEP] = settings.step_factor
    cap = settings.residence_cap
    prm[P_TCAP] = cap if cap is not None else 50.0 * mesh.length / spec.injection_velocity
    prm[P_MAXSTEPS] = settings.max_steps
    prm[P_SPEEDMAX] = 2.0 * spec.injection_velocity
    prm[P_MIN_VISITS] = settings.min_visits
    prm[P_WINDOW] = settings.window_stations
    return prm


@dataclass(frozen=True, eq=False)
class PassInputs:
    """Everything a super-batch of one pass needs, as plain picklable data (no mesh, no gas).

    Built once per pass by :func:`prepare_pass` on the driver; shipped once to every worker of
    a distributed run; :func:`run_superbatch` tracks one super-batch from it.
    physics is the effective option set (inter-particle collisions dropped when the pass has
    no cell statistics); starts/counts/supers are :func:`batch_plan`'s; prm the runtime
    parameter vector (:func:`parameters`); size the flat result length (layout.Layout).
    """

    table: FieldTable
    stats: np.ndarray
    prm: np.ndarray
    physics: PhysicsOptions
    seed: int
    pass_index: int
    parcels: int
    starts: np.ndarray
    counts: np.ndarray
    supers: tuple
    nt: int
    ncell: int
    size: int

    @property
    def superbatches(self):
        """Number of super-batches of the pass."""
        return len(self.supers)


def prepare_pass(mesh, gas, spec, physics=PhysicsOptions(), *, parcels, seed=1, pass_index=0,
                 stats=None, settings=TrackSettings(), table=None, gas_props=None):
    """The :class:`PassInputs` of one pass (arguments as :func:`track`; ``gas`` may be None
    when ``table`` and the gas properties ``gas_props`` are given)."""
    if gas_props is None:
        gas_props = gas.gas
    if table is None:
        table = FieldTable.from_gas(mesh, gas)
    nx, nr, nt = mesh.shape
    ncell = nx * nr * nt
    lay = Layout(ncell, nx * nt)
    starts, counts, supers = batch_plan(parcels, settings)
    use_pp = physics.inter_particle_collisions and stats is not None
    if physics.inter_particle_collisions and not use_pp:
        physics = PhysicsOptions(**{**physics.__dict__, "inter_particle_collisions": False})
    if stats is None:
        stats = np.zeros((ncell, NCS))
    elif stats.shape != (ncell, NCS):  # the kernel reads the rows unchecked
        raise ValueError(f"stats: shape {stats.shape}, the tracker reads ({ncell}, {NCS}) (cells, layout.NCS)")
    prm = parameters(spec, gas_props, mesh, settings, parcels, physics.gravity)
    return PassInputs(table=table, stats=stats, prm=prm, physics=physics, seed=int(seed),
                      pass_index=int(pass_index), parcels=int(parcels), starts=starts, counts=counts,
                      supers=tuple(supers), nt=nt, ncell=ncell, size=lay.size)


def _check_variant(totals, nbatches, variant):
    """Refuse the results of a kernel compiled for other physics options (collisions.conf)."""
    got = totals[totals.size - NCNT + C_VARIANT]
    want = variant * nbatches
    if got != want:
        raise RuntimeError(
            "the particle kernel numba returned was compiled for other physics options (its "
            "on-disk cache is corrupt, e.g. by processes compiling at the same time); delete the "
            "*.nbi/*.nbc files under particles/__pycache__ and collisions/__pycache__ (or "
            "NUMBA_CACHE_DIR) and run again")


def run_superbatch(inputs, isb, keep_states=False):
    """Track super-batch ``isb`` of a pass: (totals, squares, cross[, states]) of its batches.

    totals Σ_b s_b and squares Σ_b s_b² (flat, layout.Layout), cross Σ_b s_b · s_b[mass weight]
    (cell accumulators); the batches are folded in batch order, whatever the thread count.
    """
    _, track_superbatch = make_tracker(inputs.physics)
    sl = inputs.supers[isb]
    table = inputs.table
    t_s = np.zeros(inputs.size)
    q_s = np.zeros(inputs.size)
    c_s = np.zeros(inputs.ncell * NACC)
    st_s = np.empty((int(inputs.counts[sl].sum()), NSTATE))
    track_superbatch(inputs.starts[sl], inputs.counts[sl], inputs.seed, inputs.pass_index,
                     table.x_edges, table.r_edges, table.r_centres, inputs.nt, table.length,
                     table.radius, table.nu, table.x_centres, table.values, table.axis, inputs.stats,
                     inputs.prm, t_s, q_s, c_s, inputs.ncell, st_s)
    _check_variant(t_s, len(inputs.counts[sl]), track_superbatch.eulag_variant)
    if keep_states:
        return t_s, q_s, c_s, st_s
    return t_s, q_s, c_s


def fold_superbatches(inputs, results):
    """Sum super-batch results (an iterable in super-batch index order) → (totals, squares, cross).

    The order of the sums is what makes a pass bit-identical however it was run; callers that
    receive results out of order must reorder them first.
    """
    totals = np.zeros(inputs.size)
    squares = np.zeros(inputs.size)
    cross = np.zeros(inputs.ncell * NACC)
    for r in results:
        totals += r[0]
        squares += r[1]
        cross += r[2]
    return totals, squares, cross


def make_sample(mesh, spec, inputs, totals, squares, cross, wall_time=0.0, states=None):
    """The :class:`Sample` of a pass from its folded sums (batch variances and covariances)."""
    ncell = inputs.ncell
    size = inputs.size
    nb = len(inputs.starts)
    if nb > 1:
        var = nb / (nb - 1.0) * (squares - totals * totals / nb)
        wm = totals[: ncell * NACC].reshape(ncell, NACC)[:, A_WM:A_WM + 1]
        cov = (nb / (nb - 1.0) * (cross.reshape(ncell, NACC) - totals[: ncell * NACC].reshape(ncell, NACC)
                                  * wm / nb)).ravel()
    else:
        var = np.full(size, np.nan)
        cov = np.full(ncell * NACC, np.nan)
    return Sample(mesh=mesh, spec=spec, parcels=inputs.parcels, batches=nb, total=totals, var=var,
                  cov=np.concatenate((cov, np.zeros(size - cov.size))), wall_time=wall_time,
                  states=states)


def track(mesh, gas, spec, physics=PhysicsOptions(), *, parcels, seed=1, pass_index=0,
          stats=None, settings=TrackSettings(), table=None, superbatches=None,
          keep_states=False):
    """Run one Lagrangian pass; returns a :class:`Sample`.

    mesh : rans.PipeMesh;  gas : rans.GasField (converged);  spec : ParticleSpec;
    physics : PhysicsOptions (compile-time switches);  parcels : parcels in this pass;
    seed, pass_index : random-stream key (every pass draws fresh noise);
    stats : (ncell, NCS) cell statistics of the previous pass for inter-particle collisions
    (None: no collisions in this pass);  table : a prebuilt FieldTable (else built from gas);
    superbatches : indices of the super-batches to run (None: all; for distributed runs);
    keep_states : keep the final parcel states (parcels, kernel.NSTATE) in ``Sample.states``.

    The pieces (:func:`prepare_pass`, :func:`run_superbatch`, :func:`fold_superbatches`,
    :func:`make_sample`) are what a distributed tracker (eulag.distributed) runs remotely.
    """
    import time

    t0 = time.perf_counter()
    inputs = prepare_pass(mesh, gas, spec, physics, parcels=parcels, seed=seed, pass_index=pass_index,
                          stats=stats, settings=settings, table=table)
    chosen = range(inputs.superbatches) if superbatches is None else superbatches
    kept = []

    def results():  # one super-batch in memory at a time
        for isb in chosen:
            r = run_superbatch(inputs, isb, keep_states)
            if keep_states:
                kept.append(r[3])
            yield r

    totals, squares, cross = fold_superbatches(inputs, results())
    states = np.concatenate(kept) if keep_states else None
    return make_sample(mesh, spec, inputs, totals, squares, cross,
                       wall_time=time.perf_counter() - t0, states=states)
