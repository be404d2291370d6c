"""Index constants shared by the tracking kernel and its Python wrapper.

The kernel writes every per-batch result into one flat float64 vector (see ``Layout``):

    [ cell accumulators (ncell × NACC) | wall-face accumulators (nx·nt × NWALL)
      | impact-angle histogram (N_ANGLE_BINS) | impact-speed histogram (N_SPEED_BINS)
      | parcel budget (NBUD) | counters (NCNT) ]

so a batch is folded into its super-batch totals by one loop (sum, sum of squares, and the
cross product with the mass weight for the ratio statistics).
"""

from __future__ import annotations

from dataclasses import dataclass

# ---------------------------------------------------------------- cell accumulators
# Sums over trajectory segments in the cell; Ṅ = parcel number rate [1/s], m = particle
# mass [kg], δt = segment duration [s], δx = segment chord [m], J = fluid impulse [kg m/s].
A_WN = 0  # Σ Ṅ δt                   [1]          → number in cell (÷ V: number density)
A_WM = 1  # Σ Ṅ m δt                 [kg]         → mass in cell (÷ V: concentration)
A_MU = 2  # 2..4  Σ Ṅ m δx_i         [kg m/s]     → mass flux · V; ÷ A_WM: mean velocity
A_MUU = 5  # 5..7 Σ Ṅ m δt u_i²      [kg m2/s2]   → rms velocity
A_J = 8  # 8..10  Σ Ṅ J_i            [N]          → minus the momentum source · V
A_SK = 11  # Σ Ṅ u′_F · J            [W]          → minus the k source · V
A_NW = 12  # 12..14 Σ Ṅ δt ω_i       [rad]        → mean spin
A_NWW = 15  # 15..17 Σ Ṅ δt ω_i²     [rad/s]      → spin rms
A_VISITS = 18  # segments sampled (unweighted)     → poorly sampled cells
A_KSEEN = 19  # Σ Ṅ δt ½|u′_F|²          [m2/s]      → ÷ A_WN: turbulent energy the particles see
A_BETA = 20  # Σ Ṅ m δt / τ_p            [kg/s]      → ÷ V: drag coefficient β = −∂S/∂U of the source
A_PP = 21  # 21..23 Σ Ṅ m Δu_i of inter-particle collisions in the cell, partner-momentum
#            return included [N] → ÷ V: collision force on the particles [N m-3]
A_PPK = 24  # 24..26 Σ Ṅ m δt a_i, the partner momentum returned as a mean acceleration a
#             (physics.partner_momentum = "returned"; zero otherwise) [N]
A_MUV = 27  # 27..29 Σ Ṅ m δt u_x u_y, u_x u_z, u_y u_z [kg m2/s2] → velocity covariances
#             (physics.partner_covariance = "full"; zero otherwise)
NACC = 30

# Parity of each cell accumulator under the mirror z → −z of the section (+1 even, −1 odd):
# velocities, impulses and forces are polar vectors (z component odd), spins axial vectors
# (x and y components odd), everything else a scalar (particles.symmetry).
ACC_PARITY = (1, 1, 1, 1, -1, 1, 1, 1, 1, 1, -1, 1, -1, -1, 1, 1, 1, 1, 1, 1, 1,
              1, 1, -1, 1, 1, -1, 1, -1, -1)

# ---------------------------------------------------------------- wall faces (x, theta)
W_COUNT = 0  # Σ Ṅ over impacts             [1/s]
W_ANGLE = 1  # Σ Ṅ α  (nominal impact angle) [deg/s]
W_SPEED = 2  # Σ Ṅ |v| (impact speed)        [m/s2]
NWALL = 3

N_ANGLE_BINS = 90  # 1° bins on [0°, 90°]
N_SPEED_BINS = 60  # on [0, speed_max], the last bin also holds faster impacts

