"""The run layer: case → mesh → run → dataset → figures, the same for every front-end.

``eulag run``, ``eulag sweep``, the studies and the Python API (``eulag.run``) all go through
:func:`execute`; nothing else in eulag builds a mesh, starts a loop or writes a result.

    case = load_case("tsuji_morikawa_200um")          # a file path or a packaged case's name
    result = execute(case, "out.nc", resume=True)      # RunResult: dataset, verdict, figures
    result.dataset, result.converged, result.stop_reason

Which model runs is the case file's top-level ``model`` key: ``"euler-lagrange"`` (the
default: the steady k-ε gas solver alone when the case has no ``[particles]``, else the
four-way coupling loop of :mod:`eulag.coupling`), ``"dem-darcy"`` (:mod:`eulag.slug`) or
``"two-fluid"`` (:mod:`eulag.two_fluid`).

Resume rules (one place for all front-ends): a coupled run keeps its checkpoint beside the
output (``out.nc.checkpoint``); ``resume=True`` continues from it, and returns an output that
already holds a finished run of the same case without computing anything; ``resume=False``
starts afresh and removes an earlier checkpoint (saying so).  An output of a *different* case
is never taken for this one nor overwritten by a resume, and a checkpoint that this case cannot
continue (unreadable, another case's) is named, not ignored (:class:`BadInput`; checked before
any work, :func:`_prepare_output`, which also removes the temporary files of a write that a kill
interrupted).  Errors are :class:`RunError` (exit status 1) or
:class:`BadInput` (exit status 2) with a one-line message.
"""

from __future__ import annotations

import time
import tomllib
from dataclasses import dataclass
from dataclasses import field as _field
from pathlib import Path
from typing import Any, Callable

from eulag.config import Case, CaseError, check_name_and_description, name_from_stem, packaged_cases

__all__ = ["RunError", "BadInput", "RunResult", "ModelCase", "MODELS", "packaged_cases", "case_path", "load_case",
           "output_path", "dataset_state", "stored_state", "takes_as_finished", "finished_output", "same_case",
           "case_key", "checkpoint_path", "checkpoint_state", "resumable_checkpoint", "execute", "run", "with_parcels",
           "UnconvergedRunWarning", "case_difference"]

#: The models a case can name with its top-level ``model`` key, and the module that runs each.
MODELS = {"euler-lagrange": "eulag.coupling", "dem-darcy": "eulag.slug", "two-fluid": "eulag.two_fluid"}
#: The dense-phase models' entry points: (module, validate(dict), run(dict, out, resume=, progress=)).
#: Each module also defines ``same_case(attrs, dict)``, ``checkpoint_path(out)``,
#: ``checkpoint_problem(path, dict)`` and ``check_report(dict, source)`` (``eulag check``).
_DENSE = {"dem-darcy": ("eulag.slug", "validate_slug_case", "run_slug"),
          "two-fluid": ("eulag.two_fluid", "validate_two_fluid_case", "run_two_fluid")}

EXIT_FAILURE, EXIT_BAD_INPUT = 1, 2


class RunError(Exception):
    """A run that cannot be done or did not finish; ``status`` is the CLI's exit status."""

    status = EXIT_FAILURE

    def __init__(self, message: str, status: int | None = None):
        super().__init__(message)
        if status is not None:
            self.status = status


class BadInput(RunError):
    """Bad input (case file, output path, a different case where this one was expected)."""

    status = EXIT_BAD_INPUT


@dataclass(frozen=True)
class ModelCase:
    """A validated case of a dense-phase model: its ``model``, name, the parsed TOML tables
    (validated by the model's module) and the file it came from."""

    model: str
    name: str
    data: dict
    source: Path | None = None


