"""The studies of issue 6 (DESIGN.md, "Command line"): ``eulag study NAME [--quick]``.

    eulag study tsuji-morikawa            [--quick] [-o DIR] [--resume] [--report] [--quiet] [--parcels N]
    eulag study scenes                    [--quick] [-o DIR] [--resume] [--report] [--quiet] [--parcels N]
                                          [--only a,c]
    eulag study error-runtime CASE.toml   [--quick] [-o DIR] [--resume] [--report] [--quiet]
    eulag study stability                 [--quick] [-o DIR] [--resume] [--report] [--quiet] [--parcels N]
                                          [--only ...]

Each study runs its cases through :func:`eulag.runs.execute` (one dataset ``<run>.nc`` per
case in the output folder, default ``results/<study>/``), then writes a generated table
(``README.md`` and ``<study>.csv``; the machine, the eulag commit and the wall times are
stated in it) and its figures (PNG). Nothing in these files is edited by hand.

* ``--resume``: a run whose dataset already exists (and holds the same case) is not run
  again, an interrupted run continues from its checkpoint (``<run>.nc.checkpoint``), and a
  run that failed before is reported from its ``<run>.failed.json`` record. Without
  ``--resume`` every run starts afresh (and deletes the checkpoint it finds).
* Run records: what a study takes from a finished run's dataset (its table row, the data of
  the study's figures) is also written to ``<run>.record.json`` beside it. The datasets are
  too large to commit (70-90 MB); the records are committed with the tables, so that
  ``--resume`` on another machine reports a finished run from its record when its dataset
  is not there, instead of running it again (the record names the commit that ran it, where
  the dataset recorded one). A record is trusted by its case and ``RECORD_VERSION``: a change
  to what a study extracts from a dataset must bump the version. A run longer than a
  session is committed with its checkpoint (``<run>.nc.checkpoint``, results/README.md), which
  ``--resume`` continues on any machine; the study deletes it when the run has finished.
* ``--report``: run nothing; write the table from what an existing output folder holds
  (datasets, records, failed records; a dataset's record and figures are written again from
  it) and give a run that has only a checkpoint as "unfinished" with how far it got (passes,
  residual, relaxation, time so far), one with nothing as "not run" (exit status 0 for both).
* ``--parcels N``: parcels per final pass of every run (a lighter full-mode study; not in
  error-runtime, where the parcel count is an axis). ``--only``: a subset of scenes / cases.
* ``--quick``: every run on a tiny grid with a few hundred parcels and two passes, so that
  a study finishes in well under a minute on a 2-core machine. Quick numbers check the
  machinery, they are not results.
* A run that fails (:class:`eulag.runs.RunError`: the coupling stopped, a diverging gas solve) does not
  stop the study: its row says "failed: <the diagnosis>". A case the case validation
  rejects is reported as "rejected: <why>".
* Run times exclude the one-off JIT compilation of the particle kernels: before the timed
  runs, a tiny warm-up run compiles the kernels of every physics-option set the study uses.

Exit status: 0 when the study wrote its table and figures (individual runs may have failed:
the stability study is about exactly that); 1 when a run of the other studies failed or an
unexpected error occurred; 2 on bad input (arguments, case file).
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

import eulag
from eulag.analysis import attr as _attr
from eulag.config import CASES_DIR, Case, CaseError, _public_fields, comparable_attrs
from eulag.output import is_converged

__all__ = ["add_arguments", "STUDIES", "QUICK_NUMERICS", "RunRecord", "run_case", "machine_info",
           "profile_deviation", "pareto_front", "scene_cases", "stability_cases",
           "error_runtime_plan", "tsuji_morikawa_cases"]

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2
STUDIES = ("tsuji-morikawa", "scenes", "error-runtime", "stability")
BASE_CASE = CASES_DIR / "tsuji_morikawa_200um.toml"
SCENES_DIR = CASES_DIR / "scenes"
SCENE_NAMES = tuple("abcdefgh")

#: numerics of every quick-mode run (tiny grid, few parcels, two passes: one early pass without
#: collision statistics, one final pass with them)
QUICK_NUMERICS = {"axial_cells": 16, "radial_cells": 5, "azimuthal_cells": 12, "parcels": 400,
                  "parcels_start": 300, "max_passes": 2, "average_passes": 1, "batch_size": 50}
#: what the stability study's quick mode changes further (fewer parcels)
STABILITY_QUICK = {"parcels": 200, "parcels_start": 200, "batch_size": 25}
#: numerics of the warm-up run that compiles the particle kernels of a physics-option set
_WARMUP_NUMERICS = {"axial_cells": 10, "radial_cells": 4, "azimuthal_cells": 8, "parcels": 64,
                    "parcels_start": 64, "max_passes": 2, "average_passes": 1, "batch_size": 8}


class _BadInput(Exception):
    """Bad arguments or case file: exit status 2."""


# =====================================================================================
# command line
# =====================================================================================

def add_arguments(parser) -> None:
    """Define the ``eulag study`` sub-commands on ``parser`` (each sets ``func(args) -> int``)."""
    sub = parser.add_subparsers(dest="study", metavar="STUDY", parser_class=type(parser))
    sub.required = True

    p = sub.add_parser("tsuji-morikawa", help="base case at U0 = 10 and 15 m/s, four-way and two-way, "
                                              "against the Tsuji-Morikawa profiles")
    _common(p, "tsuji-morikawa")
    p.set_defaults(func=_entry(study_tsuji_morikawa))

    p = sub.add_parser("scenes", help="the secondary-flow scene matrix a-h (cases/scenes/)")
    _common(p, "scenes", only="comma-separated scenes to run, e.g. a,c (default: all)")
    p.set_defaults(func=_entry(study_scenes))

    p = sub.add_parser("error-runtime", help="error of the section profiles against wall time "
                                             "(grids, parcels, step factor, step rule)")
    p.add_argument("case", metavar="CASE.toml", help="the case studied (e.g. cases/tsuji_morikawa_200um.toml)")
    _common(p, "error-runtime")
    p.set_defaults(func=_entry(study_error_runtime))

    p = sub.add_parser("stability", help="stiff and extreme cases: converged, or a clear diagnosis")
    _common(p, "stability", only="comma-separated case names to run (default: all)")
    p.set_defaults(func=_entry(study_stability))


def _common(p, name: str, only: str | None = None) -> None:
    if only is not None:
        p.add_argument("--only", metavar="LIST", help=only)
    p.add_argument("--quick", action="store_true",
                   help="tiny grids, few parcels, two passes (checks the machinery; not results)")
    p.add_argument("-o", "--output-dir", metavar="DIR", default=None,
                   help=f"output folder (default: results/{name}/)")
    p.add_argument("--resume", action="store_true",
                   help="keep finished runs, continue interrupted ones from their checkpoints")
    p.add_argument("--report", action="store_true",
                   help="run nothing: write the table from the datasets, records and checkpoints "
                        "already in the output folder (an unfinished run's row says how far it got)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    if name != "error-runtime":  # there the parcel count is an axis of the study
        p.add_argument("--parcels", type=_positive_int, metavar="N",
                       help="parcels per pass in the final passes of every run (a lighter full-mode "
                            "study; the stability study's 1e6-parcel case keeps its count)")
    p.set_defaults(study_name=name)


def _positive_int(text: str) -> int:
    from .arguments import positive_int

    return positive_int(text)


def _with_parcels(case: Case, parcels: int | None) -> Case:
    """``case`` with ``parcels`` per final pass (and at most that many earlier); None: unchanged."""
    if parcels is None:
        return case
    return case.replace(numerics={"parcels": parcels,
                                  "parcels_start": min(case.numerics.parcels_start, parcels)})


def _entry(study: Callable) -> Callable:
    def func(args) -> int:
        t0 = time.perf_counter()
        try:
            outdir = _output_dir(args)
            return study(args, outdir, t0)
        except _BadInput as exc:
            print(f"eulag: error: {' '.join(str(exc).split())}", file=sys.stderr)
            return EXIT_BAD_INPUT
    return func


def _output_dir(args) -> Path:
    out = Path(args.output_dir) if args.output_dir else Path("results") / args.study_name
    if out.exists() and not out.is_dir():
        raise _BadInput(f"-o {out}: exists and is not a directory; allowed: a directory")
    if getattr(args, "report", False) and not out.is_dir():
        raise _BadInput(f"-o {out}: no such directory; --report reads the runs of an existing output folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _BadInput(f"-o {out}: cannot create the directory ({exc.strerror or exc})") from None
    if not os.access(out, os.W_OK):
        raise _BadInput(f"-o {out}: directory is not writable")
    return out


def _select(only: str | None, names: list[str], what: str) -> list[str]:
    if not only:
        return names
    wanted = [w.strip() for w in only.split(",") if w.strip()]
    bad = [w for w in wanted if w not in names]
    if bad or not wanted:
        raise _BadInput(f"--only {only}: unknown {what} {', '.join(bad) or '(none given)'}; "
                        f"allowed: a comma-separated list of {', '.join(names)}")
    return [n for n in names if n in wanted]


def _log(args, text: str) -> None:
    if not getattr(args, "quiet", False):
        print(text, file=sys.stderr, flush=True)


# =====================================================================================
# running cases
# =====================================================================================

@dataclass
class RunRecord:
    """What a study keeps of one run (the dataset itself is not kept in memory).

    status: "converged" | "not converged" | "failed" | "rejected" | "error", and with --report
    "unfinished" (a checkpoint only) | "not run" (nothing of the run is there; neither counts as
    a failure of the study: exit status 0);
    message: the diagnosis ("" for a converged run); time: wall time of the run [s]
    (compilation excluded, see the module docstring); passes, residual, relaxation: the
    last pass's; metrics: what the study extracted from the dataset.
    """

    name: str
    case: Case | None
    path: Path
    status: str
    message: str = ""
    time: float = math.nan
    passes: int = 0
    residual: float = math.nan
    relaxation: float = math.nan
    reused: bool = False
    metrics: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """A dataset exists (converged or not)."""
        return self.status in ("converged", "not converged")


def _canonical(case: Case) -> str:
    def default(v):
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, np.generic):
            return v.item()
        return str(v)
    return json.dumps(comparable_attrs(case.to_attrs()), sort_keys=True, default=default)


def resumable_checkpoint(ckpt: Path, case: Case):
    """(meta, residual history) of the coupling checkpoint ``ckpt`` when it is readable and
    resumable as ``case`` (``coupling.checkpoint_problem``: its stored case compared as records
    are, so one from before a key of ``config.LATER_KEYS`` counts; a changed
    ``numerics.max_passes`` only where the passes done do not depend on it), else None.  The
    file is read once (a run beside the caller may finish and delete it)."""
    from eulag import coupling

    try:
        meta, residual = coupling.read_checkpoint(ckpt)
        return (meta, residual) if coupling.checkpoint_problem(meta, residual, case) is None else None
    except Exception:  # noqa: BLE001 - absent, unreadable or foreign: not of this case
        return None


def checkpoint_of(ckpt: Path, case: Case) -> bool:
    """Whether the coupling checkpoint ``ckpt`` is readable and resumable as ``case``
    (``resumable_checkpoint``)."""
    return resumable_checkpoint(ckpt, case) is not None


def _same_case(attrs: dict, case: Case) -> bool:
    try:
        return Case.from_attrs(attrs) == case
    except CaseError:
        return False


def _open(path: Path):
    import xarray as xr

    with xr.open_dataset(path) as opened:
        return opened.load()


def _progress_printer(args, label: str, history: list):
    def progress(state):
        history.append(state)
        t_gas, t_part = state.times.get("gas_solve", 0.0), state.times.get("lagrangian", 0.0)
        _log(args, f"    {label}: pass {state.index} ({state.phase}), residual {state.residual:.3g}, "
                   f"-dp/dx {state.pressure_gradient:.4g} Pa/m, {state.parcels} parcels, relaxation "
                   f"{state.relaxation:g}, {t_gas + t_part:.1f} s (gas {t_gas:.1f} s, particles {t_part:.1f} s)")
    return progress


_WARMED: set = set()


def _warm_up(case: Case, args=None) -> None:
    """Compile the particle kernels of ``case``'s physics options with a tiny throw-away run."""
    from eulag.coupling import physics_options

    if case is None or case.particles is None:
        return
    key = (repr(physics_options(case)), case.pipe.mode)
    if key in _WARMED:
        return
    _WARMED.add(key)
    tiny = case.replace(numerics=_WARMUP_NUMERICS)
    t0 = time.perf_counter()
    try:
        from eulag.runs import run

        run(tiny)
    except Exception:  # noqa: BLE001 - only compiles; the timed run reports any failure
        pass
    if args is not None:
        _log(args, f"  (warm-up: particle kernels for the physics options of {case.name} compiled, "
                   f"{time.perf_counter() - t0:.1f} s, not counted)")


