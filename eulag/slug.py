"""Dense-phase slug conveying: DEM grains in a pressure-field gas (model "dem-darcy").

The model of Strauß, McNamara & Herrmann (SMH), "Plug conveying in a horizontal tube"
(Granular Matter 8:213–219, 2006, doi:10.1007/s10035-006-0009-0), after McNamara, Flekkøy &
Måløy (2000, Phys. Rev. E 61:4054, doi:10.1103/PhysRevE.61.4054):

- grains: soft spheres with rotation (:mod:`dem`), fed at the inlet as a packing of porosity
  ``feed.porosity`` at the speed that carries ``feed.mass_flow_kg_h``;
- gas: the linearised pressure equation (eq. 5) on a cell grid (:mod:`darcy`), a constant
  superficial gas velocity at the inlet, P′ = 0 at the outlet;
- coupling: tent-function transfer (eqs. 7–9, :mod:`dem.transfer`), porosity and grain velocity
  to the gas, pressure gradient and porosity back to the grains; each grain's cross-section
  weights are normalised to sum to one so that it deposits its whole volume also next to the
  wall (``numerics.porosity_weights = "grain"``; ``"tent"``: the plain tent weights over the
  tent volume inside the tube, which leave the nodes of a real packing about 0.02 too porous);
  the pressure gradient and porosity at a grain are the weights-normalised ("linear")
  interpolation of eq. 9 (``numerics.grain_interpolation = "normalised"``; ``"printed"``: eq.
  9's plain sums, a diagnostic, :mod:`dem.transfer`).  The gas force on grain i is

      F_i = −V_p ∇P_i / (1 − φ_i)                                          [N]

  Eq. 6 as printed, −∇P/(ρ_s(1 − φ)), is an acceleration, not a force (dimensionally wrong
  on the right of m ẍ); the force above is McNamara & Flekkøy's, and summed over the grains
  of a volume it is −∇P per unit volume, the Darcy drag on the packing.  (1 − φ_i) is floored
  at ``numerics.min_solid_fraction_force`` (lone grains in nearly empty cells).

Time stepping: DEM steps of t_c/``numerics.steps_per_contact``; the gas is advanced every
``numerics.gas_dt_s`` with the φ and u of that moment, and the gas force on each grain is held
over the DEM steps in between.  The gas θ-scheme defaults to θ = 1 (backward Euler), not the
paper's Crank–Nicolson (θ = ½, ``numerics.theta = 0.5``): measured reason — with the cap at
the empty-tube permeability the diffusivity P0κ/(ηφ) of an empty cell is ~2·10³ m²/s, its
time scale l²/D ~ 5·10⁻⁹ s, and at gas_dt = 10⁻⁴ s Crank–Nicolson's amplification of those
modes is ≈ −1: P′ flips sign from step to step (±100 Pa in a periodic tube with one slug)
and so does the force on the grains.  Backward Euler damps them; the quasi-steady P′ is the
same.

Entry points (called by the run layer for cases with ``model = "dem-darcy"``):
``validate_slug_case(case) -> dict`` (the resolved case) and
``run_slug(case, out, resume=False, progress=True) -> xarray.Dataset``.
Checkpoints: every ``numerics.checkpoint_interval_s`` of simulated time the whole state goes
to ``<out>.checkpoint`` (written to a temporary file, then renamed); ``resume=True`` continues
from it and gives the same result, bit for bit, as an uninterrupted run.

Continued runs: ``initial.state`` names a state (:func:`save_state` of a checkpoint, or the
checkpoint itself) of a case with the same tube, feed packing, grains' size and density, gas
grid and step (:data:`STATE_KEYS`); the run starts from its grains, gas and time with its own
friction, restitution, stiffness, gas viscosity, superficial velocity and feed rate (the feed
goes on from where it stood) — a filled tube for parameter studies instead of the ≈ 6 s of
filling from an empty one.  ``numerics.end_time_s`` stays
absolute.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from eulag.files import atomic_write, savez_atomic

__all__ = ["validate_slug_case", "run_slug", "summarize", "slug_profiles", "cross_section_layers", "layer_shear",
           "section_porosity",
           "gas_force_on_grains", "dataset_from_checkpoint",
           "check_report", "statistics_window",
           "save_state", "read_state", "state_time", "DEFAULTS", "SLUG_POROSITY"]

#: Slug criterion of the catalogue: slices (gas cells along x) with porosity below this.
SLUG_POROSITY = 0.6
#: Length of SMH's tube and the middle of it over which they average their slugs [m]; the
#: statistics window scales it with a tube's length (:func:`statistics_window`)
PAPER_LENGTH, MIDDLE = 0.525, (0.15, 0.40)
#: A run from an empty tube is measured from t = min(end/2, FILL_TIME_S) [s] (the paper's tube has
#: filled by about 6 s at the default feed)
FILL_TIME_S = 6.0

_G = 9.81

#: Sections and keys of a "dem-darcy" case with their defaults (SMH §3 unless noted).
DEFAULTS = {
    "tube": {"length_m": 0.525, "diameter_m": 7e-3, "orientation": "horizontal", "periodic": False},
    "grains": {"diameter_m": 1.4e-3, "density_kg_m3": 937.0, "friction": 0.5, "wall_friction": 0.5,
               "restitution": 0.5, "stiffness_N_m": 1000.0, "tangential_damping_ratio": 1.0},
    "gas": {"pressure_Pa": 101325.0, "viscosity_Pa_s": 6.73e-5, "superficial_velocity_m_s": 1.0,
            "inlet": "flux", "permeability_cap_m2": 0.0},
    "feed": {"mass_flow_kg_h": 2.49, "porosity": 0.57, "block_length_m": 0.014},
    "initial": {"plug_length_m": 0.0, "plug_start_m": 0.0, "state": ""},
    "numerics": {"cells_x": 150, "cells_across": 2, "steps_per_contact": 30, "gas_dt_s": 1e-4, "theta": 1.0,
                 "end_time_s": 4.0, "output_interval_s": 0.01, "checkpoint_interval_s": 0.5, "seed": 1,
                 "min_solid_fraction_force": 0.05, "parallel": False, "porosity_weights": "grain",
                 "grain_interpolation": "normalised", "overlap_limit": 0.05, "cross_section_at": 0.5,
                 "cross_section_pixels": 14},
}

_CHOICES = {("tube", "orientation"): ("horizontal", "vertical"), ("gas", "inlet"): ("flux", "source"),
            ("numerics", "porosity_weights"): ("grain", "tent"),
            ("numerics", "grain_interpolation"): ("normalised", "printed")}
_INTS = {("numerics", "cells_x"), ("numerics", "cells_across"), ("numerics", "steps_per_contact"),
         ("numerics", "seed"), ("numerics", "cross_section_pixels")}
#: The longest simulated time a case may ask for [s] (the paper's runs: 22.5 s).
END_TIME_MAX_S = 1e5
#: Largest values of the integers (numerics.seed: any int64 >= 0; the others at most 10⁷): the gas
#: grid of the paper has 150 x 2 x 2 nodes.
_INT_MAX = {"cells_x": 100_000}  # cells_across: MAX_CELLS_ACROSS, checked with its reason
_INT_MIN = {"cells_x": 3}
_BOOLS = {("tube", "periodic"), ("numerics", "parallel")}
#: The most gas cells across the tube for which every cell of the square grid holds part of the
#: circle: the corner cell's inner corner, at √2 R (1 − 2/n) from the axis, lies inside for n < 6.83.
MAX_CELLS_ACROSS = 6
_STRINGS = {("initial", "state")}
# (low, high, low inclusive?) for the numbers
_RANGES = {
    ("grains", "friction"): (0.0, 10.0, True), ("grains", "wall_friction"): (0.0, 10.0, True),
    ("grains", "restitution"): (0.0, 1.0, False), ("feed", "porosity"): (0.26, 0.99, True),
    ("gas", "permeability_cap_m2"): (0.0, 1.0, True), ("feed", "mass_flow_kg_h"): (0.0, 1e6, True),
    ("gas", "superficial_velocity_m_s"): (0.0, 1e3, True), ("numerics", "theta"): (0.5, 1.0, True),
    ("numerics", "min_solid_fraction_force"): (1e-6, 1.0, True), ("initial", "plug_start_m"): (0.0, 1e3, True),
    ("initial", "plug_length_m"): (0.0, 1e3, True), ("grains", "tangential_damping_ratio"): (0.0, 100.0, True),
    ("numerics", "overlap_limit"): (0.0, 1.0, False), ("numerics", "cross_section_at"): (0.0, 1.0, True),
    # plausibility of the SI quantities (a length in mm or a pressure in bar falls outside)
    ("tube", "length_m"): (0.0, 100.0, False), ("tube", "diameter_m"): (0.0, 1.0, False),
    ("grains", "diameter_m"): (0.0, 0.1, False), ("grains", "density_kg_m3"): (0.0, 25000.0, False),
    ("grains", "stiffness_N_m"): (0.0, 1e8, False), ("gas", "pressure_Pa"): (1e3, 1e8, True),
    ("gas", "viscosity_Pa_s"): (0.0, 1e-3, False), ("numerics", "gas_dt_s"): (0.0, 1.0, False),
    ("numerics", "end_time_s"): (0.0, END_TIME_MAX_S, False),
}
#: numerics.cross_section_pixels: from 2 up to pixels of d/4 (20 across the paper's tube): finer
#: pixels would resolve a single grain's outline, not a solids fraction.
CROSS_SECTION_PIXELS_MIN = 2
CROSS_SECTION_PIXEL_PER_D = 4
#: numerics.overlap_limit: the largest grain overlap / d a run may reach and still count as
#: finished. The stiffness is chosen for overlaps of about 1 % of d (docs/slug.md); the runs of
#: the paper's system reach 0.6-2.9 % in slug flow, but 9-37 % where a resting bulk jams the tube
#: and the feed, a kinematic piston, keeps compressing it (results/strauss-filled/grain-weights/
#: feed-9.95). Beyond a few per cent the linear contacts and the porosity they leave no longer
#: describe the packing: the run ends with converged = false and says so.


#: Largest eigenvalue of the tangential damping of a packing over a single pair's (7 γ_t/m), with every
#: contact sticking: the filled horizontal tube of the 22.5 s run at t = 13.25 s (3,056 grains;
#: ``python results/strauss/tangential_stability.py``; two grains on the wall 1.47, a chain of 8 on
#: the wall 1.95).
TANGENTIAL_PACKING_FACTOR = 3.55


def tangential_damping_pair_limit(restitution, steps_per_contact):
    """γ_t/γ_n [-] at which the viscous tangential force of a single pair contact turns unstable.

    A pair contact's sliding velocity relaxes under −γ_t v_t with the inverse mass of the two
    contact points, 2 (1/m + R²/I) = 7/m for solid spheres (rotation included).  The DEM step
    (kick–drift–kick, the dashpots at the velocity predicted to the end of the step; ``dem.engine``)
    maps the slip and its acceleration with the eigenvalues λ² − (1 − 3f/2) λ − f/2 = 0, f = dt γ_t
    7/m; one of them reaches −1 at f = 1, beyond which the slip grows from step to step (bounded
    only by the Coulomb cap: chatter instead of sticking).  With dt = t_c/N (t_c the pair's contact
    time, γ_n = 2ζ sqrt(k m/2)), f = 7π ζ r / (N sqrt(1 − ζ²)), r = γ_t/γ_n; the limit is r = 1/that
    (6.18 at e = 0.5, N = 30; tests/test_dem_contacts.py checks it on a pair).  Returns inf for
    e = 1 (no dashpot).
    """
    from dem.contacts import damping_ratio

    z = damping_ratio(restitution)
    if z == 0.0:
        return math.inf
    return steps_per_contact * math.sqrt(1.0 - z * z) / (7.0 * math.pi * z)


def tangential_damping_limit(restitution, steps_per_contact):
    """Largest γ_t/γ_n [-] a case may set: the pair limit over ``TANGENTIAL_PACKING_FACTOR``.

    Grains with several contacts have less margin than a pair: the step is stable while dt λ_max < 1,
    λ_max the largest eigenvalue of the tangential damping of all sticking contacts, 3.55 times a
    pair's in the filled tube.  1.74 at e = 0.5 and 30 steps per contact (the default γ_t = γ_n uses
    0.57 of it); the limit grows with numerics.steps_per_contact.
    """
    return tangential_damping_pair_limit(restitution, steps_per_contact) / TANGENTIAL_PACKING_FACTOR


def dem_steps(t_contact, steps_per_contact, gas_dt):
    """(DEM steps per gas step, DEM step [s]): at most t_contact / steps_per_contact, shortened so a
    whole number of them fills the gas step."""
    n = max(1, int(math.ceil(gas_dt / (t_contact / steps_per_contact) - 1e-9)))
    return n, gas_dt / n


def _finite(v) -> bool:
    """Whether the number v is finite as a double (an integer beyond its range is not)."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


