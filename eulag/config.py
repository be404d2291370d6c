"""Case files (TOML) -> frozen, validated case objects.

A case file has a few top-level keys (``name``, ``description``) and the tables
``[pipe]``, ``[gas]``, ``[particles]`` (absent: single-phase), ``[walls]``,
``[physics]`` and ``[numerics]``; docs/case-reference.md lists every key. Every value is
checked for type, unit sense and range when the case is built, before any work
starts. Anything wrong raises :class:`CaseError` with a one-line message naming
the key (dotted, e.g. ``pipe.diameter``), the value and what is allowed::

    pipe.diameter = -0.03: out of range; allowed: a number > 0 and <= 5 (inner diameter, m)

Typing rules: a boolean is not an integer; an integer is accepted where a number
(float) is expected and stored as a float; a float is not accepted where an
integer is expected. NaN and infinities are rejected everywhere.

All quantities are SI (m, kg m-3, Pa s, m s-1, ...); the one exception is
``walls.roughness_angle_std_deg`` [degrees].

Usage::

    case = Case.from_toml("cases/single_phase_pipe.toml")
    case.pipe.diameter            # 0.0305 [m]
    attrs = case.to_attrs()       # flat {"pipe.diameter": 0.0305, ...} for NetCDF
    Case.from_attrs(attrs) == case
    lighter = case.replace(numerics={"parcels": 20000})
"""

from __future__ import annotations

import dataclasses
import difflib
import inspect
import math
import re
import tomllib
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

__all__ = [
    "CaseError",
    "Case",
    "PipeConfig",
    "GasConfig",
    "ParticleConfig",
    "WallConfig",
    "PhysicsConfig",
    "NumericsConfig",
]

#: directory of the case files shipped with eulag (the ``cases`` package)
CASES_DIR = Path(__file__).resolve().parent.parent / "cases"
#: Most parcels per pass (and per batch): 10⁹ parcels of the base case would take weeks, and
#: parcel ids stay far from the int64 range.
MAX_PARCELS = 1_000_000_000
#: Most cells of a mesh (numerics.axial_cells × radial_cells × azimuthal_cells): about 50 GB of
#: gas and sampling arrays, far beyond a workstation; the studies use 320,000.
MAX_CELLS = 100_000_000


class CaseError(ValueError):
    """A case file or case value is not acceptable. The message is one line."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


# ---------------------------------------------------------------------------
# field specifications
# ---------------------------------------------------------------------------

NUMBER, INTEGER, BOOLEAN, STRING, NUMBERS = "number", "integer", "boolean", "string", "numbers"


def _param(kind: str, doc: str, *, default: Any = MISSING, unit: str = "", gt=None, ge=None,
           lt=None, le=None, choices: tuple[str, ...] | None = None, even: bool = False,
           optional: bool = False, none_label: str = "none", min_items: int = 0):
    """A dataclass field carrying its validation rule in ``metadata``.

    ``optional``: the value may be absent (None); ``none_label`` is how None is written
    into the dataset attributes. A field with default None that is not ``optional`` is an
    automatic default, resolved by the class from other fields.
    """
    meta = dict(kind=kind, doc=doc, unit=unit, gt=gt, ge=ge, lt=lt, le=le, choices=choices,
                even=even, optional=optional, none_label=none_label, min_items=min_items)
    if default is MISSING:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


def _fmt(value: Any) -> str:
    """A value as it would be written in TOML, on one short line."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, str):
        text = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    elif isinstance(value, (list, tuple)):
        text = "[" + ", ".join(_fmt(v) for v in value) + "]"
    elif isinstance(value, dict):
        text = "{" + ", ".join(f"{k} = {_fmt(v)}" for k, v in value.items()) + "}"
    elif isinstance(value, float):
        text = repr(value)
    else:
        text = str(value)
    text = " ".join(text.split())
    return text if len(text) <= 80 else text[:77] + "..."


def _num(x) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _allowed(meta: dict) -> str:
    """Human description of what a field accepts, e.g. 'a number > 0 and <= 5 (diameter, m)'."""
    kind = meta["kind"]
    if meta["choices"]:
        text = "one of " + ", ".join(f'"{c}"' for c in meta["choices"])
    elif kind == BOOLEAN:
        text = "true or false"
    elif kind == STRING:
        text = "a string"
    else:
        text = {NUMBER: "a number", INTEGER: "an integer", NUMBERS: "a list of numbers"}[kind]
        bounds = []
        if meta["gt"] is not None:
            bounds.append(f"> {_num(meta['gt'])}")
        if meta["ge"] is not None:
            bounds.append(f">= {_num(meta['ge'])}")
        if meta["lt"] is not None:
            bounds.append(f"< {_num(meta['lt'])}")
        if meta["le"] is not None:
            bounds.append(f"<= {_num(meta['le'])}")
        if bounds:
            text += (", each " if kind == NUMBERS else " ") + " and ".join(bounds)
        if meta["even"]:
            text += " and even"
        if meta["min_items"]:
            text += f", at least {meta['min_items']}"
    note = meta["doc"] + (f", {meta['unit']}" if meta["unit"] else "")
    return f"{text} ({note})" if note else text


def _error(key: str, value: Any, reason: str, allowed: str) -> CaseError:
    return CaseError(f"{key} = {_fmt(value)}: {reason}; allowed: {allowed}")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_bounds(key: str, value: Any, shown: Any, meta: dict) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise _error(key, shown, "not a finite number", _allowed(meta))
    for bound, ok in (("gt", lambda a, b: a > b), ("ge", lambda a, b: a >= b),
                      ("lt", lambda a, b: a < b), ("le", lambda a, b: a <= b)):
        if meta[bound] is not None and not ok(value, meta[bound]):
            raise _error(key, shown, "out of range", _allowed(meta))


def _as_float(key: str, value: Any, meta: dict) -> float:
    try:
        return float(value)
    except OverflowError:  # an integer beyond the range of a double
        raise _error(key, _short(value), "too large for a floating-point number", _allowed(meta)) from None


def _short(value: Any) -> str:
    text = str(value)
    return text if len(text) <= 24 else f"{text[:12]}...({len(text)} digits)"


def _check_value(key: str, value: Any, meta: dict) -> Any:
    """Validate one value against its field rule; return it normalised (int->float, list->tuple)."""
    kind = meta["kind"]
    if value is None:
        if meta["optional"]:
            return None
        raise _error(key, "none", "missing value", _allowed(meta))
    if kind == NUMBER:
        if not _is_number(value):
            raise _error(key, value, f"wrong type ({_type_name(value)})", _allowed(meta))
        shown, value = value, _as_float(key, value, meta)
        _check_bounds(key, value, shown, meta)
    elif kind == INTEGER:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise _error(key, value, f"wrong type ({_type_name(value)})", _allowed(meta))
        value = int(value)
        _check_bounds(key, value, value, meta)
        if meta["even"] and value % 2:
            raise _error(key, value, "odd", _allowed(meta))
    elif kind == BOOLEAN:
        if not isinstance(value, bool):
            raise _error(key, value, f"wrong type ({_type_name(value)})", _allowed(meta))
    elif kind == STRING:
        if not isinstance(value, str):
            raise _error(key, value, f"wrong type ({_type_name(value)})", _allowed(meta))
        if meta["choices"] and value not in meta["choices"]:
            raise _error(key, value, "not one of the choices", _allowed(meta))
    elif kind == NUMBERS:
        if not isinstance(value, (list, tuple)) or not all(_is_number(v) for v in value):
            raise _error(key, value, f"wrong type ({_type_name(value)})", _allowed(meta))
        shown, value = list(value), tuple(_as_float(key, v, meta) for v in value)
        if len(value) < meta["min_items"]:
            raise _error(key, shown, "too few values", _allowed(meta))
        for v in value:
            _check_bounds(key, v, shown, meta)
    else:  # pragma: no cover - programming error
        raise AssertionError(kind)
    return value


