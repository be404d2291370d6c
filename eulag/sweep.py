"""``eulag sweep CASES...``: whole cases as tasks, a summary table, resumable.

    eulag sweep cases/a.toml cases/b.toml ... [-o DIR] [--dask-local N | --scheduler ADDRESS]
                [--parcels N] [--quiet]

The cases may be of any model (``model = "euler-lagrange"`` (the default), ``"dem-darcy"``,
``"two-fluid"``) and mixed in one sweep; ``--parcels`` applies to Euler–Lagrange cases only.

Every case writes its own dataset ``DIR/<case name>.nc`` and keeps its checkpoint beside it
(``DIR/<case name>.nc.checkpoint``), exactly as ``eulag run CASE -o DIR/<name>.nc --resume``.
Without Dask options the cases run one after another in this process (numba threads as
usual); with ``--dask-local N`` each case is a task on a local cluster of N worker processes,
with ``--scheduler ADDRESS`` a task on an existing cluster (the workers must have eulag
installed and see DIR at the same path: a shared file system).

Resuming: a case whose dataset in DIR is already a finished run of the same case (converged,
as ``eulag run --resume`` recognises it; or ended unconverged after all its passes) is not run
again; a case that was interrupted continues from its checkpoint.  A case task whose worker
dies is re-run by Dask, and then also continues from the checkpoint.

After every finished case and at the end (also after failures or an interruption)
``DIR/sweep_summary.csv`` and ``DIR/sweep_summary.md`` list per case: its model, status (ran |
finished earlier | failed | not run), converged, coupling passes (Euler–Lagrange), final
residual (the coupling loop's, or the two-fluid solve's outer-iteration change), −dp/dx (the
section mean over the pipe; a slug run: its mean Δp/L over the statistics window of
:func:`eulag.slug.statistics_window`), the pressure drop (dense-phase models), the single-phase
−dp/dx, the pressure-drop ratio and λ_Z (Euler–Lagrange gas–particle cases), wall time, output
and the error message.

Bad input (a missing or invalid case file, two cases with the same name, an output or a
checkpoint that holds a different case) is reported before any case starts.  Exit status: 0 all cases finished and
converged, 2 bad input, 1 otherwise (the summary says which).
"""

from __future__ import annotations

import csv
import math
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

from eulag.output import is_converged

__all__ = ["SweepInputError", "SweepCase", "plan_sweep", "run_case", "run_sweep", "write_summary",
           "summary_row", "COLUMNS", "SUMMARY_STEM"]

SUMMARY_STEM = "sweep_summary"
COLUMNS = ("case", "model", "status", "converged", "passes", "final_residual", "pressure_gradient",
           "pressure_drop", "pressure_gradient_single_phase", "solids_pressure_drop_ratio",
           "additional_pressure_loss_coefficient", "wall_time", "output", "error")
_HEADERS = {"case": "case", "model": "model", "status": "status", "converged": "converged", "passes": "passes",
            "final_residual": "final residual", "pressure_gradient": "-dp/dx [Pa/m]",
            "pressure_drop": "pressure drop [Pa]",
            "pressure_gradient_single_phase": "-dp/dx single-phase [Pa/m]",
            "solids_pressure_drop_ratio": "dp ratio", "additional_pressure_loss_coefficient": "lambda_Z",
            "wall_time": "wall time [s]", "output": "output", "error": "error"}

RAN, FINISHED_EARLIER, FAILED, NOT_RUN = "ran", "finished earlier", "failed", "not run"


class SweepInputError(ValueError):
    """Bad input of a sweep (one line); nothing has been run."""


@dataclass
class SweepCase:
    """One case of a sweep: its file, the validated case (an :class:`eulag.config.Case`, or a
    dense-phase model's :class:`eulag.runs.ModelCase`), its output, and whether it is done."""

    path: str
    case: object
    output: Path
    finished: bool = False

    @property
    def name(self):
        return self.case.name

    @property
    def model(self):
        return getattr(self.case, "model", "euler-lagrange")