@dataclass
class RunResult:
    """What a finished run gives: its dataset and the loop's verdict.

    dataset : xarray.Dataset (written to ``out`` when an output was given); converged;
    stop_reason : the loop's one-line verdict (which criterion failed, by how much);
    reused : the output already held this finished run (``resume``); figures : PNG paths;
    figure_error : why the figures were not written ("" when they were or none were asked for);
    loop / field : the coupling loop or the single-phase gas field (None when reused);
    timings : wall-clock seconds of the run's stages.
    """

    case: Any
    out: Path | None
    dataset: Any
    converged: bool
    stop_reason: str
    reused: bool = False
    figures: list = _field(default_factory=list)
    figure_error: str = ""
    loop: Any = None
    field: Any = None
    mesh: Any = None
    timings: dict = _field(default_factory=dict)


# ---------------------------------------------------------------------------- cases
def case_path(spec: str | Path) -> Path:
    """A case file from a path or, when no such file exists, a packaged case's name."""
    import os

    if not isinstance(spec, (str, os.PathLike)):
        raise BadInput(f"case = {type(spec).__name__}: wrong type; allowed: an eulag.Case, a case file path "
                       "or a packaged case's name (eulag cases)")
    p = Path(spec)
    if p.is_file():
        return p
    known = packaged_cases()
    if p.is_dir() and str(spec) not in known:
        raise BadInput(f"{spec}: is a directory; allowed: a case file (.toml) or a packaged case's name (eulag cases)")
    if p.suffix == ".toml" or p.parent != Path("."):
        return p
    if str(spec) in known:
        return known[str(spec)]
    raise BadInput(f"{spec}: no such case file or packaged case; allowed: a .toml path or one of "
                   f"{', '.join(known)} (eulag cases)")


def model_of(path: Path) -> str:
    """The ``model`` key of a case file (``"euler-lagrange"`` when absent)."""
    try:
        data = tomllib.loads(Path(path).read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return "euler-lagrange"  # Case.from_toml gives the one-line error
    model = data.get("model", "euler-lagrange")
    if model not in MODELS:
        raise BadInput(f"model = {model!r}: unknown model; allowed: {', '.join(MODELS)}")
    return model


def load_case(spec: str | Path, *, parcels: int | None = None):
    """Read and validate a case: an :class:`eulag.config.Case` for the Euler–Lagrange model, or
    the dense-phase models' validated case (their modules define it).  ``parcels`` overrides
    ``numerics.parcels`` (and caps ``numerics.parcels_start``) of an Euler–Lagrange case; given
    for a dense-phase case it is :class:`BadInput`."""
    path = case_path(spec)
    model = model_of(path) if path.is_file() else "euler-lagrange"
    if model != "euler-lagrange":
        if parcels is not None:
            raise BadInput(f"--parcels {parcels}: {path} is a model = {model!r} case, which tracks no parcels; "
                           "allowed: Euler-Lagrange cases")
        module_name, validate, _ = _DENSE[model]
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
        try:
            getattr(_model_module(model), validate)(data)
            # the name rule of every model: the name becomes the output file's name
            check_name_and_description(data.get("name", name_from_stem(path.stem)), data.get("description", ""))
        except (CaseError, ValueError, KeyError, TypeError, OverflowError) as exc:
            raise BadInput(" ".join(str(exc).split())) from None
        return ModelCase(model, str(data.get("name", name_from_stem(path.stem))), data, path)
    try:
        return with_parcels(Case.from_toml(path), parcels)
    except CaseError as exc:
        raise BadInput(str(exc)) from None


def with_parcels(case: Case, parcels: int | None, label: str = "--parcels") -> Case:
    """``case`` with ``parcels`` per final pass (and at most that many in the early passes);
    None: unchanged.  The one place the ``--parcels`` option is applied."""
    if parcels is None:
        return case
    import numpy as np

    if isinstance(parcels, bool) or not isinstance(parcels, (int, np.integer)):
        raise CaseError(f"{label} {parcels!r}: wrong type ({type(parcels).__name__}); allowed: an integer >= 1")
    n = case.numerics
    try:
        return case.replace(numerics={"parcels": int(parcels), "parcels_start": min(n.parcels_start, int(parcels))})
    except CaseError as exc:
        raise CaseError(f"{label} {parcels}: {exc}") from None


def model_check_report(case: ModelCase) -> str:
    """``eulag check`` of a dense-phase case: its model's report (every key resolved, the derived
    numbers)."""
    return _model_module(case.model).check_report(case.data, source=case.source)


def _model_module(model: str):
    import importlib

    try:
        return importlib.import_module(MODELS[model])
    except ImportError as exc:
        raise BadInput(f"model = {model!r}: not available in this installation ({exc})") from None


# ---------------------------------------------------------------------------- outputs
def output_path(out: str | Path | None, name: str, label: str = "-o") -> Path:
    """The output file (``<name>.nc`` by default), checked to be writable before any work;
    ``label`` names the argument in the messages (``-o`` of the command line, ``out`` of the
    Python API)."""
    import os

    if out is not None and not isinstance(out, (str, os.PathLike)):
        raise BadInput(f"{label} = {out!r}: wrong type; allowed: a file path ending in .nc")
    if out is not None and not str(out).strip():
        raise BadInput(f"{label} '': an empty path; allowed: a NetCDF file path ending in .nc")
    out = Path(out) if out else Path(f"{name}.nc")
    from eulag.files import target_problem

    problem = "not a NetCDF file name; allowed: a path ending in .nc" if out.suffix != ".nc" else None
    if problem is None or out.is_symlink() or out.is_dir():  # what is in its place is named first
        problem = target_problem(out) or problem
    if problem is not None:
        raise BadInput(f"{label} {out}: {problem}")
    return out


def case_key(case) -> str:
    """The identity of a case as run records store it (canonical JSON): an Euler–Lagrange
    case by its attributes as :func:`eulag.config.comparable_attrs` compares them, a
    dense-phase case by its TOML tables."""
    import json

    import numpy as np

    from eulag.config import comparable_attrs

    def default(v):
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, np.generic):
            return v.item()
        return str(v)
    if isinstance(case, ModelCase):
        return json.dumps(case.data, sort_keys=True, default=str)
    return json.dumps(comparable_attrs(case.to_attrs()), sort_keys=True, default=default)