def _type_name(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "float"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        return "list"
    if isinstance(value, dict):
        return "table"
    return type(value).__name__


def _public_fields(cls) -> list[dataclasses.Field]:
    return [f for f in fields(cls) if f.init and not f.name.startswith("_")]


class _Section:
    """Validation shared by the section dataclasses (runs in ``__post_init__``)."""

    section: ClassVar[str] = ""

    def __post_init__(self):
        for f in _public_fields(self):
            value = getattr(self, f.name)
            if value is None and not f.metadata["optional"]:
                continue  # automatic default, resolved by the subclass
            object.__setattr__(self, f.name, _check_value(f"{self.section}.{f.name}", value, f.metadata))
        self._resolve_and_check()

    def _resolve_and_check(self) -> None:
        """Resolve automatic defaults and check relations between keys of the section."""

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    def _meta(self, name: str) -> dict:
        return next(f.metadata for f in fields(self) if f.name == name)

    @classmethod
    def _from_table(cls, table: Any, section: str | None = None):
        section = section or cls.section
        if not isinstance(table, dict):
            raise CaseError(f"{section} = {_fmt(table)}: wrong type ({_type_name(table)}); "
                            f"allowed: a table [{section}]")
        names = [f.name for f in _public_fields(cls)]
        for key, value in table.items():
            if key not in names:
                raise _unknown(f"{section}.{key}", value, names, f"[{section}]")
        for f in _public_fields(cls):
            required = f.default is MISSING and f.default_factory is MISSING
            if required and f.name not in table:
                raise CaseError(f"{section}.{f.name}: missing (a required key); "
                                f"allowed: {_allowed(f.metadata)}")
        return cls(**table)

    def _to_flat(self, prefix: str) -> dict[str, Any]:
        out = {}
        for f in _public_fields(self):
            out[f"{prefix}.{f.name}"] = _attr_value(getattr(self, f.name), f.metadata)
        return out

    def _to_table(self) -> dict[str, Any]:
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in _public_fields(self) if getattr(self, f.name) is not None}


#: Tables of the dense-phase models' cases, for the message when a case leaves out its model key.
_OTHER_MODEL_TABLES = {"tube": "dem-darcy", "grains": "dem-darcy", "feed": "dem-darcy", "initial": "dem-darcy",
                       "solids": "two-fluid", "friction": "two-fluid", "kinetic": "two-fluid", "drag": "two-fluid",
                       "experiment": "two-fluid"}


def _unknown(key: str, value: Any, names: list[str], where: str) -> CaseError:
    leaf = key.rsplit(".", 1)[-1]
    close = difflib.get_close_matches(leaf, names, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    return CaseError(f"{key} = {_fmt(value)}: unknown key{hint}; allowed keys in {where}: "
                     + ", ".join(names))


def _attr_value(value: Any, meta: dict) -> Any:
    """A field value as a NetCDF attribute: str, int, float or a float array."""
    if value is None:
        return meta["none_label"]
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple):
        return np.asarray(value, dtype=np.float64)
    return value


# ---------------------------------------------------------------------------
# sections
# ---------------------------------------------------------------------------

@dataclass(frozen=True, kw_only=True)
class PipeConfig(_Section):
    """The straight horizontal circular pipe.

    Attributes
    ----------
    diameter : float
        Inner diameter [m], > 0 and <= 5 (a value in mm would be caught here).
    length : float
        Pipe length from the inlet to the outlet [m], > 0. In periodic mode it is the pipe
        length the pressure drop refers to.
    mode : str
        ``"developing"`` (uniform inlet, marching to the outlet) or ``"periodic"``
        (axially periodic, fully developed flow at the prescribed bulk velocity).
    sections : tuple of float
        Axial stations reported and plotted [m], each within [0, length]. Default: the outlet
        (``(length,)``).
    reference_data : str or None
        File with measurements for this case (CSV), relative to the case file's directory or
        to eulag's ``cases/`` directory. None: no measurements.
    """

    section: ClassVar[str] = "pipe"

    diameter: float = _param(NUMBER, "inner diameter", unit="m", gt=0.0, le=5.0)
    length: float = _param(NUMBER, "pipe length", unit="m", gt=0.0, le=1.0e4)
    mode: str = _param(STRING, "axial treatment", default="developing",
                       choices=("developing", "periodic"))
    sections: tuple[float, ...] | None = _param(
        NUMBERS, "stations reported, within [0, pipe.length]", unit="m", default=None, ge=0.0,
        min_items=1)
    reference_data: str | None = _param(
        STRING, "measurement file beside the case file or in cases/", default=None,
        optional=True)

    def _resolve_and_check(self):
        if self.sections is None:
            self._set("sections", (self.length,))
        bad = [s for s in self.sections if s > self.length]
        if bad:
            raise _error("pipe.sections", list(self.sections), "out of range",
                         f"numbers within [0, pipe.length = {_num(self.length)}] (m)")
        if self.reference_data is not None and not self.reference_data.strip():
            raise _error("pipe.reference_data", self.reference_data, "empty",
                         _allowed(self._meta("reference_data")))

    @property
    def radius(self) -> float:
        """Inner radius [m]."""
        return 0.5 * self.diameter


@dataclass(frozen=True, kw_only=True)
class GasConfig(_Section):
    """The carrier gas (incompressible, constant properties) and its inlet state.

    Attributes
    ----------
    density : float
        Gas density [kg m-3], in (0, 100].
    viscosity : float
        Dynamic viscosity [Pa s], in (0, 1e-3] (gases are about 1e-5).
    bulk_velocity : float
        Bulk (section-mean) axial velocity U0 [m s-1], in (0, 100] (incompressible solver);
        uniform at the inlet in developing mode.
    inlet_k : float
        Turbulent kinetic energy at the inlet [m2 s-2], > 0 and <= bulk_velocity**2.
        In periodic mode only the initial guess.
    inlet_epsilon : float or None
        Dissipation rate at the inlet [m2 s-3], > 0. None: the solver computes it from a
        length scale of 0.07 D, eps = C_mu**0.75 k**1.5 / (0.07 D).
    """

    section: ClassVar[str] = "gas"

    density: float = _param(NUMBER, "gas density", unit="kg m-3", gt=0.0, le=100.0)
    viscosity: float = _param(NUMBER, "dynamic viscosity", unit="Pa s", gt=0.0, le=1.0e-3)
    bulk_velocity: float = _param(NUMBER, "bulk velocity", unit="m s-1", gt=0.0, le=100.0)
    inlet_k: float = _param(NUMBER, "inlet turbulent kinetic energy, <= bulk_velocity^2",
                            unit="m2 s-2", gt=0.0)
    inlet_epsilon: float | None = _param(
        NUMBER, "inlet dissipation rate; absent: C_mu^0.75 k^1.5 / (0.07 D)", unit="m2 s-3",
        default=None, gt=0.0, optional=True, none_label="auto: C_mu^0.75 k^1.5 / (0.07 D)")

    def _resolve_and_check(self):
        if self.inlet_k > self.bulk_velocity ** 2:
            raise _error("gas.inlet_k", self.inlet_k, "out of range",
                         f"a number > 0 and <= gas.bulk_velocity^2 = {_num(self.bulk_velocity ** 2)} "
                         "(inlet turbulent kinetic energy, m2 s-2)")

    @property
    def kinematic_viscosity(self) -> float:
        """nu = mu / rho [m2 s-1]."""
        return self.viscosity / self.density