def run_case(args, name: str, case: Case | CaseError, outdir: Path, label: str,
             extract: Callable | None = None) -> RunRecord:
    """Run (or, with ``--resume``, reuse) one case of a study; never raises for a failing run.

    ``case`` may be the CaseError its construction raised (recorded as "rejected").
    ``extract(ds, record)`` returns the study's metrics of a finished dataset; the per-run
    figures are drawn there too.
    """
    from eulag import runs

    out = outdir / f"{name}.nc"
    ckpt = Path(str(out) + ".checkpoint")
    failed = outdir / f"{name}.failed.json"
    if isinstance(case, CaseError):
        _log(args, f"  {label}: rejected by the case validation: {case}")
        return RunRecord(name, None, out, "rejected", str(case))

    report = bool(getattr(args, "report", False))
    resume = bool(getattr(args, "resume", False)) or report
    ds = None
    reused = False
    record = outdir / f"{name}.record.json"
    if resume and out.is_file():
        try:
            opened = _open(out)
        except Exception:  # noqa: BLE001 - unreadable: run again
            opened = None
        if opened is not None and _same_case(opened.attrs, case) and "coupling_passes" in opened.attrs:
            ds = opened
            reused = True
            _log(args, f"  {label}: {out} exists (same case), not run again")
    if ds is None and resume and (report or not out.is_file()):  # (--report: also beside an unusable dataset)
        kept = read_record(record, case)
        if kept is not None:
            _log(args, f"  {label}: reported from its record {record} (its dataset is not here; run "
                       f"at commit {kept.metrics.get('commit') or 'unknown'}), not run again")
            return kept
    if ds is None and resume and failed.is_file():
        try:
            info = json.loads(failed.read_text())
        except (OSError, ValueError):
            info = None
        if info and info.get("case") == _canonical(case):
            _log(args, f"  {label}: failed before ({failed}), not run again: {info['message']}")
            return RunRecord(name, case, out, info["status"], info["message"], info.get("time", math.nan),
                             info.get("passes", 0), info.get("residual", math.nan),
                             info.get("relaxation", math.nan), reused=True,
                             metrics={"residual_history": info.get("residual_history", []),
                                      "relaxation_history": info.get("relaxation_history", []),
                                      "commit": info.get("commit")})

    if ds is None and report:
        return _unfinished_record(args, name, case, out, ckpt, label)
    if ds is None:
        if not resume:
            for stale in (ckpt, failed, record):  # a fresh run: nothing of an earlier one stands
                stale.unlink(missing_ok=True)
        elif ckpt.exists() and not checkpoint_of(ckpt, case):
            ckpt.unlink(missing_ok=True)  # unreadable or of another case: start afresh
        failed.unlink(missing_ok=True)
        _warm_up(case, args)
        history: list = []
        _log(args, f"  {label}: running ({_describe_numerics(case)})")
        t0 = time.perf_counter()
        try:
            ds = runs.execute(case, out, resume=resume, progress=_progress_printer(args, name, history),
                              notify=lambda text: _log(args, f"    {name}: {text}")).dataset
        except (runs.RunError, FloatingPointError) as exc:
            kind = "failed"
            msg = " ".join(f"{exc}".split()) or type(exc).__name__
        except Exception as exc:  # noqa: BLE001 - recorded, the study goes on (exit status 1)
            kind = "error"
            msg = " ".join(f"{type(exc).__name__}: {exc}".split())
        else:
            kind = None
        if kind is not None:
            dt = time.perf_counter() - t0
            last = history[-1] if history else None
            hist = {"residual_history": [float(h.residual) for h in history],
                    "relaxation_history": [float(h.relaxation) for h in history]}
            t_before, n_before = _resumed_part(ckpt, history, hist)
            dt += t_before
            hist["commit"] = eulag.git_commit()
            res_h, rel_h = hist["residual_history"], hist["relaxation_history"]
            rec = RunRecord(name, case, out, kind, msg, dt, last.index if last else n_before,
                            res_h[-1] if res_h else math.nan, rel_h[-1] if rel_h else math.nan,
                            metrics=dict(hist))
            out.unlink(missing_ok=True)  # an older dataset or record here would contradict the table
            record.unlink(missing_ok=True)
            failed.write_text(json.dumps({"case": _canonical(case), "status": kind, "message": msg,
                                          "time": dt, "passes": rec.passes, "residual": rec.residual,
                                          "relaxation": rec.relaxation, **hist}, default=str))
            _log(args, f"  {label}: {kind}: {msg}")
            return rec
        ckpt.unlink(missing_ok=True)  # the dataset holds everything; the checkpoint is no longer needed

    rec = _record_from_dataset(name, case, out, ds)
    rec.reused = reused
    if extract is not None:
        rec.metrics.update(extract(ds, rec))
    write_record(record, case, rec)
    _log(args, f"  {label}: {rec.status} after {rec.passes} passes, {rec.time:.1f} s")
    return rec


RECORD_VERSION = 1


def _unfinished_record(args, name: str, case: Case, out: Path, ckpt: Path, label: str) -> RunRecord:
    """--report: the row of a run with neither dataset, record nor failed record here —
    "unfinished" with the state of its checkpoint (passes done, the last residual and α, the
    time so far), or "not run"."""
    found = resumable_checkpoint(ckpt, case)
    if found is not None:
        meta, residual = found
        done = int(meta.get("pass_index", 0))
        t = meta.get("timings", {})
        spent = sum(float(t.get(k, 0.0)) for k in ("gas_solve", "lagrangian", "checkpoint"))
        res = float(residual[-1]) if residual.size else math.nan
        alpha = float(meta.get("alpha", math.nan))
        msg = (f"checkpoint after pass {done} of at most {case.numerics.max_passes} ({meta.get('phase')} "
               f"passes, residual {res:.3g}, relaxation {alpha:g}); --resume continues it")
        _log(args, f"  {label}: unfinished: {msg}")
        return RunRecord(name, case, out, "unfinished", msg, spent, done, res, alpha)
    _log(args, f"  {label}: not run (no dataset, record or checkpoint of this case here)")
    return RunRecord(name, case, out, "not run", "no dataset, record or checkpoint of this case here")


def _to_json(v):
    """``v`` with numpy arrays and scalars made JSON-serialisable (arrays tagged, so that
    :func:`_from_json` gives them back as arrays)."""
    if isinstance(v, dict):
        return {str(k): _to_json(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_to_json(x) for x in v]
    if isinstance(v, np.ndarray):
        return {"__ndarray__": _to_json(v.tolist()), "dtype": str(v.dtype)}
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, Path):
        return str(v)
    return v