# ---------------------------------------------------------------------------- planning
def plan_sweep(paths, output_dir=".", parcels=None):
    """Validate every case file and the output directory; list the cases with their state.

    Raises :class:`SweepInputError` (nothing run, nothing written except ``output_dir``).
    """
    import os

    from eulag.runs import RunError, checkpoint_path, finished_output, load_case, resumable_checkpoint

    if isinstance(paths, (str, os.PathLike)):  # one case file, not its characters
        paths = [paths]
    if not paths:
        raise SweepInputError("no case files given")
    outdir = Path(output_dir)
    if outdir.exists() and not outdir.is_dir():
        raise SweepInputError(f"-o {outdir}: exists and is not a directory; allowed: a directory")
    entries = []
    by_name = {}
    for p in paths:
        try:
            case = load_case(p, parcels=parcels)
        except RunError as exc:
            text = str(exc)
            raise SweepInputError(text if str(p) in text else f"{p}: {text}") from None
        if case.name in by_name:
            raise SweepInputError(f"{p}: case name {case.name!r} is also the name of {by_name[case.name]}; "
                                  "every case of a sweep needs its own name (its output is <name>.nc)")
        by_name[case.name] = p
        entries.append(SweepCase(path=str(p), case=case, output=(outdir / f"{case.name}.nc").resolve()))
    for e in entries:
        if e.output.exists() and e.output.is_dir():
            raise SweepInputError(f"{e.output}: is a directory; the output of case {e.name} must be a file")
        try:
            e.finished = finished_output(e.output, e.case)
        except RunError as exc:
            if resumable_checkpoint(e.output, e.case):  # continued whatever the output holds (as run --resume)
                continue
            msg = (str(exc).replace("--resume: ", "")
                   .replace("or run without --resume to overwrite", "or move it away or write the sweep elsewhere (-o)")
                   .replace("or a path that does not exist yet", "or move it away or write the sweep elsewhere (-o)"))
            raise SweepInputError(f"case {e.name} ({e.path}): {msg}") from None
        if not e.finished:
            problem = _checkpoint_problem(checkpoint_path(e.output, e.case), e.case)
            if problem:
                raise SweepInputError(f"case {e.name} ({e.path}): {problem}")
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepInputError(f"-o {outdir}: cannot create the directory ({exc})") from None
    return entries


def _checkpoint_problem(ckpt, case):
    """Why the checkpoint beside a case's output cannot be resumed by this case (None: it can,
    or there is none): :func:`eulag.runs.checkpoint_state`."""
    from eulag.runs import checkpoint_state

    state = checkpoint_state(ckpt, case)
    if state is None or state[2] is None:
        return None
    problem = state[2]
    if problem.startswith("checkpoint of a different case") and "(" not in problem:
        problem += " (another case file or --parcels)"
    prefix = "" if problem.startswith(str(ckpt)) else f"{ckpt}: "
    return f"{prefix}{problem}; remove it to start the case afresh"


# ---------------------------------------------------------------------------- one case
def _float(v):
    try:
        f = float(v)
    except (TypeError, ValueError):
        return math.nan
    return f


def summary_row(name, ds, output, status, wall_time, error="", model="euler-lagrange"):
    """The summary line (dict over :data:`COLUMNS`) of a case from its dataset (or None)."""
    row = {c: "" for c in COLUMNS}
    row.update(case=name, model=model, status=status, output=str(output), error=error)
    row["wall_time"] = wall_time
    if ds is None:
        return row
    import numpy as np

    row["model"] = model = str(ds.attrs.get("model", model))
    row["converged"] = is_converged(ds)
    if model == "dem-darcy":
        return _slug_row(row, ds, wall_time)
    if model == "euler-lagrange":
        row["passes"] = int(ds.sizes.get("iteration", 0)) if "parcels" in ds.variables else 0
    elif "pressure_drop" in ds.variables:
        row["pressure_drop"] = float(ds["pressure_drop"].values)
    if "residual" in ds.variables and ds["residual"].size:
        row["final_residual"] = float(np.asarray(ds["residual"].values).ravel()[-1])
    for key in ("pressure_gradient", "pressure_gradient_single_phase"):
        if key in ds.variables:
            row[key] = float(np.mean(ds[key].values))
    for key in ("solids_pressure_drop_ratio", "additional_pressure_loss_coefficient"):
        if key in ds.variables:
            row[key] = _float(ds[key].values)
        elif key in ds.attrs:
            row[key] = _float(ds.attrs[key])
    if wall_time == "" or wall_time is None:
        row["wall_time"] = _float(ds.attrs.get("time_total", math.nan))
    return row


def _slug_row(row, ds, wall_time):
    """A slug run's numbers: Δp and Δp/L over its statistics window (as the strauss study
    takes them)."""
    import json

    from eulag.slug import statistics_window, summarize

    case = json.loads(ds.attrs["case"])
    t_from, x_window = statistics_window(case, ds["time"].values)
    s = summarize(ds, x_window=x_window, t_min=t_from)
    row["pressure_drop"] = s["pressure_drop_Pa"]
    row["pressure_gradient"] = s["pressure_drop_per_length_Pa_m"]
    if wall_time == "" or wall_time is None:
        row["wall_time"] = _float(ds.attrs.get("wall_time_s", math.nan))
    return row


def read_row(entry, status):
    import xarray as xr

    with xr.open_dataset(entry.output) as ds:
        return summary_row(entry.name, ds.load(), entry.output, status, None, model=entry.model)


def run_case(case, output, numba_threads=None):
    """Run one case to the end (resuming from its checkpoint) and write ``output``.

    The task of a sweep (through the run layer, :func:`eulag.runs.execute`); returns its
    summary row.  A failure of the case is returned as a row with status "failed" and a
    one-line error (it does not fail the task, so Dask does not retry a case that fails
    deterministically).
    """
    t0 = time.perf_counter()
    output = Path(output)
    try:
        from eulag import runs
        from eulag.distributed import set_numba_threads

        set_numba_threads(numba_threads)
        ds = runs.execute(case, output, resume=True).dataset
    except Exception as exc:  # noqa: BLE001 - reported in the summary, one line
        text = " ".join(f"{type(exc).__name__}: {exc}".split())
        return summary_row(case.name, None, output, FAILED, time.perf_counter() - t0, error=text,
                           model=getattr(case, "model", "euler-lagrange"))
    # the run's own wall time, as its dataset stores it (every session of a resumed run; the same
    # figure a later sweep reads from the finished output)
    return summary_row(case.name, ds, output, RAN, None)