#: The narrowest gas cell across the tube, in grain diameters (the paper's 3.5 mm for 1.4 mm grains):
#: with cells of 2 grains (4 or 5 across 11-14 mm tubes) or 1.7 (3 across the paper's 7 mm tube) the
#: wall's partial cells clip the node porosity; with 2.5 (4 across 14 mm) they did not.
CELL_GRAINS = 2.5

#: The node porosity below which the transfer is not a packing of spheres (solids fraction above
#: 0.8): clipped there for the gas step, counted (``porosity_clipped_cells``), and a run where it
#: happened is not a valid result (:func:`verdict`).
PHI_FLOOR = 0.2


def _bad(sec, key, val, allowed):
    return ValueError(f"{sec}.{key} = {val!r}: allowed {allowed}")


def validate_slug_case(case: dict) -> dict:
    """Check every section and key of a "dem-darcy" case; return the resolved case (defaults filled).

    Errors are one-line ``ValueError("section.key = value: allowed ...")``.
    """
    model = case.get("model", "dem-darcy")
    if model != "dem-darcy":
        raise ValueError(f"model = {model!r}: allowed 'dem-darcy' for eulag.slug")
    out = {"model": "dem-darcy"}
    for sec in case:
        if sec not in DEFAULTS and sec not in ("model", "name", "description"):
            raise ValueError(f"{sec} = {case[sec]!r}: allowed sections {', '.join(DEFAULTS)}")
    for sec, keys in DEFAULTS.items():
        given = case.get(sec, {})
        if not isinstance(given, dict):
            raise ValueError(f"{sec} = {given!r}: allowed a table")
        for k in given:
            if k not in keys:
                raise ValueError(f"{sec}.{k} = {given[k]!r}: allowed keys {', '.join(keys)}")
        res = {}
        for k, default in keys.items():
            v = given.get(k, default)
            if (sec, k) in _STRINGS:
                if not isinstance(v, str):
                    raise _bad(sec, k, v, "a string (a file path; \"\" for none)")
            elif (sec, k) in _BOOLS:
                if not isinstance(v, bool):
                    raise _bad(sec, k, v, "true or false")
            elif (sec, k) in _CHOICES:
                if v not in _CHOICES[sec, k]:
                    raise _bad(sec, k, v, " | ".join(repr(c) for c in _CHOICES[sec, k]))
            elif (sec, k) in _INTS:
                lo, hi = (0, 2 ** 63 - 1) if k == "seed" else (_INT_MIN.get(k, 1), _INT_MAX.get(k, 10 ** 7))
                if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                    raise _bad(sec, k, v, f"an integer >= {lo} and <= {hi}")
            else:
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not _finite(v):
                    shown = f"{str(v)[:12]}..." if isinstance(v, int) and not isinstance(v, bool) else v
                    raise _bad(sec, k, shown, "a finite number")
                v = float(v)
                lo, hi, inc = _RANGES.get((sec, k), (0.0, math.inf, False))
                if not ((v >= lo if inc else v > lo) and v <= hi):
                    raise _bad(sec, k, v, f"{lo} {'<=' if inc else '<'} value <= {hi}")
            res[k] = v
        out[sec] = res
    for k in ("name", "description"):
        if k in case:
            out[k] = str(case[k])
    t, gr, n = out["tube"], out["grains"], out["numerics"]
    if gr["diameter_m"] >= 0.5 * t["diameter_m"]:
        raise _bad("grains", "diameter_m", gr["diameter_m"], f"< half the tube diameter ({t['diameter_m']})")
    if n["cells_x"] < 3:
        raise _bad("numerics", "cells_x", n["cells_x"], "an integer >= 3")
    most = int(CROSS_SECTION_PIXEL_PER_D * t["diameter_m"] / gr["diameter_m"] + 1e-9)
    if not CROSS_SECTION_PIXELS_MIN <= n["cross_section_pixels"] <= most:
        raise _bad("numerics", "cross_section_pixels", n["cross_section_pixels"],
                   f"an integer from {CROSS_SECTION_PIXELS_MIN} to {most} (pixels no finer than d/"
                   f"{CROSS_SECTION_PIXEL_PER_D}: a solids fraction, not a grain's outline)")
    half = 0.5 * (t["length_m"] / n["cells_x"]) / t["length_m"]
    if not t["periodic"] and not half <= n["cross_section_at"] <= 1.0 - half:
        raise _bad("numerics", "cross_section_at", n["cross_section_at"],
                   f"{half:.4g} <= value <= {1 - half:.4g} of the tube length (the recorded slice, one gas cell wide, "
                   f"inside the tube)")
    if n["gas_dt_s"] > n["output_interval_s"]:
        raise _bad("numerics", "gas_dt_s", n["gas_dt_s"], f"<= numerics.output_interval_s ({n['output_interval_s']})")
    if n["output_interval_s"] > n["end_time_s"]:
        raise _bad("numerics", "output_interval_s", n["output_interval_s"], "<= numerics.end_time_s")
    limit = tangential_damping_limit(gr["restitution"], n["steps_per_contact"])
    if gr["tangential_damping_ratio"] >= limit and "tangential_damping_ratio" not in (case.get("grains") or {}):
        raise _bad("numerics", "steps_per_contact", n["steps_per_contact"],
                   f"a number of DEM steps per contact at which the default grains.tangential_damping_ratio "
                   f"({gr['tangential_damping_ratio']}) stays below the stability limit of the viscous tangential "
                   f"force (here {limit:.3g}; the limit grows with numerics.steps_per_contact)")
    if gr["tangential_damping_ratio"] >= limit:
        raise _bad("grains", "tangential_damping_ratio", gr["tangential_damping_ratio"],
                   f"< {limit:.3g} at grains.restitution = {gr['restitution']} and numerics.steps_per_contact = "
                   f"{n['steps_per_contact']} (above it the viscous tangential force of a packing is unstable "
                   f"in the DEM step; the limit grows with numerics.steps_per_contact)")
    from dem.engine import SKIN

    shortest = 3 * (1 + SKIN) * gr["diameter_m"]  # three cells of the neighbour search
    if out["feed"]["block_length_m"] < shortest:
        raise _bad("feed", "block_length_m", out["feed"]["block_length_m"],
                   f">= {shortest:.4g} m (3 (1 + {SKIN}) grain diameters: the feed packing is relaxed in a periodic "
                   f"block of this length)")
    if t["periodic"] and t["length_m"] < shortest:
        raise _bad("tube", "length_m", t["length_m"], f">= {shortest:.4g} m for a periodic tube (3 (1 + {SKIN}) "
                   f"grain diameters)")
    if n["cells_across"] > MAX_CELLS_ACROSS:
        raise _bad("numerics", "cells_across", n["cells_across"],
                   f"<= {MAX_CELLS_ACROSS} (with more cells across, the corner cells of the square grid lie "
                   f"wholly outside the circular tube)")
    lx = t["length_m"] / n["cells_x"]
    if not t["periodic"] and out["feed"]["block_length_m"] < 0.5 * lx:
        raise _bad("feed", "block_length_m", out["feed"]["block_length_m"],
                   f">= half a gas cell, tube.length_m / (2 numerics.cells_x) = {0.5 * lx:.4g} m (the feed "
                   f"zone before the inlet must fill the inlet node's tent)")
    across = t["diameter_m"] / (CELL_GRAINS * gr["diameter_m"])
    if n["cells_across"] > max(1.0, across):
        raise _bad("numerics", "cells_across", n["cells_across"],
                   f"<= tube.diameter_m / ({CELL_GRAINS} grains.diameter_m) = {across:.3g} (gas cells at least "
                   f"{CELL_GRAINS} grains wide, the paper's 3.5 mm cells for 1.4 mm grains: narrower cells leave the "
                   f"partial cells at the wall too small for the tent transfer, whose porosity it then clips)")
    for key in ("plug_length_m", "plug_start_m"):
        given = (case.get("initial") or {}).get(key, DEFAULTS["initial"][key])
        if not t["periodic"] and given != DEFAULTS["initial"][key]:
            raise _bad("initial", key, given, f"{DEFAULTS['initial'][key]} (not set) for a tube that is not periodic "
                       "(it fills from the feed; a filled state is initial.state)")
    if out["initial"]["state"] and t["periodic"]:
        raise _bad("initial", "state", out["initial"]["state"], "\"\" for a periodic tube (its initial plug is "
                   "initial.plug_length_m)")
    if out["initial"]["state"]:
        read_state(out["initial"]["state"], out)  # the file, its case and the end time, before any work
    if t["periodic"]:
        if out["initial"]["plug_length_m"] <= 0:
            raise _bad("initial", "plug_length_m", out["initial"]["plug_length_m"], "> 0 for a periodic tube")
        if out["initial"]["plug_length_m"] + out["initial"]["plug_start_m"] > t["length_m"] + 1e-12:
            raise _bad("initial", "plug_length_m", out["initial"]["plug_length_m"],
                       "plug_start_m + plug_length_m <= tube.length_m")
    return out