def _from_json(v):
    if isinstance(v, dict):
        if "__ndarray__" in v:
            return np.asarray(v["__ndarray__"], dtype=v.get("dtype", "float64"))
        return {k: _from_json(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_from_json(x) for x in v]
    return v


def write_record(path: Path, case: Case, rec: RunRecord) -> Path:
    """Write ``<run>.record.json``: the run record of a finished run, with what the study
    extracted from its dataset (figure paths relative to the record's folder)."""
    from eulag.output import atomic_write

    metrics = dict(rec.metrics)
    if "figures" in metrics:
        metrics["figures"] = [os.path.relpath(f, path.parent) for f in metrics["figures"]]
    data = {"version": RECORD_VERSION, "case": _canonical(case), "name": rec.name, "status": rec.status,
            "message": rec.message, "time": rec.time, "passes": rec.passes, "residual": rec.residual,
            "relaxation": rec.relaxation, "dataset": path.name.replace(".record.json", ".nc"),
            "written_by": eulag.__version__, "metrics": _to_json(metrics)}
    text = json.dumps(data, indent=1, default=str)
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def read_record(path: Path, case: Case) -> RunRecord | None:
    """The run record at ``path`` when it belongs to ``case`` (None: absent, unreadable, of
    another case or of another record version)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if data.get("version") != RECORD_VERSION or data.get("case") != _canonical(case):
        return None
    metrics = _from_json(data.get("metrics", {}))
    if "figures" in metrics:
        metrics["figures"] = [str(path.parent / f) for f in metrics["figures"]]

    def num(key):
        v = data.get(key)
        return math.nan if v is None else float(v)

    return RunRecord(data.get("name", path.name), case, path.parent / data.get("dataset", ""),
                     data["status"], data.get("message", ""), num("time"), int(data.get("passes") or 0),
                     num("residual"), num("relaxation"), reused=True, metrics=metrics)


def _describe_numerics(case: Case) -> str:
    n = case.numerics
    grid = (f"{n.radial_cells}x{n.azimuthal_cells}" if case.pipe.mode == "periodic"
            else f"{n.axial_cells}x{n.radial_cells}x{n.azimuthal_cells}")
    return (f"{grid} cells, {n.parcels} parcels, step {n.step_rule} x {n.step_factor:g}, "
            f"max {n.max_passes} passes")


def _attr_float(ds, key, default=math.nan) -> float:
    try:
        return float(ds.attrs.get(key, default))
    except (TypeError, ValueError):
        return default


def run_time(ds) -> float:
    """Wall time of a run [s]: the larger of ``time_total`` and the sum of its phases (a resumed
    run's ``time_total`` covers only the resumed part; the phase times accumulate)."""
    parts = sum(_attr_float(ds, f"time_{k}", 0.0) for k in ("gas_solve", "lagrangian", "checkpoint"))
    return max(_attr_float(ds, "time_total", 0.0), parts)


def _record_from_dataset(name, case, out, ds) -> RunRecord:
    converged = is_converged(ds)
    res = np.asarray(ds["residual"].values, dtype=float) if "residual" in ds else np.array([math.nan])
    relax = np.asarray(ds["relaxation"].values, dtype=float) if "relaxation" in ds else np.array([math.nan])
    passes = int(ds.attrs.get("coupling_passes", res.size))
    msg = "" if converged else (ds.attrs.get("stop_reason") or _why_not_converged(ds, case))
    return RunRecord(name, case, out, "converged" if converged else "not converged", msg, run_time(ds),
                     passes, float(res[-1]) if res.size else math.nan,
                     float(relax[-1]) if relax.size else math.nan,
                     metrics={"collision_momentum": _collision_momentum(ds, case),
                              "commit": ds.attrs.get("eulag_commit")})


def _resumed_part(ckpt: Path, history: list, hist: dict) -> tuple[float, int]:
    """For a run that failed after a resume: prepend the histories of the passes run before
    it (from the checkpoint, which holds every pass up to the one before the failure) to
    ``hist``; return their gas and Lagrangian time [s] and their number ((0, 0) when nothing
    was resumed).  ``history``: the passes this invocation completed (maybe none)."""
    if (history and history[0].index <= 1) or not ckpt.exists():
        return 0.0, 0
    try:
        with np.load(ckpt, allow_pickle=False) as z:
            n = history[0].index - 1 if history else len(z["hist_residual"])
            before = slice(0, n)
            res = [float(v) for v in z["hist_residual"][before]]
            rel = [float(v) for v in z["hist_relaxation"][before]]
            t = float(np.sum(z["hist_time_gas"][before]) + np.sum(z["hist_time_particles"][before]))
    except (OSError, KeyError, ValueError):
        return 0.0, 0
    hist["residual_history"] = res + hist["residual_history"]
    hist["relaxation_history"] = rel + hist["relaxation_history"]
    return t, len(res)


def _collision_momentum(ds, case: Case) -> float:
    """Net axial momentum the stochastic inter-particle collisions gave the particles, over
    their momentum inflow, averaged over the final passes (NaN: not recorded, i.e. a dataset
    written before the record existed, or no inter-particle collisions).  Real collisions
    conserve momentum; the fictitious partners do so only while the cell statistics they are
    drawn from match the particles, so this is the model's momentum error."""
    if "collision_momentum_history" not in ds:
        return math.nan
    if case is not None and not case.physics.inter_particle_collisions:
        return math.nan
    v = np.asarray(ds["collision_momentum_history"].values, dtype=float)
    v = v[-max(1, case.numerics.average_passes):] if case is not None else v[-1:]
    v = v[np.isfinite(v)]
    return float(np.mean(v)) if v.size else math.nan


def _gas_not_converged(ds, tol: float) -> str:
    """Where the last gas solve missed its tolerance: the stations, where they lie, and how far
    their last iteration still moved the velocity and k/ε (datasets before the per-station
    record: the bare statement)."""
    if "gas_station_converged" not in ds:
        return "gas solve not converged"
    bad = np.asarray(ds["gas_station_converged"].values) == 0
    if not bad.any():
        return "gas solve not converged"
    x = np.asarray(ds["x"].values)[bad]
    du = float(np.nanmax(ds["gas_station_change_velocity"].values[bad]))
    dt = float(np.nanmax(ds["gas_station_change_turbulence"].values[bad]))
    where = f"x = {x[0]:.3g} m" if x.size == 1 else f"x = {x.min():.3g}-{x.max():.3g} m"
    return (f"gas solve not converged at {int(bad.sum())} of {bad.size} stations ({where}): their last "
            f"iteration still changed the velocity by {du:.1e} U_b and k/eps by {dt:.1e} "
            f"(tolerance {tol:g})")


def _why_not_converged(ds, case: Case) -> str:
    """The first convergence criterion (eulag.coupling) a finished, unconverged run misses,
    for datasets written without the loop's own verdict (``stop_reason``, ``criterion_*``)."""
    n = case.numerics
    if ds.attrs.get("gas_converged") == "false":
        return _gas_not_converged(ds, n.gas_tolerance)
    res = np.asarray(ds["residual"].values, dtype=float)
    finite = res[np.isfinite(res)]
    if finite.size == 0:
        return f"no coupling residual in {res.size} passes (max_passes = {n.max_passes})"
    early = res[: max(1, res.size - n.average_passes)]
    early = early[np.isfinite(early)]
    last = float(early[-1]) if early.size else float(finite[-1])
    if not last < n.coupling_tolerance:
        return (f"coupling residual {last:.3g} > coupling_tolerance {n.coupling_tolerance:g} when "
                f"max_passes = {n.max_passes} was reached")
    from eulag.coupling import (COLLISION_MOMENTUM_TOL, collision_momentum_settled, collision_momentum_to_come,
                                recent_collision_momentum)

    if "collision_momentum_history" in ds:
        cm = np.asarray(ds["collision_momentum_history"].values, dtype=float)
        early_cm = cm[: max(1, cm.size - n.average_passes)]
        if not collision_momentum_settled(early_cm):
            return (f"collision momentum / inflow {recent_collision_momentum(early_cm):+.3g} (last passes) "
                    f"still changing ({collision_momentum_to_come(early_cm):.2g} to come, tolerance "
                    f"{COLLISION_MOMENTUM_TOL:g}) when max_passes = {n.max_passes} was reached")
    from eulag.coupling import _INTEGRAL_PASSES, _INTEGRAL_TOL, pressure_gradient_to_come

    if "pressure_gradient_history" in ds and "relaxation" in ds:
        # the passes before the final ones: where the loop last judged convergence
        dp = np.asarray(ds["pressure_gradient_history"].values, dtype=float)[: res.size - n.average_passes]
        rel = np.asarray(ds["relaxation"].values, dtype=float)[: res.size - n.average_passes]
        if dp.size > _INTEGRAL_PASSES and np.all(np.isfinite(dp[-_INTEGRAL_PASSES - 1:])):
            trend, to_come, alpha = pressure_gradient_to_come(dp, rel)
            if to_come > _INTEGRAL_TOL:
                return (f"-dp/dx still drifting ({trend:+.3g} Pa/m per pass at {dp[-1]:.4g} Pa/m, "
                        f"relaxation {alpha:g}: {100 * to_come:.2g} % still to come, tolerance "
                        f"{100 * _INTEGRAL_TOL:g} %) when max_passes = {n.max_passes} was reached")
    return (f"pressure gradient or mass balance still drifting when max_passes = {n.max_passes} "
            "was reached")


# =====================================================================================
# machine, tables, markdown
# =====================================================================================

def machine_info() -> dict[str, Any]:
    """The machine and the code a study ran on (stated in every table)."""
    info: dict[str, Any] = {
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "eulag": eulag.__version__,
    }
    try:
        info["cpus_usable"] = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        info["cpus_usable"] = os.cpu_count()
    try:
        import numba

        info["numba_threads"] = numba.get_num_threads()
    except Exception:  # noqa: BLE001
        pass
    info["commit"] = eulag.git_commit()
    return info


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


@dataclass
class Column:
    key: str
    header: str
    fmt: str = "{}"

    def cell(self, row: dict) -> str:
        v = row.get(self.key)
        if v is None:
            return "—"
        if isinstance(v, float) and not math.isfinite(v):
            return "—"
        try:
            return self.fmt.format(v)
        except (ValueError, TypeError):
            return str(v)


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def markdown_table(columns: list[Column], rows: list[dict]) -> str:
    lines = ["| " + " | ".join(c.header for c in columns) + " |",
             "|" + "|".join("---" for _ in columns) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(_md_escape(c.cell(row)) for c in columns) + " |")
    return "\n".join(lines)


def write_csv(path: Path, columns: list[Column], rows: list[dict]) -> Path:
    from eulag.output import atomic_write

    def write(tmp):
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([c.key for c in columns])
            for row in rows:
                vals = []
                for c in columns:
                    v = row.get(c.key)
                    if isinstance(v, float):
                        vals.append("" if not math.isfinite(v) else repr(v))
                    else:
                        vals.append("" if v is None else str(v))
                w.writerow(vals)
    return atomic_write(path, write)


def _records_text(records) -> str:
    """Which rows come from run records rather than datasets present here, and, for a record
    carried over from an earlier table (its dataset lost), where it was carried from."""
    from_record = [r for r in records if r.reused and not r.path.is_file() and r.ok]
    if not from_record:
        return ""
    text = ("Rows reported from their run records (`<run>.record.json`; the dataset is not in this "
            "folder): " + ", ".join(f"`{r.name}`" for r in from_record) + ".")
    carried: dict[str, list[str]] = {}
    for r in from_record:
        if r.metrics.get("carried_from"):
            note = r.metrics["carried_from"] + (f" ({r.metrics['carried_note']})"
                                                if r.metrics.get("carried_note") else "")
            carried.setdefault(note, []).append(f"`{r.name}`")
    for note, names in carried.items():
        text += f" {', '.join(names)}: the row carried from {note}."
    return text


def write_report(outdir: Path, study: str, args, *, title: str, intro: list[str],
                 columns: list[Column], rows: list[dict], figures: list[Path],
                 sections: list[tuple[str, str]] = (), t_start: float, settings: str,
                 records: list[RunRecord] = ()) -> Path:
    """README.md of a study folder (generated) and the CSV of its table."""
    from eulag.output import atomic_write

    csv_path = write_csv(outdir / f"{study}.csv", columns, rows)
    m = machine_info()
    quick = bool(getattr(args, "quick", False))
    cmd = f"eulag study {study}" + (f" {args.case}" if getattr(args, "case", None) else "") + \
          (" --quick" if quick else "") + \
          (f" --parcels {args.parcels}" if getattr(args, "parcels", None) else "") + \
          (f" --only {args.only}" if getattr(args, "only", None) else "") + \
          (" --resume" if getattr(args, "resume", False) else "") + \
          (" --report" if getattr(args, "report", False) else "")
    lines = [f"# {title}", "",
             "*Generated by `" + cmd + "`; do not edit by hand — re-run the command.*", ""]
    if quick:
        lines += ["> **Quick mode**: tiny grids, a few hundred parcels and two passes. These numbers "
                  "check the study machinery; they are **not results**.", ""]
    lines += intro + [""]
    lines += ["## Table", "", markdown_table(columns, rows), "",
              f"The same table as CSV: [{csv_path.name}]({csv_path.name}). Each run's dataset is "
              "`<run>.nc` in the output folder (not committed: 70-90 MB each); what the table and "
              "figures take from it is in `<run>.record.json` beside it (a failed run: "
              "`<run>.failed.json`), which `--resume` reports from when the dataset is not there."
              + "".join(" " + t for t in [_records_text(records)] if t), ""]
    for head, text in sections:
        lines += [f"## {head}", "", text, ""]
    if figures:
        lines += ["## Figures", ""]
        for f in figures:
            rel = os.path.relpath(f, outdir)
            lines += [f"![{Path(rel).stem}]({rel})", ""]
    total = time.perf_counter() - t_start
    lines += ["## Settings", "", settings, "",
              "## Machine and wall time", "",
              f"- platform: {m['platform']} ({m['machine']}), CPU: {m['cpu']}",
              f"- CPUs: {m['cpu_count']} ({m['cpus_usable']} usable), numba threads: "
              f"{m.get('numba_threads', 'n/a')}",
              f"- python {m['python']}, eulag {m['eulag']}, commit {m['commit']}",
              f"- wall time of this invocation: {total:.1f} s (runs reused with `--resume` count with the "
              "time they took when they ran; the time column excludes the JIT compilation of the "
              "particle kernels, done once per physics-option set by a warm-up run)",
              f"- written {time.strftime('%Y-%m-%d %H:%M:%S %Z')}", ""]
    text = "\n".join(lines)
    path = outdir / "README.md"
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))
    return path