# ---------------------------------------------------------------- parcel budget (rate-weighted)
B_MOM_IN = 0  # 0..2 Σ Ṅ m u at injection                   [N]
B_MOM_OUT = 3  # 3..5 Σ Ṅ m u at the outlet (or when stopped) [N]
B_WEIGHT = 6  # 6..8 Σ Ṅ m g′ t_res (net weight impulse rate) [N]
B_WALL = 9  # 9..11 Σ Ṅ m Δu of wall collisions              [N]
B_PP = 12  # 12..14 Σ Ṅ m Δu of inter-particle collisions   [N]
B_INLET = 15  # 15..17 Σ Ṅ m Δu of reflections at the inlet plane [N]
B_J = 18  # 18..20 Σ Ṅ J (the fluid impulse, all steps)       [N]
B_MASS_IN = 21  # Σ Ṅ m injected                               [kg/s]
B_MASS_OUT = 22  # Σ Ṅ m through the outlet                    [kg/s]
B_MASS_STUCK = 23  # Σ Ṅ m stopped by the residence cap        [kg/s]
B_RESIDENCE = 24  # Σ Ṅ m t_res                                 [kg]
NBUD = 25

# ---------------------------------------------------------------- counters (parcels, events)
C_INJECTED = 0
C_EXITED = 1
C_STUCK = 2
C_LOST = 3
C_STEPS = 4
C_REBOUNDS = 5
C_SLIDING = 6
C_ROLLING = 7
C_PP = 8
C_INLET = 9
C_VARIANT = 10  # the option set the kernel was compiled for (kernel.tracker_variant), per batch
NCNT = 11

# ---------------------------------------------------------------- cell statistics for collisions
CS_N = 0  # number density [1/m3]
CS_F = 1  # mean collision frequency [1/s] (step limit)
CS_U = 2  # 2..4 mean velocity [m/s]
CS_RMS = 5  # 5..7 rms velocity [m/s]
CS_WM = 8  # 8..10 mean spin [rad/s]
CS_WRMS = 11  # 11..13 spin rms [rad/s]
CS_OK = 14  # 1 if the cell is sampled well enough for collisions
CS_ST = 15  # Stokes number tau_p/T_L of the cell (cell-mean slip, cell-centre k and eps) [-]
CS_APP = 16  # 16..18 acceleration returning the partners' momentum to the cell's particles [m s-2]
CS_COV = 19  # 19..21 velocity covariances xy, xz, yz [m2 s-2] (physics.partner_covariance = "full")
NCS = 22

# ---------------------------------------------------------------- runtime parameters
P_RHO_F = 0  # gas density [kg/m3]
P_MU = 1  # gas viscosity [Pa s]
P_RHO_P = 2  # particle density [kg/m3]
P_DP = 3  # particle diameter [m]
P_NDOT = 4  # number rate per parcel [1/s]
P_U0 = 5  # mean axial injection velocity [m/s]
P_INJ_RMS = 6  # injection velocity rms per component [m/s]
P_GRAV = 7  # reduced gravity g (1 − ρ_F/ρ_p) [m/s2] (acts along −y)
P_DGAMMA = 8  # wall roughness std [rad]
P_VMIN = 9  # minimum rebound speed [m/s]
P_STEP = 10  # time-step factor c [-]
P_TCAP = 11  # residence-time cap [s]
P_MAXSTEPS = 12  # step cap per parcel [-]
P_SPEEDMAX = 13  # upper end of the impact-speed histogram [m/s]
P_MIN_VISITS = 14  # samples a cell needs for collision statistics [-]
P_WINDOW = 15  # stations per window of the tracking sweep (0: all; kernel.track_parcels) [-]
NPRM = 16

# parcel status codes (STYLE.md: integer codes, counted by the driver)
S_ACTIVE = 0
S_EXITED = 1
S_STUCK = 2
S_LOST = 3


@dataclass(frozen=True)
class Layout:
    """Offsets of the parts of the flat per-batch result vector."""

    ncell: int
    nwall: int

    @property
    def acc(self):
        return 0

    @property
    def wall(self):
        return self.ncell * NACC

    @property
    def angle(self):
        return self.wall + self.nwall * NWALL

    @property
    def speed(self):
        return self.angle + N_ANGLE_BINS

    @property
    def budget(self):
        return self.speed + N_SPEED_BINS

    @property
    def counts(self):
        return self.budget + NBUD

    @property
    def size(self):
        return self.counts + NCNT