def gas_force_on_grains(transfer, pos, status, grad, phi, v_grain, min_solid):
    """Gas force [N] (N, 3) on the grains: F_i = −V_p ∇P_i / (1 − φ_i), with ∇P_i and φ_i the tent
    interpolations (eq. 9; normalised, or the plain sums with ``numerics.grain_interpolation =
    "printed"``, :class:`dem.transfer.TentTransfer`) of the node fields grad (nx, ny, ny, 3)
    [Pa/m] and phi (nx, ny, ny);
    1 − φ_i floored at ``min_solid``; zero on grains that are not FREE.  (SMH eq. 6 as printed,
    −∇P/(ρ_s(1 − φ)), is an acceleration; summed over the grains of a volume this force is
    −∇P per unit volume, the Darcy drag of the packing.)"""
    from dem import FREE

    vals = transfer.to_grains(pos, status, np.concatenate([grad, phi[..., None]], axis=3))
    solid = np.maximum(1.0 - vals[:, 3], min_solid)
    f = -v_grain * vals[:, :3] / solid[:, None]
    f[status != FREE] = 0.0
    return f


# ---------------------------------------------------------------------------------------------
class _Simulation:
    """State and one gas step of the coupled model; everything a checkpoint needs is here."""

    def __init__(self, c):
        from darcy import DarcySolver, TubeGrid
        from dem import FEED, FREE, CellGrid, ContactModel, Grains, TentTransfer
        from dem.feed import Feed, feed_speed, relaxed_packing

        self.c = c
        t, gr, gas, fd, num = c["tube"], c["grains"], c["gas"], c["feed"], c["numerics"]
        self.L, self.Dt = t["length_m"], t["diameter_m"]
        self.Rt = 0.5 * self.Dt
        self.periodic = t["periodic"]
        self.d = gr["diameter_m"]
        self.model = ContactModel(self.d, gr["density_kg_m3"], gr["stiffness_N_m"], gr["restitution"],
                                  gr["friction"], gr["wall_friction"], tangential_ratio=gr["tangential_damping_ratio"])
        self.n_sub, self.dt = dem_steps(self.model.t_contact, num["steps_per_contact"], num["gas_dt_s"])
        self.gas_dt = num["gas_dt_s"]
        self.n_out = max(1, int(round(num["output_interval_s"] / self.gas_dt)))
        self.n_ckpt = max(1, int(round(num["checkpoint_interval_s"] / self.gas_dt)))
        self.n_gas_total = int(round(num["end_time_s"] / self.gas_dt))
        self.gravity = np.array([0.0, 0.0, -_G]) if t["orientation"] == "horizontal" else np.array([-_G, 0.0, 0.0])
        self.v_s = gas["superficial_velocity_m_s"]
        nx, ny = num["cells_x"], num["cells_across"]
        self.grid = TubeGrid(self.L, self.Dt, nx, ny, periodic=self.periodic)
        cap = gas["permeability_cap_m2"] or None
        self.darcy = DarcySolver(self.grid, gas["pressure_Pa"], gas["viscosity_Pa_s"], self.d, kappa_max=cap,
                                 theta=num["theta"], inlet=gas["inlet"])
        self.transfer = TentTransfer(nx, ny, self.L, self.Rt, 0.5 * self.d, periodic=self.periodic,
                                     parallel=num["parallel"], weights=num["porosity_weights"],
                                     interpolation=num["grain_interpolation"])
        # feed template
        lb = fd["block_length_m"]
        vol_t = math.pi * self.Rt ** 2 * lb
        n_tpl = int(round((1 - fd["porosity"]) * vol_t / self.model.volume))
        self.template = relaxed_packing(n_tpl, lb, self.Rt, self.d, gr["density_kg_m3"], gr["stiffness_N_m"],
                                        num["seed"])
        self.block_length = lb
        mdot = fd["mass_flow_kg_h"] / 3600.0
        self.v_feed = 0.0 if self.periodic else feed_speed(mdot, gr["density_kg_m3"], fd["porosity"], self.Dt)
        self.feed = Feed(self.template, lb, self.v_feed)
        # the feed's advance s = s0 + v_feed (t − t0) [m]; (s0, gas step of t0) = (0, 0) but in a
        # run continued from a state written at another feed rate (start_from)
        self.feed_origin = (0.0, 0)
        if self.periodic:
            self.cells = CellGrid(0.0, self.L, self.Rt, self.d, periodic=True)
        else:
            self.cells = CellGrid(-3 * lb - 2 * self.d, self.L + 2 * self.d, self.Rt, self.d)
        self.x_lost = -3 * lb - self.d
        self.grains = Grains(4096)
        self.gas_force = np.zeros((4096, 3))
        self.work = {}
        self.FEED, self.FREE = FEED, FREE
        # counters
        self.gas_step = 0
        self.t_start = 0.0  # the time the run started from (a state's time for a continued run)
        self.next_gid = 0
        self.outflow = 0
        self.lost = 0
        self.lost_reasons = {"behind_feed": 0, "outside_wall": 0, "not_finite": 0}
        self.max_overlap = 0.0
        self.phi_clipped = 0
        self.rec = {k: [] for k in ("time", "phi", "ux", "p", "dp", "n_tube", "outflow", "overlap", "gas_share",
                                    "wall_stress", "temperature", "contact", "section", "layer_n", "layer_u",
                                    "layer_rms", "section_ok")}
        # the recorded cross-section (SMH §3.4, Figs. 17-19): a gas-cell-wide slice at
        # numerics.cross_section_at of the tube length
        from dem.sections import layer_edges, pixel_centres, pixel_inside_fraction, radial_layer_edges
        self.sec_x = num["cross_section_at"] * self.L
        self.sec_w = self.grid.lx
        self.sec_pix = num["cross_section_pixels"]
        self.sec_inside = pixel_inside_fraction(self.Rt, self.sec_pix)
        self.sec_centres = pixel_centres(self.Rt, self.sec_pix)
        # layers by height; in a vertical tube, where gravity singles out no height, by radius
        self.layer_radial = t["orientation"] == "vertical"
        self.layer_edges = (radial_layer_edges if self.layer_radial else layer_edges)(self.Rt, self.d)
        self.slugs = []
        self.t_gas = 0.0
        self.t_total = 0.0
        self.wall_origin = time.time()  # this session's start (wall clock) and the time before it
        self.wall_before = 0.0
        if self.periodic:
            ini = c["initial"]
            nb = int(math.ceil(ini["plug_length_m"] / lb - 1e-9))
            blocks = [self.template + np.array([ini["plug_start_m"] + k * lb, 0, 0]) for k in range(nb)]
            pos = np.concatenate(blocks)
            pos = pos[pos[:, 0] < ini["plug_start_m"] + ini["plug_length_m"]]
            pos[:, 0] -= self.L * np.floor(pos[:, 0] / self.L)
            self._add(pos, FREE)
        else:
            self._feed_blocks()

    # --------------------------------------------------------------- bookkeeping
    def _add(self, pos, status):
        m = len(pos)
        vel = np.zeros_like(pos)
        if status == self.FEED:
            vel[:, 0] = self.v_feed
        self.grains.append(pos, vel, np.full(m, status, dtype=np.int8), np.arange(self.next_gid, self.next_gid + m))
        self.next_gid += m
        if len(self.gas_force) < len(self.grains.status):
            gf = np.zeros((len(self.grains.status), 3))
            gf[: len(self.gas_force)] = self.gas_force
            self.gas_force = gf

    def _feed_blocks(self):
        s0, step0 = self.feed_origin
        s = s0 + self.v_feed * ((self.gas_step - step0) * self.n_sub) * self.dt
        for p in self.feed.blocks_due(s):
            self._add(p, self.FEED)

    def _bookkeeping(self):
        from dem import GONE
        g = self.grains
        n = g.n
        st, pos = g.status[:n], g.pos[:n]
        if not self.periodic:
            st[(st == self.FEED) & (pos[:, 0] >= 0.0)] = self.FREE
            out = (st == self.FREE) & (pos[:, 0] >= self.L)
            self.outflow += int(out.sum())
            st[out] = GONE
            self._feed_blocks()
            behind = (st == self.FREE) & (pos[:, 0] < self.x_lost)
        else:
            behind = np.zeros(n, bool)
        r = np.sqrt(pos[:, 1] ** 2 + pos[:, 2] ** 2)
        outside = (st == self.FREE) & (r > self.Rt)
        bad = (st != GONE) & ~np.isfinite(pos).all(axis=1)
        for key, mask in (("behind_feed", behind), ("outside_wall", outside), ("not_finite", bad)):
            k = int(mask.sum())
            if k:
                self.lost_reasons[key] += k
                self.lost += k
                st[mask] = GONE
        if np.count_nonzero(st == GONE) > 0.2 * n + 64:
            keep = np.flatnonzero(st != GONE)
            gf = self.gas_force[:n][keep].copy()
            g.compact()
            self.gas_force[: len(keep)] = gf
            self.gas_force[len(keep): n] = 0.0

    # --------------------------------------------------------------- one gas step
    def gas_step_advance(self):
        from dem import dem_step
        g = self.grains
        t0 = time.perf_counter()
        om = dem_step(g, self.model, self.cells, self.gas_force, self.gravity, self.dt, self.v_feed, np.nan,
                      self.work, nsteps=self.n_sub, parallel=self.c["numerics"]["parallel"])
        self.max_overlap = max(self.max_overlap, om)
        self.gas_step += 1
        self._bookkeeping()
        t1 = time.perf_counter()
        n = g.n
        phi, u = self.transfer.porosity_velocity(g.pos[:n], g.vel[:n], g.status[:n])
        low = phi < PHI_FLOOR
        self.phi_clipped += int(low.sum())
        phi = np.clip(phi, PHI_FLOOR, 1.0)
        self.phi, self.u = phi, u
        self.darcy.step(phi, u, self.gas_dt, self.v_s)
        self.gas_force[:n] = gas_force_on_grains(self.transfer, g.pos[:n], g.status[:n], self.darcy.gradient(), phi,
                                                 self.model.volume, self.c["numerics"]["min_solid_fraction_force"])
        t2 = time.perf_counter()
        self.t_gas += t2 - t1
        self.t_total += t2 - t0

    # --------------------------------------------------------------- records
    def record(self):
        g, grid = self.grains, self.grid
        n = g.n
        a = grid.area[None]
        phi1 = (self.phi * a).sum(axis=(1, 2)) / grid.cross_area
        w = (1.0 - self.phi) * a
        ux1 = (self.u[..., 0] * w).sum(axis=(1, 2)) / np.maximum(w.sum(axis=(1, 2)), 1e-300)
        p1 = (self.darcy.p * a).sum(axis=(1, 2)) / grid.cross_area
        if self.periodic:  # the total pressure: P' + G (x - L/2), G the mean gradient (darcy.gradient)
            p1 = p1 + self.darcy.G * (grid.x - 0.5 * self.L)
        free = g.status[:n] == self.FREE
        x = g.pos[:n, 0]
        in_tube = free & (x >= 0) & (x < self.L)
        t = self.gas_step * self.gas_dt
        r = self.rec
        r["time"].append(t)
        r["phi"].append(phi1)
        r["ux"].append(ux1)
        r["p"].append(p1)
        r["dp"].append(self.darcy.inlet_pressure())
        r["n_tube"].append(int(in_tube.sum()))
        r["outflow"].append(self.outflow)
        r["overlap"].append(self.max_overlap / self.d)
        r["gas_share"].append(self.t_gas / max(self.t_total, 1e-300))
        self.max_overlap = 0.0
        # per-slice grain statistics: wall normal stress, granular temperature, contact force
        nxg = grid.nx
        k = np.clip((x[in_tube] / grid.lx).astype(np.int64), 0, nxg - 1)
        cnt = np.bincount(k, minlength=nxg).astype(float)
        fw = self.work["wall_fn"][:n][in_tube] if "wall_fn" in self.work else np.zeros(len(k))
        r["wall_stress"].append(np.bincount(k, weights=fw, minlength=nxg) / (math.pi * self.Dt * grid.lx))
        v = g.vel[:n][in_tube]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean_v = np.stack([np.bincount(k, weights=v[:, q], minlength=nxg) for q in range(3)], axis=1) / cnt[:, None]
            dv = v - mean_v[k]
            # a slice without grains has no fluctuation energy and no contact force: 0, not 0/0
            per = np.maximum(cnt, 1.0)
            r["temperature"].append(np.bincount(k, weights=(dv * dv).sum(axis=1) / 3.0, minlength=nxg) / per)
            fc = np.linalg.norm(g.force[:n][in_tube], axis=1)
            r["contact"].append(np.bincount(k, weights=fc, minlength=nxg) / per)
        # the cross-section at sec_x: solids-fraction image and layer velocities (dem.sections)
        from dem.sections import layer_velocity, solids_fraction_image
        free_pos = g.pos[:n][free]
        r["section"].append(solids_fraction_image(free_pos, self.d, self.sec_x, self.sec_w, self.Rt, self.sec_pix,
                                                  self.periodic, self.L, self.sec_inside))
        cnt_l, u_l, rms_l = layer_velocity(free_pos, g.vel[:n][free], self.sec_x, self.sec_w, self.layer_edges,
                                           self.periodic, self.L, radial=self.layer_radial)
        r["layer_n"].append(cnt_l)
        r["layer_u"].append(u_l)
        r["layer_rms"].append(rms_l)
        r["section_ok"].append(1)
        # slug catalogue: runs of slices with φ < SLUG_POROSITY
        lx = grid.lx
        s = phi1 < SLUG_POROSITY
        if s.any() and not s.all():
            start = 0
            if self.periodic and s[0]:
                start = int(np.flatnonzero(~s)[0])
            order = (np.arange(grid.nx) + start) % grid.nx
            ss = s[order]
            i = 0
            xs = x[in_tube]
            while i < grid.nx:
                if ss[i]:
                    j = i
                    while j + 1 < grid.nx and ss[j + 1]:
                        j += 1
                    cells = order[i:j + 1]
                    x0, length = cells[0] * lx, (j - i + 1) * lx
                    rel = (xs - x0) % self.L if self.periodic else xs - x0
                    cnt = int(((rel >= 0) & (rel < length)).sum())
                    wgt = 1.0 - phi1[cells]  # solids-weighted centroid: sub-cell position
                    centre = x0 + (np.sum(wgt * (np.arange(len(cells)) + 0.5)) / np.sum(wgt)) * lx
                    if self.periodic:
                        centre %= self.L
                    self.slugs.append((t, centre, float(phi1[cells].min()), float(ux1[cells].max()), length, cnt))
                    i = j + 1
                else:
                    i += 1

    # --------------------------------------------------------------- checkpoint
    def state(self):
        st = {"g_" + k: v for k, v in self.grains.state().items()}
        st.update({"d_" + k: v for k, v in self.darcy.state().items()})
        n = self.grains.n
        st["gas_force"] = self.gas_force[:n].copy()
        scal = dict(gas_step=self.gas_step, next_gid=self.next_gid, outflow=self.outflow, lost=self.lost,
                    max_overlap=self.max_overlap, phi_clipped=self.phi_clipped, next_block=self.feed.next_block,
                    feed_origin=list(self.feed_origin), feed_speed=self.v_feed, t_start=self.t_start,
                    lost_reasons=self.lost_reasons, wall_time_s=self.wall_before + (time.time() - self.wall_origin))
        st["scalars"] = np.array(json.dumps(scal))
        for k, v in self.rec.items():
            st["rec_" + k] = np.array(v)
        st["slugs"] = np.array(self.slugs, dtype=float).reshape(-1, 6)
        st["phi"], st["u"] = self.phi, self.u
        return st

    def _load_grains_and_gas(self, st) -> dict:
        """Grains, gas pressure, gas force, φ, u, time and the feed's next block from the
        arrays ``st`` of a checkpoint or state; returns its scalars."""
        from dem import Grains
        self.grains = Grains.from_state({k[2:]: st[k] for k in st if k.startswith("g_")})
        self.darcy.load_state({"p": st["d_p"], "G": st["d_G"]})
        n = self.grains.n
        self.gas_force = np.zeros((len(self.grains.status), 3))
        self.gas_force[:n] = st["gas_force"]
        scal = json.loads(str(st["scalars"]))
        self.gas_step, self.next_gid = scal["gas_step"], scal["next_gid"]
        self.feed.next_block = scal["next_block"]
        self.phi, self.u = st["phi"], st["u"]
        self.work = {}
        return scal

    def load(self, st):
        scal = self._load_grains_and_gas(st)
        self.outflow = scal["outflow"]
        self.lost, self.max_overlap, self.phi_clipped = scal["lost"], scal["max_overlap"], scal["phi_clipped"]
        self.feed_origin = tuple(scal.get("feed_origin", (0.0, 0)))
        self.t_start = scal.get("t_start", 0.0)
        self.wall_before = scal.get("wall_time_s", 0.0)  # the sessions before this resume
        self.lost_reasons = scal["lost_reasons"]
        n_rec = len(st["rec_time"])
        for k in self.rec:
            if "rec_" + k not in st:  # a checkpoint written before this record existed
                if k == "section_ok":
                    self.rec[k] = [0] * n_rec
                elif k == "section" or k.startswith("layer_"):  # zeros, flagged by section_ok = 0
                    shape = (self.sec_pix, self.sec_pix) if k == "section" else (len(self.layer_edges) - 1,)
                    self.rec[k] = [np.zeros(shape) for _ in range(n_rec)]
                else:
                    self.rec[k] = [np.full(self.grid.nx, np.nan) for _ in range(n_rec)]
                continue
            a = st["rec_" + k]
            self.rec[k] = [row for row in a] if a.ndim > 1 else a.tolist()
        self.slugs = [tuple(r) for r in st["slugs"]]

    def start_from(self, st):
        """Continue from a saved state (a checkpoint or :func:`save_state` file of a compatible
        case) with this case's parameters: grains, gas and time from the state; records,
        outflow, losses and the overlap maximum start afresh."""
        scal = self._load_grains_and_gas(st)
        s0, step0 = scal.get("feed_origin", (0.0, 0))
        v_old = scal["feed_speed"] if "feed_speed" in scal else _state_feed_speed(st)
        if v_old != self.v_feed:  # the feed continues from where it stood, at this case's speed
            self.feed_origin = (s0 + v_old * (self.gas_step - step0) * self.gas_dt, self.gas_step)
        else:
            self.feed_origin = (s0, step0)
        self.t_start = self.gas_step * self.gas_dt

    # --------------------------------------------------------------- dataset
    def dataset(self):
        import xarray as xr
        r, grid = self.rec, self.grid
        time_ = np.array(r["time"])
        sl = np.array(self.slugs, dtype=float).reshape(-1, 6)
        nl = len(self.layer_edges) - 1
        mdot = self.model.mass * np.diff(np.concatenate([[0], r["outflow"]])) / np.diff(np.concatenate([[self.t_start], time_]))

        def var(dims, data, units, long_name, **kw):
            return (dims, np.asarray(data), dict(units=units, long_name=long_name, **kw))

        ds = xr.Dataset(
            {
                "porosity": var(("time", "x"), r["phi"], "1", "gas volume fraction, cross-section mean (tent transfer)"),
                "grain_velocity": var(("time", "x"), r["ux"], "m s-1",
                                      "axial grain velocity, solids-weighted cross-section mean"),
                "gas_pressure": var(("time", "x"), r["p"], "Pa", "gas pressure relative to P0, cross-section mean"),
                "wall_normal_stress": var(("time", "x"), r["wall_stress"], "Pa",
                                          "grain normal force on the tube wall per wall area, per slice (last DEM step)"),
                "granular_temperature": var(("time", "x"), r["temperature"], "m2 s-2",
                                            "granular temperature <|v - mean v|^2>/3 of the grains of a slice (0 without grains)"),
                "contact_force": var(("time", "x"), r["contact"], "N",
                                     "mean magnitude of the contact force (grains and wall) per grain of a slice (0 without grains)"),
                "section_solids_fraction": var(
                    ("time", "section_z", "section_y"), np.reshape(r["section"], (-1, self.sec_pix, self.sec_pix)),
                    "1", f"solids volume fraction in the slice x = section_x_m +- {0.5 * self.sec_w:g} m (each grain's "
                    f"chords through the slice on 8 x 8 sub-cells per pixel; pixels less than half inside the wall: 0)"),
                "section_recorded": var(("time",), np.asarray(r["section_ok"], dtype=np.int8), "1",
                                        "1 where the record holds the section and layers (0: a record resumed from a "
                                        "checkpoint written before they were recorded; zeros there)"),
                "section_pixel_inside": var(("section_z", "section_y"), self.sec_inside, "1",
                                            "share of the pixel's area inside the tube wall"),
                "layer_grains": var(("time", "layer"), np.reshape(r["layer_n"], (-1, nl)), "1",
                                    "grains with centres in the section slice, by layer"),
                "layer_velocity": var(("time", "layer"), np.reshape(r["layer_u"], (-1, nl)), "m s-1",
                                      "mean axial velocity of the grains of a layer of the section slice "
                                      "(0 without grains)"),
                "layer_velocity_rms": var(("time", "layer"), np.reshape(r["layer_rms"], (-1, nl)), "m s-1",
                                          "rms of the axial grain velocity about the layer's mean (0 without grains)"),
                "pressure_drop": var(("time",), r["dp"], "Pa", "gas pressure at the inlet minus outlet"),
                "grains_in_tube": var(("time",), r["n_tube"], "1", "free grains with 0 <= x < L"),
                "outflow_count": var(("time",), r["outflow"], "1", "grains left through the outlet since the start of the run"),
                "outflow_mass_rate": var(("time",), mdot, "kg s-1", "grain mass leaving per time over the last interval"),
                "max_overlap_per_d": var(("time",), r["overlap"], "1",
                                         "largest grain overlap over the last interval / grain diameter"),
                "gas_solve_share": var(("time",), r["gas_share"], "1", "share of wall time in the gas solve (so far)"),
                "slug_time": var(("slug",), sl[:, 0], "s", "time of the slug record"),
                "slug_position": var(("slug",), sl[:, 1], "m", "slug centre (solids-weighted centroid of its slices)"),
                "slug_min_porosity": var(("slug",), sl[:, 2], "1", "minimum slice porosity in the slug"),
                "slug_max_velocity": var(("slug",), sl[:, 3], "m s-1", "maximum slice grain velocity in the slug"),
                "slug_length": var(("slug",), sl[:, 4], "m", f"length of the run of slices with porosity < {SLUG_POROSITY}"),
                "slug_grains": var(("slug",), sl[:, 5], "1", "grains in the slug"),
                "grains_lost": var((), self.lost, "1", "grains lost (left the tube other than through the outlet)"),
            },
            coords={"time": ("time", time_, dict(units="s", long_name="time")),
                    "x": ("x", grid.x, dict(units="m", long_name="axial position of the gas cells")),
                    "section_y": ("section_y", self.sec_centres, dict(units="m", long_name="y position of the "
                                                                      "section's pixel centres (horizontal)")),
                    "section_z": ("section_z", self.sec_centres, dict(units="m", long_name="z position of the "
                                                                      "section's pixel centres (up in a horizontal "
                                                                      "tube, gravity along -z; horizontal in a "
                                                                      "vertical one, gravity along -x)")),
                    "layer": ("layer", 0.5 * (self.layer_edges[1:] + self.layer_edges[:-1]),
                              dict(units="m", long_name=("radius" if self.layer_radial else "height") +
                                   " of the layer's centre (bins of grain-centre " +
                                   ("distance from the axis" if self.layer_radial else "height z") + ", d/2 wide)"))},
        )
        ds.attrs.update(
            title="dense-phase slug conveying (DEM grains + pressure-field gas)", Conventions="CF-1.8",
            model="dem-darcy", references="Strauss, McNamara & Herrmann, Granular Matter 8 (2006) 213, "
                                          "doi:10.1007/s10035-006-0009-0",
            case=json.dumps(self.c), seed=self.c["numerics"]["seed"], grains_lost=int(self.lost),
            lost_reasons=json.dumps(self.lost_reasons), dem_dt_s=self.dt, contact_time_s=self.model.t_contact,
            feed_speed_m_s=self.v_feed, porosity_clipped_cells=int(self.phi_clipped),
            slug_criterion=f"porosity < {SLUG_POROSITY} in gas-cell slices of {grid.lx} m, every output interval",
            gas_force="-V_p grad(P)/(1 - phi) (eq. 6 of the paper as printed is not a force)",
            section_x_m=self.sec_x, section_width_m=self.sec_w,
            layer_coordinate="radius" if self.layer_radial else "height",
        )
        try:
            from importlib.metadata import version
            ds.attrs["eulag_version"] = version("eulag")
        except Exception:  # noqa: BLE001 - a source tree without metadata
            ds.attrs["eulag_version"] = "unknown"
        return ds