@dataclass(frozen=True, kw_only=True)
class ParticleConfig(_Section):
    """The dispersed phase (monodisperse spheres). Absent from a case: single-phase flow.

    Attributes
    ----------
    diameter : float
        Particle diameter [m], > 0 and < pipe.diameter / 5 (point particles: larger ones
        span a good part of the section, and from about the wall-cell size on their sources
        are point sources in cells smaller than the particle; the experiment's 3.4 mm pellets,
        D/9, are inside the limit).
    density : float
        Particle material density [kg m-3], > gas.density and <= 25000.
    mass_loading : float
        Particle mass flow rate / gas mass flow rate [1], > 0 (a case without particles leaves
        out [particles]).
    injection_rms : float
        Rms of the Gaussian injection velocity, each component [m s-1], >= 0 (default 0.5).
        The mean injection velocity is (bulk_velocity, 0, 0).
    restitution : float
        Particle-particle normal restitution coefficient [1], in [0, 1] (default 0.9, seed).
    friction : float
        Particle-particle (static = dynamic) friction coefficient [1], in [0, 1] (default 0.4,
        seed).
    """

    section: ClassVar[str] = "particles"

    diameter: float = _param(NUMBER, "particle diameter, < pipe.diameter / 5", unit="m", gt=0.0)
    density: float = _param(NUMBER, "particle density, > gas.density", unit="kg m-3", gt=0.0,
                            le=25000.0)
    mass_loading: float = _param(NUMBER, "particle / gas mass flow (a case without particles leaves out "
                                 "[particles])", gt=0.0, le=1000.0)
    injection_rms: float = _param(NUMBER, "injection velocity rms per component", unit="m s-1",
                                  default=0.5, ge=0.0)
    restitution: float = _param(NUMBER, "particle-particle restitution coefficient", default=0.9,
                                ge=0.0, le=1.0)
    friction: float = _param(NUMBER, "particle-particle friction coefficient", default=0.4,
                             ge=0.0, le=1.0)


@dataclass(frozen=True, kw_only=True)
class WallConfig(_Section):
    """Particle-wall collisions on the rough wall (Sommerfeld & Huber 1999).

    Attributes
    ----------
    roughness_angle_std_deg : float
        Standard deviation of the wall roughness angle, Delta gamma [degrees], in [0, 45];
        0 is a smooth wall (default).
    impact_angle : str
        Angle used in e_w(alpha), mu_w(alpha): ``"effective"`` (alpha + gamma, relative to
        the virtual wall; default) or ``"nominal"``.
    lateral_roughness : bool
        Also tilt the virtual wall laterally by gamma_2 ~ N(0, Delta gamma) (default true);
        false: in-plane roughness only.
    shadow_effect : str
        ``"weighted"``: the sin(alpha + gamma)-weighted effective pdf (default);
        ``"rejection"``: only reject alpha + gamma <= 0.
    """

    section: ClassVar[str] = "walls"

    roughness_angle_std_deg: float = _param(NUMBER, "roughness angle standard deviation",
                                            unit="degrees", default=0.0, ge=0.0, le=45.0)
    impact_angle: str = _param(STRING, "angle in e_w, mu_w", default="effective",
                               choices=("effective", "nominal"))
    lateral_roughness: bool = _param(BOOLEAN, "lateral roughness angle", default=True)
    shadow_effect: str = _param(STRING, "shadow-effect sampling", default="weighted",
                                choices=("weighted", "rejection"))


@dataclass(frozen=True, kw_only=True)
class PhysicsConfig(_Section):
    """Physics switches of a scene. What a scene switches off is not computed.

    Attributes
    ----------
    coupling : str
        ``"one-way"`` (gas -> particles), ``"two-way"`` (+ particles -> gas) or
        ``"four-way"`` (+ particle-particle collisions; default).
    drag : str
        Drag law: ``"schiller-naumann"``.
    saffman_mei_lift, magnus_lift, rotation, langevin, gravity : bool
        Slip-shear lift (Saffman with the Mei correction), slip-rotation (Magnus) lift,
        particle rotation, Langevin dispersion (fluid velocity seen), gravity. Default true;
        ``magnus_lift`` defaults to ``rotation`` and needs it.
    magnus_model : str
        Rotational lift coefficient: ``"lun-liu"`` (default) or ``"oesterle-bui-dinh"``.
    langevin_drift_correction : bool
        Drift correction for inhomogeneous turbulence (MacInnes & Bracco 1992), its time factor
        set by ``langevin_drift_form`` (default true; false: the reference paper's eq. 12).
    inter_particle_collisions : bool
        Stochastic inter-particle collisions (Sommerfeld 2001). Default: true for four-way
        coupling, false otherwise; true needs four-way coupling.
    c_eps3 : float
        C_eps3 of the dissipation source S_eps = C_eps3 (eps/k) S_k [1], in [0, 3] (default 1.8,
        the seed's). With C_eps3 > C_eps1 = 1.44 the k-eps equations have no positive local
        equilibrium where the particle sink dominates; an option for
        sensitivity studies, not a tuning knob.
    k_source_scaling : str
        How the sampled turbulence source S_k = -<u'_F . J> enters the gas: ``"seen-energy"``
        (default) rescales it per cell by k / k_seen, the gas k over the energy 1/2<|u'_F|^2>
        of the fluctuations the particles saw there (identical where the Langevin model is
        consistent with the gas k; where particles carry their fluid-velocity memory into a
        pocket the sink has already drained, it stops the sink from feeding on energy the gas
        no longer has); ``"none"``: the seed's estimator as sampled.
    langevin_drift_form : str
        Time factor of the drift correction (1 - R) T_L (2/3) grad k of the fluid velocity seen:
        ``"lagrangian"`` (default; R = R_L, the fluid's Lagrangian correlation: the drift
        d<u'u'>/dx dt that the mean pressure gradient gives the fluid seen over the step, whatever
        the particle's inertia, Minier & Peirano 2001) or ``"particle"`` (R = R_P, the particle's
        correlation with the crossing-trajectory part, the form in which the MacInnes & Bracco
        term is usually quoted; its mean fluid velocity seen is T_L d<u'u'>/dx instead of T_L* d<u'u'>/dx, T_L* the
        shorter decorrelation time of the fluid seen), or ``"response"`` (the Lagrangian factor
        times 1/(1 + St), St = tau_p/T_L, the particle's response to the fluid after Bocksell &
        Loth 2006 and Dehbi 2008: zero for a particle too heavy to follow the fluid, whose fluid
        seen is the Eulerian one with zero mean fluctuation). Identical for tracers.
    partner_correlation : str
        Where the stochastic collision model takes the Stokes number of its partner
        correlation R(St) = exp(-0.55 St^0.4): ``"particle"`` (default; at the real particle,
        with T_L of the gas at its position) or ``"cell"`` (once per cell, from the cell-mean
        slip of the statistics and the cell-centre k, eps of the gas the pass runs in). Same
        constants; the partner is drawn about the cell mean either way (a per-particle R that
        varies across the wall cell makes the collisions' net momentum non-zero).
    partner_covariance : str
        How the fictitious partner's velocity fluctuation is drawn: ``"components"`` (default;
        Sommerfeld 2001 and the reference paper: each Cartesian component with the cell's rms
        of that component, independently) or ``"full"`` (with the cell's whole velocity
        covariance matrix, through its Cholesky factor: the same velocity law in any frame (the
        spin fluctuation stays per component). Near the wall
        the particles' wall-normal and along-wall fluctuations differ; in the cells at 45° to the
        axes that difference is a y-z covariance, which the components' draw drops, so there the
        partners are more isotropic than the particles).
    partner_momentum : str
        What becomes of the impulse the fictitious collision partners would receive:
        ``"discarded"`` (Sommerfeld 2001 and the reference paper: only the real particle is
        updated, so the collisions conserve momentum only while the partners' Gaussian law
        matches the cell's particles, which rebounds from a rough wall skew) or ``"returned"``
        (default; real collisions conserve momentum: the cell's particles receive an
        acceleration a spread over their residence time; the coupling
        loop adjusts a from pass to pass by -3 alpha F_net / W_ref (``coupling.RETURNED_GAIN``),
        F_net the cell's net collision force and W_ref its mean particle mass over the earlier
        passes, so the net
        collision force per cell vanishes in the mean at the coupled steady state;
        ``particles.PhysicsOptions``, ``eulag.coupling``).
    wall_cell_fields : str
        The gas fields a particle sees between the wall-ring centre and the wall (the
        wall-function cell): ``"log-law"`` (default) reconstructs U (log law, or the
        sublayer's linear profile below y*_v), ∇ × U and ε ∝ 1/y from the wall-ring values;
        ``"wall-ring"`` holds the wall-ring values out to the wall. The reference paper does not
        say how its particles see the wall cell (docs/physics.md, section 3).
    """

    section: ClassVar[str] = "physics"

    coupling: str = _param(STRING, "phase coupling", default="four-way",
                           choices=("one-way", "two-way", "four-way"))
    drag: str = _param(STRING, "drag law", default="schiller-naumann",
                       choices=("schiller-naumann",))
    saffman_mei_lift: bool = _param(BOOLEAN, "slip-shear lift", default=True)
    magnus_lift: bool | None = _param(BOOLEAN, "slip-rotation lift, needs physics.rotation",
                                      default=None)
    magnus_model: str = _param(STRING, "rotational lift coefficient", default="lun-liu",
                               choices=("lun-liu", "oesterle-bui-dinh"))
    rotation: bool = _param(BOOLEAN, "particle rotation", default=True)
    langevin: bool = _param(BOOLEAN, "Langevin dispersion", default=True)
    langevin_drift_correction: bool = _param(BOOLEAN, "drift correction", default=True)
    langevin_drift_form: str = _param(STRING, "time factor of the drift correction", default="lagrangian",
                                      choices=("particle", "lagrangian", "response"))
    gravity: bool = _param(BOOLEAN, "gravity", default=True)
    inter_particle_collisions: bool | None = _param(
        BOOLEAN, "inter-particle collisions, needs four-way coupling", default=None)
    c_eps3: float = _param(NUMBER, "C_eps3 of the particle dissipation source", default=1.8, ge=0.0,
                           le=3.0)
    k_source_scaling: str = _param(STRING, "scaling of the sampled turbulence source",
                                   default="seen-energy", choices=("seen-energy", "none"))
    partner_correlation: str = _param(STRING, "where the collision partner's correlation R(St) is taken",
                                      default="particle", choices=("particle", "cell"))
    partner_covariance: str = _param(STRING, "the collision partner's velocity fluctuation",
                                     default="components", choices=("components", "full"))
    partner_momentum: str = _param(STRING, "the collision partners' impulse", default="returned",
                                   choices=("discarded", "returned"))
    wall_cell_fields: str = _param(STRING, "gas fields the particles see in the wall-function cell",
                                   default="log-law", choices=("log-law", "wall-ring"))

    def _resolve_and_check(self):
        if self.magnus_lift is None:
            self._set("magnus_lift", self.rotation)
        elif self.magnus_lift and not self.rotation:
            raise _error("physics.magnus_lift", True, "needs physics.rotation = true",
                         "false when physics.rotation = false")
        if self.inter_particle_collisions is None:
            self._set("inter_particle_collisions", self.coupling == "four-way")
        elif self.inter_particle_collisions and self.coupling != "four-way":
            raise _error("physics.inter_particle_collisions", True,
                         f'needs physics.coupling = "four-way" (is "{self.coupling}")',
                         'false unless physics.coupling = "four-way"')