# ---------------------------------------------------------------------------- the sweep
def run_sweep(entries, client=None, *, numba_threads=None, progress=None, summary_dir=None):
    """Run the unfinished cases of ``entries`` (from :func:`plan_sweep`); rows in input order.

    client : a dask.distributed.Client (each case one task) or None (one after another here).
    numba_threads : numba threads per case (None: numba's default; on Dask workers with one
        thread each, 1).  progress : callable(str) for one line per case, or None.
    summary_dir : if given, the summary files there are rewritten after every case, so a
    long sweep always has an up-to-date table (cases still to come say "not run").
    On an interruption or a lost scheduler the rows of the cases not done say "not run".
    """
    say = progress or (lambda line: None)
    rows = {}
    todo = []
    for e in entries:
        if e.finished:
            rows[e.name] = read_row(e, FINISHED_EARLIER)
            say(f"{e.name}: finished earlier ({e.output}); not run again")
        else:
            todo.append(e)
    done = 0

    def current():
        return [rows.get(e.name) or summary_row(e.name, None, e.output, NOT_RUN, "", model=e.model)
                for e in entries]

    def report(row):
        nonlocal done
        done += 1
        rows[row["case"]] = row
        if summary_dir is not None:
            write_summary(current(), summary_dir)
        if row["status"] == FAILED:
            what = f"FAILED: {row['error']}"
        else:
            conv = "converged" if row["converged"] else "NOT converged"
            passes = f"{row['passes']} passes, " if row["model"] == "euler-lagrange" else ""
            what = f"{conv}, {passes}{row['wall_time']:.1f} s -> {row['output']}"
        say(f"[{done}/{len(todo)}] {row['case']}: {what}")

    try:
        if client is None:
            for e in todo:
                report(run_case(e.case, e.output, numba_threads))
        else:
            _run_on_dask(client, todo, numba_threads, report)
    finally:
        for e in entries:
            if e.name not in rows:
                rows[e.name] = summary_row(e.name, None, e.output, NOT_RUN, "", model=e.model,
                                           error="interrupted before it finished; run the sweep again "
                                                 "to resume")
    return [rows[e.name] for e in entries]


def _run_on_dask(client, todo, numba_threads, report):
    from dask.distributed import as_completed

    from eulag.distributed import DaskConnectionError, _connection_errors, _oneline

    tag = uuid.uuid4().hex[:8]
    futures = {client.submit(run_case, e.case, str(e.output), numba_threads, pure=False,
                             key=f"eulag-case-{e.name}-{tag}"): e for e in todo}
    try:
        for fut in as_completed(futures):
            e = futures[fut]
            try:
                row = fut.result()
            except _connection_errors() as exc:
                raise DaskConnectionError(f"lost the Dask scheduler or the connection to it "
                                          f"({_oneline(exc)}); finished cases are kept, run the sweep "
                                          "again to resume") from None
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: the case failed
                row = summary_row(e.name, None, e.output, FAILED, "", error=_oneline(exc), model=e.model)
            report(row)
    finally:
        for f in futures:
            f.release()


# ---------------------------------------------------------------------------- summary
_FLOAT_COLUMNS = ("final_residual", "pressure_gradient", "pressure_drop", "pressure_gradient_single_phase",
                  "solids_pressure_drop_ratio", "additional_pressure_loss_coefficient", "wall_time")


def write_summary(rows, output_dir):
    """Write ``sweep_summary.csv`` and ``sweep_summary.md`` in ``output_dir`` (the studies' table
    writers, :mod:`eulag.studies.report`); returns both paths."""
    from eulag.output import atomic_write
    from eulag.studies.report import Column, markdown_table, write_csv

    outdir = Path(output_dir)
    columns = [Column(c, _HEADERS[c], "{:.4g}" if c in _FLOAT_COLUMNS else "{}") for c in COLUMNS]

    def flagged(r, yes, no):
        c = r["converged"]
        return {**r, "converged": yes if c is True else no if c is False else c}

    csv_path = write_csv(outdir / f"{SUMMARY_STEM}.csv", columns, [flagged(r, "true", "false") for r in rows])
    n_ok = sum(1 for r in rows if r["status"] in (RAN, FINISHED_EARLIER) and r["converged"] is True)
    text = (f"# eulag sweep: {len(rows)} case{'' if len(rows) == 1 else 's'}, {n_ok} finished and converged\n\n"
            + markdown_table(columns, [flagged(r, "yes", "no") for r in rows]) + "\n")
    md_path = atomic_write(outdir / f"{SUMMARY_STEM}.md", lambda tmp: Path(tmp).write_text(text))
    return csv_path, md_path


def read_summary(path):
    """Rows of a ``sweep_summary.csv`` (dicts of str)."""
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))