def checkpoint_path(out) -> Path:
    """The checkpoint beside the output ``out``: ``<out>.checkpoint``."""
    out = Path(out)
    return out.with_name(out.name + ".checkpoint")


def _comparable(c: dict) -> dict:
    """A resolved case in the form stored cases are compared in: keys that came after stored
    runs are dropped at the value those runs had — ``initial.state`` when empty (they all
    started from an empty tube), ``numerics.grain_interpolation`` when "normalised",
    ``numerics.overlap_limit`` at its default (it judges a run, it does not change it), and the
    recorded cross-section's ``numerics.cross_section_at`` and ``cross_section_pixels`` at
    theirs (they choose what is recorded, not what is run)."""
    same = json.loads(json.dumps(c))
    if not same.get("initial", {}).get("state", None):
        same.get("initial", {}).pop("state", None)
    if same.get("numerics", {}).get("grain_interpolation", None) == "normalised":
        same["numerics"].pop("grain_interpolation")
    for key in ("overlap_limit", "cross_section_at", "cross_section_pixels"):
        if same.get("numerics", {}).get(key, None) == DEFAULTS["numerics"][key]:
            same["numerics"].pop(key)
    return same


def _checkpoint_key(c: dict) -> str:
    """The identity a checkpoint stores: the resolved case (:func:`_comparable`) without
    ``numerics.end_time_s`` (a run may be continued to a later end)."""
    same = _comparable(c)
    same.get("numerics", {}).pop("end_time_s", None)
    same.get("numerics", {}).pop("overlap_limit", None)  # judges the run's end, not its course
    return json.dumps(same, sort_keys=True)