@dataclass(frozen=True, kw_only=True)
class NumericsConfig(_Section):
    """Mesh, solver and Lagrangian-pass settings.

    Attributes
    ----------
    axial_cells : int
        Axial stations, >= 10 (default 400); ignored in periodic mode.
    radial_cells : int
        Radial rings of the cross-section, >= 4 (default 20), and enough that no ring is more
        than 4 times as thick as the next one outward (rans.mesh.MAX_RING_GROWTH: the rings
        grow geometrically from the wall cell, which is thin in a large pipe at high Re).
    azimuthal_cells : int
        Azimuthal sectors, >= 8 and even, so the mesh is mirror-symmetric about the vertical
        diameter (default 40).
    first_cell_yplus : float
        Target y+ of the wall-cell centroid [1], in (11.53, 500] (log-law region, above where u+ = y+ meets the log law; default 30).
    parcels : int
        Parcels per Lagrangian pass in the final passes, >= 1 (default 240000).
    parcels_start : int
        Parcels per pass in the earlier passes, in [1, parcels] (default min(30000, parcels)).
    average_passes : int
        Passes averaged for the reported particle statistics, in [1, max_passes] (default 3).
    step_rule : str
        Particle time step: ``"default"`` (0.5 min(T_L, cell crossing, 0.1/f_coll)),
        ``"paper"`` (0.5 min(tau_p, T_L, tau_coll)) or ``"kolmogorov"`` (the default rule with
        T_L bounded below by the Kolmogorov time sqrt(nu/eps), where the turbulence has died out).
    relaxation : float
        Under-relaxation factor of the particle sources [1], in [0.05, 1] (default 0.3).
    max_passes : int
        Maximum number of coupling passes, >= 1 (default 40).
    seed : int
        Seed of the counter-based random numbers, in [0, 2**63) (default 1).
    gas_tolerance : float
        Convergence tolerance of the gas solver (residual) [1], in (0, 0.1] (default 1e-6).
    gas_max_iterations : int
        Outer-iteration cap of a periodic (fully developed) gas solve, >= 1 (default 3000). The
        developing march does not use it: it caps each station's outer iterations itself (200
        in a station's first attempt, more in its relaxed retries and extensions;
        ``rans.solve``), and a station that does not converge is reported in the dataset.
    gas_iterations_per_pass : int
        Outer-iteration cap of the periodic gas solve between two Lagrangian passes, >= 1
        (default 300): the coupling loop iterates on, so each gas solve need not converge
        fully; convergence of the run requires the last one to.
    gas_station_retries : str
        ``"always"`` (default): every gas solve of a developing pipe retries a stalled station
        (``rans.solve``, the coupled cross-flow step, more relaxation, an extension of its
        iterations); ``"near-convergence"``: only where the coupling residual of the sources
        being solved is within ``coupling_tolerance``, in the final passes and in the solve on
        the averaged final sources; earlier solves keep a stalled station's first attempt (a diverging
        one is retried either way). On scene h's
        pass-3 sources the retries take two thirds of the solve's time and change nothing
        downstream of the stalled stations (docs/numerics.md, "Gas solver").
    gas_tolerance_early : float
        Tolerance of the gas solves whose sources' coupling residual is above
        ``coupling_tolerance`` [1], in (0, 0.1] (default: ``gas_tolerance``). Such sources
        still move by more than their noise from pass to pass, and a looser solve of them only
        shortens each station's slow last decade of outer iterations; the final passes, the
        solve on the averaged final sources and every solve within the coupling tolerance use
        ``gas_tolerance``. On scene h's pass-51 sources 1e-4 took 5,552 outer iterations
        against 9,223, the fields within 2.5e-3 of the maximum cross flow (docs/numerics.md,
        "Gas solver").
    step_factor : float
        Factor c of the particle time step c · min(...) [1], in (0, 1] (default 0.5).
    batch_size : int
        Parcels per batch [1], >= 1 (default 4096); at least 8 batches are formed, and the
        spread between batches gives the standard errors. With ``seed`` it fixes the numbers.
    batches_per_superbatch : int
        Batches per super-batch, the unit of parallel or distributed work [1], >= 1 (default 8).
    coupling_tolerance : float
        Coupling residual below which the sources are no longer changing beyond their noise
        [1], > 0 (default 1.5; the residual is about 1 when the changes are pure noise).
    residence_cap : float
        Residence time after which a parcel is stopped and counted as stuck [s], > 0
        (default 50 pipe.length / gas.bulk_velocity).
    drag_implicit_weight : float
        Weight w of the linearised drag [1], in (0.5, 1] (default 1): the pass's part of the
        relaxed momentum source is applied as α S_pass + w α β (U_ref − U), −w α β U implicit
        (docs/numerics.md, "Relaxation of the sources"). The converged state does not depend on
        it (U = U_ref there). Per pass, a mode that the particles follow (β_eff ≪ β) contracts
        by about 1 − β_eff/(w β) where the drag dominates the gas's own transport (w α g β ≫ 1),
        so a smaller w shortens the slow approach of the dense 50 µm scenes (by at most 1/w);
        a stiff mode (β_eff = β) contracts by −(1 − w)/w there, which is why w stays above 0.5.
    residual_noise : str
        The noise each cell's change of the relaxed sources is measured against in the coupling
        residual (default "batch"): "batch", α sqrt(2/(2 − α)) times the batch standard error of
        the pass's source, at least 1 % of the RMS source; "batch-visits", also at least
        α sqrt(2/(2 − α)) |S| / sqrt(n + 1), S the cell's relaxed source before the pass and n
        its visits (particle segments) in the pass: the sampling noise of a source estimated from
        n visits, which the batch spread misses where few parcels pass (a cell the particles have
        left, whose source then decays by α per pass). docs/numerics.md, "The residual".
    mirror_symmetry : bool
        Average every pass's sampled particle fields (sources, statistics, wall impacts) with
        their mirror image z -> -z before they are relaxed (``particles.symmetry``): exact in
        the mean for a horizontal pipe with gravity along -y, half the variance, no modes of
        the wrong parity. Default true (every case of this model is mirror-symmetric: uniform
        injection, isotropic wall roughness, gravity in the mirror plane).
    """

    section: ClassVar[str] = "numerics"

    axial_cells: int = _param(INTEGER, "axial stations; ignored in periodic mode", default=400,
                              ge=10, le=100_000)
    radial_cells: int = _param(INTEGER, "radial rings", default=20, ge=4, le=1_000)
    azimuthal_cells: int = _param(INTEGER, "azimuthal sectors, mirror-symmetric mesh",
                                  default=40, ge=8, le=4_000, even=True)
    first_cell_yplus: float = _param(NUMBER, "target y+ of the wall cell, log-law region",
                                     default=30.0, gt=11.53, le=500.0)
    parcels: int = _param(INTEGER, "parcels per pass in the final passes", default=240000, ge=1,
                          le=MAX_PARCELS)
    parcels_start: int | None = _param(INTEGER, "parcels per pass earlier, <= numerics.parcels",
                                       default=None, ge=1, le=MAX_PARCELS)
    average_passes: int = _param(INTEGER, "passes averaged, <= numerics.max_passes", default=3,
                                 ge=1)
    step_rule: str = _param(STRING, "particle time-step rule", default="default",
                            choices=("default", "paper", "kolmogorov"))
    relaxation: float = _param(NUMBER, "source under-relaxation factor", default=0.3, ge=0.05,
                               le=1.0)
    max_passes: int = _param(INTEGER, "maximum coupling passes", default=40, ge=1, le=10_000)
    seed: int = _param(INTEGER, "random seed", default=1, ge=0, lt=2 ** 63)
    gas_tolerance: float = _param(NUMBER, "gas-solver residual tolerance", default=1e-6, gt=0.0,
                                  le=0.1)
    gas_max_iterations: int = _param(INTEGER, "gas-solver iteration cap of the periodic mode "
                                     "(the developing march caps each station's iterations itself)", default=3000, ge=1,
                                     le=10_000_000)
    gas_iterations_per_pass: int = _param(INTEGER, "periodic gas iterations per coupling pass",
                                          default=300, ge=1, le=10_000_000)
    gas_station_retries: str = _param(STRING, "when the developing gas march retries a stalled "
                                      "station (coupled step, more relaxation, extension): "
                                      "in every coupled solve, or only once the coupling residual "
                                      "is within its tolerance and in the final passes",
                                      default="always", choices=("always", "near-convergence"))
    gas_tolerance_early: float | None = _param(NUMBER, "gas-solver tolerance while the coupling "
                                               "residual is above its tolerance", default=None,
                                               gt=0.0, le=0.1, optional=True,
                                               none_label="numerics.gas_tolerance")
    step_factor: float = _param(NUMBER, "particle time-step factor", default=0.5, gt=0.0, le=1.0)
    batch_size: int = _param(INTEGER, "parcels per batch", default=4096, ge=1, le=MAX_PARCELS)
    batches_per_superbatch: int = _param(INTEGER, "batches per super-batch", default=8, ge=1,
                                         le=100_000)
    coupling_tolerance: float = _param(NUMBER, "coupling residual tolerance (noise units)",
                                       default=1.5, gt=0.0, le=1000.0)
    residence_cap: float | None = _param(NUMBER, "parcel residence-time cap", unit="s",
                                         default=None, gt=0.0, optional=True,
                                         none_label="50 pipe.length / gas.bulk_velocity")
    drag_implicit_weight: float = _param(NUMBER, "weight of the linearised drag in the relaxed "
                                         "momentum source (w in α S_pass + w α β (U_ref − U))",
                                         default=1.0, gt=0.5, le=1.0)
    residual_noise: str = _param(STRING, "noise of a cell's source change in the coupling residual: "
                                 "the batch standard error (floor 1 % of the RMS source), or also the "
                                 "sampling noise of the cell's visits", default="batch",
                                 choices=("batch", "batch-visits"))
    mirror_symmetry: bool = _param(BOOLEAN, "mirror-symmetric sampling", default=True)

    def _resolve_and_check(self):
        if self.parcels_start is None:
            self._set("parcels_start", min(30000, self.parcels))
        elif self.parcels_start > self.parcels:
            raise _error("numerics.parcels_start", self.parcels_start, "out of range",
                         f"an integer >= 1 and <= numerics.parcels = {self.parcels}")
        if self.average_passes > self.max_passes:
            raise _error("numerics.average_passes", self.average_passes, "out of range",
                         f"an integer >= 1 and <= numerics.max_passes = {self.max_passes}")