def same_case(attrs: dict, case) -> bool:
    """Whether the global attributes ``attrs`` of a dataset are those of a result of ``case``
    (the one "same case" rule of ``--resume``, the sweep and the studies)."""
    if isinstance(case, ModelCase):
        return bool(getattr(_model_module(case.model), "same_case")(attrs, case.data))
    try:
        return Case.from_attrs(attrs) == case
    except CaseError:
        return False


def checkpoint_path(out: str | Path, case=None) -> Path:
    """The checkpoint a run of ``case`` keeps beside its output ``out``."""
    if isinstance(case, ModelCase):
        return getattr(_model_module(case.model), "checkpoint_path")(Path(out))
    return Path(str(out) + ".checkpoint")


def checkpoint_state(ckpt: str | Path, case):
    """The checkpoint ``ckpt`` of a coupled run as ``case`` would resume it: ``(meta, residual
    history, None)`` when it can (``coupling.checkpoint_problem``: its stored case compared as
    records are), ``(None, None, why)`` when it cannot (unreadable, another case, ...), and None
    when there is no such file.  A dense-phase model's checkpoint is checked by its module
    (``checkpoint_problem``), and gives ``({}, empty, None)`` when it can be resumed.  The file
    is read once (a run beside the caller may finish and delete it)."""
    import numpy as np

    ckpt = Path(ckpt)
    if not ckpt.is_file():
        return None
    if isinstance(case, ModelCase):
        problem = getattr(_model_module(case.model), "checkpoint_problem")(ckpt, case.data)
        return ({}, np.zeros(0), None) if problem is None else (None, None, problem)
    from eulag import coupling

    try:
        meta, residual = coupling.read_checkpoint(ckpt)
    except coupling.CouplingError as exc:
        return None, None, str(exc)
    except OSError as exc:  # deleted or unreadable meanwhile
        return None, None, f"{ckpt}: cannot be read ({exc})"
    try:
        problem = coupling.checkpoint_problem(meta, residual, case)
    except Exception as exc:  # noqa: BLE001 - a foreign file: not of this case
        problem = f"not a checkpoint of this case ({type(exc).__name__})"
    return (meta, residual, None) if problem is None else (None, None, problem)


