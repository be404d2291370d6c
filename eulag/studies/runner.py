"""Running the cases of a study: one case through :func:`eulag.runs.execute` (or, with
``--resume`` / ``--report``, reused from its dataset, its run record, its failed record or its
checkpoint), the run records (``<run>.record.json``) and failed records (``<run>.failed.json``),
the study's base case and quick numerics, the output folder and the exit status.

A record is trusted by its case (compared as :func:`eulag.config.comparable_attrs` compares
cases) and ``RECORD_VERSION``: a change to what a study extracts from a dataset must bump it.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

import eulag
from eulag.config import CASES_DIR, Case, CaseError
from eulag.output import is_converged

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2
BASE_CASE = CASES_DIR / "tsuji_morikawa_200um.toml"

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


def _with_parcels(case: Case, parcels: int | None) -> Case:
    """``case`` with ``parcels`` per final pass (``eulag.runs.with_parcels``)."""
    from eulag.runs import with_parcels

    try:
        return with_parcels(case, parcels)
    except CaseError as exc:
        raise _BadInput(str(exc)) from None


def _output_dir(args, made: list | None = None) -> Path:
    """The study's output folder, created if needed; the folders created are appended to
    ``made`` (outermost first), so that bad input found later leaves nothing behind."""
    out = Path(args.output_dir) if args.output_dir else Path("results") / args.study_name
    if out.exists() and not out.is_dir():
        raise _BadInput(f"-o {out}: exists and is not a directory; allowed: a directory")
    if getattr(args, "report", False) and not out.is_dir():
        raise _BadInput(f"-o {out}: no such directory; --report reads the runs of an existing output folder")
    if made is not None:
        made.extend(p for p in reversed([out, *out.parents]) if str(p) not in ("", ".") and not p.exists())
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _BadInput(f"-o {out}: cannot create the directory ({exc.strerror or exc})") from None
    if not os.access(out, os.W_OK):
        raise _BadInput(f"-o {out}: directory is not writable")
    return out


def _select(only: str | None, names: list[str], what: str) -> list[str]:
    """The names ``--only`` selects (None, the option not given: all; an empty list is bad input)."""
    if only is None:
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


def _canonical(case) -> str:
    """The case identity records store (:func:`eulag.runs.case_key`)."""
    from eulag.runs import case_key

    return case_key(case)


def resumable_checkpoint(ckpt: Path, case):
    """(meta, residual history) of the checkpoint ``ckpt`` when it is readable and resumable
    as ``case`` (:func:`eulag.runs.checkpoint_state`), else None."""
    from eulag.runs import checkpoint_state

    state = checkpoint_state(ckpt, case)
    return None if state is None or state[2] is not None else state[:2]


def checkpoint_of(ckpt: Path, case: Case) -> bool:
    """Whether the coupling checkpoint ``ckpt`` is readable and resumable as ``case``
    (``resumable_checkpoint``)."""
    return resumable_checkpoint(ckpt, case) is not None


def _same_case(attrs: dict, case) -> bool:
    from eulag.runs import same_case

    return same_case(attrs, case)


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

    if not isinstance(case, Case) or case.particles is None:
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
    failed = outdir / f"{name}.failed.json"
    if isinstance(case, CaseError):
        _log(args, f"  {label}: rejected by the case validation: {case}")
        return RunRecord(name, None, out, "rejected", str(case))

    ckpt = runs.checkpoint_path(out, case)
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
        finished = (opened is not None and ("coupling_passes" in opened.attrs or not isinstance(case, Case))
                    and _same_case(opened.attrs, case))
        if finished and not report:  # --report tabulates every dataset; a resume reuses what the run layer would
            finished = runs.takes_as_finished("converged" if is_converged(opened) else "unconverged", case)
        if finished:
            ds = opened
            reused = True
            _log(args, f"  {label}: {out} exists (same case), not run again")
        elif not report and (opened is None or not _same_case(opened.attrs, case)):
            # unreadable or of another case: this study's run replaces it (a resume never
            # takes it for this case, and it would make the run's layer refuse the output)
            _log(args, f"  {label}: {out} holds another case or cannot be read; it is replaced")
            out.unlink(missing_ok=True)
            record.unlink(missing_ok=True)
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
            quiet_model = not isinstance(case, Case) and getattr(args, "quiet", False)
            ds = runs.execute(case, out, resume=resume,
                              progress=None if quiet_model else _progress_printer(args, name, history),
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
        if isinstance(case, Case):  # the dataset holds everything; the checkpoint is no longer needed
            ckpt.unlink(missing_ok=True)  # (a dense-phase model keeps or removes its own)

    rec = _record_from_dataset(name, case, out, ds)
    rec.reused = reused
    if rec.metrics.get("commit") is None:  # a dataset that does not name its commit
        rec.metrics["commit"] = (_recorded_commit(record) if reused else None) or eulag.git_commit()
    if extract is not None:
        rec.metrics.update(extract(ds, rec))
    write_record(record, case, rec)
    if isinstance(case, Case):
        _log(args, f"  {label}: {rec.status} after {rec.passes} passes, {rec.time:.1f} s")
    elif getattr(case, "model", "") == "dem-darcy" and rec.status == "converged":  # runs to its end time
        _log(args, f"  {label}: finished, {rec.time:.1f} s")
    else:
        _log(args, f"  {label}: {rec.status}, {rec.time:.1f} s")
    return rec


RECORD_VERSION = 1


def _recorded_commit(record: Path):
    """The commit the run record at ``record`` names (None: no readable record)."""
    try:
        return json.loads(record.read_text()).get("metrics", {}).get("commit")
    except (OSError, ValueError, AttributeError):
        return None


def _unfinished_record(args, name: str, case: Case, out: Path, ckpt: Path, label: str) -> RunRecord:
    """--report: the row of a run with neither dataset, record nor failed record here —
    "unfinished" with the state of its checkpoint (passes done, the last residual and α, the
    time so far), or "not run"."""
    found = resumable_checkpoint(ckpt, case)
    if found is not None and not isinstance(case, Case):
        msg = f"a checkpoint {ckpt.name} is here; --resume continues it"
        _log(args, f"  {label}: unfinished: {msg}")
        return RunRecord(name, case, out, "unfinished", msg)
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


def _describe_numerics(case) -> str:
    if not isinstance(case, Case):  # a dense-phase model: its [numerics] table as given
        n = case.data.get("numerics", {})
        return f"{case.model}, " + (", ".join(f"{k} {v}" for k, v in sorted(n.items())) or "default numerics")
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
    return max(_attr_float(ds, "time_total", 0.0), _attr_float(ds, "wall_time_s", 0.0), parts)


def _record_from_dataset(name, case, out, ds) -> RunRecord:
    converged = is_converged(ds)
    res = np.asarray(ds["residual"].values, dtype=float) if "residual" in ds else np.array([math.nan])
    relax = np.asarray(ds["relaxation"].values, dtype=float) if "relaxation" in ds else np.array([math.nan])
    passes = int(ds.attrs.get("coupling_passes", ds.attrs.get("iterations", res.size)))
    msg = "" if converged else (ds.attrs.get("stop_reason") or _why_not_converged(ds, case))
    if ds.attrs.get("model") == "dem-darcy" and not converged:  # judged again by today's rules
        from eulag.slug import verdict

        msg = verdict(ds)[1]
    metrics = {"commit": ds.attrs.get("eulag_commit")}
    if isinstance(case, Case):
        metrics["collision_momentum"] = _collision_momentum(ds, case)
    return RunRecord(name, case, out, "converged" if converged else "not converged", msg, run_time(ds),
                     passes, float(res[-1]) if res.size else math.nan,
                     float(relax[-1]) if relax.size else math.nan, metrics=metrics)


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