# ---------------------------------------------------------------------------
# the case
# ---------------------------------------------------------------------------

_SECTIONS: dict[str, type[_Section]] = {
    "pipe": PipeConfig,
    "gas": GasConfig,
    "particles": ParticleConfig,
    "walls": WallConfig,
    "physics": PhysicsConfig,
    "numerics": NumericsConfig,
}
_TOP_KEYS = ["name", "description", "model", "profile", *_SECTIONS]

#: Where eulag's model departs from the reference paper's (Laín & Sommerfeld; the rough wall of
#: Sommerfeld & Huber 1999 as the paper uses it), each departure a case key:
#: key -> (eulag's default, the paper's form, what it is).  ``profile = "paper"`` in a case file
#: takes the paper's form for every one of them the file does not set; the ablation study
#: (``eulag study scenes-ablation``) switches them one at a time.
DEVIATIONS: dict[str, tuple[Any, Any, str]] = {
    "walls.impact_angle": ("effective", "nominal",
                           "angle in e_w(alpha), mu_w(alpha): alpha + gamma, or the impact angle alpha "
                           "(the paper does not say which; Sommerfeld & Huber 1999 tabulate them against "
                           "the impact angle)"),
    "walls.lateral_roughness": (True, False, "a lateral roughness angle gamma_2 beside the in-plane gamma_1"),
    "walls.shadow_effect": ("weighted", "rejection",
                            "shadow effect: the sin(alpha + gamma)-weighted pdf, or rejection of "
                            "alpha + gamma <= 0 (Sommerfeld & Huber 1999)"),
    "physics.k_source_scaling": ("seen-energy", "none", "S_k rescaled by k/k_seen per cell, or as sampled"),
    "physics.langevin_drift_correction": (True, False,
                                          "the drift correction of the Langevin model for inhomogeneous "
                                          "turbulence (MacInnes & Bracco 1992), or none (the paper's eq. 12)"),
    "physics.partner_momentum": ("returned", "discarded",
                                 "the fictitious partners' impulse: discarded (Sommerfeld 2001), or "
                                 "returned to the cell's particles"),
    "physics.wall_cell_fields": ("log-law", "wall-ring",
                                 "gas fields the particles see in the wall-function cell: the log-law "
                                 "reconstruction, or the wall-ring values (the paper does not say)"),
    "numerics.step_rule": ("default", "paper",
                           "particle time step: 0.5 min(T_L, cell crossing, 0.1/f_coll), or the paper's "
                           "0.5 min(tau_p, T_L, tau_coll)"),
}