def checkpoint_problem(ckpt, case: dict):
    """Why the checkpoint ``ckpt`` cannot be resumed as ``case`` (None: it can)."""
    try:
        with np.load(Path(ckpt), allow_pickle=False) as z:
            key = str(z["case_json"]) if "case_json" in z.files else None
    except Exception as exc:  # noqa: BLE001 - unreadable for whatever reason
        from eulag.arguments import unreadable_archive_reason

        return f"cannot be read ({unreadable_archive_reason(exc)})"
    if key is None:
        return "checkpoint written without its case, which cannot be checked"
    try:
        stored = _checkpoint_key(json.loads(key))  # keys that came later dropped at their former value
    except (ValueError, TypeError, AttributeError):
        return "checkpoint with an unreadable case"
    mine = _checkpoint_key(validate_slug_case(case))
    if stored == mine:
        return None
    from eulag.config import case_differences

    what = case_differences(json.loads(stored), json.loads(mine), there="in the checkpoint")
    return "checkpoint of a different case" + (f" ({what})" if what else "")


#: Keys a continued run (``initial.state``) must share with the case that wrote the state: the
#: geometry, the grains' size and density, the feed's packing (porosity, block) and the gas grid
#: and step.  Friction, restitution, stiffness, gas viscosity, pressure, v_s and the feed rate
#: may differ (a new feed rate continues the feed from where it stood).
STATE_KEYS = (("tube", None), ("feed", "porosity"), ("feed", "block_length_m"), ("grains", "diameter_m"),
              ("grains", "density_kg_m3"),
              ("numerics", "cells_x"), ("numerics", "cells_across"), ("numerics", "gas_dt_s"),
              ("numerics", "seed"))
_STATE_ARRAYS = ("gas_force", "scalars", "phi", "u", "case_json")


def _state_feed_speed(st) -> float:
    """The feed speed [m/s] of the case that wrote the state ``st`` (states written before the
    checkpoints stored it)."""
    from dem.feed import feed_speed

    c = json.loads(str(st["case_json"]))
    if c["tube"]["periodic"]:
        return 0.0
    return feed_speed(c["feed"]["mass_flow_kg_h"] / 3600.0, c["grains"]["density_kg_m3"], c["feed"]["porosity"],
                      c["tube"]["diameter_m"])


def _state_file(text: str) -> Path:
    """The file of ``initial.state``: the path as given, else relative to ``cases/slug``."""
    from eulag.config import CASES_DIR

    p = Path(text)
    if p.is_file():
        return p
    if not p.is_absolute() and (CASES_DIR / "slug" / p).is_file():
        return CASES_DIR / "slug" / p
    raise ValueError(f"initial.state = {text!r}: no such file; allowed: a state written by "
                     f"eulag.slug.save_state or a run's .checkpoint (a path, or a file in cases/slug)")


def read_state(text: str, case: dict) -> tuple[dict, float]:
    """(arrays, time [s]) of the state ``initial.state = text`` for the resolved ``case``;
    ValueError (one line) when it cannot continue as this case."""
    path = _state_file(text)
    try:
        with np.load(path, allow_pickle=False) as z:
            st = {k: z[k] for k in z.files if k.startswith(("g_", "d_")) or k in _STATE_ARRAYS}
    except Exception as exc:  # noqa: BLE001 - unreadable for whatever reason
        raise ValueError(f"initial.state = {text!r}: cannot be read ({' '.join(str(exc).split())})") from None
    if "case_json" not in st or "scalars" not in st:
        raise ValueError(f"initial.state = {text!r}: not a slug state (no case or scalars stored)")
    other = json.loads(str(st["case_json"]))
    pairs = []
    for sec, key in STATE_KEYS:
        keys = case[sec] if key is None else (key,)
        pairs += [(sec, k) for k in keys]
    for sec, key in pairs:
        a, b = other.get(sec, {}).get(key), case[sec][key]
        if a != b:
            raise ValueError(f"initial.state = {text!r}: written with {sec}.{key} = {a!r}, "
                             f"this case has {b!r}; allowed: a state of a case with the same tube, feed packing, grain "
                             f"size and density, gas grid, gas step and seed")
    t0 = json.loads(str(st["scalars"]))["gas_step"] * case["numerics"]["gas_dt_s"]
    if case["numerics"]["end_time_s"] <= t0 + case["numerics"]["output_interval_s"]:
        raise ValueError(f"numerics.end_time_s = {case['numerics']['end_time_s']}: the state of initial.state "
                         f"= {text!r} is at t = {t0:.6g} s; allowed > {t0 + case['numerics']['output_interval_s']:.6g}")
    return st, t0