def dataset_state(out: str | Path, case) -> str | None:
    """What the output ``out`` holds for ``case``: None (no file) or its :func:`stored_state`;
    :class:`BadInput` if it holds another case (never overwritten by a resume) or if it cannot be
    read as a dataset."""
    out = Path(out)
    if not out.is_file():
        return None
    state, foreign = _output_contents(out, case)
    if foreign is not None:
        what, allowed = foreign
        raise BadInput(f"--resume: {what}; allowed: {allowed}")
    return state


def _output_contents(out: Path, case) -> tuple[str | None, str | None]:
    """(:func:`stored_state` of the existing file ``out`` for ``case``, None) when it holds this
    case's dataset, else (None, (what it holds instead, what a resume allows)): another case,
    naming the keys that differ, or a file that cannot be read as a dataset."""
    import xarray as xr

    try:
        with xr.open_dataset(out) as ds:
            attrs = dict(ds.attrs)
            same = same_case(attrs, case)  # first: another case's dataset is not judged by this one's rules
            state = stored_state(ds, case) if same else None
    except Exception as exc:  # noqa: BLE001 - any unreadable file is reported the same way
        from eulag.arguments import short_reason

        return None, (f"{out} exists but cannot be read as a dataset ({short_reason(exc)})",
                      "this case's output, or a path that does not exist yet")
    if not same:
        what = case_difference(attrs, case)
        return None, (f"{out} holds a different case{f' ({what})' if what else ''}",
                      "the output of this case, or run without --resume to overwrite")
    return state, None


def case_difference(attrs: dict, case) -> str:
    """The keys in which the case stored in a dataset's global attributes ``attrs`` differs from
    ``case`` (:func:`eulag.config.case_differences`; "" when none can be named)."""
    from eulag.config import case_differences, case_keys_from_dataset, comparable_attrs

    try:
        if isinstance(case, ModelCase):
            stored, mine = getattr(_model_module(case.model), "compared_cases")(attrs, case.data)
        else:
            stored = comparable_attrs(case_keys_from_dataset(attrs))
            mine = comparable_attrs(case.to_attrs())
        if not isinstance(stored, dict):
            return ""
        return case_differences(stored, mine)
    except Exception:  # noqa: BLE001 - a foreign file: the message then names no key
        return ""


def stored_state(ds, case=None) -> str:
    """The verdict of a finished run's dataset: ``"converged"``; ``"unconverged"`` (it ended
    unconverged after all its passes or iterations: running it again gives the same); ``"budget
    raised"``, unconverged, but ``case`` (when given) allows more iterations than it had (a
    two-fluid ``numerics.max_iterations``, which is not part of the case's identity); or
    ``"rejected"``, a slug dataset stored as finished that today's rules reject
    (``eulag.slug.verdict``; written by a code before the rule, e.g. a jammed tube)."""
    from eulag.output import is_converged

    if is_converged(ds):  # a slug dataset: judged by today's rules
        return "converged"
    if ds.attrs.get("model") == "dem-darcy" and ds.attrs.get("converged") == "true":
        return "rejected"
    if isinstance(case, ModelCase):
        more = getattr(_model_module(case.model), "budget_raised", None)
        if more is not None and more(dict(ds.attrs), case.data):
            return "budget raised"
    return "unconverged"