#: The values ``profile = "paper"`` sets (the paper's column of DEVIATIONS), as Case.replace takes them.
PAPER_MODEL: dict[str, dict[str, Any]] = {}
for _key, (_ours, _paper, _) in DEVIATIONS.items():
    PAPER_MODEL.setdefault(_key.split(".")[0], {})[_key.split(".")[1]] = _paper
PROFILES = ("eulag", "paper")

#: Case keys added after the first stored run records and checkpoints, each with the value that
#: does what eulag did before the key existed. A stored case without the key is the same case
#: as one holding that value, so comparisons of stored cases drop it there
#: (:func:`comparable_attrs`); the datasets' attributes keep every key.
LATER_KEYS: dict[str, Any] = {"physics.partner_correlation": "particle",
                               "physics.langevin_drift_form": "particle",
                               "physics.partner_momentum": "discarded",
                               "numerics.mirror_symmetry": "false",
                               "numerics.gas_station_retries": "always",
                               "numerics.gas_tolerance_early": "numerics.gas_tolerance",
                               "numerics.drag_implicit_weight": 1.0,
                               "numerics.residual_noise": "batch",
                               "physics.wall_cell_fields": "log-law",
                               "physics.partner_covariance": "components"}


def comparable_attrs(attrs: dict) -> dict:
    """``attrs`` (as :meth:`Case.to_attrs` gives them) without the keys of ``LATER_KEYS``
    that hold their earlier behaviour: the form in which stored cases are compared."""
    return {k: v for k, v in attrs.items() if not (k in LATER_KEYS and v == LATER_KEYS[k])}


#: Bulk Reynolds numbers rho U0 D / mu an Euler–Lagrange case may have: turbulent pipe flow, for
#: which the k-ε model with wall functions is meant (the validation runs 1.2·10⁴ to 10⁶).
REYNOLDS_RANGE = (4.0e3, 1.0e8)
_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,99}")
_NAME_ALLOWED = ("a string of letters, digits, _ . + - starting with a letter or digit, "
                 "at most 100 characters (used as the output file name)")