def state_time(case: dict) -> float:
    """The time [s] at which a case starts: 0, or the time of its ``initial.state``."""
    c = validate_slug_case(case)  # a state that cannot start this case stops here, in one line
    if not c["initial"]["state"]:
        return 0.0
    return read_state(c["initial"]["state"], c)[1]


def save_state(checkpoint, out) -> Path:
    """Write the state of a run's checkpoint without its records to ``out`` (.npz, a fraction
    of the checkpoint's size): the start of continued runs (``initial.state``)."""
    with np.load(Path(checkpoint), allow_pickle=False) as z:
        st = {k: z[k] for k in z.files if k.startswith(("g_", "d_")) or k in _STATE_ARRAYS}
    out = Path(out)
    savez_atomic(out, st)
    return out


def compared_cases(attrs: dict, case: dict) -> tuple[dict, dict]:
    """The stored case of a dataset's attributes ``attrs`` (the ``case`` attribute) and ``case``
    resolved, as :func:`same_case` compares them."""
    return _comparable(json.loads(attrs.get("case", "null"))), _comparable(validate_slug_case(case))


def same_case(attrs: dict, case: dict) -> bool:
    """Whether a dataset's attributes ``attrs`` are those of a result of ``case`` (its resolved
    case, stored as the ``case`` attribute)."""
    try:
        stored, mine = compared_cases(attrs, case)
    except (ValueError, KeyError, TypeError, AttributeError):
        return False
    return stored == mine


def run_slug(case: dict, out, resume=False, progress=True):
    """Run a "dem-darcy" case; write the transient dataset to ``out`` (NetCDF; None: not written,
    no checkpoints) and return it.  Attributes ``converged`` ("true" unless grains were lost or
    the largest overlap went beyond ``numerics.overlap_limit``, :func:`problem_overlap`) and
    ``stop_reason`` give the run layer its verdict (:func:`verdict`).

    ``<out>.checkpoint`` receives the state every ``numerics.checkpoint_interval_s``; with
    ``resume=True`` the run continues from it (bit-identical to an uninterrupted run), else an
    old checkpoint is removed.  The checkpoint is removed once the dataset is written.
    """
    c = validate_slug_case(case)
    out = None if out is None else Path(out)
    ckpt = None if out is None else checkpoint_path(out)
    sim = _Simulation(c)
    if ckpt is None:
        pass
    elif resume and ckpt.exists():
        problem = checkpoint_problem(ckpt, case)
        if problem is not None:
            raise ValueError(f"--resume: {ckpt}: {problem}; remove it or run without --resume")
        with np.load(ckpt, allow_pickle=False) as z:
            sim.load({k: z[k] for k in z.files if k != "case_json"})
        if progress:
            print(f"slug: resuming from {ckpt} at t = {sim.gas_step * sim.gas_dt:.4g} s", flush=True)
    elif ckpt.exists():
        ckpt.unlink()
    if c["initial"]["state"] and not (resume and ckpt is not None and ckpt.exists()):
        st, _ = read_state(c["initial"]["state"], c)
        sim.start_from(st)
    t_start = time.time()
    sim.wall_origin = t_start
    last_report = t_start
    while sim.gas_step < sim.n_gas_total:
        sim.gas_step_advance()
        if sim.gas_step % sim.n_out == 0:
            sim.record()
        if ckpt is not None and sim.gas_step % sim.n_ckpt == 0 and sim.gas_step < sim.n_gas_total:
            savez_atomic(ckpt, {**sim.state(), "case_json": np.array(_checkpoint_key(c))})
        if progress and time.time() - last_report > 10:
            last_report = time.time()
            r = sim.rec
            print(f"slug: t = {sim.gas_step * sim.gas_dt:.3f} / {c['numerics']['end_time_s']} s, "
                  f"grains in tube {r['n_tube'][-1] if r['n_tube'] else 0}, dp {r['dp'][-1] if r['dp'] else 0:.1f} Pa, "
                  f"wall {last_report - t_start:.0f} s", flush=True)
    ds = sim.dataset()
    ds.attrs["wall_time_s"] = sim.wall_before + (time.time() - t_start)  # every session of the run
    converged, reason = verdict(ds)
    ds.attrs["converged"] = "true" if converged else "false"
    ds.attrs["stop_reason"] = reason
    if out is None:
        return ds
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, lambda tmp: ds.to_netcdf(tmp))
    if ckpt.exists():
        ckpt.unlink()
    return ds


def overlap_limit(stored_case: dict) -> float:
    """``numerics.overlap_limit`` of a stored slug case (a dataset's or a run record's; its
    default when the case has none), read without validating the case: a stored case is judged
    by today's verdict, not refused by rules that came after it."""
    value = ((stored_case or {}).get("numerics") or {}).get("overlap_limit")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value <= 1.0:
        return DEFAULTS["numerics"]["overlap_limit"]
    return float(value)


def verdict(ds) -> tuple[bool, str]:
    """(converged, stop_reason) of a finished slug dataset by today's rules: no grain lost, the
    largest overlap within the case's ``numerics.overlap_limit`` (:func:`problem_overlap`), and
    no porosity clipped at :data:`PHI_FLOOR`."""
    limit = overlap_limit(json.loads(ds.attrs["case"]))
    lost = int(np.asarray(ds["grains_lost"].values)) if "grains_lost" in ds else int(ds.attrs.get("grains_lost", 0))
    problems = [f"{lost} grains lost"] if lost else []
    overlap = problem_overlap(ds, limit)
    if overlap:
        problems.append(overlap)
    clipped = int(ds.attrs.get("porosity_clipped_cells", 0))
    if clipped:
        problems.append(f"the node porosity fell below {PHI_FLOOR} (denser than any packing of spheres) in {clipped} "
                        "node-steps and was clipped there: the tent transfer does not resolve the grid's cells")
    return (not problems), ("finished, but " + "; ".join(problems) if problems else "finished")


def record_verdict(stored_case: dict, grains_lost, max_overlap, clipped=None) -> tuple[bool, str]:
    """:func:`verdict` from what a study's run record keeps of the run (the grains lost, the
    largest overlap / d and the clipped node-steps) instead of its dataset.  Records written
    before the clipped count was kept (``clipped`` None) are not judged on it: they ran on the
    paper's two cells across, where the transfer does not clip."""
    limit = overlap_limit(stored_case)
    problems = [f"{int(grains_lost)} grains lost"] if grains_lost else []
    if max_overlap is not None and math.isfinite(float(max_overlap)) and float(max_overlap) > limit:
        problems.append(f"the largest grain overlap reached {100 * float(max_overlap):.3g} % of d "
                        f"(numerics.overlap_limit {100 * limit:g} %)")
    if clipped:
        problems.append(f"the node porosity fell below {PHI_FLOOR} in {int(clipped)} node-steps and was clipped there")
    return (not problems), ("finished, but " + "; ".join(problems) if problems else "finished")


def _comparable_stored(c: dict) -> dict:
    """A stored case (a dataset's ``case`` attribute) as input to :func:`validate_slug_case`: the
    state file of a continued run may be gone, and only the verdict's keys are wanted."""
    c = json.loads(json.dumps(c))
    c.pop("model", None)
    c.get("initial", {}).pop("state", None)
    return {"model": "dem-darcy", **c}


def problem_overlap(ds, limit: float) -> str:
    """"" if the largest grain overlap of the run (``max_overlap_per_d``) stayed within ``limit``
    (a fraction of d; ``numerics.overlap_limit``), else one line saying how far and when it went
    beyond, and why that happens."""
    if "max_overlap_per_d" not in ds:
        return ""
    ovl = np.asarray(ds["max_overlap_per_d"].values, dtype=float)
    if not ovl.size or not np.nanmax(ovl) > limit:
        return ""
    first = float(ds["time"].values[int(np.argmax(ovl > limit))])
    case = json.loads(ds.attrs["case"]) if "case" in ds.attrs else {}
    fed = not case.get("tube", {}).get("periodic", False)
    return (f"the largest grain overlap reached {100 * float(np.nanmax(ovl)):.3g} % of d (numerics.overlap_limit "
            f"{100 * limit:g} %, first exceeded at t = {first:.4g} s): the linear contacts no longer describe the "
            "packing" + ("; so it goes where a resting bulk jams the tube and the feed, pushed in at a fixed speed, "
                         "compresses it without bound (the run then measures that compression, not the conveying)"
                         if fed else ""))


def statistics_window(case: dict, times=None) -> tuple[float, tuple[float, float]]:
    """(t_from [s], (x0, x1) [m]) over which a run's slug statistics are taken: from an empty tube
    t ≥ min(end/2, FILL_TIME_S); a run continued from a state (``initial.state``) over the second
    half of its own time, t ≥ t0 + (end − t0)/2, t0 the state's time (read from the state file, or
    when ``times``, the dataset's record times, are given, one output interval before the first
    record); slugs centred in the middle of the tube (15–40 cm of the paper's 52.5 cm, scaled with
    the length), or anywhere in a periodic tube."""
    end = float(case["numerics"]["end_time_s"])
    L = float(case["tube"]["length_m"])
    if case["tube"].get("periodic"):
        xw = (0.0, L)
    else:
        xw = (MIDDLE[0] * L / PAPER_LENGTH, MIDDLE[1] * L / PAPER_LENGTH)
    if case.get("initial", {}).get("state"):
        if times is not None and len(times):
            t0 = float(times[0]) - float(case["numerics"]["output_interval_s"])
        else:
            t0 = state_time(case)
        return t0 + 0.5 * (end - t0), xw
    return min(0.5 * end, FILL_TIME_S), xw