def takes_as_finished(state: str | None) -> bool:
    """Whether an output in ``state`` (:func:`dataset_state`) is taken as this case's finished run
    instead of running it again: the one rule of ``--resume``, the sweep and the studies.  A run
    that converged is, and one that ended unconverged; a ``"rejected"`` slug dataset is run
    again, and so is an unconverged run whose iteration budget the case has since raised
    (``"budget raised"``: a two-fluid ``numerics.max_iterations``, which is not part of the
    case's identity).  (``eulag run --resume`` continues a checkpoint beside the output instead, which
    for a finished coupled run writes the same dataset again.)"""
    return state in ("converged", "unconverged")


def finished_output(out: str | Path, case) -> bool:
    """Whether ``out`` holds a finished run of ``case`` that a resume keeps
    (:func:`takes_as_finished`; :class:`BadInput` as :func:`dataset_state`)."""
    return takes_as_finished(dataset_state(out, case))


def resumable_checkpoint(out: str | Path, case) -> bool:
    """Whether a checkpoint of ``case`` that it can continue lies beside the output ``out``
    (:func:`checkpoint_state`); a resume continues it whatever ``out`` holds (a run of this case
    was started there and its dataset replaces the file when it ends)."""
    if isinstance(case, Case) and case.particles is None:
        return False  # a single-phase run keeps no checkpoint
    state = checkpoint_state(checkpoint_path(out, case), case)
    return state is not None and state[2] is None


def _reused(case, out: Path) -> RunResult:
    import xarray as xr

    from eulag.output import is_converged

    with xr.open_dataset(out) as ds:
        ds = ds.load()
    if ds.attrs.get("model") == "dem-darcy":  # judged again by today's rules (eulag.slug.verdict)
        from eulag.slug import verdict

        converged, reason = verdict(ds)
    else:
        converged = is_converged(ds)
        reason = ds.attrs.get("stop_reason", "converged" if converged else
                              "not converged (the stored dataset says converged = false)")
    return RunResult(case, out, ds, converged, reason, reused=True)


# ---------------------------------------------------------------------------- running
def execute(case, out: str | Path | None = None, *, resume: bool = False, parcels: int | None = None,
            progress: Callable | None = None, notify: Callable | None = None, tracker=None,
            plots: bool = False, gas_progress: bool = False) -> RunResult:
    """Run ``case`` to its end and return a :class:`RunResult`; write the dataset to ``out``.

    progress(state) is called after every coupling pass (``eulag.coupling.PassState``);
    notify(text) with the loop's remarks (relaxation changes); tracker: a replacement for
    ``particles.track`` (the Dask front-end); plots: draw the model's figures beside ``out``
    (:func:`eulag.plots.plot_all`; if they fail, the dataset stays and ``figure_error`` says why).
    A run that fails raises :class:`RunError` naming what failed (the checkpoint of the last
    complete pass is kept for ``resume``).
    """
    import os

    if isinstance(case, (str, os.PathLike)):
        case = load_case(case)
    if not isinstance(case, (Case, ModelCase)):
        case_path(case)  # BadInput: the type allowed
    if not isinstance(resume, bool):  # "no" or 0 must not pass for a decision about an existing output
        raise BadInput(f"resume = {resume!r}: wrong type ({type(resume).__name__}); allowed: True or False")
    if isinstance(case, ModelCase):
        if parcels is not None:
            raise BadInput(f"parcels = {parcels!r}: a model = {case.model!r} case tracks no parcels; "
                           "allowed: None (Euler-Lagrange cases only)")
    else:
        try:
            case = with_parcels(case, parcels, label="parcels =")
        except CaseError as exc:
            raise BadInput(str(exc)) from None
    if out is not None:
        out = output_path(out, case.name, label="out")
        _prepare_output(case, out, resume=resume, notify=notify)
    if isinstance(case, ModelCase):
        result = _execute_other(case, out, resume=resume, progress=progress)
    else:
        if case.particles is None:
            result = _single_phase(case, out, resume=resume, gas_progress=gas_progress)
        else:
            result = _coupled(case, out, resume=resume, progress=progress, notify=notify, tracker=tracker)
    if plots and out is not None and not result.reused:
        from eulag import plots as plotting

        try:
            result.figures = list(plotting.plot_all(out))
        except Exception as exc:  # noqa: BLE001 - the dataset is written; a figure must not hide it
            result.figure_error = (f"figures not written ({type(exc).__name__}: {' '.join(str(exc).split())}); "
                                   f"the dataset {out} is complete")
    return result