def _status_cell(rec: RunRecord) -> str:
    if rec.status == "converged":
        return "yes"
    if rec.status == "not converged":
        return f"no: {rec.message}" if rec.message else "no"
    return f"{rec.status}: {rec.message}"


COLLISION_MOMENTUM_TEXT = (
    "collision momentum / inflow = the net axial momentum the stochastic inter-particle collisions "
    "gave the particles over their momentum inflow, mean of the final passes (real collisions "
    "conserve momentum; the fictitious partners do so only while the cell statistics they are drawn "
    "from match the particles, so this is the collision model's momentum error; — where the "
    "dataset predates the record, the run failed or has no inter-particle collisions); commit = the eulag commit that wrote the "
    "run's dataset (a run reused with --resume may predate this invocation; — where the dataset "
    "predates the record)")


def _run_columns() -> list[Column]:
    return [Column("converged", "converged"), Column("passes", "passes", "{:d}"),
            Column("time_s", "run time [s]", "{:.1f}"),
            Column("collision_momentum", "collision momentum / inflow", "{:+.2g}"),
            Column("commit", "commit")]


def _run_cells(rec: RunRecord) -> dict:
    return {"converged": _status_cell(rec), "passes": rec.passes, "time_s": rec.time,
            "final_residual": rec.residual, "relaxation": rec.relaxation,
            # (records written before e3ab6c7 hold 0 for runs without inter-particle collisions)
            "collision_momentum": (rec.metrics.get("collision_momentum")
                                   if rec.case is None or rec.case.physics.inter_particle_collisions
                                   else None),
            "commit": rec.metrics.get("commit")}


def _numerics_differences(cases: list[Case]) -> str:
    """Which numerics of the other runs differ from the first run's (names and values)."""
    first = cases[0].numerics
    names = [f.name for f in _public_fields(type(first))]
    runs = []
    for c in cases[1:]:
        d = [f"{k} {_setting_value(getattr(c.numerics, k))}" for k in names
             if getattr(c.numerics, k) != getattr(first, k)]
        if d:
            runs.append(f"{c.name} {', '.join(d)}")
    return "the others' are the same" if not runs else "differing in the others: " + "; ".join(runs)