@dataclass(frozen=True, kw_only=True)
class Case:
    """A complete, validated case.

    Attributes
    ----------
    name : str
        Case name; the default output file is ``<name>.nc``. From a file: defaults to the
        file's stem.
    description : str
        Free text (default "").
    pipe, gas, walls, physics, numerics : sections
        See :class:`PipeConfig`, :class:`GasConfig`, :class:`WallConfig`,
        :class:`PhysicsConfig`, :class:`NumericsConfig`.
    particles : ParticleConfig or None
        None for a single-phase case.
    source : str or None
        The case file it was read from (not part of the case's identity or attributes).
    """

    name: str
    description: str = ""
    pipe: PipeConfig
    gas: GasConfig
    particles: ParticleConfig | None = None
    walls: WallConfig = field(default_factory=WallConfig)
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    numerics: NumericsConfig = field(default_factory=NumericsConfig)
    source: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        check_name_and_description(self.name, self.description)
        for key, cls in _SECTIONS.items():
            value = getattr(self, key)
            if value is None and key == "particles":
                continue
            if not isinstance(value, cls):
                raise CaseError(f"{key}: wrong type ({type(value).__name__}); allowed: {cls.__name__}")
        p = self.particles
        if p is not None:
            if p.diameter >= 0.2 * self.pipe.diameter:
                raise _error("particles.diameter", p.diameter, "out of range",
                             f"a number > 0 and < pipe.diameter / 5 = {_num(0.2 * self.pipe.diameter)} "
                             "(particle diameter, m)")
            if p.density <= self.gas.density:
                raise _error("particles.density", p.density, "out of range",
                             f"a number > gas.density = {_num(self.gas.density)} and <= 25000 "
                             "(particle density, kg m-3)")
        self._check_flow_and_wall_cell()

    def _check_flow_and_wall_cell(self):
        """Values each within its own range that can still clash: the mesh within MAX_CELLS
        (a periodic case has one station), the bulk Reynolds number within the turbulent range
        of the k-ε model with wall functions, and a wall cell (its centre at
        numerics.first_cell_yplus) that fits the pipe."""
        n = self.numerics
        stations = 1 if self.pipe.mode == "periodic" else n.axial_cells
        cells = stations * n.radial_cells * n.azimuthal_cells
        if cells > MAX_CELLS:
            raise CaseError(f"numerics.axial_cells x radial_cells x azimuthal_cells = {stations} x "
                            f"{n.radial_cells} x {n.azimuthal_cells} = {cells:,} cells: out of range; "
                            f"allowed: at most {MAX_CELLS:,} cells")
        g, d = self.gas, self.pipe.diameter
        re = g.density * g.bulk_velocity * d / g.viscosity
        given = (f"gas.density = {_num(g.density)}, gas.bulk_velocity = {_num(g.bulk_velocity)}, "
                 f"pipe.diameter = {_num(d)}, gas.viscosity = {_num(g.viscosity)}")
        if not (REYNOLDS_RANGE[0] <= re <= REYNOLDS_RANGE[1]):
            raise CaseError(f"Re = rho U0 D / mu = {re:.4g} ({given}): out of range; allowed: "
                            f"{REYNOLDS_RANGE[0]:g} <= Re <= {REYNOLDS_RANGE[1]:g} (turbulent pipe flow, "
                            "k-epsilon with wall functions)")
        from rans.mesh import wall_cell_thickness

        yplus = self.numerics.first_cell_yplus
        thickness, _ = wall_cell_thickness(d, yplus, g.bulk_velocity, g.density, g.viscosity)
        if not (0.0 < thickness < 0.5 * d):
            raise _error("numerics.first_cell_yplus", yplus, "out of range",
                         f"a y+ whose wall cell fits the pipe: at Re = {re:.4g} ({given}) the wall cell "
                         f"would be {thickness:.3g} m thick in a pipe of radius {_num(0.5 * d)} m; lower "
                         "numerics.first_cell_yplus or raise the Reynolds number")
        from rans.mesh import ring_growth_problem

        problem = ring_growth_problem(0.5 * d, n.radial_cells, thickness)
        if problem is not None:
            raise _error("numerics.radial_cells", n.radial_cells, "out of range",
                         f"{problem} (the wall cell's centre at y+ = {_num(yplus)}, Re = {re:.4g})")

    # -- construction -------------------------------------------------------

    @classmethod
    def from_dict(cls, d: dict, *, name: str | None = None, source: str | None = None) -> "Case":
        """Build and validate a case from a nested dict as parsed from TOML.

        ``name`` is used when the dict has no ``name`` key.
        """
        if not isinstance(d, dict):
            raise CaseError(f"case: wrong type ({_type_name(d)}); allowed: a table")
        if d.get("model", "euler-lagrange") != "euler-lagrange":
            raise CaseError(f"model = {_fmt(d['model'])}: not a case of the Euler-Lagrange model; allowed "
                            "here: euler-lagrange (eulag.runs.load_case reads the other models' cases)")
        for key, value in d.items():
            if key not in _TOP_KEYS:
                other = _OTHER_MODEL_TABLES.get(key)
                if other is not None and isinstance(value, dict):
                    raise CaseError(f'[{key}]: a table of the {other} model, in a case without model = "{other}" '
                                    f'(read as an Euler-Lagrange case); allowed: model = "{other}" at the top '
                                    f"of the file, or the Euler-Lagrange tables {', '.join(_SECTIONS)}")
                raise _unknown(key, value, _TOP_KEYS, "the top level")
        kwargs: dict[str, Any] = {}
        if "name" in d:
            kwargs["name"] = d["name"]
        elif name is not None:
            kwargs["name"] = name
        else:
            raise CaseError("name: missing (a required key); allowed: " + _NAME_ALLOWED)
        if "description" in d:
            kwargs["description"] = d["description"]
        for key in ("pipe", "gas"):
            if key not in d:
                raise CaseError(f"{key}: missing (a required table); allowed: a table [{key}]")
        profile = d.get("profile", "eulag")
        if profile not in PROFILES:
            raise CaseError(f"profile = {_fmt(profile)}: unknown profile; allowed: "
                            + ", ".join(f'"{p}"' for p in PROFILES)
                            + " (paper: the reference paper's model for every key of config.DEVIATIONS "
                              "the file does not set)")
        if profile == "paper":
            d = dict(d)
            for key, values in PAPER_MODEL.items():
                table = d.get(key, {})
                if isinstance(table, dict):
                    d[key] = {**values, **table}
        for key, section_cls in _SECTIONS.items():
            if key in d:
                kwargs[key] = section_cls._from_table(d[key])
        return cls(**kwargs, source=source)

    @classmethod
    def from_toml(cls, path: str | Path) -> "Case":
        """Read and validate a TOML case file; the name defaults to the file's stem.

        ``pipe.reference_data`` must name an existing file, relative to the case file's
        directory or to eulag's ``cases/`` directory.
        """
        path = Path(_path_argument(path, "case file"))
        try:
            text = path.read_bytes().decode("utf-8")
        except FileNotFoundError:
            raise CaseError(f"{path}: no such case file") from None
        except IsADirectoryError:
            raise CaseError(f"{path}: is a directory, not a case file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise CaseError(f"{path}: cannot read the case file ({exc})") from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise CaseError(f"{path}: not valid TOML ({exc})") from None
        case = cls.from_dict(data, name=name_from_stem(path.stem), source=str(path))
        ref = case.pipe.reference_data
        if ref is not None:
            found = case.reference_data_path()
            if found is None:
                raise _error("pipe.reference_data", ref, "no such file",
                             f"a file relative to {path.parent or '.'}/ or to {CASES_DIR}/")
            import csv

            from eulag.reference import read_reference  # read now: a coupled run would find out after hours

            try:
                read_reference(found)
            except (OSError, UnicodeDecodeError, ValueError, KeyError, csv.Error) as exc:
                raise _error("pipe.reference_data", ref, f"cannot be read as reference profiles ({exc})",
                             "a CSV file with a column y_over_R or y_over_D and a velocity column "
                             "(docs/case-reference.md)") from None
        return case

    @classmethod
    def from_file(cls, spec: str | Path) -> "Case":
        """A case from a TOML file path or a packaged case's name (``eulag cases``), e.g.
        ``Case.from_file("tsuji_morikawa_200um")``."""
        p = Path(_path_argument(spec, "case file"))
        if not p.is_file() and p.suffix != ".toml" and p.parent == Path("."):
            p = packaged_cases().get(p.name, p)
        return cls.from_toml(p)

    @classmethod
    def from_attrs(cls, attrs: dict) -> "Case":
        """Rebuild a case from the flattened attributes of :meth:`to_attrs`, or from a dataset's
        global attributes (``ds.attrs``, :func:`case_keys_from_dataset`).  A key of
        ``LATER_KEYS`` that the attributes lack (a result written before the key existed) takes
        its earlier value, not today's default."""
        d: dict[str, Any] = {}
        keys = case_keys_from_dataset(attrs)
        if any(k.partition(".")[0] == "physics" for k in keys):
            keys = {**{k: v for k, v in LATER_KEYS.items() if k not in keys}, **keys}
        for key, value in keys.items():
            if key in ("case.name", "case.description"):
                d[key.split(".", 1)[1]] = _plain(value)
                continue
            section, _, leaf = key.partition(".")
            if section not in _SECTIONS or not leaf:
                continue
            meta = next((f.metadata for f in _public_fields(_SECTIONS[section]) if f.name == leaf),
                        None)
            if meta is None:
                raise _unknown(key, _plain(value), [f.name for f in _public_fields(_SECTIONS[section])],
                               f"[{section}]")
            value = _plain(value)
            if meta["optional"] and value == meta["none_label"]:
                continue
            if meta["kind"] == BOOLEAN and value in ("true", "false"):
                value = value == "true"
            elif meta["kind"] == NUMBERS and not isinstance(value, list):
                value = [value]
            d.setdefault(section, {})[leaf] = value
        return cls.from_dict(d)

    # -- export ---------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Nested plain dict (TOML layout, every default filled in); ``from_dict`` inverts it."""
        d: dict[str, Any] = {"name": self.name}
        if self.description:
            d["description"] = self.description
        for key in _SECTIONS:
            section = getattr(self, key)
            if section is not None:
                d[key] = section._to_table()
        return d

    def to_attrs(self) -> dict[str, Any]:
        """The case flattened to ``"section.key" -> value`` for NetCDF global attributes.

        Every key, defaults included. Values are str, int, float or float arrays only:
        booleans become "true"/"false", None becomes the field's label (e.g. "none"), lists
        become float64 arrays. A single-phase case has no ``particles.*`` keys.
        """
        out: dict[str, Any] = {"case.name": self.name, "case.description": self.description}
        for key in _SECTIONS:
            section = getattr(self, key)
            if section is not None:
                out.update(section._to_flat(key))
        return out

    def replace(self, **changes: Any) -> "Case":
        """A new, re-validated case with some values changed.

        Top-level keys take values (``name="x"``); sections take dicts that are merged into
        the section (``numerics={"parcels": 20000}``; ``particles=None`` removes the particle
        phase). Keys that hold their automatic default (``numerics.parcels_start``,
        ``physics.magnus_lift``, ``physics.inter_particle_collisions``) follow the new values.
        """
        d = self.to_dict()
        n, ph = self.numerics, self.physics
        if n.parcels_start == min(30000, n.parcels):
            del d["numerics"]["parcels_start"]
        if ph.magnus_lift == ph.rotation:
            del d["physics"]["magnus_lift"]
        if ph.inter_particle_collisions == (ph.coupling == "four-way"):
            del d["physics"]["inter_particle_collisions"]
        for key, value in changes.items():
            if key in _SECTIONS:
                if value is None and key == "particles":
                    d.pop("particles", None)
                    continue
                if not isinstance(value, dict):
                    raise CaseError(f"{key} = {_fmt(value)}: wrong type ({_type_name(value)}); "
                                    f"allowed: a table of changes to [{key}]")
                d[key] = {**d.get(key, {}), **value}
            elif key in _TOP_KEYS:
                d[key] = value
            else:
                raise _unknown(key, value, _TOP_KEYS, "the top level")
        return Case.from_dict(d, source=self.source)

    # -- conveniences ----------------------------------------------------------

    @property
    def single_phase(self) -> bool:
        """True when the case has no ``[particles]``."""
        return self.particles is None

    @property
    def reynolds_number(self) -> float:
        """Bulk Reynolds number U0 D rho / mu [1]."""
        return self.gas.bulk_velocity * self.pipe.diameter * self.gas.density / self.gas.viscosity

    def reference_data_path(self) -> Path | None:
        """The existing file ``pipe.reference_data`` names, or None (unset or not found)."""
        ref = self.pipe.reference_data
        if ref is None:
            return None
        candidates = [Path(ref)]
        if self.source is not None and not Path(ref).is_absolute():
            candidates.insert(0, Path(self.source).parent / ref)
        candidates.append(CASES_DIR / ref)
        return next((c for c in candidates if c.is_file()), None)


def dataset_attr_name(key: str) -> str:
    """The CF-clean global attribute name of a flattened case key: ``"pipe.diameter"`` ->
    ``"case_pipe_diameter"``, ``"case.name"`` -> ``"case_name"`` (CF 2.3: letters, digits and
    underscores)."""
    section, _, leaf = key.partition(".")
    return f"case_{leaf}" if section == "case" else f"case_{section}_{leaf}"


def case_keys_from_dataset(attrs: dict) -> dict:
    """The flattened case keys (``"section.key"``) of a dataset's global attributes, read from
    their CF-clean names (:func:`dataset_attr_name`) or, in datasets written before, from the
    dotted names themselves; other attributes are left out."""
    out = {}
    for name, value in attrs.items():
        if "." in name:
            if name.partition(".")[0] in _SECTIONS or name in ("case.name", "case.description"):
                out.setdefault(name, value)
            continue
        if name in ("case_name", "case_description"):
            out["case." + name[5:]] = value
            continue
        if not name.startswith("case_"):
            continue
        rest = name[5:]
        for section in _SECTIONS:
            if rest.startswith(section + "_"):
                out[f"{section}.{rest[len(section) + 1:]}"] = value
                break
    return out


def _flat(d: dict, prefix: str = "") -> dict:
    """A nested case (TOML tables) as flattened ``"section.key"`` entries."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _comparable_value(v: Any) -> Any:
    """A stored value as the comparison of :func:`case_differences` sees it (arrays and numpy
    scalars as Python values; a one-element list as its element: netCDF stores it so)."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, (list, tuple)):
        v = [_comparable_value(x) for x in v]
        return v[0] if len(v) == 1 else v
    return v


def case_differences(stored: dict, mine: dict, *, there: str = "stored", limit: int = 3) -> str:
    """The keys in which two cases differ, for a message: ``"numerics.parcels = 1000 stored,
    2000 in this case"``, at most ``limit`` of them, "; "-separated ("" when none is found).
    ``stored`` and ``mine``: flattened (``"section.key"``) or nested (TOML tables) dicts.  A key of
    :data:`LATER_KEYS` missing on a side (a case stored before it existed, or dropped at that value
    by :func:`comparable_attrs`) reads as the value it had before it existed."""
    a, b = _flat(stored), _flat(mine)
    if any(k.startswith("physics.") for k in a):  # an Euler-Lagrange case ([physics] is its own table)
        a, b = {**LATER_KEYS, **a}, {**LATER_KEYS, **b}
    missing = object()
    rows = []
    for key in sorted(set(a) | set(b)):
        x, y = _comparable_value(a.get(key, missing)), _comparable_value(b.get(key, missing))
        if x == y or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)):
            continue
        shown = ["(not set)" if v is missing else _fmt(v) for v in (x, y)]
        shown = [t if len(t) <= 40 else t[:37] + "..." for t in shown]
        rows.append(f"{key} = {shown[0]} {there}, {shown[1]} in this case")
    more = f"; and {len(rows) - limit} more" if len(rows) > limit else ""
    return "; ".join(rows[:limit]) + more