def _prepare_output(case, out: Path, *, resume: bool, notify) -> None:
    """Before any work on ``out``: with ``resume`` a checkpoint beside it that this case can
    continue is continued, whatever ``out`` holds (a run of this case started there, and its
    dataset replaces the file when it ends; ``notify`` says so); without such a checkpoint an
    existing output must hold this case (:func:`dataset_state`: BadInput for another case, naming
    the keys that differ, or for a file that is not a dataset), and an existing checkpoint must be
    one this case can continue (BadInput naming it otherwise); without ``resume``, the checkpoint
    of an earlier run is removed, and ``notify`` says so, as it says when the output it will
    replace holds another case's dataset.  Then the
    temporary files of a write that a kill interrupted (``eulag.files.atomic_write``:
    ``.<out name>.<8 characters>.tmp``, the checkpoint's too) are removed."""
    single_phase = isinstance(case, Case) and case.particles is None
    ckpt = None if single_phase else checkpoint_path(out, case)
    if resume:
        state = checkpoint_state(ckpt, case) if ckpt is not None else None
        if state is None or state[2] is not None:  # no checkpoint this case continues (resumable_checkpoint)
            dataset_state(out, case)  # raises for another case's output or an unreadable one
        elif out.is_file() and notify is not None:  # a checkpoint of this case continues, whatever is at out
            try:
                dataset_state(out, case)
            except BadInput:
                notify(f"{out}: does not hold this case's dataset; the checkpoint beside it is this case's and "
                       "continues (the file is replaced when the run ends)")
        if state is not None and state[2] is not None:
            problem = state[2].removeprefix(f"{ckpt}: ")
            raise BadInput(f"--resume: {ckpt}: {problem}; allowed: a checkpoint of this case (remove it, "
                           "or run without --resume to start afresh)")
    else:
        if out.is_file() and notify is not None:
            foreign = _output_contents(out, case)[1]  # another case's dataset, or not a dataset
            if foreign is not None:
                notify(f"{foreign[0]}; this run replaces it when it ends")
        if ckpt is not None and ckpt.exists():
            ckpt.unlink()
            if notify is not None:
                notify(f"{ckpt}: the checkpoint of an earlier run was removed (--resume continues one)")
    # atomic_write's temporaries of the output and its checkpoint: ".<name>.<8 random>.tmp"
    import re

    stem = re.escape(out.name)
    own = re.compile(rf"\.{stem}(\.checkpoint(\.npz)?)?\.[A-Za-z0-9_]{{8}}\.tmp")
    directory = out.parent if str(out.parent) else Path(".")
    for tmp in directory.glob(".*.tmp"):
        if own.fullmatch(tmp.name):
            try:
                tmp.unlink()
            except OSError:
                pass


class UnconvergedRunWarning(UserWarning):
    """:func:`run` returned the dataset of a run that did not converge (its ``converged`` is false;
    the message is the run's verdict)."""


def run(case, out: str | Path | None = None, **kwargs):
    """Run ``case`` (a :class:`eulag.config.Case`, a case file or a packaged case's name) and
    return its dataset (``xarray.Dataset``); keyword arguments as :func:`execute`.  A run that
    did not converge warns (:class:`UnconvergedRunWarning`, with the verdict)."""
    import warnings

    if isinstance(case, (str, Path)):
        case = load_case(case)
    result = execute(case, out, **kwargs)
    if not result.converged:
        warnings.warn(f"case {result.case.name}: {result.stop_reason} (the dataset says converged = false)",
                      UnconvergedRunWarning, stacklevel=2)
    return result.dataset


