"""The four-way coupling loop (Laín & Sommerfeld): gas ⇄ Lagrangian passes.

    case = Case.from_toml("cases/tsuji_morikawa_200um.toml")
    for state in CouplingLoop(case):          # one PassState per Lagrangian pass
        print(state.index, state.residual)
    ds = eulag.runs.run(case, "out.nc")        # the whole run, written and returned

Cycle (the reference paper's):

1. the gas without particles, converged (single-phase reference: k₀, −dp/dx₀);
2. a first Lagrangian pass without inter-particle collisions (no cell statistics yet);
3. then alternately: gas solve with the relaxed sources S_used = (1 − α) S_used + α S_pass
   (α = ``numerics.relaxation``; halved automatically, down to 0.05, if a gas solve fails or
   if the residual stagnates above the tolerance, see below), and a Lagrangian pass in the new
   gas field with the cell statistics of the earlier passes.  The cell statistics the
   inter-particle collisions use (number density, rms velocity and spin, collision frequency)
   are relaxed with ``numerics.relaxation`` (not with a lowered α; the mean velocity and spin
   with weight at least STATISTICS_MEAN_WEIGHT = 0.5; those of the collision-free first pass
   are replaced, not blended, by the second pass's): statistics taken from one pass
   alone feed back with a negative gain (dense cell → many collisions → the particles spread →
   few collisions next pass …), which for 50 µm particles at η = 2.2 made the loop oscillate
   between two states; statistics relaxed with a lowered α stay stale and inject momentum
   (``CouplingLoop.statistics_weight``).
   What is relaxed are the momentum source and S_k (its sinks as the rate S_k/k, below); the
   dissipation source C_ε3 (ε/k) S_k is formed inside the gas solve from the relaxed S_k and
   the iterate's ε/k (``rans.Sources.c_eps3``), so that it follows the turbulence it acts on.

Linearised drag: a pass also samples β = (1/V) Σ Ṅ m δt/τ_p, the drag coefficient by which
its momentum source falls as the gas velocity rises (−∂S/∂U at fixed particle velocities).
The pass's part of the blend is applied linearised about the gas U_ref it was sampled in:
S(U) = (1 − α) S_prev + α [S_pass + w β (U_ref − U)], −w α β U implicitly (``rans.Sources.drag``;
w = ``numerics.drag_implicit_weight``, default 1, so θ = w α below);
after the solve the source as applied in the new gas field is what is kept (and blended
next).  An explicit source whose β is many times the gas's own cross-section transport
coefficients (the dense bottom layer at η = 30: up to 58×; the 0.3 m pipe at Re = 10⁶: 17×;
the base case: 0.3×, measured on the converged datasets) brakes the gas with the slip of the
last pass and overshoots (reversed flow in the bottom wall cell at η = 30 and α = 0.3;
−dp/dx of 77, 84, −156, 14 Pa/m in the first passes of scene f).  Why α β and not the
relaxed β (model of one mode: gas U = U* + g S, pass S_pass = −F − β_eff (U − U*), β_eff ≤ β
as the particles follow the gas): with β_used = θ β the contraction per pass is
[1 − α + g β (θ − α β_eff/β)]/(1 + g θ β).  Short modes, where β_eff ≈ β (the stiff ones),
contract by (1 − α)/(1 + α g β) at θ = α, and the explicit θ = 0 diverges once α (1 + g β) > 2;
long modes, where the particles follow the gas (β_eff ≪ β), contract by 1 − α β_eff/θβ as
g β grows, so the fully relaxed β (θ = 1) holds them near 1 (scene f at θ = 1: −dp/dx rising
by ~3 Pa/m per pass from 24.4 Pa/m, below its single-phase 48).  Where the iteration has
converged, U = U_ref and the applied source is the relaxed one: the fixed point is that of the
explicit source.  ``LINEARISED_DRAG = False`` restores the explicit source.

Stagnation: when the residual has stayed above the tolerance for ``2 W`` passes (W = 4) since
the start or the last change of α, and the best residual of the last W passes is not at least
10 % below the best of the W before, α is halved (not below 0.05) — unless the section-mean
−dp/dx of those 2 W passes drifts steadily (trend above 3 standard errors, and more than 1 %
still to come at this α: ``steady_drift``); then the residual measures the approach as much as
the noise, and a halved α would only halve its pace (a 50 µm scene halved at passes 10 and 18
while −dp/dx rose by 4–8 Pa/m per pass stayed unconverged after 40 passes).  The halving lowers the
pass-to-pass noise the lagged fields carry into the next pass (it is what kept the residual of
such cases at about 2) and damps an oscillating mode; each change is in the history
(``relaxation``) and in the progress line.

Recovery: when the last W residuals since the last change of α are all below the tolerance
(the changes are noise) but the loop has not converged (the pressure gradient, the mass balance
or the collision momentum still drifts, or the gas solve did not converge), α is doubled again,
up to the case's α and never above an α whose gas solve failed; once only (a recovered α that
stagnates again is halved for good), and not when fewer than W early passes are left (the
averaged final passes would run at an α the loop has not judged).  At a small α
the relaxed sources close only about α of their remaining gap per pass: η = 10 and the 0.3 m
pipe, halved to 0.075 when their residual sat just above the tolerance, reached the residual
of pure noise but still had 2.3 % and 1.3 % of −dp/dx to come after 40 passes; with the rule
the pipe converged in 35 passes.  The residual is not independent of α (the pass's sources
respond to the noise the relaxed sources put into the gas): η = 10 at the recovered 0.15 rose
to ~2 again (docs/history.md).

Convergence ("no longer changing beyond noise"): per cell the change of the relaxed sources,
ΔS = α (S_pass − S_used_prev), is compared with its own statistical noise
α · se(S_pass) · sqrt(2/(2 − α)) (se from the batch spread; the relaxed history adds the
sqrt term), with a floor of 1 % of the RMS source for poorly sampled cells (and, with
``numerics.residual_noise = "batch-visits"``, of α sqrt(2/(2 − α)) |S_used| / sqrt(n + 1), the
sampling noise of a cell visited n times in the pass); the residual of a
pass is the RMS of these ratios over the cells and the momentum and k sources (≈ 1 once the
changes are pure noise).  Converged when the residual is below ``numerics.coupling_tolerance``
and, over the last three passes, the section-mean pressure gradient changed so little that
the drift still to come of the relaxed iteration (least-squares change per pass over the last
four values × (1 − α)/α, α the smallest of those four passes', or × r/(1 − r) where the eight
last passes show a slower contraction r, ``_geometric_ahead``; where the last sixteen passes show
a swing that has turned, at least its range, ``_swing_range``, and a trend that is not slowing
down counts as unbounded only without such a swing) is below 1 %
and the particle mass balance (in = out + stuck) closes within 1 %, and the net momentum the
stochastic inter-particle collisions gave the particles has settled (its change still to come,
from its trend, below 2 % of their momentum inflow; ``collision_momentum_settled``).  Then ``average_passes``
final passes with ``numerics.parcels`` parcels give the reported statistics (their average);
the earlier passes use ``numerics.parcels_start``.  One-way coupling solves the gas once and
runs the final passes only.

Stop on the collision model's momentum error: when the net axial momentum the stochastic
collisions gave the particles is beyond ±COLLISION_MOMENTUM_LIMIT (0.5) of their momentum
inflow, with one sign, in three early passes in a row (``collision_momentum_excessive``; the
final passes of a loop that has converged are not judged again), the loop stops with a
CouplingError saying so: that momentum is the fictitious-partner model's error (real
collisions conserve it) and it then drives the gas (the 1 µm tracers: +1.1 to +1.9 of the
inflow in passes 4-8, −dp/dx falling from 51 to 19 Pa/m).

Checkpoint: after every pass the whole loop state is written atomically to ``checkpoint``
(``out.nc.checkpoint``); ``CouplingLoop(case, checkpoint=..., resume=True)`` continues from the
last complete pass and ends with the same numbers as an uninterrupted run (the random streams
are keyed by the pass index; the gas solve is deterministic).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np

import particles
import rans
from particles.layout import CS_APP, CS_COV, CS_ST, NCS
from particles.stream import StreamedPass, StreamOvershoot
from collisions import InterparticleOptions, WallOptions
from eulag.files import savez_atomic

__all__ = ["CouplingLoop", "PassState", "CouplingError", "Criterion", "CRITERIA", "convergence_criteria", "physics_options", "particle_spec",
           "build_mesh", "CHECKPOINT_VERSION"]

CHECKPOINT_VERSION = 3
MIN_RELAXATION = 0.05
_STAGNATION_WINDOW = 4  # passes (W in the module docstring)
_STAGNATION_GAIN = 0.9  # the best residual must fall below this fraction of the previous best
_FLOOR = 0.01  # noise floor of the residual, as a fraction of the RMS source
_INTEGRAL_TOL = 0.01  # pressure gradient and mass balance, relative
_INTEGRAL_PASSES = 3
#: Change still to come of the net axial momentum the stochastic collisions give the particles,
#: / their momentum inflow, below which the loop may call itself converged: the least-squares
#: trend per pass over the last COLLISION_MOMENTUM_PASSES passes times COLLISION_MOMENTUM_AHEAD
#: (the statistics close at least a tenth of their gap to the particles per pass while
#: f_coll τ_p ≤ 9).  Numerical choices of ours, not model constants.  The level itself need
#: not vanish and is reported, not required to be small — up to
#: COLLISION_MOMENTUM_LIMIT, beyond which the loop stops (below).
COLLISION_MOMENTUM_TOL = 0.02
#: |net collision momentum| / inflow that, in each of COLLISION_MOMENTUM_LIMIT_PASSES passes
#: in a row (from the third pass on), stops the loop: an error of that size drives the gas
#: (the 1 µm tracers: +1.1 to +1.9 of the inflow, −dp/dx 51 → 19 Pa/m; Δγ = 20°: −0.7 to −1.6;
#: the largest level of any finished run: +0.22 at eta = 30).  A numerical guard of ours, not
#: a model constant.
COLLISION_MOMENTUM_LIMIT = 0.5
COLLISION_MOMENTUM_LIMIT_PASSES = 3
COLLISION_MOMENTUM_PASSES = 6
COLLISION_MOMENTUM_AHEAD = 10.0
#: With the partners' impulse returned (physics.partner_momentum = "returned") the level must
#: vanish as well: the net collision momentum / inflow of the last COLLISION_BALANCE_PASSES
#: passes, their mean and their trend line's present value, within 3 standard errors of zero
#: (``collision_momentum_balance``).  The returned
#: acceleration is an integral controller, and the loop swings about the balance while the
#: partners' impulse drifts with the developing flow (the base case with the gain α of
#: RETURNED_GAIN = 1: −0.083 of the inflow at pass 10, +0.017 at pass 30, within ±0.004
#: from pass 51); the trend criterion alone is met at a turning point of the swing (pass 13,
#: −dp/dx 67.8 Pa/m against the 63.3 it settles at).  A numerical choice of ours.
COLLISION_BALANCE_PASSES = 10
#: Weight of the newest pass in the collision statistics' mean velocity and spin (at least;
#: the rest of the statistics take the case's α): a numerical choice.
STATISTICS_MEAN_WEIGHT = 0.5
#: Passes in the running mean of a cell's number density that the returned partner momentum's
#: integral control divides by (CouplingLoop._next_statistics): long enough that the reference
#: hardly moves with the last passes' noise (which would leave a small net force where a cell's
#: mass and its collision rate per unit mass fluctuate together), short enough to forget the
#: loadings of the first passes (a cell that fills or empties as the flow develops).
STATS_REFERENCE_PASSES = 20
#: Gain of the returned partner momentum's integral control per pass, as a multiple of the
#: loop's relaxation α (so 0.9 at α = 0.3; capped per cell at RETURNED_GAIN_CAP: CouplingLoop._next_statistics).  The
#: partners' net impulse with nothing returned drifts with the developing coupled flow for
#: about 20 passes (base-case proxy, 40 × 10 × 20 cells, 8,000 parcels: from +0.16 of the
#: particles' axial momentum inflow at pass 2 to −0.024 at pass 25), and an integral control
#: lags a drift by about drift / gain: with gain α the net collision momentum fell to −0.08
#: of the inflow (pass 11) and the loop swung about the balance until it converged after pass
#: 48; with 3α after passes 29 and 30 (two seeds; 28 and 30 with a per-cell cap of 1), with
#: gain 2α after 47.  A numerical choice of ours.
RETURNED_GAIN = 3.0
#: Largest base gain (before the n/n_ref factor), whatever α: 0.9, the value at α = 0.3.
#: Above it the per-cell cap would bind on most denser passes and bias the mean net force
#: again (the toy cell of tests/test_symmetry_and_collision_momentum.py at α = 0.5: +0.21).
RETURNED_GAIN_MAX = 0.9
#: Largest gain of one cell's update (CouplingLoop._next_statistics: the base gain times the
#: pass's number density over its reference, so a denser pass takes a larger step): 1.5, so a
#: pass moves a at most half the way beyond its own a_new.  A cap at 1 (a pass never moves a beyond its own a_new)
#: clipped the denser passes of a cell whose mass fluctuates and left a net force (0.15 per
#: pass in the fourfold-fluctuating cell of tests/test_symmetry_and_collision_momentum.py).
RETURNED_GAIN_CAP = 1.5
#: Apply the pass's part of the relaxed momentum source linearised in the gas velocity,
#: α [S_pass + w β (U_ref − U)] (module docstring, "Linearised drag"; w =
#: numerics.drag_implicit_weight); False: the explicit
#: relaxed source.
#: The fixed point is the same either way.
LINEARISED_DRAG = True


def recent_collision_momentum(history) -> float:
    """Mean of the last _INTEGRAL_PASSES recorded values of the collisions' net momentum / the
    particle inflow (NaN when none is recorded: passes resumed from an older checkpoint)."""
    v = np.asarray(history[-_INTEGRAL_PASSES:], dtype=float)
    v = v[np.isfinite(v)]
    return float(np.mean(v)) if v.size else math.nan


def collision_momentum_to_come(history) -> float:
    """The change of the collisions' net momentum / inflow still to come: |least-squares trend
    per pass over the last COLLISION_MOMENTUM_PASSES recorded passes| × COLLISION_MOMENTUM_AHEAD;
    inf while fewer passes are recorded, 0 when none is (passes resumed from an older
    checkpoint).  The first two passes do not count: the first has no collisions and the second
    draws its partners from the first's statistics."""
    v = np.asarray(history[2:], dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0
    if v.size < COLLISION_MOMENTUM_PASSES:
        return math.inf
    v = v[-COLLISION_MOMENTUM_PASSES:]
    trend = np.polyfit(np.arange(v.size, dtype=float), v, 1)[0]
    return float(abs(trend) * COLLISION_MOMENTUM_AHEAD)


def collision_momentum_balance(history) -> float:
    """How far the collisions' net momentum / inflow of the last COLLISION_BALANCE_PASSES
    recorded passes stands from zero, in units of three standard errors: the larger of |their
    mean| and |their least-squares line at the last pass|, each over three of its own standard
    errors (from the scatter about the line).  Below 1 when the net momentum is zero within
    the passes' noise.  Either reading alone is fooled by a swing of the loop: the mean
    vanishes when the window straddles a zero crossing, the line's end where the swing
    crosses zero at the last pass (the base case: passes 28 and 42); both vanish only once
    the swing has died down.  inf while fewer passes are recorded (the first two do not count,
    as in ``collision_momentum_to_come``)."""
    v = np.asarray(history[2:], dtype=float)
    v = v[np.isfinite(v)][-COLLISION_BALANCE_PASSES:]
    n = v.size
    if n < max(COLLISION_BALANCE_PASSES, 3):
        return math.inf
    x = np.arange(n, dtype=float)
    line = np.polyfit(x, v, 1)
    scatter = v - np.polyval(line, x)
    s = math.sqrt(float(np.sum(scatter * scatter)) / (n - 2))
    end = abs(float(np.polyval(line, x[-1])))
    mean = abs(float(np.mean(v)))
    se_mean = s / math.sqrt(n)
    se_end = s * math.sqrt(1.0 / n + (x[-1] - x.mean()) ** 2 / float(np.sum((x - x.mean()) ** 2)))
    if s == 0.0:
        return 0.0 if mean == 0.0 and end == 0.0 else math.inf
    return max(mean / (3.0 * se_mean), end / (3.0 * se_end))


def pressure_gradient_to_come(history, relaxation) -> tuple[float, float, float]:
    """(trend [Pa/m per pass], change still to come / last value, relaxation used) of the
    section-mean pressure gradient over the last ``_INTEGRAL_PASSES + 1`` passes of ``history``,
    ``relaxation`` the α of each pass (the same length).

    A relaxed iteration still moving by d per pass has about d (1 - alpha)/alpha to go; d is the
    least-squares trend over the last passes (the sampled sources make the pressure gradient
    scatter from pass to pass; the trend is what is still to come), alpha the smallest of those
    passes' (a trend measured at a small α, just before it was raised, is a slow approach to
    the same gap)."""
    dp = np.asarray(history[-(_INTEGRAL_PASSES + 1):], dtype=float)
    alpha = float(np.min(np.asarray(relaxation, dtype=float)[-(_INTEGRAL_PASSES + 1):]))
    trend = float(np.polyfit(np.arange(dp.size, dtype=float), dp, 1)[0])
    relaxed = abs(trend) * max(1.0, (1.0 - alpha) / alpha)
    slow = _geometric_ahead(history, relaxation)
    drift = relaxed if slow is None else max(relaxed, abs(trend) * slow)
    swing = _swing_range(history)
    if swing is not None:  # a turned swing: its range, not an unbounded creep
        drift = max(swing, relaxed if math.isinf(drift) else drift)
    last = abs(float(dp[-1]))
    if not math.isfinite(drift):
        return trend, math.inf, alpha
    return trend, drift / last if last > 0.0 else (math.inf if drift > 0.0 else 0.0), alpha


def _geometric_ahead(history, relaxation, w=_INTEGRAL_PASSES + 1):
    """Passes' worth of the present trend still to come, r/(1 − r), from the contraction r
    per pass the last 2w values show, or None where they do not show one.

    (1 − α)/α assumes the relaxed iteration closes α of its gap per pass; a mode that the
    particles follow closes less (the linearised drag, module docstring), and a run whose
    −dp/dx creeps by 0.3 % per pass with r = 0.97 still has 10 % to come, where (1 − α)/α
    would say 0.7 %.  The least-squares trends s_a, s_b of the two windows of w passes (at one
    α) give r = (s_b/s_a)^(1/w) when s_a stands above the noise (3 standard errors, from the
    scatter about both fits) and s_b has its sign; a trend that is not falling (s_b ≥ s_a)
    gives inf; otherwise (noise, an oscillation, α changed) None."""
    h = np.asarray(history[-2 * w:], dtype=float)
    rel = np.asarray(relaxation[-2 * w:], dtype=float)
    if h.size < 2 * w or not np.all(np.isfinite(h)) or np.ptp(rel) > 0.0:
        return None
    x = np.arange(w, dtype=float)
    fa, fb = np.polyfit(x, h[:w], 1), np.polyfit(x, h[w:], 1)
    scatter = np.sum((h[:w] - np.polyval(fa, x)) ** 2) + np.sum((h[w:] - np.polyval(fb, x)) ** 2)
    se = math.sqrt(scatter / (2 * w - 4) / np.sum((x - x.mean()) ** 2))
    sa, sb = float(fa[0]), float(fb[0])
    if not abs(sa) > 3.0 * se or sa * sb <= 0.0:
        return None
    q = sb / sa
    if q >= 1.0:
        return math.inf
    r = q ** (1.0 / w)
    return r / (1.0 - r)


def _swing_range(history, w=_INTEGRAL_PASSES + 1):
    """The peak-to-peak range of the last 4w values of ``history`` where they show a swing
    that has turned, else None.

    ``_geometric_ahead`` reads a trend that is not slowing down as unbounded; that is right
    for a creep, but not at the turn of a slow oscillation about the converged state, whose
    trend steepens after the turn (scene a: -dp/dx 63.58, 63.31, 63.59, 63.31 Pa/m at passes
    18, 22, 31, 38, period ~18 passes, 0.44 % peak to peak, read as "inf" for ten passes).
    And the trend alone is flat at a swing's extreme, where a large swing would pass.
    A swing: of the least-squares trends of the four quarters of the last 4w values (w each),
    two stand above 3 standard errors (pooled from the scatter about the four fits) with
    opposite signs.  The change still to come is then taken as at least the range the swing
    covers: a swing that does not grow stays within it, a growing one is caught once its range
    exceeds the tolerance."""
    h = np.asarray(history[-4 * w:], dtype=float)
    if h.size < 4 * w or not np.all(np.isfinite(h)):
        return None
    x = np.arange(w, dtype=float)
    fits = [np.polyfit(x, h[i * w:(i + 1) * w], 1) for i in range(4)]
    scatter = sum(float(np.sum((h[i * w:(i + 1) * w] - np.polyval(f, x)) ** 2)) for i, f in enumerate(fits))
    se = math.sqrt(scatter / (4 * w - 8) / np.sum((x - x.mean()) ** 2))
    slopes = [float(f[0]) for f in fits if abs(float(f[0])) > 3.0 * se]
    if not (any(s > 0.0 for s in slopes) and any(s < 0.0 for s in slopes)):
        return None
    return float(np.ptp(h))


def steady_drift(history, relaxation, n=2 * _STAGNATION_WINDOW):
    """The least-squares trend [Pa/m per pass] of the last ``n`` section-mean pressure
    gradients in ``history`` (passes at one α = ``relaxation``) where it is a drift that
    matters, else None: the trend stands above 3 standard errors of the scatter about the
    line and the change still to come at this α, trend × (1 − α)/α, is above the loop's
    tolerance on −dp/dx (1 % of its last value).

    While the relaxed iteration follows such a drift, the residual measures the drift as
    much as the noise, and halving α would halve the pace of the approach (module docstring,
    "Stagnation")."""
    h = np.asarray(history[-n:], dtype=float)
    if h.size < n or n < 4 or not np.all(np.isfinite(h)):
        return None
    x = np.arange(n, dtype=float)
    fit = np.polyfit(x, h, 1)
    se = math.sqrt(np.sum((h - np.polyval(fit, x)) ** 2) / (n - 2) / np.sum((x - x.mean()) ** 2))
    trend = float(fit[0])
    ahead = abs(trend) * (1.0 - relaxation) / relaxation
    if abs(trend) > 3.0 * se and ahead > _INTEGRAL_TOL * abs(float(h[-1])):
        return trend
    return None


def collision_momentum_excessive(history) -> float | None:
    """The mean net collision momentum / inflow of the last COLLISION_MOMENTUM_LIMIT_PASSES
    passes when every one of them is beyond +COLLISION_MOMENTUM_LIMIT, or every one beyond
    −COLLISION_MOMENTUM_LIMIT, else None (an error of one sign is what drives the gas; the
    first two passes do not count, as in ``collision_momentum_to_come``)."""
    v = np.asarray(history[2:], dtype=float)[-COLLISION_MOMENTUM_LIMIT_PASSES:]
    if v.size < COLLISION_MOMENTUM_LIMIT_PASSES or not (np.all(v > COLLISION_MOMENTUM_LIMIT)
                                                        or np.all(v < -COLLISION_MOMENTUM_LIMIT)):
        return None
    return float(np.mean(v))


def collision_momentum_settled(history) -> bool:
    """Whether the stochastic collisions' net momentum (per pass, / the particle inflow) has
    settled: less than COLLISION_MOMENTUM_TOL of change still to come.  The fictitious partners
    are drawn from the previous passes' cell statistics, which approach the particles by only
    1/(1 + f_coll τ_p) of the gap per pass; until then they inject momentum that the sources
    and the pressure gradient may not yet show."""
    return collision_momentum_to_come(history) < COLLISION_MOMENTUM_TOL


@dataclass(frozen=True)
class Criterion:
    """One convergence criterion of the loop as judged after a pass: ``value`` must be below
    ``threshold`` (``met``); ``what`` says in words what is compared."""

    name: str
    value: float
    threshold: float
    met: bool
    what: str

    def line(self) -> str:
        rel = "<" if self.value < self.threshold else ">="
        return f"{self.name} {self.value:.3g} {rel} {self.threshold:g} ({self.what})"


#: The criteria in the order the loop judges them (``convergence_criteria``).
CRITERIA = ("gas_solve", "residual", "pressure_gradient_to_come", "mass_balance", "collision_momentum_to_come",
            "collision_momentum_balance")


def convergence_criteria(history, gas_converged, tolerance, collisions=True, returned=False) -> list[Criterion]:
    """Each convergence criterion of the coupling loop after the last pass of ``history``
    (a ``_History``), with its value and threshold (module docstring, "Convergence").

    gas_converged : whether the last gas solve converged; tolerance : numerics.coupling_tolerance;
    collisions : whether inter-particle collisions run (else their momentum is not judged);
    returned : whether the partners' impulse is returned (physics.partner_momentum), which adds
    the criterion that the net collision momentum vanish (``collision_momentum_balance``).
    The loop has converged when every criterion is met."""
    h = history
    crit = [Criterion("gas_solve", 0.0 if gas_converged else 1.0, 0.5, bool(gas_converged),
                      "stations of the last gas solve not converged: 0 = none")]
    res = float(h.residual[-1]) if h.residual else math.nan
    enough = len(h.residual) >= _INTEGRAL_PASSES + 1
    crit.append(Criterion("residual", res if math.isfinite(res) else math.inf, tolerance,
                          bool(enough and res < tolerance),
                          "RMS change of the relaxed sources over their noise"
                          + ("" if enough else f"; judged from pass {_INTEGRAL_PASSES + 1} on, "
                             f"this was pass {len(h.residual)}")))
    if len(h.pressure_gradient) >= 2:
        ahead = pressure_gradient_to_come(h.pressure_gradient, h.relaxation)[1]
    else:
        ahead = math.inf
    crit.append(Criterion("pressure_gradient_to_come", ahead, _INTEGRAL_TOL, bool(ahead < _INTEGRAL_TOL),
                          "change of -dp/dx still to come / -dp/dx"))
    mb = max(h.mass_balance[-_INTEGRAL_PASSES:]) if h.mass_balance else math.inf
    crit.append(Criterion("mass_balance", mb, _INTEGRAL_TOL, bool(mb < _INTEGRAL_TOL),
                          f"|in - out| / in (particle mass not delivered to the outlet: parcels stuck at the "
                          f"residence-time cap), largest of the last {_INTEGRAL_PASSES} passes"))
    if collisions:
        cm = collision_momentum_to_come(h.collision_momentum)
        crit.append(Criterion("collision_momentum_to_come", cm, COLLISION_MOMENTUM_TOL,
                              bool(cm < COLLISION_MOMENTUM_TOL),
                              "change still to come of the collisions' net momentum / inflow"))
        if returned:
            cb = collision_momentum_balance(h.collision_momentum)
            crit.append(Criterion("collision_momentum_balance", cb, 1.0, bool(cb < 1.0),
                                  f"net collision momentum / inflow of the last {COLLISION_BALANCE_PASSES} passes, "
                                  "mean and trend at the last pass, over 3 standard errors "
                                  "(partner momentum returned)"))
    return crit


class CouplingError(RuntimeError):
    """The coupling loop cannot go on; the message names the pass and the quantity."""


# ---------------------------------------------------------------------------- case → objects
def build_mesh(case):
    n = case.numerics
    return rans.PipeMesh.build(
        diameter=case.pipe.diameter, length=case.pipe.length, mode=case.pipe.mode,
        axial_cells=n.axial_cells, radial_cells=n.radial_cells, azimuthal_cells=n.azimuthal_cells,
        first_cell_yplus=n.first_cell_yplus, bulk_velocity=case.gas.bulk_velocity,
        density=case.gas.density, viscosity=case.gas.viscosity)


def physics_options(case):
    """Compile-time switches of the tracker from the case ([physics], [walls], [particles])."""
    ph, w, p = case.physics, case.walls, case.particles
    return particles.PhysicsOptions(
        saffman_mei_lift=ph.saffman_mei_lift, magnus_lift=ph.magnus_lift, magnus_model=ph.magnus_model,
        rotation=ph.rotation, langevin=ph.langevin, drift_correction=ph.langevin_drift_correction,
        drift_form=ph.langevin_drift_form,
        gravity=ph.gravity, inter_particle_collisions=ph.inter_particle_collisions,
        step_rule=case.numerics.step_rule, partner_correlation=ph.partner_correlation,
        partner_momentum=ph.partner_momentum, wall_cell=ph.wall_cell_fields,
        wall=WallOptions(impact_angle=w.impact_angle, shadow_effect=w.shadow_effect,
                         lateral_roughness=w.lateral_roughness, rotation=ph.rotation),
        interparticle=InterparticleOptions(restitution=p.restitution, friction=p.friction,
                                           rotation=ph.rotation, covariance=ph.partner_covariance))


def particle_spec(case):
    p = case.particles
    return particles.ParticleSpec(diameter=p.diameter, density=p.density, mass_loading=p.mass_loading,
                                  injection_velocity=case.gas.bulk_velocity, injection_rms=p.injection_rms,
                                  roughness_angle_std_deg=case.walls.roughness_angle_std_deg)


def track_settings(case):
    n = case.numerics
    return particles.TrackSettings(step_factor=n.step_factor, batch_size=n.batch_size,
                                   batches_per_superbatch=n.batches_per_superbatch,
                                   residence_cap=n.residence_cap)


# ---------------------------------------------------------------------------- state
@dataclass
class PassState:
    """What the loop reports after each Lagrangian pass (and its gas solve).

    index: pass number (1 = the first Lagrangian pass); parcels; relaxation α used;
    residual (NaN for pass 1); pressure_gradient: section-mean −dp/dx averaged over x [Pa/m];
    phase: "early" | "final", the phase the pass ran in (the pass at which the loop converges
    is early: its parcels are ``parcels_start``); converged: the loop has finished and converged; finished;
    counts: parcel fates of the pass; times: wall-clock seconds of the pass's phases.
    """

    index: int
    parcels: int
    relaxation: float
    residual: float
    pressure_gradient: float
    phase: str
    converged: bool
    finished: bool
    counts: dict
    times: dict


@dataclass
class _History:
    residual: list = field(default_factory=list)
    parcels: list = field(default_factory=list)
    lost: list = field(default_factory=list)
    stuck: list = field(default_factory=list)
    relaxation: list = field(default_factory=list)
    pressure_gradient: list = field(default_factory=list)
    mass_balance: list = field(default_factory=list)
    time_gas: list = field(default_factory=list)
    time_particles: list = field(default_factory=list)
    floored: list = field(default_factory=list)
    gas_relaxation: list = field(default_factory=list)  # implicit k-eps relaxation the gas solve needed
    # net axial momentum the inter-particle collisions gave the particles / their momentum inflow
    collision_momentum: list = field(default_factory=list)
    # each convergence criterion's value after the pass (NaN in the final passes, which are
    # not judged again): convergence_criteria, CRITERIA
    criterion_gas_solve: list = field(default_factory=list)
    criterion_residual: list = field(default_factory=list)
    criterion_pressure_gradient_to_come: list = field(default_factory=list)
    criterion_mass_balance: list = field(default_factory=list)
    criterion_collision_momentum_to_come: list = field(default_factory=list)
    criterion_collision_momentum_balance: list = field(default_factory=list)

    def arrays(self):
        return {k: np.asarray(v, dtype=np.float64) for k, v in self.__dict__.items()}


def read_checkpoint(path):
    """(meta, residual history) of the coupling checkpoint at ``path``; CouplingError if it is
    not a readable eulag checkpoint."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            residual = np.asarray(z["hist_residual"], dtype=float) if "hist_residual" in z.files else np.zeros(0)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is reported the same way
        from eulag.arguments import unreadable_archive_reason

        raise CouplingError(f"{path}: not a readable eulag checkpoint ({unreadable_archive_reason(exc)})") from None
    return meta, residual


def checkpoint_problem(meta, residual, case):
    """Why a checkpoint (its ``meta`` and residual history) cannot be resumed as ``case``; None
    if it can.

    The stored case must be ``case`` (compared as records are: ``config.comparable_attrs``),
    except ``numerics.max_passes``, which a resumed run may change (e.g. raise, when the early
    passes ran out) as long as the passes done are those a run started under the new limit
    would have done: the limit enters only where the loop forces the final passes
    (pass > max_passes − average_passes) and where it forbids raising α again (fewer than W
    early passes left; module docstring, "Recovery").  Neither may have acted differently:
    a limit below the passes done, final passes forced by the old limit, or a pass at which
    only one of the limits forbade the recovery although its residuals would have allowed it
    (the last W all below the tolerance; judged conservatively on the whole history) refuse.
    """
    if meta.get("version") != CHECKPOINT_VERSION:
        return f"checkpoint version {meta.get('version')} is not {CHECKPOINT_VERSION} (an older eulag)"
    stored = dict(meta.get("case") or {})
    mine = json.loads(json.dumps(case.to_attrs(), default=_json_default))
    key = "numerics.max_passes"
    old, new = stored.get(key), mine.get(key)
    stored[key] = new
    if _canonical(stored) != _canonical(mine):
        from eulag.config import case_differences, comparable_attrs

        what = case_differences(comparable_attrs(stored), comparable_attrs(mine), there="in the checkpoint")
        return "checkpoint of a different case" + (f" ({what})" if what else "")
    if old == new or old is None:
        return None
    n = case.numerics
    old, done = int(old), int(meta.get("pass_index", 0))
    what = f"numerics.max_passes changed from {old} to {new}"
    if done > new:
        return f"{what}, but the checkpoint has done {done} passes"
    if meta.get("phase") == "final" and meta.get("converged_at") is None:
        return f"{what}, but the checkpoint's final passes were started by the limit {old}"
    if meta.get("phase") == "final" and done + int(meta.get("final_left", 0)) > new:
        return f"{what}, fewer than the {done + int(meta.get('final_left', 0))} passes its final passes need"
    if meta.get("phase") == "early" and done > new - n.average_passes:
        return f"{what}, which would have started the final passes before pass {done}"
    w, tol = _STAGNATION_WINDOW, n.coupling_tolerance
    r = np.asarray(residual, dtype=float)
    for p in range(1, done + 1):
        if (old - n.average_passes - p >= w) == (new - n.average_passes - p >= w):
            continue
        for end in (p - 1, p):  # the residuals the judgement at pass p saw (before or after it)
            last = r[max(0, end - w):end]
            if last.size == w and np.all(last < tol):
                return (f"{what}, but at pass {p} only one of the limits allowed raising the relaxation "
                        f"again (residuals {last.min():.3g}-{last.max():.3g} below {tol:g})")
    return None


class CouplingLoop:
    """Iterate the coupled solution of ``case``; see the module docstring.

    Parameters
    ----------
    case : eulag.config.Case (with [particles])
    checkpoint : path or None — write the loop state there after every pass
    resume : continue from ``checkpoint`` if it exists (it must belong to the same case)
    parcels : override of numerics.parcels (and parcels_start, if larger)
    progress : callable(PassState) or None, called after every pass
    notify : callable(str) or None, told of what happens inside a pass that the user should
        see before it ends: a gas solve that failed and is retried with more relaxation, α
        halved (or kept while −dp/dx drifts) by the stagnation rule
    tracker : callable with the signature of :func:`particles.track` that runs a Lagrangian
        pass (default: ``particles.track``, local numba threads; e.g. a Dask-distributed one)
    """

    #: the convergence criteria, in the order they are judged (``convergence_criteria``)
    criteria_names = CRITERIA

    def __init__(self, case, *, checkpoint=None, resume=False, parcels=None, progress=None,
                 tracker=None, notify=None, stream=None):
        started = time.perf_counter()
        if case.particles is None:
            raise ValueError("CouplingLoop needs a case with [particles]")
        if parcels is not None:
            case = case.replace(numerics={"parcels": int(parcels),
                                          "parcels_start": min(int(parcels), case.numerics.parcels_start)})
        self.case = case
        self.checkpoint = Path(checkpoint) if checkpoint is not None else None
        self.progress = progress
        self.notify = notify
        self.tracker = particles.track if tracker is None else tracker
        # the next pass tracked beside the gas march that feeds it (particles.stream; the same
        # numbers): by default with the local tracker, in a developing pipe
        self.stream_passes = (tracker is None) if stream is None else bool(stream)
        self._stream = None
        self.streamed = 0  # passes (of this session) whose tracking ran beside a gas solve
        self.mesh = build_mesh(case)
        self.gas_props = rans.GasProperties(density=case.gas.density, viscosity=case.gas.viscosity)
        self.spec = particle_spec(case)
        self.physics = physics_options(case)
        self.settings = track_settings(case)
        self.alpha = case.numerics.relaxation
        self.alpha_changed_at = 0  # pass after which alpha was last changed (stagnation rule)
        self.alpha_cap = self.alpha  # the recovery never goes above an α whose gas solve failed
        self.recovered = False  # α was raised again by the recovery rule (once only)
        self.drift_told_at = -1  # α level (alpha_changed_at) at which a kept α was reported
        self.two_way = case.physics.coupling != "one-way"
        self.history = _History()
        # wall-clock seconds per stage; "total" (the run's whole wall time, over every resumed
        # session) is kept up to date at each checkpoint
        # ("lagrangian_after_gas": the particle time not overlapped by a gas solve, particles.stream)
        self.timings = {"gas_solve": 0.0, "lagrangian": 0.0, "lagrangian_after_gas": 0.0, "checkpoint": 0.0}
        self.pass_index = 0
        self.phase = "early"
        self.final_left = case.numerics.average_passes
        self.converged = False
        self.converged_at = None  # the pass after which every criterion was met
        self.criteria = []  # the criteria as judged after the last early pass (Criterion)
        self.finished = False
        self.gas = None
        self.gas0 = None
        # relaxed, as used: dict momentum (3,...), k, k_ref, eps_ref (the gas the sinks were
        # referred to) and epsilon (C_eps3 (eps/k) S_k as applied in the last gas solve: output only)
        self.sources = None
        self.stats = None
        # per cell: the reference number density of the returned partner momentum's integral
        # control (a running mean of the collisional passes' statistics, STATS_REFERENCE_PASSES)
        # and the number of passes in it
        self.stats_n_ref = None
        self.stats_n_count = None
        self.window = None  # running sums (total, var, cov) of the final passes' samples
        self.window_n = 0
        self.window_batches = 0
        self.window_parcels = 0
        self.final_sources = []  # each final pass's sampled momentum and k sources
        self.replicas = []  # gas (ux, uy, uz) at the first station, solved on each final pass's sources
        self.replica_pressure_gradients = []  # the section-mean -dp/dx(x) of those solves
        self.gas_relaxed = None
        self.gas_field_note = "last relaxed iterate of the coupling loop"
        self.final_solve_failure = None  # why the solve on the final passes' averaged sources failed
        self.replica_failures = []  # "final pass j of n: why", for each final pass whose own solve failed
        self.last_sample = None
        if resume and self.checkpoint is not None and self.checkpoint.exists():
            self._load()
        self._clock = (started, self.timings.get("total", 0.0))  # this session's start, the time before it

    def elapsed(self) -> float:
        """The run's wall time so far [s]: the sessions before a resume and this one."""
        return self._clock[1] + (time.perf_counter() - self._clock[0])

    # ------------------------------------------------------------------ gas
    # implicit under-relaxation of (k, eps) and momentum tried in turn when a periodic gas solve
    # with strong particle sinks fails.  The developing march retries a failing station itself
    # (rans.solver._march_station: the coupled cross-flow step, then k-eps/momentum relaxations
    # down to 0.05/0.3) and the stations upstream of it converge to the same state whatever the
    # relaxation, so a whole new march with more relaxation would mostly repeat those attempts:
    # there, a failed solve goes straight to the halving of the source relaxation α.
    _GAS_RELAXATION = ((1.0, 1.0), (0.7, 1.0), (0.5, 0.7))

    def _solve_gas(self, sources, final=False, residual=math.nan, on_station=None):
        """The gas field with ``sources`` (None: single phase), its wall time and the implicit
        k-ε relaxation it needed (1 unless a first attempt diverged).  ``final``: a solve to
        convergence (periodic mode: not capped at gas_iterations_per_pass), from the last
        iterate; a march station still converging when the usual extension of its iterations
        runs out iterates on (rans.solver.FINAL_STATION_EXTENSION).  ``residual``: the coupling
        residual of ``sources`` (numerics.gas_station_retries, numerics.gas_tolerance_early).
        ``on_station``: the march's station callback (rans.solve), for a streamed pass."""
        n = self.case.numerics
        g = self.case.gas
        initial = self.gas if self.mesh.mode == "periodic" else None
        inner = sources is not None and self.mesh.mode == "periodic" and not final
        near = bool(sources is None or final or self.phase == "final"
                    or (np.isfinite(residual) and residual <= n.coupling_tolerance))
        retries = near or n.gas_station_retries == "always"
        tol = n.gas_tolerance if near or n.gas_tolerance_early is None else n.gas_tolerance_early
        cap = n.gas_iterations_per_pass if inner else n.gas_max_iterations
        t0 = time.perf_counter()
        try:
            relaxations = self._GAS_RELAXATION if self.mesh.mode == "periodic" else self._GAS_RELAXATION[:1]
            for attempt, (tr, mr) in enumerate(relaxations):
                try:
                    field_ = rans.solve(self.mesh, self.gas_props, g.bulk_velocity, g.inlet_k,
                                        g.inlet_epsilon, sources, tol=tol,
                                        max_iterations=cap, initial=initial,
                                        turbulence_relaxation=tr, momentum_relaxation=mr,
                                        require_convergence=not inner, station_retries=retries,
                                        station_extension=(rans.solver.FINAL_STATION_EXTENSION if final
                                                           else rans.solver.STATION_EXTENSION),
                                        on_station=on_station)
                    sr = field_.station_relaxation
                    used = min(tr, float(np.min(sr))) if sr is not None else tr
                    break
                except rans.SolverDivergence as err:
                    if attempt + 1 == len(relaxations):
                        raise
                    self._tell(f"gas solve failed with k-eps/momentum relaxation {tr:g}/{mr:g} "
                               f"({err}); retrying with {relaxations[attempt + 1][0]:g}/"
                               f"{relaxations[attempt + 1][1]:g}")
        finally:
            dt = time.perf_counter() - t0
            self.timings["gas_solve"] += dt
        return field_, dt, used

    def statistics_weight(self):
        """The weight of the newest pass in the relaxed collision statistics: the case's
        relaxation, also after α was lowered for the gas. The statistics only damp the
        dense/sparse alternation of the collision rate; held at a small
        α they stay those of the first passes, and at collision rates far above 1/τ_p the
        stochastic partners drawn from them pull the particles toward stale velocities and
        inject momentum (scene h: +5.9 N against an inflow of 0.8 N at α = 0.075)."""
        return max(self.alpha, self.case.numerics.relaxation)

    def _next_statistics(self, new):
        # the first pass runs without inter-particle collisions (no statistics yet): its
        # statistics only start the second pass, and the first collisional pass's replace them
        # rather than being blended with them (they belong to another model)
        from particles.layout import CS_N, CS_OK

        if self.stats is None or not self.two_way or self.pass_index <= 2:
            self.stats_n_ref = np.where(new[:, CS_OK] > 0, new[:, CS_N], 0.0)
            self.stats_n_count = (new[:, CS_OK] > 0).astype(float)
            return new
        if self.stats_n_ref is None:  # resumed from a checkpoint without them: start from the statistics
            self.stats_n_ref = np.where(self.stats[:, CS_OK] > 0, self.stats[:, CS_N], 0.0)
            self.stats_n_count = (self.stats[:, CS_OK] > 0).astype(float)
        n_ref = np.where(self.stats_n_count > 0, self.stats_n_ref, np.nan)
        ok = new[:, CS_OK] > 0
        self.stats_n_count = self.stats_n_count + ok
        # the mean of the passes so far, then an exponential window of STATS_REFERENCE_PASSES
        lam = np.where(ok, 1.0 / np.minimum(np.maximum(self.stats_n_count, 1.0), STATS_REFERENCE_PASSES), 0.0)
        self.stats_n_ref = np.where(ok, (1.0 - lam) * self.stats_n_ref + lam * new[:, CS_N], self.stats_n_ref)
        return _relax_statistics(self.stats, new, self.statistics_weight(), n_ref)

    def _gas_sources(self, s):
        # S_eps = C_eps3 (eps/k) S_k is evaluated in the solve with the iterate's eps/k
        # (rans.Sources): only S_k is relaxed, so S_eps always follows the present turbulence
        return rans.Sources(momentum=s["momentum"], k=s["k"], epsilon=np.zeros_like(s["k"]),
                            k_reference=s["k_ref"], c_eps3=self.case.physics.c_eps3,
                            drag=s.get("drag"), velocity_reference=s.get("u_ref"))

    # ------------------------------------------------------------------ iteration
    def __iter__(self):
        while not self.finished:
            yield self.step()

    def step(self):
        """Run one Lagrangian pass and the gas solve that follows; returns its PassState."""
        if self.finished:
            raise StopIteration
        try:
            return self._step()
        except BaseException:
            self._drop_stream()
            raise

    # ------------------------------------------------------------------ streamed passes
    def _stream_next(self, m):
        """Pass m + 1, to be tracked beside the gas march of pass m that feeds it
        (particles.StreamedPass), or None where it is not streamed: a tracker other than the
        local one, a one-way or periodic run, no pass m + 1, or fewer than two numba threads
        (the streamed part of a pass takes a thread beside the march, which a run held to one
        thread, e.g. one of several run side by side, does not have).  Its parcel count is the
        one pass m + 1 has unless pass m is the one after which the loop converges (then it is
        dropped)."""
        n = self.case.numerics
        if not (self.stream_passes and self.two_way and self.mesh.mode == "developing"
                and numba.get_num_threads() >= 2):
            return None
        if self.phase == "final":
            if self.final_left <= 1:
                return None
            parcels = n.parcels
        else:
            parcels = n.parcels if m + 1 > n.max_passes - n.average_passes else n.parcels_start
        stats = self.stats if self.physics.inter_particle_collisions else None
        stream = StreamedPass(self.mesh, self.gas_props, self.spec, self.physics, parcels=parcels,
                              seed=n.seed, pass_index=m + 1, stats=stats, settings=self.settings,
                              partner_stokes=self.physics.partner_correlation == "cell")
        stream.key = (m + 1, parcels, stats)
        return stream

    def _streamed_sample(self, m, parcels):
        """The sample of pass m if it was streamed with the inputs it has, else None (also when
        a parcel reached fields the march had not delivered yet: the pass is then tracked again,
        and the passes after it are not streamed)."""
        stream = self._stream
        if stream is None:
            return None
        stats = self.stats if self.physics.inter_particle_collisions else None
        key = stream.key
        if key[0] == m and key[1] == parcels and key[2] is stats:
            try:
                sample = stream.result()  # raises what stopped it (e.g. a streamed gas unlike the solve's)
            except StreamOvershoot as err:
                self._stream = None
                self.stream_passes = False
                self._tell(f"pass {m}: {err}; the pass is tracked again in the finished gas field, and the "
                           "passes after it are tracked after their gas solves")
                return None
            self._stream = None
            if stream.gas is not self.gas:  # finish() was given the field this pass runs in
                raise RuntimeError(f"pass {m} was streamed beside the solve of another gas field")
            self.streamed += 1
            return sample
        self._drop_stream(wait=True)
        return None

    def _drop_stream(self, wait=False):
        """Cancel the streamed pass; ``wait``: until its thread has left the kernel (before
        tracking in this thread, so that the two never run at once)."""
        if self._stream is not None:
            self._stream.cancel(wait=wait)
            self._stream = None

    def close(self):
        """Stop a pass still being streamed (a loop left before it finished; ``run`` does this)."""
        self._drop_stream(wait=True)

    def _step(self):
        n = self.case.numerics
        if self.gas0 is None:
            self._stream = self._stream_next(self.pass_index)  # the first pass, beside the single-phase march
            self.gas0, _, _ = self._solve_gas(None, on_station=None if self._stream is None else self._stream.station)
            if not self.gas0.converged:
                raise CouplingError("single-phase gas solve did not converge")
            self.gas = self.gas0
            if self._stream is not None:
                self._stream.finish(self.gas0)
        self.pass_index += 1
        m = self.pass_index
        if not self.two_way:
            self.phase = "final"
        elif self.phase == "early" and m > n.max_passes - n.average_passes:
            self.phase = "final"
        phase_m = self.phase  # the phase this pass runs in (the loop may enter "final" after it)
        parcels_m = n.parcels if self.phase == "final" else n.parcels_start
        stats = self.stats if self.physics.inter_particle_collisions else None
        if stats is not None and self.physics.partner_correlation == "cell":
            # the partners' R(St) with T_L of the gas this pass runs in (the statistics were taken
            # in the previous gas: after the tracers' first pass its turbulence had collapsed)
            stats = stats.copy()
            stats[:, CS_ST] = particles.cell_stokes(stats, self.gas, self.spec)
        t0 = time.perf_counter()
        sample = self._streamed_sample(m, parcels_m)
        if sample is None:
            sample = self.tracker(self.mesh, self.gas, self.spec, self.physics, parcels=parcels_m,
                                  seed=n.seed, pass_index=m, stats=stats, settings=self.settings)
            t_part = time.perf_counter() - t0
        else:  # tracked beside the gas solve of the pass before: its own wall time, of which
            # the part after that solve goes to timings["lagrangian_after_gas"]
            t_part = sample.wall_time
        self.timings["lagrangian_after_gas"] = (self.timings.get("lagrangian_after_gas", 0.0)
                                                + time.perf_counter() - t0)
        if n.mirror_symmetry:
            sample = sample.mirror_symmetrised()
        self.timings["lagrangian"] += t_part
        counts = sample.counts
        if counts["lost"]:
            raise CouplingError(f"pass {m}: {counts['lost']} parcels lost (non-finite state or left "
                                "the pipe through a wall); the tracker must never lose parcels")
        if self.two_way and self.phase == "early":
            self._adapt_relaxation()
        if self.physics.inter_particle_collisions:
            new_stats = sample.cell_statistics(self.gas, min_visits=self.settings.min_visits)
            self.stats = self._next_statistics(new_stats)
        computed = self._computed_sources(sample)
        residual = math.nan
        t_gas = 0.0
        gas_relax = 1.0
        if self.two_way:
            alpha = self.alpha
            while True:
                relaxed, residual = self._relax(computed, sample, alpha)
                self._stream = self._stream_next(m)
                try:
                    gas, t_gas, gas_relax = self._solve_gas(
                        self._gas_sources(relaxed), residual=residual,
                        on_station=None if self._stream is None else self._stream.station)
                    break
                except rans.SolverDivergence as err:
                    self._drop_stream(wait=True)
                    if alpha / 2 < MIN_RELAXATION:
                        raise CouplingError(f"pass {m}: gas solve with the particle sources failed even "
                                            f"with relaxation {alpha:g}: {err}") from None
                    self._tell(f"pass {m}: gas solve with source relaxation {alpha:g} failed ({err}); "
                               f"retrying with {max(MIN_RELAXATION, alpha / 2):g}")
                    alpha = max(MIN_RELAXATION, alpha / 2)
            if alpha != self.alpha:
                self.alpha_changed_at = m - 1
                self.alpha_cap = min(self.alpha_cap, alpha)
            self.alpha = alpha
            if self._stream is not None:
                self._stream.finish(gas)
            applied = self._gas_sources(relaxed)
            relaxed["epsilon"] = applied.applied_epsilon(gas.k, gas.epsilon)
            if "drag" in relaxed:  # the source as applied in the new gas field, which it now refers to
                relaxed["momentum"] = applied.applied_momentum(gas.ux, gas.uy, gas.uz)
                relaxed["u_ref"] = np.stack([gas.ux, gas.uy, gas.uz])
            self.sources = relaxed
            self.gas = gas
        b = sample.budget
        # the mass that did not reach the outlet (parcels stopped by the residence-time cap):
        # in = out + stuck holds by construction (a lost parcel stops the run)
        mass_balance = abs(b["mass_in"] - b["mass_out"]) / b["mass_in"]
        dpdx = float(np.mean(self.gas.pressure_gradient))
        h = self.history
        h.residual.append(residual)
        h.parcels.append(parcels_m)
        h.lost.append(counts["lost"])
        h.stuck.append(counts["stuck"])
        h.relaxation.append(self.alpha if self.two_way else 0.0)
        h.pressure_gradient.append(dpdx)
        h.mass_balance.append(mass_balance)
        h.time_gas.append(t_gas)
        h.time_particles.append(t_part)
        fl = self.gas.floored
        h.floored.append(int(np.sum(fl)) if fl is not None else 0)
        h.gas_relaxation.append(gas_relax)
        h.collision_momentum.append(float(b["particle_collisions"][0] / b["momentum_in"][0])
                                    if b["momentum_in"][0] else math.nan)
        self.last_sample = sample
        excess = collision_momentum_excessive(h.collision_momentum) if self.phase == "early" else None
        if excess is not None:
            raise CouplingError(
                f"pass {m}: the stochastic inter-particle collisions gave the particles {excess:+.3g} of "
                f"their axial momentum inflow (mean of the last {COLLISION_MOMENTUM_LIMIT_PASSES} passes, "
                f"each beyond ±{COLLISION_MOMENTUM_LIMIT:g}, the loop's limit); real collisions conserve "
                "momentum, so this is the fictitious-partner model's error ("
                + ('physics.partner_correlation = "cell" removes the part that comes from R(St) '
                   "varying inside a cell; " if self.case.physics.partner_correlation == "particle" else "")
                + ('physics.partner_momentum = "returned" gives the partners\' impulse back to the cell)'
                   if self.case.physics.partner_momentum == "discarded" else
                   "the partners' impulse is returned to the cell, but the net force it controls has "
                   "not come down yet)"))
        if self.phase == "final":
            self._add_to_window(sample)
            if self.two_way:
                c = self._computed_sources(sample)
                self.final_sources.append({"momentum": c["momentum"], "k": c["k"]})
            self.final_left -= 1
            if self.final_left <= 0:
                self.finished = True
                if self.two_way:
                    self._final_gas_solves()
                self.converged = ((self.converged or not self.two_way) and bool(self.gas.converged)
                                  and self.final_solve_failure is None)
        elif self._converged_now():
            self.converged = True
            self.converged_at = m
            self.phase = "final"
        judged = {c.name: c.value for c in self.criteria} if (self.phase == "early" or m == self.converged_at) else {}
        for name in CRITERIA:  # NaN: not judged (a final pass, or a criterion the case has not)
            getattr(h, "criterion_" + name).append(judged.get(name, math.nan))
        state = PassState(index=m, parcels=parcels_m, relaxation=h.relaxation[-1], residual=residual,
                          pressure_gradient=dpdx, phase=phase_m, converged=self.converged and self.finished,
                          finished=self.finished, counts=counts,
                          times={"gas_solve": t_gas, "lagrangian": t_part})
        if self.checkpoint is not None:
            t0 = time.perf_counter()
            self.timings["total"] = self.elapsed()
            self._save()
            self.timings["checkpoint"] += time.perf_counter() - t0
        if self.progress is not None:
            self.progress(state)
        return state

    def _adapt_relaxation(self):
        """Halve α when the residual has stopped falling; raise it again when the residual has
        come below the tolerance (module docstring, "Stagnation" and "Recovery")."""
        w = _STAGNATION_WINDOW
        r = np.asarray(self.history.residual[self.alpha_changed_at:], dtype=float)
        r = r[np.isfinite(r)]
        n = self.case.numerics
        tol = n.coupling_tolerance
        early_left = n.max_passes - n.average_passes - self.pass_index
        if (r.size >= w and np.all(r[-w:] < tol) and self.alpha < self.alpha_cap
                and not self.recovered and early_left >= w):
            self.alpha = min(self.alpha_cap, 2.0 * self.alpha)
            self.alpha_changed_at = self.pass_index - 1
            self.recovered = True
            self._tell(f"pass {self.pass_index}: the residual is below {tol:g} (last {w} passes "
                       f"{r[-w:].min():.3g}-{r[-w:].max():.3g}) but the loop has not converged; "
                       f"relaxation raised again to {self.alpha:g}")
            return
        if r.size < 2 * w or self.alpha <= MIN_RELAXATION:
            return
        last, before = r[-w:], r[-2 * w:-w]
        if np.all(last >= tol) and last.min() > _STAGNATION_GAIN * before.min():
            dp = self.history.pressure_gradient[self.alpha_changed_at:]
            drift = steady_drift(dp, self.alpha, 2 * w)
            if drift is not None:
                if self.drift_told_at != self.alpha_changed_at:
                    self.drift_told_at = self.alpha_changed_at
                    self._tell(f"pass {self.pass_index}: the residual stays above {tol:g} (last {w} passes "
                               f"{last.min():.3g}-{last.max():.3g}) while -dp/dx drifts steadily "
                               f"({drift:+.3g} Pa/m per pass); relaxation kept at {self.alpha:g}")
                return
            self.alpha = max(MIN_RELAXATION, self.alpha / 2)
            self.alpha_changed_at = self.pass_index - 1
            self._tell(f"pass {self.pass_index}: the residual stagnates above {tol:g} "
                       f"(last {w} passes {last.min():.3g}-{last.max():.3g}); relaxation halved to {self.alpha:g}")

    def _final_gas_solves(self):
        """The gas field of the dataset: one solve with the sources of the averaged final passes
        (the particle statistics of the dataset are that average too), applied as sampled,
        without relaxation; and, for error bars of the section's pattern, one solve on each final
        pass's own sources (``self.replicas``: the gas velocities at the first reported station;
        ``self.replica_pressure_gradients``: the section-mean −dp/dx along the pipe, whose spread
        is the error bar of the averaged solve's −dp/dx, and whose order shows a drift over the
        final passes). The relaxed iterate the loop ended with is kept as ``self.gas_relaxed``.
        Should the solve on the averaged sources fail (their noise, no longer relaxed, can
        reverse the flow over a dense bottom layer), the relaxed iterate stays the dataset's gas
        field and the run is reported as not converged (``final_solve_failure``, stop_reason):
        the passes are not lost."""
        avg = self._computed_sources(self.sample())
        self.gas_relaxed = self.gas

        def solve(src):
            d = {"momentum": src["momentum"], "k": src["k"], "k_ref": self.gas_relaxed.k,
                 "eps_ref": self.gas_relaxed.epsilon}
            field_, _, _ = self._solve_gas(self._gas_sources(d), final=True)
            return field_

        try:
            self.gas = solve(avg)
            self.gas_field_note = "solve on the averaged sources of the final passes"
        except rans.SolverDivergence as err:
            # nothing lost: self.gas stays the relaxed iterate, which the dataset keeps, and the run
            # is reported as not converged, with the reason
            self.final_solve_failure = str(err)
            self.gas_field_note = ("relaxed iterate after the last final pass: the solve on the averaged "
                                   f"sources of the final passes failed ({err})")
            self._tell(f"the gas solve on the averaged sources of the final passes failed ({err}); their sources "
                       "differ more than their relaxation hid (more parcels per final pass or more "
                       "numerics.average_passes average more noise out). The dataset keeps the relaxed "
                       "iterate and reports the run as not converged")
        i = int(np.argmin(np.abs(np.asarray(self.mesh.x) - self.case.pipe.sections[0])))
        self.replicas = []
        self.replica_pressure_gradients = []
        self.replica_failures = []
        for j, src in enumerate(self.final_sources):
            try:
                r = solve(src)
            except rans.SolverDivergence as err:
                # the replica is missing and the error bars rest on the others; said in the
                # dataset (replica_solve_failures) and here
                what = f"final pass {j + 1} of {len(self.final_sources)}: {err}"
                self.replica_failures.append(what)
                self._tell(f"the gas solve on the sources of {what}; that replica is left out of the "
                           "error bars")
                continue
            self.replicas.append(np.stack([np.asarray(r.ux)[i], np.asarray(r.uy)[i], np.asarray(r.uz)[i]]))
            self.replica_pressure_gradients.append(np.asarray(r.pressure_gradient, dtype=float).copy())

    def _tell(self, text):
        if self.notify is not None:
            self.notify(text)

    def _computed_sources(self, sample):
        mom = np.stack([sample.momentum_source(c) for c in range(3)])
        sk = sample.k_source
        se_k = sample.k_source_stderr
        if self.case.physics.k_source_scaling == "seen-energy":
            scale = self._seen_energy_scale(sample)
            sk = sk * scale
            se_k = se_k * scale
        return {"momentum": mom, "k": sk, "drag": sample.drag_coefficient if LINEARISED_DRAG else None,
                "se_momentum": np.stack([sample.momentum_source_stderr(c) for c in range(3)]),
                "se_k": se_k, "visits": sample.visits}

    def _seen_energy_scale(self, sample):
        """k / k_seen per cell (physics.k_source_scaling = "seen-energy"); 1 where the cell is
        poorly sampled (fewer than numerics' min_visits segments)."""
        seen = sample.seen_k
        ok = (sample.visits >= self.settings.min_visits) & np.isfinite(seen) & (seen > 0.0)
        return np.where(ok, self.gas.k / np.where(ok, seen, 1.0), 1.0)

    def _relax(self, comp, sample, alpha):
        """Relaxed sources and the coupling residual of this pass (see the module docstring)."""
        prev = self.sources
        shape = self.mesh.shape
        if prev is None:
            prev = {"momentum": np.zeros((3,) + shape), "k": np.zeros(shape)}
        else:
            # the sinks of k are used as linear sinks, S k/k_ref (rans.Sources): what is
            # relaxed is their rate S/k_ref, so the previous sinks are carried over to the
            # present reference field before they are blended with this pass's
            prev = dict(prev)
            prev["k"] = np.where(prev["k"] < 0.0, prev["k"] * (self.gas.k / prev["k_ref"]), prev["k"])
        # the previous momentum source is already the one applied in the present gas field
        # (step() stores it so); only this pass's part, α S_pass, is linearised (α β_pass)
        new = {"momentum": (1 - alpha) * prev["momentum"] + alpha * comp["momentum"],
               "k": (1 - alpha) * prev["k"] + alpha * comp["k"],
               "k_ref": self.gas.k.copy(), "eps_ref": self.gas.epsilon.copy()}
        if comp.get("drag") is not None:
            new["drag"] = self.case.numerics.drag_implicit_weight * alpha * comp["drag"]
            new["u_ref"] = np.stack([self.gas.ux, self.gas.uy, self.gas.uz])
        residual = math.nan
        if self.sources is not None:
            fac = alpha * math.sqrt(2.0 / (2.0 - alpha))
            visits_floor = self.case.numerics.residual_noise == "batch-visits"
            ratios = []
            for d, se, before in ((new["momentum"] - prev["momentum"], comp["se_momentum"], prev["momentum"]),
                                  (new["k"] - prev["k"], comp["se_k"], prev["k"])):
                scale = np.sqrt(np.mean(new["momentum"] ** 2)) if d.ndim == 4 else np.sqrt(np.mean(new["k"] ** 2))
                noise = np.where(np.isfinite(se), fac * se, 0.0)
                noise = np.maximum(noise, _FLOOR * scale + 1e-300)
                if visits_floor:  # the sampling noise of a source estimated from n visits
                    noise = np.maximum(noise, fac * np.abs(before) / np.sqrt(comp["visits"] + 1.0))
                ratios.append((d / noise).ravel())
            z = np.concatenate(ratios)
            residual = float(np.sqrt(np.mean(z * z)))
        return new, residual

    def _converged_now(self):
        """Judge every criterion after this pass (kept as ``self.criteria``, the verdict a run
        that ends unconverged reports) and return whether all are met."""
        self.criteria = convergence_criteria(self.history, bool(self.gas.converged),
                                             self.case.numerics.coupling_tolerance,
                                             collisions=self.physics.inter_particle_collisions,
                                             returned=self.physics.partner_momentum == "returned")
        return all(c.met for c in self.criteria)

    @property
    def stop_reason(self) -> str:
        """Why the loop stopped (or has not yet): one line for the user and the dataset."""
        if not self.finished:
            return "running"
        if not self.two_way:
            return "one-way coupling: the final passes in the single-phase gas"
        if self.converged:
            return (f"converged after pass {self.converged_at}; then {self.window_n} final passes "
                    "averaged")
        if self.final_solve_failure is not None:
            failed = "; ".join(c.line() for c in self.criteria if not c.met)
            how = (f"the loop converged after pass {self.converged_at}, but" if self.converged_at is not None
                   else f"max_passes = {self.case.numerics.max_passes} was reached ({self._judged_at()}: "
                        f"{failed}), and")
            return (f"not converged: {how} the gas solve on the {self.window_n} final passes' averaged sources "
                    f"failed ({self.final_solve_failure}); the gas field is the relaxed iterate after the "
                    "last final pass")
        if self.converged_at is not None and not self.gas.converged:
            sc = getattr(self.gas, "station_converged", None)
            where = (f" at {int(np.size(sc) - np.count_nonzero(sc))} of {np.size(sc)} stations"
                     if sc is not None else "")
            return (f"not converged: the loop converged after pass {self.converged_at}, but the gas solve on "
                    f"the {self.window_n} final passes' averaged sources did not reach gas_tolerance{where}")
        n = self.case.numerics
        if self.pass_index - self.window_n < 1:
            return (f"not converged: max_passes = {n.max_passes} leaves no early pass to judge convergence "
                    f"after (all {self.window_n} passes were final passes; allowed for a look at the sources, "
                    f"a converged run needs max_passes > average_passes = {n.average_passes})")
        failed = [c.line() for c in self.criteria if not c.met]
        if not failed:
            failed = ["the gas solve of a final pass did not converge"]
        return (f"not converged when max_passes = {n.max_passes} was reached "
                f"({self._judged_at()}): " + "; ".join(failed))

    def _judged_at(self) -> str:
        """Which pass the reported criteria were judged after: the last early pass (the final
        passes that follow it are averaged, not judged)."""
        judged = self.pass_index - self.window_n
        if judged < 1:
            return f"no early pass was judged: all {self.window_n} passes were final passes"
        return f"as judged after pass {judged}, before the {self.window_n} final passes"

    def _add_to_window(self, s):
        if self.window is None:
            self.window = [s.total.copy(), s.var.copy(), s.cov.copy()]
        else:
            self.window[0] += s.total
            self.window[1] += s.var
            self.window[2] += s.cov
        self.window_n += 1
        self.window_batches += s.batches
        self.window_parcels += s.parcels

    # ------------------------------------------------------------------ results
    def sample(self):
        """The averaged sample of the final passes (a particles.Sample)."""
        if not self.window_n:
            raise CouplingError("no final passes yet")
        n = self.window_n
        return particles.Sample(mesh=self.mesh, spec=self.spec, parcels=self.window_parcels,
                                batches=self.window_batches, total=self.window[0] / n,
                                var=self.window[1] / n**2, cov=self.window[2] / n**2, passes=n)

    def run(self):
        try:
            for _ in self:
                pass
        finally:
            self.close()
        return self

    # ------------------------------------------------------------------ checkpoint
    _GAS = ("ux", "uy", "uz", "p", "k", "epsilon", "pressure_gradient", "wall_shear", "residuals",
            "station_iterations")
    #: kept when present (older checkpoints lack them: None, the dataset then leaves them out)
    _GAS_OPTIONAL = ("station_converged", "station_change")

    def _save(self):
        arrays = {}
        for tag, g in (("gas", self.gas), ("gas0", self.gas0)):
            for name in self._GAS:
                arrays[f"{tag}_{name}"] = np.asarray(getattr(g, name))
            if g.face_flux is not None:
                arrays[f"{tag}_face_flux"] = g.face_flux
            for name in self._GAS_OPTIONAL:
                if getattr(g, name) is not None:
                    arrays[f"{tag}_{name}"] = np.asarray(getattr(g, name))
            arrays[f"{tag}_converged"] = np.asarray(bool(g.converged))
        if self.sources is not None:
            for k, v in self.sources.items():
                arrays[f"src_{k}"] = v
        if self.stats is not None:
            arrays["stats"] = self.stats
        if self.stats_n_ref is not None:
            arrays["stats_n_ref"], arrays["stats_n_count"] = self.stats_n_ref, self.stats_n_count
        if self.window is not None:
            for i, v in enumerate(self.window):
                arrays[f"window_{i}"] = v
        for k, v in self.history.arrays().items():
            arrays[f"hist_{k}"] = v
        for i, src in enumerate(self.final_sources):
            arrays[f"final_{i}_momentum"] = src["momentum"]
            arrays[f"final_{i}_k"] = src["k"]
        for i, rep in enumerate(self.replicas):
            arrays[f"replica_{i}"] = rep
        for i, dp in enumerate(self.replica_pressure_gradients):
            arrays[f"replica_dpdx_{i}"] = dp
        meta = {"version": CHECKPOINT_VERSION, "case": self.case.to_attrs(), "pass_index": self.pass_index,
                "phase": self.phase, "final_left": self.final_left, "converged": self.converged,
                "finished": self.finished, "alpha": self.alpha, "alpha_changed_at": self.alpha_changed_at,
                "drift_told_at": self.drift_told_at,
                "alpha_cap": self.alpha_cap, "recovered": self.recovered,
                "converged_at": self.converged_at, "criteria": [c.__dict__ for c in self.criteria],
                "window_n": self.window_n, "gas_field_note": self.gas_field_note,
                "final_solve_failure": self.final_solve_failure,
                "replica_failures": self.replica_failures,
                "window_batches": self.window_batches, "window_parcels": self.window_parcels,
                "timings": self.timings}
        arrays["meta"] = np.frombuffer(json.dumps(meta, default=_json_default).encode(), dtype=np.uint8)
        savez_atomic(self.checkpoint, arrays)

    def _load(self):
        try:
            with np.load(self.checkpoint, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
            meta = json.loads(bytes(data["meta"]).decode())
        except Exception as exc:  # noqa: BLE001 - any unreadable file is reported the same way
            raise CouplingError(f"{self.checkpoint}: not a readable eulag checkpoint ({exc})") from None
        problem = checkpoint_problem(meta, data.get("hist_residual", np.zeros(0)), self.case)
        if problem is not None:
            raise CouplingError(f"{self.checkpoint}: {problem}; remove it or run without --resume")
        old_limit = meta["case"].get("numerics.max_passes")
        if old_limit is not None and int(old_limit) != self.case.numerics.max_passes:
            self._tell(f"resumed after pass {meta['pass_index']} with numerics.max_passes = "
                       f"{self.case.numerics.max_passes} (the checkpoint's was {old_limit}; the passes "
                       "done are the same under either)")
        self.gas = self._gas_from(data, "gas")
        self.gas0 = self._gas_from(data, "gas0")
        if "src_momentum" in data:
            self.sources = {k[4:]: data[k] for k in data if k.startswith("src_")}
        self.stats = data.get("stats")
        self.stats_n_ref, self.stats_n_count = data.get("stats_n_ref"), data.get("stats_n_count")
        if self.stats_n_ref is None and self.stats is not None and self.physics.partner_momentum == "returned":
            self._tell(f"{self.checkpoint}: written before the returned partner momentum kept its reference "
                       "mass per cell; it starts from the checkpoint's statistics, so the passes from here "
                       "differ from those of an uninterrupted run")
        if self.stats is not None:
            if self.stats.shape[1] == CS_ST:  # a checkpoint from before the Stokes-number column
                st = particles.cell_stokes(self.stats, self.gas, self.spec)
                self.stats = np.ascontiguousarray(np.column_stack([self.stats, st]))
            if self.stats.shape[1] == CS_APP:  # ... and before the returned partner momentum:
                # nothing returned yet (partner_momentum = "discarded" never reads the columns)
                pad = np.zeros((self.stats.shape[0], CS_COV - CS_APP))
                self.stats = np.ascontiguousarray(np.column_stack([self.stats, pad]))
            if self.stats.shape[1] == CS_COV:  # ... and before the velocity covariances: none
                # (partner_covariance = "components" never reads them; "full" did not exist)
                pad = np.zeros((self.stats.shape[0], NCS - CS_COV))
                self.stats = np.ascontiguousarray(np.column_stack([self.stats, pad]))
            if self.stats.shape[1] != NCS:
                raise CouplingError(f"{self.checkpoint}: its collision statistics hold {self.stats.shape[1]} "
                                    f"values per cell, this eulag's tracker reads {NCS}; remove it or run "
                                    "without --resume")
        if "window_0" in data:
            from particles.layout import Layout

            self.window = [data["window_0"].copy(), data["window_1"].copy(), data["window_2"].copy()]
            nx, nr, nt = self.mesh.shape
            size = Layout(nx * nr * nt, nx * nt).size
            if self.window[0].size != size:
                raise CouplingError(f"{self.checkpoint}: its averaged passes hold {self.window[0].size} "
                                    f"values per pass, this eulag's tracker writes {size} (a checkpoint "
                                    "of an older version); remove it or run without --resume")
        done = data["hist_residual"].size
        for k in self.history.__dict__:  # a record added since the checkpoint: NaN for its passes
            getattr(self.history, k).extend(data.get(f"hist_{k}", np.full(done, np.nan)).tolist())
        self.history.parcels = [int(v) for v in self.history.parcels]
        self.history.lost = [int(v) for v in self.history.lost]
        self.history.stuck = [int(v) for v in self.history.stuck]
        self.history.floored = [int(v) for v in self.history.floored]
        for k in ("pass_index", "phase", "final_left", "converged", "finished", "alpha",
                  "alpha_changed_at", "window_n",
                  "window_batches", "window_parcels"):
            setattr(self, k, meta[k])
        # checkpoints from before the recovery rule: no recovery (an earlier α may have failed)
        self.alpha_cap = meta.get("alpha_cap", self.alpha)
        self.recovered = meta.get("recovered", False)
        self.converged_at = meta.get("converged_at")
        self.gas_field_note = meta.get("gas_field_note", self.gas_field_note)
        self.final_solve_failure = meta.get("final_solve_failure")
        self.replica_failures = list(meta.get("replica_failures", []))
        i = 0
        while f"final_{i}_momentum" in data:
            self.final_sources.append({"momentum": data[f"final_{i}_momentum"], "k": data[f"final_{i}_k"]})
            i += 1
        i = 0
        while f"replica_{i}" in data:
            self.replicas.append(data[f"replica_{i}"])
            i += 1
        i = 0
        while f"replica_dpdx_{i}" in data:
            self.replica_pressure_gradients.append(data[f"replica_dpdx_{i}"])
            i += 1
        self.criteria = [Criterion(**c) for c in meta.get("criteria", [])]
        self.drift_told_at = meta.get("drift_told_at", -1)
        self.timings.update({k: v for k, v in meta["timings"].items() if k != "compile"})  # (never measured)
        self._tell(f"resuming from {self.checkpoint} after pass {self.pass_index} ({self.phase} passes)")

    def _gas_from(self, data, tag):
        kw = {name: data[f"{tag}_{name}"] for name in self._GAS}
        kw.update({name: data.get(f"{tag}_{name}") for name in self._GAS_OPTIONAL})
        return rans.GasField(mesh=self.mesh, gas=self.gas_props, bulk_velocity=self.case.gas.bulk_velocity,
                             converged=bool(data[f"{tag}_converged"]),
                             face_flux=data.get(f"{tag}_face_flux"), **kw)


def _relax_statistics(old, new, alpha, n_ref=None):
    """Collision statistics blended like the sources: (1 − α) old + α new per cell, the rms
    columns through their variances; a cell sampled in only one of them keeps that one's row.
    The collision frequency is blended linearly (it is close to linear in n and σ).

    The mean velocity and spin take the newest pass with weight max(α, STATISTICS_MEAN_WEIGHT):
    they approach the particles' own by only 1/(1 + f τ_p) of the gap per pass, blending at α
    slowed that further while the partners drawn about stale means inject momentum, but taken
    unblended they joined the dense/sparse alternation of 50 µm scene e.  The velocity
    covariances (``CS_COV``) are blended linearly with the variances' weight, so that the
    blended covariance matrix stays positive semi-definite."""
    from particles.layout import CS_APP, CS_N, CS_OK, CS_RMS, CS_U, CS_WM, CS_WRMS

    both = (old[:, CS_OK] > 0) & (new[:, CS_OK] > 0)
    out = np.where((new[:, CS_OK] > 0)[:, None], new, old)
    blend = (1.0 - alpha) * old[both] + alpha * new[both]
    for c0 in (CS_RMS, CS_WRMS):
        sl = slice(c0, c0 + 3)
        blend[:, sl] = np.sqrt((1.0 - alpha) * old[both, sl] ** 2 + alpha * new[both, sl] ** 2)
    w = max(alpha, STATISTICS_MEAN_WEIGHT)
    for c0 in (CS_U, CS_WM):
        blend[:, c0:c0 + 3] = (1.0 - w) * old[both, c0:c0 + 3] + w * new[both, c0:c0 + 3]
    if new.shape[1] > CS_APP:
        # The returned partner momentum a (physics.partner_momentum = "returned") as an integral
        # controller on the cell's net collision force: the pass ran with a_old and left the net
        # force F_net = W (a_old − a_new) (a_new = −F_jump/W of that pass, W its particle mass in
        # the cell); a moves by −g F_net / W_ref (g = RETURNED_GAIN α), W_ref the mean mass of the earlier passes
        # (n_ref, the mean of their number densities over a window of STATS_REFERENCE_PASSES passes;
        # the previous statistics' where it is not given), so
        # a only stops drifting where the net force vanishes in the mean.  The plain blend
        # (1 − α) a_old + α a_new divides by each pass's own W instead and settles where the mean
        # of F/W vanishes, which leaves a net force wherever a cell's mass and its collision rate
        # per unit mass fluctuate together from pass to pass; a reference that moves with the
        # recent passes (the relaxed number density) leaves a smaller one of the same kind.  The
        # base gain min(RETURNED_GAIN α, RETURNED_GAIN_MAX) times n/n_ref, at most RETURNED_GAIN_CAP:
        # a pass moves a beyond its own a_new by at most half the way (1 − gain within [−0.5, 1)).
        sl = slice(CS_APP, CS_APP + 3)
        ref = old[both, CS_N] if n_ref is None else np.where(n_ref[both] > 0, n_ref[both], old[both, CS_N])
        base = min(RETURNED_GAIN * alpha, RETURNED_GAIN_MAX)
        gain = np.minimum(base * new[both, CS_N] / ref, RETURNED_GAIN_CAP)
        blend[:, sl] = old[both, sl] + gain[:, None] * (new[both, sl] - old[both, sl])
    blend[:, CS_OK] = 1.0
    out[both] = blend
    return out


def _json_default(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, tuple):
        return list(v)
    return str(v)


def _canonical(d):
    """A stored case (flattened attributes) as the string checkpoints are compared by."""
    from eulag.config import comparable_attrs

    return json.dumps(comparable_attrs(d) if isinstance(d, dict) else d, sort_keys=True,
                      default=_json_default)