def summarize(ds, x_window=(0.15, 0.4), t_min=0.0, min_grains=100, link_records=5):
    """Numbers to compare with SMH from a slug dataset (a dict of floats).

    Over records with time ≥ t_min: mean pressure drop [Pa] and per length [Pa/m], mean grains
    in the tube; over slugs of at least ``min_grains`` grains whose centre lies in
    ``x_window`` [m]: mean minimum porosity, length [m], grain count, and the slug velocity
    [m/s] from the catalogue — each such slug linked to the nearest slug ``link_records``
    records later whose centre lies 0–10 cm ahead (periodic tubes: modulo the length),
    velocity = Δx/Δt, median over the links.
    """
    t = ds["time"].values
    sel = t >= t_min
    c = json.loads(ds.attrs["case"])
    L, periodic = c["tube"]["length_m"], c["tube"]["periodic"]
    out = {"t_from_s": float(t_min), "t_to_s": float(t[-1]) if len(t) else float("nan"),
           "pressure_drop_Pa": float(ds["pressure_drop"].values[sel].mean()),
           "grains_in_tube": float(ds["grains_in_tube"].values[sel].mean())}
    out["pressure_drop_per_length_Pa_m"] = out["pressure_drop_Pa"] / L
    st, sx = ds["slug_time"].values, ds["slug_position"].values
    sg = ds["slug_grains"].values
    big = (st >= t_min) & (sg >= min_grains)
    win = big & (sx >= x_window[0]) & (sx <= x_window[1])
    out["slug_records"] = int(win.sum())
    if win.any():
        out["slug_min_porosity"] = float(ds["slug_min_porosity"].values[win].mean())
        out["slug_length_m"] = float(ds["slug_length"].values[win].mean())
        out["slug_grains"] = float(sg[win].mean())
        out["slug_max_grain_velocity_m_s"] = float(ds["slug_max_velocity"].values[win].mean())
    dt_rec = float(np.median(np.diff(t))) if len(t) > 1 else float("nan")
    span = link_records * dt_rec
    v = []
    for i in np.flatnonzero(win):
        nxt = big & np.isclose(st, st[i] + span, atol=0.25 * dt_rec)
        dx = sx[nxt] - sx[i]
        if periodic:
            dx %= L
        dx = dx[(dx >= 0) & (dx <= 0.1)]
        if len(dx):
            v.append(dx.min() / span)
    out["slug_velocity_m_s"] = float(np.median(v)) if v else float("nan")
    out["slug_velocity_links"] = len(v)
    return out


def slug_profiles(ds, x_window=(0.15, 0.4), t_min=0.0, min_grains=100, dx_max_d=40.0):
    """Averaged slug profiles against Δx/d, the distance from the slug centre in grain diameters
    (SMH Figs. 12–16; Δx > 0 ahead of the slug): porosity, grain velocity, the gas pressure
    gradient −∂P′/∂x (the drag per unit volume on the packing), and where the dataset has them
    the wall normal stress, granular temperature and contact force per grain, from the fields
    of the records, shifted to each catalogued slug's centre
    (slugs of ≥ ``min_grains`` grains centred in ``x_window`` [m], time ≥ t_min) by linear
    interpolation and averaged.  Returns an xarray.Dataset on ``dx_over_d``.
    """
    import xarray as xr

    c = json.loads(ds.attrs["case"])
    d, L, periodic = c["grains"]["diameter_m"], c["tube"]["length_m"], c["tube"]["periodic"]
    x = ds["x"].values
    t = ds["time"].values
    q = np.linspace(-dx_max_d, dx_max_d, int(2 * dx_max_d) + 1)
    st, sx, sg = ds["slug_time"].values, ds["slug_position"].values, ds["slug_grains"].values
    pick = (st >= t_min) & (sg >= min_grains) & (sx >= x_window[0]) & (sx <= x_window[1])
    phi, ux, p = ds["porosity"].values, ds["grain_velocity"].values, ds["gas_pressure"].values
    dpdx = -np.gradient(p, x, axis=1)
    extra = [k for k in ("wall_normal_stress", "granular_temperature", "contact_force") if k in ds]
    fields = {"porosity": phi, "grain_velocity": ux, "drag": dpdx, **{k: ds[k].values for k in extra}}
    acc = {k: np.zeros_like(q) for k in fields}
    cnt_f = {k: np.zeros_like(q) for k in fields}
    cnt = np.zeros_like(q)
    for i in np.flatnonzero(pick):
        k = int(np.argmin(np.abs(t - st[i])))
        xs = sx[i] + q * d
        if periodic:
            xs = xs % L
            ok = np.ones_like(q, bool)
        else:
            ok = (xs >= x[0]) & (xs <= x[-1])
        for name, f in fields.items():
            fk = f[k]
            good = np.isfinite(fk)
            if good.sum() < 2:
                continue
            vals = np.interp(xs[ok], x[good], fk[good])
            acc[name][ok] += vals
            cnt_f[name][ok] += 1
        cnt[ok] += 1
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = {k: v / cnt_f[k] for k, v in acc.items()}
    units = {"wall_normal_stress": ("Pa", "mean wall normal stress"),
             "granular_temperature": ("m2 s-2", "mean granular temperature"),
             "contact_force": ("N", "mean contact force per grain")}
    extra_vars = {k: ("dx_over_d", mean[k], dict(units=units[k][0], long_name=units[k][1])) for k in extra}
    return xr.Dataset(
        {"porosity": ("dx_over_d", mean["porosity"], dict(units="1", long_name="mean porosity")),
         "grain_velocity": ("dx_over_d", mean["grain_velocity"], dict(units="m s-1", long_name="mean axial grain velocity")),
         "drag": ("dx_over_d", mean["drag"], dict(units="Pa m-1", long_name="-dP/dx, gas force per unit volume")),
         "samples": ("dx_over_d", cnt, dict(units="1", long_name="slug records averaged")), **extra_vars},
        coords={"dx_over_d": ("dx_over_d", q, dict(units="1", long_name="distance from the slug centre / d"))})


def section_porosity(ds) -> np.ndarray:
    """The porosity of the recorded slice at ``section_x_m`` per record: ``porosity(time, x)``
    interpolated linearly between the gas cells (periodically in a periodic tube)."""
    xs = float(ds.attrs["section_x_m"])
    c = json.loads(ds.attrs["case"])
    period = float(c["tube"]["length_m"]) if c["tube"].get("periodic") else None
    x = ds["x"].values
    return np.array([np.interp(xs, x, row, period=period) for row in np.asarray(ds["porosity"].values)])


def cross_section_layers(ds, t_min=0.0, min_layer_grains=1.0):
    """The recorded cross-section (``section_x_m``; SMH §3.4, Figs. 17–19) averaged over the
    records with time ≥ ``t_min``, separately while a slug passes (the slice's porosity,
    ``porosity`` interpolated to ``section_x_m``, below :data:`SLUG_POROSITY`) and between slugs;
    records without the section (``section_recorded`` = 0) are left out.  The layers are heights
    in a horizontal tube and radii in a vertical one (``layer_coordinate``).

    Per layer (grain-centre height, ``layer``): the grain-weighted mean axial velocity,
    Σ n u / Σ n over the records; its fluctuation, the pooled rms about that mean of every grain
    of every record, √(Σ n (rms² + (u − ū)²) / Σ n); the mean number of grains per record; and the
    mean solids-fraction image.  Layers with fewer than ``min_layer_grains`` grains per record
    carry NaN velocities.  Returns an xarray.Dataset; its attributes hold the record counts and
    ``section_x_m``.  Raises ValueError for a dataset without the cross-section records."""
    import xarray as xr

    need = ("section_solids_fraction", "layer_grains", "layer_velocity", "layer_velocity_rms")
    missing = [v for v in need if v not in ds]
    if missing or "section_x_m" not in ds.attrs:
        raise ValueError(f"dataset without the recorded cross-section (no {', '.join(missing) or 'section_x_m'}); "
                         "runs record it since numerics.cross_section_at exists")
    xs = float(ds.attrs["section_x_m"])
    t = np.asarray(ds["time"].values, dtype=float)
    phi_s = section_porosity(ds)
    use = t >= t_min
    if "section_recorded" in ds:
        use &= np.asarray(ds["section_recorded"].values) == 1
    n = np.asarray(ds["layer_grains"].values, dtype=float)
    u = np.asarray(ds["layer_velocity"].values, dtype=float)
    rms = np.asarray(ds["layer_velocity_rms"].values, dtype=float)
    img = np.asarray(ds["section_solids_fraction"].values, dtype=float)
    out, attrs = {}, {"section_x_m": xs, "t_min_s": float(t_min)}
    for tag, sel in (("slug", use & (phi_s < SLUG_POROSITY)), ("between", use & (phi_s >= SLUG_POROSITY))):
        k = int(sel.sum())
        attrs[f"records_{tag}"] = k
        ns, us, rs = n[sel], u[sel], rms[sel]
        tot = ns.sum(axis=0)
        per = np.maximum(tot, 1e-300)
        mean = (ns * us).sum(axis=0) / per
        pooled = np.sqrt((ns * (rs ** 2 + (us - mean) ** 2)).sum(axis=0) / per)
        thin = tot < min_layer_grains * max(k, 1)
        mean[thin] = np.nan
        pooled[thin] = np.nan
        out[f"velocity_{tag}"] = (("layer",), mean, dict(units="m s-1", long_name=f"grain-weighted mean axial grain "
                                                                                 f"velocity of the layer, {tag} records"))
        out[f"velocity_rms_{tag}"] = (("layer",), pooled, dict(units="m s-1", long_name=f"rms of the grains' axial "
                                                                                        f"velocity about the layer mean, {tag} records"))
        out[f"grains_{tag}"] = (("layer",), tot / max(k, 1), dict(units="1", long_name=f"grains per record in the layer, {tag} records"))
        out[f"section_{tag}"] = (("section_z", "section_y"), img[sel].mean(axis=0) if k else np.zeros(img.shape[1:]),
                                 dict(units="1", long_name=f"mean solids fraction of the slice, {tag} records"))
    return xr.Dataset(out, coords={c: ds[c] for c in ("layer", "section_y", "section_z")}, attrs=attrs)