def _single_phase(case: Case, out: Path | None, *, resume: bool, gas_progress: bool) -> RunResult:
    import rans
    from eulag.coupling import build_mesh
    from eulag.output import gas_dataset, write_dataset

    if resume and out is not None and finished_output(out, case):
        return _reused(case, out)
    t_start = time.perf_counter()
    timings = {}
    mesh = build_mesh(case)
    timings["mesh"] = time.perf_counter() - t_start
    gas = rans.GasProperties(density=case.gas.density, viscosity=case.gas.viscosity)
    t0 = time.perf_counter()
    try:
        fld = rans.solve(mesh, gas, bulk_velocity=case.gas.bulk_velocity, inlet_k=case.gas.inlet_k,
                         inlet_epsilon=case.gas.inlet_epsilon, sources=None, tol=case.numerics.gas_tolerance,
                         max_iterations=case.numerics.gas_max_iterations, progress=gas_progress)
    except rans.SolverDivergence as exc:
        raise RunError(str(exc) or "the gas solver diverged") from None
    timings["gas_solve"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    ds = gas_dataset(case, mesh, fld, timings=timings)
    if out is not None:
        t0 = time.perf_counter()
        write_dataset(ds, out)
        timings["write"] = time.perf_counter() - t0
    if fld.converged:
        reason = f"gas solve converged in {fld.iterations} iterations"
    else:
        res = list(fld.residuals)
        reason = (f"the gas solver did not converge in {fld.iterations} iterations (final residual "
                  f"{float(res[-1]) if res else float('nan'):.3g} > gas_tolerance {case.numerics.gas_tolerance:g})")
    return RunResult(case, out, ds, bool(fld.converged), reason, field=fld, mesh=mesh, timings=timings)


def _coupled(case: Case, out: Path | None, *, resume: bool, progress, notify, tracker) -> RunResult:
    import rans
    from eulag.coupling import CouplingError, CouplingLoop
    from eulag.output import coupled_dataset, write_dataset

    ckpt = checkpoint_path(out, case) if out is not None else None
    if ckpt is not None:
        if resume and not ckpt.exists() and finished_output(out, case):
            return _reused(case, out)
        if not resume and ckpt.exists():
            ckpt.unlink()  # a fresh run starts from scratch
    try:
        loop = CouplingLoop(case, checkpoint=ckpt, resume=resume, progress=progress, tracker=tracker,
                            notify=notify)
        loop.run()
    except (CouplingError, rans.SolverDivergence) as exc:
        where = f" (checkpoint of the last complete pass: {ckpt})" if ckpt is not None else ""
        raise RunError(f"{exc}{where}") from None
    loop.timings["total"] = loop.elapsed()
    ds = coupled_dataset(loop)
    if out is not None:
        write_dataset(ds, out)
    return RunResult(case, out, ds, bool(loop.converged), loop.stop_reason, loop=loop, mesh=loop.mesh,
                     timings=dict(loop.timings))


def _execute_other(case: ModelCase, out, *, resume: bool, progress) -> RunResult:
    """A dense-phase case: its model's module runs it and returns the dataset (its ``converged``
    and ``stop_reason`` attributes give the verdict)."""
    _, _, runner = _DENSE[case.model]
    out = Path(out) if out is not None else None
    if resume and out is not None and not checkpoint_path(out, case).exists() and finished_output(out, case):
        return _reused(case, out)
    try:
        ds = getattr(_model_module(case.model), runner)(case.data, out, resume=resume, progress=progress is not None)
    except (CaseError, ValueError) as exc:
        raise BadInput(" ".join(str(exc).split())) from None
    except (RuntimeError, FloatingPointError, ArithmeticError) as exc:  # a failing solve: one line
        raise RunError(" ".join(f"{exc}".split()) or type(exc).__name__) from None
    ok = ds.attrs.get("converged", "true") == "true"
    return RunResult(case, out, ds, ok, ds.attrs.get("stop_reason", "finished"))