def _setting_value(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _settings_text(cases: list[Case], quick: bool) -> str:
    if not cases:
        return "no case ran"
    c = cases[0]
    n = c.numerics
    which = "the run" if len(cases) == 1 else f"the runs (the first run's; {_numerics_differences(cases)})"
    text = (f"Numerics of {which}: "
            f"{n.axial_cells} axial x {n.radial_cells} radial x {n.azimuthal_cells} azimuthal cells, "
            f"{n.parcels} parcels per pass in the final passes ({n.parcels_start} earlier), "
            f"{n.average_passes} final passes averaged, at most {n.max_passes} passes, relaxation "
            f"{n.relaxation:g} (halved by the loop when a gas solve fails or the residual stagnates, "
            "raised again once when a halved α has brought the residual below the tolerance), "
            f"step rule {n.step_rule} x "
            f"{n.step_factor:g}, coupling tolerance {n.coupling_tolerance:g}, seed {n.seed}. "
            "Model constants are the paper's (PHYSICS.md §12); nothing is tuned to the measurements.")
    if quick:
        text += (f" Quick mode replaces the numerics of every case by {QUICK_NUMERICS} (the stability "
                 f"study further by {STABILITY_QUICK}; error-runtime varies grid, parcels and step).")
    return text


def _finish(args, outdir: Path, records: list[RunRecord], *, allowed_failures: bool) -> int:
    bad = [r for r in records if r.status == "error" or (not allowed_failures and r.status == "failed")]
    _log(args, f"eulag study {args.study_name}: wrote {outdir / 'README.md'}")
    if bad:
        names = ", ".join(f"{r.name} ({r.status})" for r in bad)
        print(f"eulag: error: {len(bad)} of {len(records)} runs did not finish: {names}; see "
              f"{outdir / 'README.md'}", file=sys.stderr)
        return EXIT_FAILURE
    return EXIT_OK


# The resolution the studies run the base case at (the paper's scale; every study table states
# its cells and parcels).  The case file's own defaults are the error-against-run-time study's
# Pareto-best setting (results/error-runtime), which is coarser.
STUDY_NUMERICS = {"axial_cells": 400, "radial_cells": 20, "azimuthal_cells": 40, "parcels": 240_000}


def _base_case(quick: bool, path: Path = BASE_CASE) -> Case:
    """The case at ``path``; the base case (by content: any copy of its file) at the studies'
    resolution STUDY_NUMERICS; quick mode on the quick numerics."""
    case = Case.from_toml(path)
    if case == Case.from_toml(BASE_CASE):
        case = case.replace(numerics=STUDY_NUMERICS)
    return _quick(case) if quick else case


def _quick(case: Case, **numerics) -> Case:
    return case.replace(numerics={**QUICK_NUMERICS, **numerics})


def _figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    def make(w, h):
        fig = Figure(figsize=(w, h), dpi=110, layout="constrained")
        FigureCanvasAgg(fig)
        return fig
    return make


def _station(ds, x: float) -> float:
    """The x [m] of the station nearest x that the analysis uses."""
    from eulag import analysis as an

    sec = an.section(ds, x)
    return float(sec["x"].values) if "x" in sec.coords else float(x)


def _stations_text(records, x: float) -> str:
    xs = sorted({round(r.metrics["x_station"], 6) for r in records if "x_station" in r.metrics})
    if not xs:
        return ""
    return (f" The analysis uses the cell station nearest x = {x:g} m: x = "
            + ", ".join(f"{v:.4g}" for v in xs) + " m.")


def _per_run_figures(ds, x: float, outdir: Path) -> list[Path]:
    from eulag import plots

    try:
        return plots.plot_all(ds, x=x, outdir=outdir)
    except Exception as exc:  # noqa: BLE001 - a figure must not lose the table
        print(f"eulag: warning: figures of {ds.attrs.get('case.name')}: {type(exc).__name__}: {exc}",
              file=sys.stderr)
        return []


# =====================================================================================
# profiles against measurements / a reference
# =====================================================================================

def read_measurements(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """{phase: {"y_over_R": array, "u": array}} from the Tsuji-Morikawa CSV (its velocities are
    normalised by a reference velocity, see the file's header)."""
    from eulag import plots

    prof = plots.read_reference(path)
    return {ph: {"y_over_R": 2.0 * p["y_over_D"], "u": np.asarray(p["u"], dtype=float)}
            for ph, p in prof.items()}


def provenance(path: Path) -> list[str]:
    """The header comment lines of a measurement file (its provenance), without the '#'."""
    out = []
    with open(path) as fh:
        for line in fh:
            if not line.startswith("#"):
                break
            out.append(line[1:].rstrip())
    return out


def diameter_profile(ds, var: str, x: float, y_over_R: np.ndarray, *, wall_value: float | None = None,
                     scale: float = 1.0) -> np.ndarray:
    """``var`` along the vertical diameter at the station nearest x, interpolated linearly at
    ``y_over_R``; NaN cells (no particles) are dropped; beyond the outermost cell centres the
    value is the wall value when given (gas: no slip), else the outermost cell's. Divided by
    ``scale``."""
    from eulag import analysis as an

    y, v = an.vertical_profile(ds, var, x)
    R = 0.5 * float(_attr(ds, "pipe.diameter"))
    ok = np.isfinite(v)
    y, v = y[ok] / R, v[ok]
    if y.size == 0:
        return np.full(np.shape(y_over_R), np.nan)
    if wall_value is not None:
        y = np.concatenate([[-1.0], y, [1.0]])
        v = np.concatenate([[wall_value], v, [wall_value]])
    return np.interp(np.asarray(y_over_R, dtype=float), y, v) / scale


def profile_deviation(sim: np.ndarray, ref: np.ndarray, se: np.ndarray | None = None) -> dict[str, float]:
    """Deviation of a simulated profile from a reference one at the same points, both in the same
    normalised units; returned in % of those units: rms, max (absolute), bias (mean signed) and
    stderr (RMS over the points of the simulation's standard error, when ``se`` is given)."""
    sim = np.asarray(sim, dtype=float)
    ref = np.asarray(ref, dtype=float)
    ok = np.isfinite(sim) & np.isfinite(ref)
    out = {"rms": math.nan, "max": math.nan, "bias": math.nan, "stderr": math.nan, "points": int(ok.sum())}
    if not ok.any():
        return out
    d = 100.0 * (sim[ok] - ref[ok])
    out.update(rms=float(np.sqrt(np.mean(d * d))), max=float(np.max(np.abs(d))), bias=float(np.mean(d)))
    if se is not None:
        s = 100.0 * np.asarray(se, dtype=float)[ok]
        s = s[np.isfinite(s)]
        if s.size:
            out["stderr"] = float(np.sqrt(np.mean(s * s)))
    return out


def pareto_front(times, errors) -> list[int]:
    """Indices of the non-dominated points (no other point is at least as fast and as accurate
    and strictly better in one), sorted by time. NaN points are never on the front."""
    t = np.asarray(times, dtype=float)
    e = np.asarray(errors, dtype=float)
    idx = [i for i in range(t.size) if np.isfinite(t[i]) and np.isfinite(e[i])]
    front = []
    for i in idx:
        dominated = any((t[j] <= t[i] and e[j] <= e[i]) and (t[j] < t[i] or e[j] < e[i]) for j in idx)
        if not dominated:
            front.append(i)
    return sorted(front, key=lambda i: (t[i], e[i]))


# =====================================================================================
# 1. Tsuji-Morikawa comparison
# =====================================================================================

TM_VELOCITIES = (10.0, 15.0)
TM_COUPLINGS = ("four-way", "two-way")


def tsuji_morikawa_cases(quick: bool, parcels: int | None = None) -> list[tuple[str, Case]]:
    """The four runs: base case at U0 = 10 and 15 m/s, four-way and two-way coupling."""
    base = _with_parcels(_base_case(quick), parcels)
    out = []
    for u0 in TM_VELOCITIES:
        for coupling in TM_COUPLINGS:
            name = f"tm_U{u0:g}_{coupling}"
            case = base.replace(name=name, description=f"{base.description}; U0 = {u0:g} m/s, {coupling}",
                                gas={"bulk_velocity": u0}, physics={"coupling": coupling})
            out.append((name, case))
    return out


def study_tsuji_morikawa(args, outdir: Path, t_start: float) -> int:
    cases = tsuji_morikawa_cases(args.quick, getattr(args, "parcels", None))
    base = cases[0][1]
    ref_path = base.reference_data_path()
    if ref_path is None:
        raise _BadInput(f"{BASE_CASE}: pipe.reference_data names no existing file")
    meas = read_measurements(ref_path)
    x = base.pipe.sections[0]
    figdir = outdir / "figures"
    records = []
    curves = {}
    for i, (name, case) in enumerate(cases, 1):
        u0 = case.gas.bulk_velocity

        def extract(ds, rec, u0=u0, name=name):
            ys = np.linspace(-1.0, 1.0, 201)
            m = {"curves": {
                "y": ys,
                "gas": diameter_profile(ds, "gas_ux", x, ys, wall_value=0.0, scale=u0),
                "particle": diameter_profile(ds, "particle_ux", x, ys, scale=u0),
                "particle_se": diameter_profile(ds, "particle_ux_stderr", x, ys, scale=u0)}}
            for phase in ("gas", "particle"):
                if phase not in meas:
                    continue
                yp, up = meas[phase]["y_over_R"], meas[phase]["u"]
                if phase == "gas":
                    sim = diameter_profile(ds, "gas_ux", x, yp, wall_value=0.0, scale=u0)
                    se = None
                else:
                    sim = diameter_profile(ds, "particle_ux", x, yp, scale=u0)
                    se = diameter_profile(ds, "particle_ux_stderr", x, yp, scale=u0)
                m[phase] = profile_deviation(sim, up, se)
                m[f"{phase}_points"] = [{"run": name, "phase": phase, "y_over_R": float(a), "measured": float(b),
                                         "simulated": float(c), "stderr": float(d) if se is not None else None}
                                        for a, b, c, d in zip(yp, up, sim, se if se is not None else sim)]
            _per_run_figures(ds, x, figdir)
            m["x_station"] = _station(ds, x)
            return m

        rec = run_case(args, name, case, outdir, f"[tsuji-morikawa {i}/{len(cases)}] {name}", extract)
        records.append(rec)
        if "curves" in rec.metrics:
            curves[name] = rec.metrics["curves"]

    rows = []
    for (name, case), rec in zip(cases, records):
        for phase in ("gas", "particle"):
            dev = rec.metrics.get(phase, {})
            rows.append({"run": name, "U0": case.gas.bulk_velocity, "coupling": case.physics.coupling,
                         "phase": phase, "rms": dev.get("rms"), "max": dev.get("max"),
                         "bias": dev.get("bias"), "stderr": dev.get("stderr"),
                         "points": dev.get("points"), **_run_cells(rec)})
    columns = [Column("U0", "U0 [m/s]", "{:g}"), Column("coupling", "coupling"), Column("phase", "phase"),
               Column("rms", "RMS dev. [% U0]", "{:.2f}"), Column("max", "max dev. [% U0]", "{:.2f}"),
               Column("bias", "mean dev. [% U0]", "{:+.2f}"),
               Column("stderr", "sim. std. error [% U0]", "{:.2f}"), Column("points", "points", "{:d}"),
               *_run_columns()]
    points = [pt for rec in records for ph in ("gas", "particle") for pt in rec.metrics.get(f"{ph}_points", [])]
    write_csv(outdir / "tsuji-morikawa_points.csv",
              [Column("run", ""), Column("phase", ""), Column("y_over_R", ""), Column("measured", ""),
               Column("simulated", ""), Column("stderr", "")], points)
    figures = []
    if curves:
        figures.append(_tm_figure(outdir / "tsuji_morikawa_profiles.png", cases, curves, meas, x))
    figures += sorted(figdir.glob("*_section*.png")) if figdir.is_dir() else []
    prov = "\n".join("    " + line for line in provenance(ref_path))
    intro = [
        f"Gas and particle mean axial velocity along the vertical diameter at x = {x:g} m of the base "
        f"case ({BASE_CASE.name}: D_p = {base.particles.diameter * 1e6:g} µm, eta = "
        f"{base.particles.mass_loading:g}, Delta-gamma = {base.walls.roughness_angle_std_deg:g} deg) "
        f"against the measurements of Tsuji & Morikawa (1982) in `{ref_path.name}`."
        + _stations_text(records, x),
        "",
        "The digitised profiles are normalised by 15 m/s and the source does not confirm the air "
        "velocity, so the case is run at U0 = 10 and 15 m/s and each run's profile is normalised by "
        "its own U0. Deviation = simulation - measurement at the measured points (the simulated "
        "profile interpolated linearly in y; particles: beyond the outermost cell centre with "
        "particles, that cell's value), in % of U0: RMS, maximum of the absolute value, and mean "
        "(bias). 'sim. std. error' is the RMS over the points of the particle velocity's batch "
        "standard error (`particle_ux_stderr`, final passes averaged); the gas field is "
        "deterministic given the relaxed particle sources and has no standard error of its own "
        "(their noise reaches it through the sources). The digitising error of the measured points "
        "is about ±1-2 % of the reference velocity (file header). Point by point (u_x / U0 at each "
        "measured y/R, measured and simulated, with the particle standard error): "
        "[tsuji-morikawa_points.csv](tsuji-morikawa_points.csv). Last two columns: "
        + COLLISION_MOMENTUM_TEXT + ".",
        "",
        "Provenance of the measurements (header of the file):", "", prov]
    write_report(outdir, "tsuji-morikawa", args, title="Tsuji–Morikawa comparison", intro=intro,
                 columns=columns, rows=rows, figures=figures, t_start=t_start,
                 settings=_settings_text([c for _, c in cases], args.quick), records=records)
    return _finish(args, outdir, records, allowed_failures=False)


def _tm_figure(path: Path, cases, curves, meas, x) -> Path:
    fig = _figure()(11.0, 5.6)
    axes = fig.subplots(1, 2, sharey=True)
    styles = {10.0: "-", 15.0: "--"}
    colours = {"four-way": "C0", "two-way": "C3"}
    for ax, phase in zip(axes, ("gas", "particle")):
        if phase in meas:
            ax.plot(meas[phase]["u"], meas[phase]["y_over_R"], "ko", mfc="none",
                    label="Tsuji & Morikawa (1982), U/15 m/s")
        for name, case in cases:
            c = curves.get(name)
            if c is None:
                continue
            u0, cpl = case.gas.bulk_velocity, case.physics.coupling
            ax.plot(c[phase], c["y"], styles.get(u0, ":"), color=colours.get(cpl, "k"),
                    label=f"eulag U0 = {u0:g} m/s, {cpl}")
            if phase == "particle":
                lo, hi = c["particle"] - 2 * c["particle_se"], c["particle"] + 2 * c["particle_se"]
                ax.fill_betweenx(c["y"], lo, hi, color=colours.get(cpl, "k"), alpha=0.12, lw=0)
        ax.set_xlabel("u_x / U0 [1]")
        ax.set_title(f"{phase}, x = {x:g} m" + ("  (band: ±2 std. errors)" if phase == "particle" else ""),
                     fontsize=10)
        ax.set_xlim(left=0.0)
        ax.set_ylim(-1.0, 1.0)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y / R [1] (top +1, bottom -1, gravity down)")
    axes[0].legend(fontsize=7, loc="lower left")
    fig.savefig(path, format="png")
    return path


# =====================================================================================
# 2. the scene matrix
# =====================================================================================

def scene_cases(quick: bool, names=SCENE_NAMES, parcels: int | None = None) -> list[tuple[str, Case]]:
    """The shipped scene files cases/scenes/scene_<a..h>.toml (quick: with the quick numerics)."""
    out = []
    for s in names:
        path = SCENES_DIR / f"scene_{s}.toml"
        case = Case.from_toml(path)
        out.append((f"scene_{s}", _with_parcels(_quick(case) if quick else case, parcels)))
    return out


def study_scenes(args, outdir: Path, t_start: float) -> int:
    from eulag import analysis as an

    names = _select(getattr(args, "only", None), list(SCENE_NAMES), "scenes")
    try:
        cases = scene_cases(args.quick, names, getattr(args, "parcels", None))
    except CaseError as exc:
        raise _BadInput(str(exc)) from None
    figdir = outdir / "figures"
    records = []
    for i, (name, case) in enumerate(cases, 1):
        x = case.pipe.sections[0]

        def extract(ds, rec, x=x):
            u0 = float(_attr(ds, "gas.bulk_velocity"))
            sec = an.section(ds, x)
            rates = an.wall_impact_rates(ds, x)
            dp = float(sec["pressure_gradient"].values)
            dp0 = float(sec["pressure_gradient_single_phase"].values)
            figs = _per_run_figures(ds, x, figdir)
            return {"strength": an.secondary_flow_strength(ds, x), "cells": an.recirculation_cells(ds, x),
                    "half": an.gas_maximum_half(ds, x), "impact_upper": rates["upper"],
                    "impact_lower": rates["lower"], "dpdx": dp, "dpdx_ratio": dp / dp0 if dp0 else math.nan,
                    "x_station": _station(ds, x), "u0": u0,
                    "figures": [str(f) for f in figs]}

        records.append(run_case(args, name, case, outdir, f"[scenes {i}/{len(cases)}] {name}", extract))

    rows = []
    for (name, case), rec in zip(cases, records):
        p = case.particles
        eta0 = 2.2
        rows.append({"scene": name.split("_")[-1], "dp_um": p.diameter * 1e6,
                     "dgamma": case.walls.roughness_angle_std_deg, "coupling": case.physics.coupling,
                     "loading": f"{p.mass_loading / eta0:g} eta0 = {p.mass_loading:g}",
                     **{k: rec.metrics.get(k) for k in ("strength", "cells", "half", "impact_upper",
                                                        "impact_lower", "dpdx", "dpdx_ratio")},
                     **_run_cells(rec)})
    columns = [Column("scene", "scene"), Column("dp_um", "D_p [µm]", "{:g}"),
               Column("dgamma", "Δγ [deg]", "{:g}"), Column("coupling", "coupling"),
               Column("loading", "loading"), Column("strength", "secondary flow [% U0]", "{:.3g}"),
               Column("cells", "recirc. cells", "{:d}"), Column("half", "gas max in half"),
               Column("impact_upper", "wall impacts upper [1/(m² s)]", "{:.3g}"),
               Column("impact_lower", "wall impacts lower [1/(m² s)]", "{:.3g}"),
               Column("dpdx", "-dp/dx [Pa/m]", "{:.4g}"), Column("dpdx_ratio", "/ single-phase", "{:.3f}"),
               *_run_columns()]
    figures = []
    for rec in records:
        figures += [Path(f) for f in rec.metrics.get("figures", []) if "_section" in Path(f).name]
    x0 = cases[0][1].pipe.sections[0] if cases else 3.56
    intro = [
        f"The secondary-flow scene matrix of the reference paper at x = {x0:g} m, U0 = 10 m/s, "
        "rho_p = 1020 kg/m³, eta0 = 2.2. One case file per scene ships in `cases/scenes/` "
        "(`scene_<a..h>.toml`, derived from the base case `cases/tsuji_morikawa_200um.toml`; the "
        "header of each says what differs)." + _stations_text(records, x0),
        "",
        "Columns: secondary-flow strength = largest in-plane gas speed in % of U0 "
        "(`eulag.analysis.secondary_flow_strength`); recirculation cells = connected same-sign "
        "regions of the in-plane stream function above 10 % of its maximum "
        "(`recirculation_cells`); the half (upper y > 0 / lower y < 0) holding the maximum of the gas "
        "axial velocity; particle-wall impacts per wall area and time on the upper and lower wall "
        "halves at the station; the section-mean -dp/dx at the station and its ratio to the "
        "single-phase value; coupling passes and run time; " + COLLISION_MOMENTUM_TEXT + ". "
        "Figures: the three-panel section figure of "
        "each scene (gas axial velocity with the secondary-flow stream lines, particle axial "
        "velocity, particle concentration / section mean); profile and convergence figures of each "
        "scene are in `figures/`."]
    write_report(outdir, "scenes", args, title="Secondary-flow scene matrix (scenes a–h)", intro=intro,
                 columns=columns, rows=rows, figures=figures, t_start=t_start,
                 settings=_settings_text([c for _, c in cases], args.quick), records=records)
    return _finish(args, outdir, records, allowed_failures=False)


# =====================================================================================
# 3. error against run time
# =====================================================================================

@dataclass
class Setting:
    name: str
    axis: str
    grid: tuple[int, int, int]
    parcels: int
    step_factor: float
    step_rule: str
    reference: bool = False


def _even(n: float) -> int:
    return max(8, 2 * int(round(n / 2.0)))


def error_runtime_plan(case: Case, quick: bool) -> tuple[list[Setting], Setting]:
    """The settings of the error-against-run-time study, one axis at a time around a centre
    setting, and the reference (the finest setting of every axis, its own seed).

    Full mode: grids at 0.5, 0.75 and 1 times the case's cells per direction; 1e4, 3e4, 1e5 and
    3e5 parcels per pass; step factors f0 and f0/2 (f0 the case's); step rules default and
    paper. Centre: the case's grid, 3e4 parcels, f0, the default rule. Quick mode: tiny grids and
    100-800 parcels.
    """
    n = case.numerics
    f0 = n.step_factor
    if quick:
        grids = [(10, 4, 8), (12, 4, 10), (16, 5, 12)]
        parcels = [100, 200, 400, 800]
    else:
        base = (n.axial_cells, n.radial_cells, n.azimuthal_cells)
        grids = [(max(10, int(round(f * base[0]))), max(4, int(round(f * base[1]))), _even(f * base[2]))
                 for f in (0.5, 0.75, 1.0)]
        parcels = [10_000, 30_000, 100_000, 300_000]
    centre = Setting("centre", "centre", grids[-1], parcels[1], f0, "default")
    runs = [centre]
    for g in grids[:-1]:
        runs.append(Setting(f"grid_{g[0]}x{g[1]}x{g[2]}", "grid", g, centre.parcels, f0, "default"))
    for p in parcels:
        if p != centre.parcels:
            runs.append(Setting(f"parcels_{p}", "parcels", centre.grid, p, f0, "default"))
    runs.append(Setting(f"step_factor_{f0 / 2:g}", "step factor", centre.grid, centre.parcels, f0 / 2, "default"))
    runs.append(Setting("step_rule_paper", "step rule", centre.grid, centre.parcels, f0, "paper"))
    ref = Setting("reference", "reference", grids[-1], parcels[-1], f0 / 2, "default", reference=True)
    return runs, ref


def _default_verdict(own: Case, best: dict) -> str:
    """Whether the case file's own numerics are the best setting of the table."""
    n = own.numerics
    mine = (f"{n.axial_cells}x{n.radial_cells}x{n.azimuthal_cells}", n.parcels, n.step_factor, n.step_rule)
    if mine == (best["grid"], best["parcels"], best["step_factor"], best["step_rule"]):
        return "It is the default of the case file (`eulag run` on the case uses it)."
    return (f"The case file's defaults ({mine[0]} cells, {n.parcels} parcels, step {n.step_rule} x "
            f"{n.step_factor:g}) differ from it.")


def _setting_case(case: Case, s: Setting, quick: bool) -> Case:
    n = case.numerics
    num = dict(QUICK_NUMERICS) if quick else {}
    num.update({"axial_cells": s.grid[0], "radial_cells": s.grid[1], "azimuthal_cells": s.grid[2],
                "parcels": s.parcels, "parcels_start": min(num.get("parcels_start", n.parcels_start), s.parcels),
                "step_factor": s.step_factor, "step_rule": s.step_rule})
    if quick:
        num["batch_size"] = max(8, s.parcels // 8)
    if s.reference:
        num["seed"] = (n.seed + 1000) % (2 ** 63)  # its noise independent of the other runs'
    return case.replace(name=f"{case.name}_{s.name}", numerics=num)


ER_POINTS = np.linspace(-0.95, 0.95, 39)  # y/R of the comparison points on the vertical diameter


def _er_profiles(ds, x: float) -> dict[str, np.ndarray]:
    from eulag import analysis as an

    u0 = float(_attr(ds, "gas.bulk_velocity"))
    ys = ER_POINTS
    cbar = an.section_mean(ds, np.nan_to_num(an._field(ds, "particle_concentration", x)), x)
    if not cbar > 0.0:  # no particles at the station: no concentration profile
        cbar = math.nan
    return {"gas": diameter_profile(ds, "gas_ux", x, ys, wall_value=0.0, scale=u0),
            "particle": diameter_profile(ds, "particle_ux", x, ys, scale=u0),
            "particle_se": diameter_profile(ds, "particle_ux_stderr", x, ys, scale=u0),
            "concentration": diameter_profile(ds, "particle_concentration", x, ys, scale=cbar),
            "concentration_se": diameter_profile(ds, "particle_concentration_stderr", x, ys, scale=cbar)}


def study_error_runtime(args, outdir: Path, t_start: float) -> int:
    try:
        own = Case.from_toml(args.case)  # the case file's own defaults
        case = _base_case(False, Path(args.case))  # the base case at the studies' resolution
    except CaseError as exc:
        raise _BadInput(str(exc)) from None
    if case.particles is None:
        raise _BadInput(f"{args.case}: a single-phase case; allowed: a case with [particles]")
    x = case.pipe.sections[0]
    ref_path = case.reference_data_path()
    meas = read_measurements(ref_path) if ref_path is not None else {}
    runs, ref = error_runtime_plan(case, args.quick)
    settings = [ref] + runs  # the reference first: every other run is compared with it
    records, profiles = {}, {}
    for i, s in enumerate(settings, 1):
        c = _setting_case(case, s, args.quick)

        def extract(ds, rec, s=s):
            m = {"x_station": _station(ds, x), "profiles": _er_profiles(ds, x)}
            u0 = float(_attr(ds, "gas.bulk_velocity"))
            for phase in ("gas", "particle"):
                if phase in meas:
                    sim = diameter_profile(ds, f"{phase}_ux", x, meas[phase]["y_over_R"],
                                           wall_value=0.0 if phase == "gas" else None, scale=u0)
                    m[f"meas_{phase}"] = profile_deviation(sim, meas[phase]["u"])["rms"]
            return m

        records[s.name] = run_case(args, s.name, c, outdir, f"[error-runtime {i}/{len(settings)}] {s.name}",
                                   extract)
        if "profiles" in records[s.name].metrics:
            profiles[s.name] = records[s.name].metrics["profiles"]

    refp = profiles.get(ref.name)
    rows = []
    for s in settings:
        rec = records[s.name]
        row = {"run": s.name, "axis": s.axis, "grid": "x".join(map(str, s.grid)), "parcels": s.parcels,
               "step_factor": s.step_factor, "step_rule": s.step_rule, **_run_cells(rec),
               "meas_gas": rec.metrics.get("meas_gas"), "meas_particle": rec.metrics.get("meas_particle")}
        p = profiles.get(s.name)
        if p is not None and refp is not None and not s.reference:
            sq_total, sq_disc = [], []
            for q, se in (("gas", None), ("particle", "particle_se"), ("concentration", "concentration_se")):
                e = profile_deviation(p[q], refp[q])["rms"]
                noise = 0.0
                if se is not None:
                    a = profile_deviation(p[se], np.zeros_like(p[se]))["rms"]
                    b = profile_deviation(refp[se], np.zeros_like(refp[se]))["rms"]
                    noise = math.sqrt(a * a + b * b) if math.isfinite(a) and math.isfinite(b) else math.nan
                row[f"err_{q}"] = e
                row[f"noise_{q}"] = noise if se is not None else None
                disc = math.sqrt(max(e * e - noise * noise, 0.0)) if math.isfinite(e) and math.isfinite(noise) else math.nan
                sq_total.append(e * e)
                sq_disc.append(disc * disc)
            row["err_total"] = math.sqrt(sum(sq_total) / 3.0)
            row["err_disc"] = math.sqrt(sum(sq_disc) / 3.0)
        rows.append(row)
    cand = [r for r in rows if r["axis"] != "reference"]
    front = pareto_front([r["time_s"] for r in cand], [r.get("err_total", math.nan) for r in cand])
    for i, r in enumerate(cand):
        r["pareto"] = "yes" if i in front else ""
    best = None
    if front:
        best = min(front, key=lambda i: cand[i]["time_s"] * cand[i]["err_total"])
        cand[best]["pareto"] = "yes (best: min error x time)"
    columns = [Column("run", "run"), Column("axis", "axis"), Column("grid", "cells (x·r·θ)"),
               Column("parcels", "parcels", "{:d}"), Column("step_factor", "step factor", "{:g}"),
               Column("step_rule", "step rule"), Column("time_s", "run time [s]", "{:.1f}"),
               Column("err_gas", "gas u err. [% U0]", "{:.3g}"),
               Column("err_particle", "part. u err. [% U0]", "{:.3g}"),
               Column("noise_particle", "part. u noise [% U0]", "{:.3g}"),
               Column("err_concentration", "conc. err. [% c̄]", "{:.3g}"),
               Column("noise_concentration", "conc. noise [% c̄]", "{:.3g}"),
               Column("err_total", "total err. [%]", "{:.3g}"),
               Column("err_disc", "discretisation part [%]", "{:.3g}"),
               Column("meas_gas", "gas vs meas. [% U0]", "{:.3g}"),
               Column("meas_particle", "part. vs meas. [% U0]", "{:.3g}"),
               Column("pareto", "Pareto"), Column("converged", "converged"),
               Column("passes", "passes", "{:d}"), Column("commit", "commit")]
    fig = _er_figure(outdir / "error_runtime.png", rows, cand, front)
    pareto_lines = []
    for i in front:
        r = cand[i]
        pareto_lines.append(f"- `{r['run']}`: {r['grid']} cells, {r['parcels']} parcels, step "
                            f"{r['step_rule']} x {r['step_factor']:g}: {r['time_s']:.1f} s, total error "
                            f"{r['err_total']:.3g} %")
    if best is not None:
        r = cand[best]
        pareto_lines += ["", f"Best by the stated criterion (smallest error x run time on the front): "
                             f"`{r['run']}` ({r['grid']} cells, {r['parcels']} parcels, step {r['step_rule']} "
                             f"x {r['step_factor']:g})." + ("" if args.quick else " " + _default_verdict(own, r))]
    n_ref = _setting_case(case, ref, args.quick).numerics
    intro = [
        f"Case `{args.case}`: error of the section profiles at x = {x:g} m against the reference run "
        f"(station used: the cell centre nearest x; the grids differ, so the stations may differ by up "
        f"to half a cell) "
        f"(the finest setting of every axis: {'x'.join(map(str, ref.grid))} cells, {ref.parcels} "
        f"parcels, step {ref.step_rule} x {ref.step_factor:g}, seed {n_ref.seed} so that its noise is "
        "independent of the other runs') and against the measurements, as a function of the run's "
        "wall time. One axis is varied at a time around the centre setting (`centre`): the grid, the "
        "parcels per pass, the particle time-step factor and the step rule (default / the paper's)."
        + (f" The axes are built around the studies' resolution of the base case "
           f"({case.numerics.axial_cells}x{case.numerics.radial_cells}x{case.numerics.azimuthal_cells} cells, "
           "`eulag.studies.STUDY_NUMERICS`), not the case file's own default."
           if case.numerics != own.numerics and not args.quick else ""),
        "",
        f"Profiles: along the vertical diameter at {ER_POINTS.size} points y/R in [-0.95, 0.95] "
        "(linear interpolation): gas and particle axial velocity / U0, particle concentration / its "
        "section mean. Error = RMS difference over the points, in % (of U0, of the section-mean "
        "concentration). Noise = the statistical part expected from the batch standard errors of the "
        "run and the reference, sqrt(se_run² + se_ref²) (RMS over the points); the discretisation part "
        "= sqrt(max(error² - noise², 0)). The gas field has no standard error of its own (the noise "
        "of the sources reaches it), so its error is counted as discretisation error. Total = RMS of "
        "the three quantities. 'vs meas.': RMS deviation from the Tsuji–Morikawa points "
        "(normalised by each run's U0; the data are normalised by 15 m/s, see the tsuji-morikawa study)."
        if meas else
        f"Profiles: along the vertical diameter at {ER_POINTS.size} points y/R in [-0.95, 0.95]; "
        "the case names no measurement file."]
    write_report(outdir, "error-runtime", args, title="Error against run time", intro=intro,
                 columns=columns, rows=rows, figures=[fig],
                 sections=[("Pareto front (total error against run time)", "\n".join(pareto_lines) or
                            "no run finished with an error estimate")],
                 t_start=t_start,
                 settings=_settings_text([_setting_case(case, r, args.quick) for r in settings], args.quick),
                 records=list(records.values()))
    return _finish(args, outdir, list(records.values()), allowed_failures=False)


def _er_figure(path: Path, rows, cand, front) -> Path:
    fig = _figure()(11.5, 4.8)
    ax1, ax2 = fig.subplots(1, 2)
    markers = {"centre": ("k", "*"), "grid": ("C0", "s"), "parcels": ("C1", "o"), "step factor": ("C2", "^"),
               "step rule": ("C3", "D")}
    seen = set()
    for r in cand:
        t, e = r.get("time_s"), r.get("err_total")
        if not (isinstance(t, float) and isinstance(e, float) and t > 0 and e > 0):
            continue
        col, mk = markers.get(r["axis"], ("0.5", "x"))
        ax1.loglog([t], [e], mk, color=col, label=None if r["axis"] in seen else r["axis"])
        d = r.get("err_disc")
        if isinstance(d, float) and d > 0:
            ax1.loglog([t], [d], mk, mfc="none", color=col)
        seen.add(r["axis"])
        for key, mk2, lab in (("meas_gas", "o", "gas"), ("meas_particle", "s", "particle")):
            v = r.get(key)
            if isinstance(v, float) and v > 0:
                ax2.loglog([t], [v], mk2, color=col, mfc="none" if key == "meas_gas" else col,
                           label=f"{lab}" if (key, r["axis"]) == (key, "centre") else None)
    for r in rows:
        if r["axis"] == "reference":
            for key, mk2 in (("meas_gas", "o"), ("meas_particle", "s")):
                v, t = r.get(key), r.get("time_s")
                if isinstance(v, float) and v > 0 and isinstance(t, float) and t > 0:
                    ax2.loglog([t], [v], mk2, color="0.5", mfc="none" if key == "meas_gas" else "0.5",
                               label="reference run" if key == "meas_gas" else None)
    pts = [(cand[i]["time_s"], cand[i]["err_total"]) for i in front]
    if len(pts) > 1:
        ax1.loglog(*zip(*pts), "-", color="0.4", lw=1, label="Pareto front")
    ax1.set_xlabel("run wall time [s]")
    ax1.set_ylabel("error vs reference [%] (filled: total, open: discretisation part)")
    ax1.grid(alpha=0.3, which="both")
    if seen:
        ax1.legend(fontsize=8)
    ax2.set_xlabel("run wall time [s]")
    ax2.set_ylabel("RMS deviation from the measurements [% U0]")
    ax2.set_title("vs Tsuji & Morikawa (o gas, ■ particles)", fontsize=10)
    ax2.grid(alpha=0.3, which="both")
    if ax2.get_legend_handles_labels()[0]:
        ax2.legend(fontsize=8)
    fig.savefig(path, format="png")
    return path


# =====================================================================================
# 4. stiff and extreme cases
# =====================================================================================

def _reynolds_velocity(case: Case, diameter: float, re: float) -> float:
    return re * case.gas.viscosity / (case.gas.density * diameter)


def stability_cases(quick: bool, parcels: int | None = None) -> list[tuple[str, str, Case | CaseError]]:
    """(name, what changes, case or the CaseError the change raised) for every stiff/extreme case.

    Each derives from the base case (200 µm, eta = 2.2, Delta-gamma = 1.5 deg, U0 = 10 m/s,
    four-way); quick mode on the quick numerics with 200 parcels (the 1 µm tracers take ~10^5
    steps each), where "4x cells" doubles the radial and azimuthal cells of the quick grid and
    "1e6 parcels" is 8x the quick parcels.
    """
    base = _base_case(False)
    if quick:
        base = _quick(base, **STABILITY_QUICK)
    base = _with_parcels(base, parcels)
    n = base.numerics
    d0, length, sections = base.pipe.diameter, base.pipe.length, base.pipe.sections
    d_big = 0.3
    u_big = _reynolds_velocity(base, d_big, 1.0e6)
    scale = d_big / d0
    many = 8 * n.parcels if quick else 1_000_000
    # 1 µm tracers at eta = 2.2: ~5e15 particles per m3, so the stochastic collision frequency
    # (~5e3 /s) limits the step to 0.1/f_coll: ~7.5e4 steps per parcel, 40x the base case's.
    # A fifteenth of the parcels keeps the pass at about the base case's cost; the noise this
    # leaves is in the batch standard errors and the coupling residual's noise units.
    tracer_parcels = n.parcels if quick else max(1000, n.parcels_start // 15)
    specs = [
        ("tracers_1um", f"D_p = 1 µm (tracers), {tracer_parcels} parcels per pass (each takes ~7.5·10^4 "
                        "collision-limited steps)",
         {"particles": {"diameter": 1e-6},
          "numerics": {"parcels": tracer_parcels, "parcels_start": min(n.parcels_start, tracer_parcels)}}),
        ("pellets_3.4mm", "D_p = 3.4 mm (the experiment's pellets)", {"particles": {"diameter": 3.4e-3}}),
        ("loading_eta10", "eta = 10", {"particles": {"mass_loading": 10.0}}),
        ("loading_eta30", "eta = 30", {"particles": {"mass_loading": 30.0}}),
        ("roughness_20deg", "Delta-gamma = 20 deg", {"walls": {"roughness_angle_std_deg": 20.0}}),
        ("U0_5", "U0 = 5 m/s (near saltation)", {"gas": {"bulk_velocity": 5.0}}),
        ("U0_30", "U0 = 30 m/s", {"gas": {"bulk_velocity": 30.0}}),
        ("pipe_0.3m_Re1e6", f"D = 0.3 m, U0 = {u_big:.3g} m/s (Re = 1e6), L/D and x/D as the base case",
         {"pipe": {"diameter": d_big, "length": length * scale, "sections": [s * scale for s in sections]},
          "gas": {"bulk_velocity": u_big}}),
        ("cells_4x", f"4x cells: {n.radial_cells * 2} radial x {n.azimuthal_cells * 2} azimuthal "
                     f"(x {n.axial_cells} axial)",
         {"numerics": {"radial_cells": 2 * n.radial_cells, "azimuthal_cells": 2 * n.azimuthal_cells}}),
        ("parcels_1e6", f"{many} parcels per pass" + (" (quick: 8x the quick parcels)" if quick else ""),
         {"numerics": {"parcels": many}}),
    ]
    out = []
    for name, what, changes in specs:
        try:
            case = base.replace(name=f"stability_{name}", description=f"{base.description}; {what}",
                                **changes)
        except CaseError as exc:
            case = exc
        out.append((name, what, case))
    return out


def _field_health(ds) -> dict[str, Any]:
    bad = [v for v in ("gas_ux", "gas_uy", "gas_uz", "gas_k", "gas_epsilon", "gas_p", "pressure_gradient")
           if v in ds and not np.all(np.isfinite(ds[v].values))]
    kmin = float(np.nanmin(ds["gas_k"].values)) if "gas_k" in ds else math.nan
    emin = float(np.nanmin(ds["gas_epsilon"].values)) if "gas_epsilon" in ds else math.nan
    stuck = int(np.sum(ds["parcels_stuck"].values)) if "parcels_stuck" in ds else 0
    lost = int(np.sum(ds["parcels_lost"].values)) if "parcels_lost" in ds else 0
    relax = np.asarray(ds["relaxation"].values, dtype=float) if "relaxation" in ds else np.array([math.nan])
    steps = _attr_float(ds, "particle_steps_final", math.nan)
    sliding = _attr_float(ds, "wall_sliding_steps_final", math.nan)
    return {"nonfinite": ", ".join(bad) if bad else "none", "k_min": kmin, "eps_min": emin,
            "stuck_total": stuck, "stuck_final": int(_attr_float(ds, "parcels_stuck_final", 0)),
            "lost": lost, "relax_min": float(np.nanmin(relax)) if np.any(np.isfinite(relax)) else math.nan,
            "sliding_pct": 100.0 * sliding / steps if steps and math.isfinite(steps) else math.nan,
            "floored_max": int(np.max(ds["gas_floored_cells"].values)) if "gas_floored_cells" in ds else None,
            "floored_last": int(ds["gas_floored_cells"].values[-1]) if "gas_floored_cells" in ds else None,
            **_floored_where(ds),
            "residual_history": [float(v) for v in np.asarray(ds["residual"].values, dtype=float)],
            "relaxation_history": [float(v) for v in relax]}


def _floored_where(ds) -> dict[str, Any]:
    """Where the final gas field sits at the k/ε floor (rans.solver.K_FLOOR): the axial range
    of those cells and how many of them are in the wall ring (empty when none or unknown)."""
    from rans.solver import turbulence_floors
    try:
        k = np.asarray(ds["gas_k"].values, dtype=float)
        eps = np.asarray(ds["gas_epsilon"].values, dtype=float)
        x = np.asarray(ds["x"].values, dtype=float)
        k_floor, eps_floor = turbulence_floors(float(_attr(ds, "gas.bulk_velocity")),
                                               float(_attr(ds, "pipe.diameter")))
    except (KeyError, ValueError, TypeError):
        return {}
    at = (k <= k_floor * (1.0 + 1e-6)) | (eps <= eps_floor * (1.0 + 1e-6))  # (x, r, theta)
    if not at.any():
        return {}
    xs = x[at.any(axis=(1, 2))]
    return {"floored_x": [float(xs.min()), float(xs.max())], "floored_wall": int(at[:, -1, :].sum())}


def _wall_cell_thickness(case: Case) -> float:
    from eulag.coupling import build_mesh

    mesh = build_mesh(case)
    re = np.asarray(mesh.r_edges, dtype=float)
    return float(re[-1] - re[-2])


def study_stability(args, outdir: Path, t_start: float) -> int:
    specs = stability_cases(args.quick, getattr(args, "parcels", None))
    names = _select(getattr(args, "only", None), [s[0] for s in specs], "cases")
    specs = [s for s in specs if s[0] in names]
    records = []
    for i, (name, what, case) in enumerate(specs, 1):
        rec = run_case(args, name, case, outdir, f"[stability {i}/{len(specs)}] {name}",
                       lambda ds, rec, name=name: {**_field_health(ds),
                                                   **(_tracer_ratios(ds) if name == "tracers_1um" else {})})
        records.append(rec)
    rows = []
    for (name, what, case), rec in zip(specs, records):
        m = rec.metrics
        if rec.status == "converged":
            wrong = "—"
        elif rec.status == "rejected":
            wrong = f"case rejected: {rec.message}"
        else:
            wrong = rec.message
        if rec.ok and m.get("nonfinite") not in (None, "none"):
            wrong = f"non-finite {m['nonfinite']}; " + wrong
        rows.append({"case": name, "change": what,
                     "converged": {"converged": "yes", "not converged": "no"}.get(rec.status, rec.status),
                     "passes": rec.passes if rec.status != "rejected" else None,
                     "time_s": rec.time, "final_residual": rec.residual, "relaxation": rec.relaxation,
                     "relax_min": m.get("relax_min"), "stuck_total": m.get("stuck_total"),
                     "stuck_final": m.get("stuck_final"), "lost": m.get("lost"),
                     "sliding_pct": m.get("sliding_pct"), "nonfinite": m.get("nonfinite"),
                     "k_min": m.get("k_min"), "eps_min": m.get("eps_min"),
                     "floored": _floored_cell(m),
                     "collision_momentum": m.get("collision_momentum"), "commit": m.get("commit"),
                     "first_wrong": wrong})
    columns = [Column("case", "case"), Column("change", "change from the base case"),
               Column("converged", "converged"), Column("passes", "passes", "{:d}"),
               Column("time_s", "run time [s]", "{:.1f}"), Column("final_residual", "final residual", "{:.3g}"),
               Column("relaxation", "relaxation (final)", "{:g}"), Column("relax_min", "relaxation (min)", "{:g}"),
               Column("stuck_total", "parcels stuck (all passes)", "{:d}"),
               Column("stuck_final", "stuck (final passes)", "{:d}"), Column("lost", "lost", "{:d}"),
               Column("sliding_pct", "sliding/rolling steps [%]", "{:.3g}"),
               Column("nonfinite", "non-finite gas fields"), Column("k_min", "min k [m²/s²]", "{:.3g}"),
               Column("eps_min", "min ε [m²/s³]", "{:.3g}"),
               Column("floored", "cells at the k/ε floor: last pass (max)"),
               Column("collision_momentum", "collision momentum / inflow", "{:+.2g}"),
               Column("commit", "commit"),
               Column("first_wrong", "first quantity to go wrong / why not converged")]
    base = _base_case(args.quick)
    try:
        wall = _wall_cell_thickness(base)
        wall_text = f"{wall * 1e3:.2f} mm"
    except Exception:  # noqa: BLE001
        wall, wall_text = math.nan, "n/a"
    r_p = 0.5 * 3.4e-3
    if math.isfinite(wall) and wall < r_p:
        where = (f"so the centre of a 3.4 mm pellet (radius {r_p * 1e3:.2f} mm) never enters the "
                 f"{wall_text} wall cell: its sources land in the rings further in")
    else:
        where = (f"so the centre of a 3.4 mm pellet (radius {r_p * 1e3:.2f} mm) reaches only the inner "
                 f"part of the {wall_text} wall cell")
    pellet = (
        f"The pellets (D_p = 3.4 mm) are larger than the wall cell of the base mesh (radial thickness "
        f"{wall_text} at U0 = {base.gas.bulk_velocity:g} m/s, from `numerics.first_cell_yplus` = "
        f"{base.numerics.first_cell_yplus:g}), but below the limit of the case validation "
        f"(`eulag.config`: D_p < pipe.diameter / 5 = {base.pipe.diameter * 200:.3g} mm), so they run as "
        "point particles. The PSI-cell sources of a parcel go into the cell that holds its centre along "
        "each trajectory segment (particles/tracking.py), split between the cells the segment crosses "
        "by time fraction; they are not spread over the volume the pellet covers. The wall contact is "
        f"at the centre distance R - D_p/2 from the axis, {where}, and the gas it sees is "
        "interpolated at its centre. What the point-particle model cannot capture at D_p/D = 0.11: "
        "the flow around the "
        "pellet and its wake (it spans the log layer, particle Reynolds numbers of order 10^2-10^3), "
        "the volume it displaces (volume fraction is not in the gas equations), finite-size lift and "
        "the shear across the pellet, and the rolling/sliding contact geometry of a particle that is "
        "not small against the wall curvature.")
    intro = [
        "Stiff and extreme variants of the base case (200 µm, eta = 2.2, Delta-gamma = 1.5 deg, U0 = "
        "10 m/s, four-way). Each must run to convergence or stop with a clear diagnosis: never NaN, "
        "never negative k or epsilon, never a lost parcel, never a silent hang; parcels stopped by the "
        "residence-time cap are counted.",
        "",
        "Columns: converged (yes / no = finished at max_passes / failed = the coupling loop stopped "
        "with a diagnosis / rejected = the case validation refused it); final coupling residual; the "
        "source under-relaxation the loop chose (final and smallest; the loop halves it, down to "
        "0.05, when a gas solve with the sources fails or the residual stagnates above the tolerance, "
        "and doubles it again, once, when the residual at a halved α is below the tolerance but the "
        "loop has not converged); "
        "parcels stopped by the residence-time cap "
        "(all passes, and in the averaged final passes); lost parcels (must be 0); the share of "
        "particle steps spent sliding or rolling on the wall (final passes; near saltation this is "
        "the bottom layer); gas fields with a non-finite value; the smallest k and epsilon; the gas "
        "cells where k or epsilon was held at its floor (k = 1e-10 U0², rans.solver.K_FLOOR) in the last pass's gas solve and the "
        "most in any pass (counted by the solver, `gas_floored_cells`; — where the record predates the "
        "column), and where the final field has them: their axial range and how many lie in the wall "
        "ring (the wall function's cell); "
        + COLLISION_MOMENTUM_TEXT + "; the first "
        "quantity to go wrong (the CouplingError message), or why the run did not converge."]
    fig = _stability_figure(outdir / "stability_history.png", specs, records)  # None: no history
    write_report(outdir, "stability", args, title="Stiff and extreme cases", intro=intro, columns=columns,
                 rows=rows, figures=[fig] if fig is not None else [],
                 sections=[("The 3.4 mm pellets", pellet),
                           ("The 1 µm tracers", _tracer_sink_text(specs, records))], t_start=t_start,
                 settings=_settings_text([c for _, _, c in specs if isinstance(c, Case)], args.quick),
                 records=records)
    return _finish(args, outdir, records, allowed_failures=True)


def _tracer_sink_text(specs, records) -> str:
    """What the first-order Langevin model makes of tracers' S_k, with the run's own ratio."""
    from particles.kernel import C_T

    text = (
        "The seen fluid velocity is a first-order Langevin (Ornstein-Uhlenbeck) process, whose "
        "acceleration is white noise. A particle filters it with its response time tau_p, and the "
        "slip that is left dissipates, per unit particle mass, <u'_F (u_F - u_p)>/tau_p = "
        "2k/(T_L + tau_p) (the two-fluid result k - k_fp = k tau_p/(T_L + tau_p)). For tau_p -> 0 "
        f"this does not vanish: S_k -> -2 c_p k/T_L = -(3/C_T) c_p eps = -{3 / C_T:.1f} c_p eps "
        f"(T_L = C_T (2/3) k/eps, C_T = {C_T:g}), with c_p the particle mass concentration; "
        "tests/test_coupling.py checks the sampled S_k of 1 and 10 µm particles against it. At eta = "
        "2.2 that is some 20-27 times the gas's own dissipation rho eps, so the sinks all but remove "
        "the turbulence and, through the wall function, lower the wall shear: -dp/dx can fall below "
        "the single-phase value. Real 1 µm particles (tau_p = 3 µs, far below the Kolmogorov time "
        "(nu/eps)^1/2, 0.2 ms in the wall cells of the converged base case) follow the fluid down to the dissipative scales and add almost no "
        "dissipation. The tracer run shows what the point-particle model with this dispersion model "
        "gives, not what 1 µm particles do.")
    for (name, _, _), rec in zip(specs, records):
        ratio, gas_ratio = rec.metrics.get("tracer_sk_ratio"), rec.metrics.get("tracer_sk_gas_ratio")
        if name != "tracers_1um" or not rec.ok or ratio is None or gas_ratio is None:
            continue
        text += (f" In this run (core, r < R/2, median over the cells with particles; S_k as applied, "
                 f"i.e. relaxed, so it reaches the sampled value only as the loop converges): "
                 f"-S_k/(c_p eps) = {ratio:.3g} against {3 / C_T:.1f}, and -S_k/(rho eps) = {gas_ratio:.3g}.")
    return text


def _floored_cell(m: dict) -> str | None:
    if m.get("floored_max") is None:
        return None
    text = f"{m['floored_last']} (max {m['floored_max']})"
    if m.get("floored_x"):
        x0, x1 = m["floored_x"]
        text += f"; final field: x = {x0:.3g}–{x1:.3g} m, {m.get('floored_wall', 0)} in the wall ring"
    return text


def _tracer_ratios(ds) -> dict[str, float]:
    """Median -S_k/(c_p eps) and -S_k/(rho eps) in the core (r < R/2) cells with particles."""
    try:
        r = np.asarray(ds["r"].values)
        core = r < 0.5 * float(_attr(ds, "pipe.diameter")) / 2
        cp = ds["particle_concentration"].values[:, core, :]
        sk = ds["source_k"].values[:, core, :]
        eps = ds["gas_epsilon"].values[:, core, :]
        rho = float(_attr(ds, "gas.density"))
        ok = cp > 0
        return {"tracer_sk_ratio": float(np.median(-sk[ok] / (cp[ok] * eps[ok]))),
                "tracer_sk_gas_ratio": float(np.median(-sk[ok] / (rho * eps[ok])))}
    except Exception:  # noqa: BLE001 - the explanation stands without the run's numbers
        return {}


def _stability_figure(path: Path, specs, records) -> Path | None:
    """Coupling residual and chosen relaxation per pass of every stability run (None, and no
    file, when no run has a history: e.g. all reported from carried records)."""
    if not any(len(rec.metrics.get("residual_history", [])) for rec in records):
        path.unlink(missing_ok=True)
        return None
    fig = _figure()(11.5, 4.6)
    ax1, ax2 = fig.subplots(1, 2)
    for i, ((name, _, _), rec) in enumerate(zip(specs, records)):
        res = np.asarray(rec.metrics.get("residual_history", []), dtype=float)
        rel = np.asarray(rec.metrics.get("relaxation_history", []), dtype=float)
        if res.size == 0:
            continue
        style = "-" if rec.status == "converged" else ("--" if rec.status == "not converged" else ":")
        it = np.arange(1, res.size + 1)
        ax1.semilogy(it, np.where(res > 0, res, np.nan), style, marker="o", ms=3, color=f"C{i % 10}",
                     label=f"{name} ({rec.status})")
        ax2.plot(it[: rel.size], rel, style, marker="o", ms=3, color=f"C{i % 10}")
    ax1.set_xlabel("coupling pass")
    ax1.set_ylabel("coupling residual [noise units]")
    ax1.grid(alpha=0.3, which="both")
    if ax1.get_legend_handles_labels()[0]:
        ax1.legend(fontsize=7)
    ax1.set_title("residual (solid: converged, dashed: not, dotted: failed)", fontsize=9)
    from matplotlib.ticker import MaxNLocator

    for ax in (ax1, ax2):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax2.set_xlabel("coupling pass")
    ax2.set_ylabel("source under-relaxation used [1]")
    ax2.grid(alpha=0.3)
    fig.savefig(path, format="png")
    return path