def packaged_cases() -> dict[str, Path]:
    """The case files shipped with eulag (``cases/`` and its folders), by name (file stem)."""
    return {p.stem: p for p in sorted(CASES_DIR.rglob("*.toml"))}


def _path_argument(value: Any, what: str):
    """``value`` if it can be a file path (str or os.PathLike), else CaseError saying so."""
    import os

    if isinstance(value, (str, os.PathLike)):
        return value
    raise CaseError(f"{what} = {_fmt(value) if not isinstance(value, dict) else '{...}'}: wrong type "
                    f"({_type_name(value)}); allowed: a file path (str or pathlib.Path) or a packaged case's name")


def check_name_and_description(name: Any, description: Any = "") -> None:
    """The top-level ``name`` and ``description`` rules of every model's case file (the name
    becomes the output file's name); CaseError with one line otherwise."""
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise CaseError(f"name = {_fmt(name)}: not a valid case name; allowed: " + _NAME_ALLOWED)
    if not isinstance(description, str):
        raise CaseError(f"description = {_fmt(description)}: wrong type ({_type_name(description)}); "
                        "allowed: a string")


def name_from_stem(stem: str) -> str:
    """A valid case name from a file stem (invalid characters become '_')."""
    name = re.sub(r"[^A-Za-z0-9_.+-]", "_", stem)[:100]
    return name if name and name[0].isalnum() else ("case_" + name)[:100]


def _plain(value: Any) -> Any:
    """numpy scalars/arrays (as read back from NetCDF) -> Python scalars/lists."""
    if isinstance(value, np.ndarray):
        return [v.item() for v in value.ravel()] if value.ndim else value.item()
    if isinstance(value, np.generic):
        return value.item()
    return value


# ---------------------------------------------------------------------------- key reference
def _docstring_entries(cls) -> dict[str, str]:
    """``name -> text`` of the numpy-style Attributes section of a section class's docstring."""
    doc = inspect.getdoc(cls) or ""
    out: dict[str, str] = {}
    current = None
    for line in doc.splitlines():
        head = re.match(r"^([a-z_][a-z0-9_]*) : ", line)
        if head:
            current = head.group(1)
            out[current] = ""
        elif current is not None and line.startswith("    "):
            out[current] = (out[current] + " " + line.strip()).strip()
        elif current is not None and not line.strip():
            continue
        else:
            current = None
    return out


def key_reference() -> str:
    """The case-file key reference (Markdown): every key of every section with its type and
    allowed range, default, units and meaning, generated from the schema above.

    ``python -m eulag.config docs/case-reference.md`` writes it; a test checks that the
    committed file is current."""
    lines = ["# Case-file reference", "",
             "Generated from the case schema (`eulag/config.py`) by "
             "`python -m eulag.config docs/case-reference.md`; do not edit by hand.", "",
             "A case file is TOML. Top-level keys: `name` (default: the file's stem), `description`, "
             "`model` (`\"euler-lagrange\"`, the default; `\"dem-darcy\"` and `\"two-fluid\"` cases are "
             "validated by their own models: `eulag check CASE` lists their keys with defaults; docs/slug.md, "
             "docs/two-fluid.md), and "
             "`profile` (`\"paper\"`: the reference paper's value for every departure the file does not "
             "set; docs/physics.md, section 7). The keys below are the Euler-Lagrange model's; every one "
             "is written into the result dataset as a global attribute `case_<section>_<key>`, defaults "
             "included.", ""]
    for name, cls in _SECTIONS.items():
        first = (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")
        lines += [f"## `[{name}]`", "", first, "",
                  "| key | allowed | default | units | meaning |", "|---|---|---|---|---|"]
        docs = _docstring_entries(cls)
        for f in _public_fields(cls):
            meta = f.metadata
            if f.default is MISSING:
                default = "required"
            elif f.default is None:
                default = meta["none_label"] if meta["optional"] else "automatic (see meaning)"
            else:
                default = f"`{_fmt(f.default)}`"
            allowed = _allowed({**meta, "doc": "", "unit": ""}).replace("|", "\\|")
            meaning = (docs.get(f.name) or meta["doc"]).replace("|", "\\|")
            lines.append(f"| `{f.name}` | {allowed} | {default} | {meta['unit'] or '-'} | {meaning} |")
        lines.append("")
    return "\n".join(lines)


def resolved_case_lines(case: dict, model: str, source, rows) -> list[str]:
    """The head of a dense-phase model's ``eulag check`` report: the case's name, file and model,
    its name and description, then every key, ``rows`` of (dotted key, value, unit, given): the
    value as TOML writes it, the unit in brackets, "(default)" where the file does not set it."""
    import json

    name = case.get("name") or (name_from_stem(Path(source).stem) if source else "")
    lines = [f"case {name}" + (f" ({source})" if source else "") + f": model {model}", "",
             "Case (every key; '(default)': the key's default)"]
    for k in ("name", "description"):
        if k in case:
            text = json.dumps(case[k])
            lines.append(f"  {k} = {text if len(text) <= 90 else text[:87] + '...'}")
    for key, value, unit, given in rows:
        lines.append(f"  {key} = {json.dumps(value)}" + (f" [{unit}]" if unit else "") + ("" if given else "  (default)"))
    return lines


if __name__ == "__main__":  # python -m eulag.config [docs/case-reference.md]
    import sys

    text = key_reference()
    if len(sys.argv) > 1:
        Path(sys.argv[1]).write_text(text, encoding="utf-8")
    else:
        print(text)