def layer_shear(layers, tag: str = "slug") -> dict:
    """Numbers of the layer profile in slugs from :func:`cross_section_layers` (SMH Fig. 19: the
    lowest layers slowest, the uppermost fastest; in a vertical tube, where the layers are radial,
    "first" is the axis and "last" the wall): the velocities of the first and last populated
    layers [m/s], their difference, how monotonically the profile rises across the layers
    (Spearman rank correlation of velocity with layer), and the ratio of the grain-weighted
    fluctuation to the grain-weighted mean velocity.  ``tag``: "slug" (records while a slug passes
    the slice) or "between"."""
    u = np.asarray(layers[f"velocity_{tag}"].values, dtype=float)
    r = np.asarray(layers[f"velocity_rms_{tag}"].values, dtype=float)
    w = np.asarray(layers[f"grains_{tag}"].values, dtype=float)
    ok = np.isfinite(u)
    if ok.sum() < 2:
        return {"layers": int(ok.sum())}
    from scipy.stats import rankdata

    uo, ro, wo = u[ok], r[ok], w[ok]
    ranks = rankdata(uo)  # average ranks for ties: a constant profile has no correlation (NaN)
    rho = float(np.corrcoef(ranks, np.arange(len(uo)))[0, 1]) if np.ptp(uo) > 0 else float("nan")
    mean = float((wo * uo).sum() / wo.sum())
    fluct = float(np.sqrt((wo * ro ** 2).sum() / wo.sum()))
    return {"layers": int(ok.sum()), "u_first_m_s": float(uo[0]), "u_last_m_s": float(uo[-1]),
            "shear_m_s": float(uo[-1] - uo[0]), "rank_correlation_with_layer": rho,
            "mean_velocity_m_s": mean, "fluctuation_m_s": fluct,
            "fluctuation_over_mean": fluct / mean if mean else float("nan")}


# ---------------------------------------------------------------------------------------------
#: porosity of the paper's slugs (SMH §3.2: minimum slug porosity 0.47-0.49), for the numbers of
#: :func:`check_report`
CHECK_SLUG_POROSITY = 0.48
#: Wall time of the run-time estimate of :func:`check_report` [s per grain in the tube and
#: simulated second]: the three runs of the filled horizontal tube at v_s = 1 m/s over 6 s, one
#: thread each beside a scene run on the 2-core x86_64 machine, 0.062-0.066 (955-1,346 s over 6 s
#: with 2,574-3,636 grains, the means over each run's second half; results/strauss-filled/
#: grain-weights/eta-6s, the records' wall_time_s and grains_in_tube); the upper end is taken
CHECK_WALL_S_PER_GRAIN_SECOND = 0.065
#: the DEM steps per simulated second of those runs (k_n = 1000 N/m, e = 0.5, t_c/30: 36 per 1e-4 s gas step)
CHECK_REFERENCE_STEPS_PER_S = 36 / 1e-4

_UNITS = {"length_m": "m", "diameter_m": "m", "density_kg_m3": "kg m-3", "stiffness_N_m": "N m-1",
          "pressure_Pa": "Pa", "viscosity_Pa_s": "Pa s", "superficial_velocity_m_s": "m s-1",
          "permeability_cap_m2": "m2", "mass_flow_kg_h": "kg h-1", "block_length_m": "m", "plug_length_m": "m",
          "plug_start_m": "m", "gas_dt_s": "s", "end_time_s": "s", "output_interval_s": "s",
          "checkpoint_interval_s": "s", "overlap_limit": "d"}


def check_report(case: dict, source=None) -> str:
    """``eulag check`` of a "dem-darcy" case: every key resolved (defaults marked) and the numbers
    the run will meet — the grains' mass and contact time, the DEM step, the feed, the gas flow,
    the Carman-Kozeny permeability and Darcy pressure gradient of a slug, the gas diffusivity,
    the steps and records of the run, and a wall-time estimate. Raises ValueError as
    :func:`validate_slug_case` for a bad case."""
    from darcy.permeability import carman_kozeny, poiseuille_tube_permeability
    from dem.engine import ContactModel
    from dem.feed import feed_speed

    from eulag.config import resolved_case_lines

    c = validate_slug_case(case)
    rows = [(f"{sec}.{k}", c[sec][k], _UNITS.get(k, ""), k in case.get(sec, {})) for sec, keys in DEFAULTS.items()
            for k in keys]
    lines = resolved_case_lines(c, "dem-darcy", source, rows)
    t, gr, gas, fd, num = c["tube"], c["grains"], c["gas"], c["feed"], c["numerics"]
    d, rho, Dt = gr["diameter_m"], gr["density_kg_m3"], t["diameter_m"]
    area = math.pi * Dt * Dt / 4.0
    cm = ContactModel(d, rho, gr["stiffness_N_m"], gr["restitution"], gr["friction"], gr["wall_friction"],
                      tangential_ratio=gr["tangential_damping_ratio"])
    n_sub, dt = dem_steps(cm.t_contact, num["steps_per_contact"], num["gas_dt_s"])
    weight = cm.mass * _G
    lines += ["", "Grains",
              f"  mass         m = {cm.mass:.4g} [kg]; weight m g = {weight:.4g} [N], per tube cross-section "
              f"m g / A_t = {weight / area:.4g} [Pa]",
              f"  contact      t_c = {cm.t_contact:.4g} [s] (k_n = {gr['stiffness_N_m']:g} N/m, e = {gr['restitution']:g}); "
              f"DEM step {dt:.4g} [s] = t_c / {cm.t_contact / dt:.3g}, {n_sub} per gas step",
              f"  overlap      an impact at 1 m/s overlaps at most {100 * math.sqrt(0.5 * cm.mass / gr['stiffness_N_m']) / d:.3g} % "
              "of d (an undamped pair; the runs report their largest overlap)",
              f"  tangential   gamma_t / gamma_n = {gr['tangential_damping_ratio']:g}, stable below "
              f"{tangential_damping_limit(gr['restitution'], num['steps_per_contact']):.3g} (a packing in the DEM step)"]
    if t["periodic"]:
        lines += ["", "Feed", "  none         periodic tube: the initial plug of "
                  f"{c['initial']['plug_length_m']:g} m circulates"]
    else:
        mdot = fd["mass_flow_kg_h"] / 3600.0
        vf = feed_speed(mdot, rho, fd["porosity"], Dt)
        lines += ["", "Feed",
                  f"  grains       {mdot / cm.mass:.4g} [s-1] ({fd['mass_flow_kg_h']:g} kg/h), pushed in at "
                  f"{vf:.4g} [m s-1] as a packing of porosity {fd['porosity']:g}"]
    vs, eta, P0 = gas["superficial_velocity_m_s"], gas["viscosity_Pa_s"], gas["pressure_Pa"]
    k_slug = float(carman_kozeny(CHECK_SLUG_POROSITY, d))
    k_feed = float(carman_kozeny(fd["porosity"], d))
    k_cap = gas["permeability_cap_m2"] or poiseuille_tube_permeability(Dt)
    dx = t["length_m"] / num["cells_x"]
    diff = P0 * k_slug / (eta * CHECK_SLUG_POROSITY)
    scheme = "backward Euler" if num["theta"] == 1.0 else f"theta = {num['theta']:g}"
    lines += ["", "Gas",
              f"  flow         v_s = {vs:g} [m s-1] = {vs * area * 6e4:.3g} [l min-1] through the tube",
              f"  Darcy        Carman-Kozeny kappa = {k_slug:.4g} [m2] in a slug (porosity {CHECK_SLUG_POROSITY}), "
              f"{k_feed:.4g} [m2] in the feed ({fd['porosity']:g})",
              f"  slug         a packing at {CHECK_SLUG_POROSITY} at rest: -dP/dx = eta v_s / kappa = "
              f"{eta * vs / k_slug / 100:.4g} [hPa m-1]; its weight rho_s (1 - phi) g = "
              f"{rho * (1 - CHECK_SLUG_POROSITY) * _G / 100:.4g} [hPa m-1]",
              f"  empty tube   kappa cap {k_cap:.4g} [m2]" + (" (D_t^2/32, Poiseuille)" if not gas["permeability_cap_m2"] else "")
              + f": -dP/dx = {eta * vs / k_cap:.4g} [Pa m-1]",
              f"  diffusivity  P0 kappa / (eta phi) = {diff:.4g} [m2 s-1] in a slug: a gas cell (dx = {1e3 * dx:.3g} mm) "
              f"relaxes in dx^2/D = {dx * dx / diff:.3g} [s], the gas step is {num['gas_dt_s']:g} [s] "
              f"({scheme}, implicit)"]
    # a run continued from a saved state simulates from the state's time to end_time_s
    t0 = state_time(case)
    span = num["end_time_s"] - t0
    n_gas = int(round(span / num["gas_dt_s"]))
    per_s = 1000.0 * CHECK_WALL_S_PER_GRAIN_SECOND * (n_sub / num["gas_dt_s"]) / CHECK_REFERENCE_STEPS_PER_S
    lines += ["", "Numerics",
              f"  grid         {num['cells_x']} x {num['cells_across']} x {num['cells_across']} gas nodes, dx = {1e3 * dx:.3g} [mm]",
              f"  time         {span:g} s" + (f" (from the state's t = {t0:g} s to {num['end_time_s']:g} s)" if t0 else "")
              + f": {n_gas:,} gas steps, {n_gas * n_sub:,} DEM steps; a record every "
              f"{num['output_interval_s']:g} s ({int(round(span / num['output_interval_s'])):,}), "
              f"a checkpoint every {num['checkpoint_interval_s']:g} s",
              f"  cost         about {per_s:.3g} s of wall time per simulated second and 1,000 grains in the tube on one "
              "core (measured with the default DEM step, scaled by the steps per second; SMH's default tube holds "
              "about 3,200 grains)"]
    packed = (1.0 - fd["porosity"]) * area / cm.volume  # grains per metre of tube packed as the feed
    if t["periodic"]:
        n = packed * c["initial"]["plug_length_m"]
        lines.append(f"  this run     {n:,.0f} grains (the initial plug): about {per_s * n / 1000 * span:,.0f} s")
    else:
        n = packed * t["length_m"]
        lines.append(f"  this run     at most {n:,.0f} grains (the tube packed as the feed): at most about "
                     f"{per_s * n / 1000 * span:,.0f} s")
    return "\n".join(lines)


def dataset_from_checkpoint(case: dict, checkpoint):
    """The dataset of a run so far, from its checkpoint (``<out>.checkpoint``): a look at a
    running or interrupted run without disturbing it."""
    sim = _Simulation(validate_slug_case(case))
    with np.load(Path(checkpoint), allow_pickle=False) as z:
        sim.load({k: z[k] for k in z.files if k != "case_json"})
    ds = sim.dataset()
    ds.attrs["partial"] = f"from checkpoint at t = {sim.gas_step * sim.gas_dt:.4g} s"
    return ds
