"""The ``eulag`` command line.

    eulag run CASE.toml|NAME [-o out.nc] [--parcels N] [--resume] [--quiet] [--no-plots]
                             [--dask-local N | --scheduler ADDRESS]
    eulag check CASE.toml|NAME
    eulag cases
    eulag plot out.nc [--x 3.56] [-o figs/]
    eulag export out.nc out.vts
    eulag study NAME [CASE.toml] [--quick]
    eulag sweep CASES... [-o DIR] [--dask-local N | --scheduler ADDRESS] [--parcels N] [--quiet]

The Dask options (docs/scale_out.md) need the ``dask`` extra (``pip install '.[dask]'``).

Exit status: 0 done, 2 bad input (case file, arguments), 1 anything else (a run that stopped
unconverged: the failing criterion with its value and threshold); every failure prints one
line ``eulag: error: <what>`` on stderr and leaves no output file behind (an unconverged run
writes its dataset with converged = false).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import eulag
from eulag.config import CASES_DIR, Case
from eulag.arguments import short_reason

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2


class _Fail(Exception):
    """A failure reported as one line with an exit status."""

    def __init__(self, message: str, status: int = EXIT_FAILURE):
        super().__init__(" ".join(str(message).split()))
        self.status = status


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2)."""

    def error(self, message):
        raise _Fail(f"{message} (see '{self.prog} --help')", EXIT_BAD_INPUT)


def _build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="eulag", description="Steady Euler-Lagrange RANS for gas-particle flow in "
                                           "horizontal pipes.")
    ap.add_argument("--version", action="version", version=f"eulag {eulag.__version__}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    run = sub.add_parser("run", help="solve a case and write the NetCDF dataset")
    run.add_argument("case", metavar="CASE.toml|NAME", help="case file, or the name of a packaged case "
                                                         "(eulag cases)")
    run.add_argument("-o", "--output", metavar="OUT.nc",
                     help="output dataset (default: <case name>.nc in the current directory)")
    run.add_argument("--parcels", type=_positive_int, metavar="N",
                     help="parcels per Lagrangian pass in the final passes (overrides numerics.parcels; "
                          "Euler-Lagrange cases only)")
    run.add_argument("--resume", action="store_true",
                     help="continue from the checkpoint beside the output; succeed at once if the "
                          "output is already a finished run of the same case")
    run.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    run.add_argument("--no-plots", action="store_true",
                     help="do not write the figures (eulag plot) beside the dataset (gas-particle and "
                          "dense-phase cases)")
    _add_dask_arguments(run, "the Lagrangian passes' super-batches")
    run.set_defaults(func=cmd_run)

    check = sub.add_parser("check", help="the resolved case with every default, derived numbers and the "
                                         "saltation check; runs nothing")
    check.add_argument("case", metavar="CASE.toml|NAME", help="case file or packaged case name")
    check.set_defaults(func=cmd_check)

    cases = sub.add_parser("cases", help="list the packaged cases (run them by name)")
    cases.set_defaults(func=cmd_cases)

    export = sub.add_parser("export", help="write a dataset's 3-D pipe as a VTK file for ParaView")
    export.add_argument("dataset", metavar="OUT.nc", help="dataset written by 'eulag run'")
    export.add_argument("target", metavar="OUT.vts", help="VTK file to write: .vts (structured grid; needs "
                        "the extra eulag[vtk]) or .vtu (unstructured grid)")
    export.set_defaults(func=cmd_export)

    plot = sub.add_parser("plot", help="figures (PNG) from a dataset: section, profiles, convergence; slug runs: "
                                       "space-time, history, averaged slug profiles")
    plot.add_argument("dataset", metavar="OUT.nc", help="dataset written by 'eulag run'")
    plot.add_argument("--x", type=float, metavar="X",
                      help="axial station [m] (default: the first pipe.sections entry; a marched two-fluid "
                           "pipe: its end; not for slug datasets)")
    plot.add_argument("-o", "--output", metavar="DIR",
                      help="figure directory (default: <dataset stem>_figures/ beside the dataset)")
    plot.set_defaults(func=cmd_plot)

    study = sub.add_parser("study", help="the validation and verification studies (eulag.studies)")
    import importlib.util

    if importlib.util.find_spec("eulag.studies") is None:  # not part of this build
        study.add_argument("name")
        study.add_argument("case", nargs="?")
        study.add_argument("--quick", action="store_true")
        study.set_defaults(func=_not_yet("eulag study"))
    else:
        from . import studies

        studies.add_arguments(study)  # defines its own sub-commands and sets func(args) -> exit code

    sweep = sub.add_parser("sweep", help="run several cases, each writing <name>.nc, with a summary table; "
                                         "resumable")
    sweep.add_argument("cases", nargs="+", metavar="CASE.toml|NAME",
                       help="case files or packaged case names (distinct case names)")
    sweep.add_argument("-o", "--output-dir", metavar="DIR", default=".",
                       help="directory of the datasets, checkpoints and sweep_summary.csv/.md "
                            "(default: the current directory; created if missing)")
    sweep.add_argument("--parcels", type=_positive_int, metavar="N",
                       help="parcels per Lagrangian pass in the final passes, for every case "
                            "(Euler-Lagrange cases only)")
    sweep.add_argument("--quiet", action="store_true", help="no progress lines")
    _add_dask_arguments(sweep, "whole cases")
    sweep.set_defaults(func=cmd_sweep)
    return ap


def _add_dask_arguments(parser, what):
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--dask-local", type=_positive_int, metavar="N",
                       help=f"run {what} as tasks on a local Dask cluster of N worker processes "
                            "(one thread each); needs pip install '.[dask]'")
    group.add_argument("--scheduler", metavar="ADDRESS",
                       help=f"run {what} as tasks on the Dask cluster of the scheduler at ADDRESS "
                            "(e.g. tcp://10.0.0.5:8786); needs pip install '.[dask]'")


def _positive_int(text: str) -> int:
    from eulag.arguments import positive_int

    return positive_int(text)


def _not_yet(what: str):
    def run(args) -> int:
        raise _Fail(f"{what} is not available in eulag {eulag.__version__} yet")
    return run


# ---------------------------------------------------------------------------
# eulag run
# ---------------------------------------------------------------------------

def _load_case(args):
    from eulag import runs

    try:
        return runs.load_case(args.case, parcels=getattr(args, "parcels", None))
    except runs.RunError as exc:
        raise _Fail(str(exc), exc.status) from None


def _progress_bar(case, total: int):
    """A tqdm bar on a terminal; line mode (one line per pass) when stderr is not a terminal."""
    if sys.stderr.isatty():
        from tqdm import tqdm

        # no ETA: the loop stops when converged, usually well before max_passes
        return tqdm(total=total, desc=case.name, unit="pass", file=sys.stderr, dynamic_ncols=True,
                    bar_format="{desc}: pass {n} of at most {total} [{elapsed}] {postfix}")
    return None


def cmd_run(args) -> int:
    """Run a case through the run layer (eulag.runs) and print its summary and verdict.

    Exit status 0: converged (or a converged finished run reused with --resume); 1: failed, or
    stopped unconverged, also when --resume finds such a finished run (the failing criterion with
    its value and threshold on stderr); 2: bad input."""
    from eulag import runs

    case = _load_case(args)
    try:
        out = runs.output_path(args.output, case.name)
    except runs.RunError as exc:
        raise _Fail(str(exc), exc.status) from None
    _check_dask(args)
    coupled = isinstance(case, Case) and case.particles is not None
    dask = getattr(args, "dask_local", None) is not None or getattr(args, "scheduler", None) is not None
    if not coupled and dask:
        what = "a single-phase case" if isinstance(case, Case) else f"a model = \"{case.model}\" case"
        raise _Fail(f"--dask-local/--scheduler: {what} runs in this process (Dask spreads the particle passes "
                    "of a coupled Euler-Lagrange run); allowed: leave them out, or `eulag sweep` to spread "
                    "several cases", EXIT_BAD_INPUT)
    client, tracker = _dask_tracker(args) if coupled else (None, None)
    bar = None if args.quiet or not coupled else _progress_bar(case, case.numerics.max_passes)

    def progress(state):
        loop_line = (f"residual {state.residual:.3g} (tolerance {case.numerics.coupling_tolerance:g}), "
                     f"-dp/dx {state.pressure_gradient:.4g} Pa/m, {state.parcels} parcels, {state.phase}")
        if bar is not None:
            bar.update(state.index - bar.n)
            bar.set_postfix_str(loop_line)
        elif not args.quiet:
            print(f"{case.name}: pass {state.index}: {loop_line}", file=sys.stderr, flush=True)

    def notify(text):
        if args.quiet:
            return
        if bar is not None:
            bar.write(f"{case.name}: {text}", file=sys.stderr)
        else:
            print(f"{case.name}: {text}", file=sys.stderr, flush=True)

    if not args.quiet:
        what = (f"{case.physics.coupling}, {case.numerics.parcels} parcels per final pass, at most "
                f"{case.numerics.max_passes} passes" if coupled else
                "single-phase gas" if isinstance(case, Case) else f"model {case.model}")
        print(f"eulag {eulag.__version__}: case {case.name} ({what}) -> {out}"
              + ("; a first run compiles the particle kernels (about a minute)" if coupled else ""),
              flush=True)
    try:
        result = runs.execute(case, out, resume=args.resume, progress=None if args.quiet else progress,
                              notify=notify, tracker=tracker,
                              plots=not args.no_plots,
                              gas_progress=not args.quiet and sys.stderr.isatty())
    except runs.RunError as exc:
        raise _Fail(str(exc), exc.status) from None
    finally:
        if bar is not None:
            bar.close()
        _close_dask(client)
    if result.figure_error:  # also with --quiet: the user asked for figures and has none
        print(f"eulag: warning: {result.figure_error}", file=sys.stderr)
    if result.reused:
        if not args.quiet:
            print(f"{out}: already a finished run of case {case.name}; nothing to do")
        if not result.converged:  # a finished run that ended unconverged keeps its verdict
            raise _Fail(f"{result.stop_reason}; {out} holds this case's finished run with converged = false")
        return EXIT_OK
    if not args.quiet:
        if result.loop is not None:
            print(_coupled_summary(case, result.loop, result.dataset, out))
        elif result.field is not None:
            print(_summary(case, result.mesh, result.field, out, result.timings, result.timings.get("write", 0.0),
                           result.dataset))
        elif result.converged:
            print(f"eulag {eulag.__version__}: case {case.name} ({case.model}): {result.stop_reason}; written {out}")
        else:  # the reason follows on stderr (the error line below)
            print(f"eulag {eulag.__version__}: case {case.name} ({case.model}): written {out}")
        if result.figures:
            print(f"  figures      {Path(result.figures[0]).parent}/ ({len(result.figures)} PNG)")
    if not result.converged:
        raise _Fail(f"{result.stop_reason}; {out} was written with converged = false")
    return EXIT_OK


def _check_dask(args) -> None:
    """Bad input (exit 2) before any work: a Dask option without dask installed."""
    if getattr(args, "dask_local", None) is None and getattr(args, "scheduler", None) is None:
        return
    from eulag.distributed import DaskUnavailable, require_dask

    try:
        require_dask()
    except DaskUnavailable as exc:
        raise _Fail(str(exc), EXIT_BAD_INPUT) from None


def _dask_client(args):
    """A Dask client for --dask-local / --scheduler (None without them)."""
    if args.dask_local is None and args.scheduler is None:
        return None
    import logging

    from eulag.distributed import DaskConnectionError, make_client

    if not os.environ.get("EULAG_DEBUG"):
        # the distributed loggers print tracebacks on a lost connection; the error is reported
        # in one line by us
        for name in ["distributed", *logging.root.manager.loggerDict]:
            if name == "distributed" or name.startswith("distributed."):
                logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    try:
        return make_client(scheduler=args.scheduler, local_workers=args.dask_local)
    except DaskConnectionError as exc:
        raise _Fail(str(exc)) from None
    except ValueError as exc:
        raise _Fail(str(exc), EXIT_BAD_INPUT) from None


def _dask_tracker(args):
    """(client, tracker) for ``eulag run`` (None, None: local numba threads)."""
    client = _dask_client(args)
    if client is None:
        return None, None
    from eulag.distributed import DaskTracker, describe

    if not args.quiet:
        print(describe(client), file=sys.stderr)
    return client, DaskTracker(client)


def _close_dask(client) -> None:
    if client is None:
        return
    import contextlib

    cluster = getattr(client, "cluster", None)  # a LocalCluster of --dask-local; None for --scheduler
    lost = getattr(client, "status", "") not in ("running", "connecting", "newly-created")
    with contextlib.suppress(Exception):
        client.close(timeout=2 if lost else 10)
    if cluster is not None:
        with contextlib.suppress(Exception):
            cluster.close(timeout=10)


def _coupled_summary(case, loop, ds, out) -> str:
    import numpy as np

    t = loop.timings
    h = loop.history
    x = case.pipe.sections[0]
    try:
        from eulag import analysis

        strength = f"{analysis.secondary_flow_strength(ds, x):.3g} % of U0 at x = {x:g} m"
    except Exception:  # noqa: BLE001 - the summary must not fail the run
        strength = "n/a"
    lines = [
        f"eulag {eulag.__version__}: case {case.name} ({case.physics.coupling}, {case.pipe.mode}), "
        f"Re = {case.reynolds_number:.4g}",
        f"  passes       {len(h.residual)} ({'converged' if loop.converged else 'NOT converged'}), "
        f"residual of the last pass {h.residual[-1]:.3g}, relaxation {h.relaxation[-1]:g}",
        f"  verdict      {loop.stop_reason}",
        *_criteria_lines(loop),
        f"  -dp/dx       {float(np.mean(ds.pressure_gradient)):.4g} Pa/m (single-phase "
        f"{float(np.mean(ds.pressure_gradient_single_phase)):.4g}); dp ratio "
        f"{float(ds.solids_pressure_drop_ratio):.4g}, lambda_Z {float(ds.additional_pressure_loss_coefficient):.4g}",
        *_replica_pressure_gradient_line(ds),
        f"  secondary    {strength}",
        f"  parcels      {int(h.parcels[-1])} per final pass; stuck "
        f"{int(ds.attrs.get('parcels_stuck_final', 0))} in the final passes ({int(sum(h.stuck))} in all passes), "
        f"lost {int(sum(h.lost))}",
        *_collision_momentum_line(case, h),
        *_collision_force_line(case, ds),
        *_conveying_lines(case, ds),
        f"  wall time    gas {t.get('gas_solve', 0):.1f} s, Lagrangian {t.get('lagrangian', 0):.1f} s"
        + (f" ({t.get('lagrangian_after_gas', 0):.1f} s of it after the gas solves)"
           if t.get('lagrangian_after_gas', 0) < 0.99 * t.get('lagrangian', 0) else "")
        + f", checkpoints {t.get('checkpoint', 0):.1f} s, total {t.get('total', 0):.1f} s",
        f"  written      {out}",
    ]
    return "\n".join(lines)


def _replica_pressure_gradient_line(ds) -> list[str]:
    """-dp/dx (mean over x) solved on each final pass's sources alone, in their order: the
    spread behind the averaged value, and a drift the final passes still carried."""
    if "replica_pressure_gradient" not in ds:
        return []
    v = ds["replica_pressure_gradient"].values.mean(axis=1)
    return [f"               each final pass alone: {', '.join(f'{x:.4g}' for x in v)} Pa/m"]


def _conveying_lines(case, ds) -> list[str]:
    """The conveying engineer's numbers: total pressure drop [Pa] and the saltation check
    (eulag.check, fluids.saltation)."""
    from eulag import check

    lines = [check.total_pressure_drop_line(ds), check.saltation_line(case)]
    return [ln for text in lines if text for ln in text.splitlines()]


def _criteria_lines(loop) -> list[str]:
    """Each convergence criterion as the loop judged it last: value, threshold, met or not."""
    return [f"    {'ok ' if c.met else 'NO '} {c.line()}" for c in loop.criteria]


def _collision_momentum_line(case, h) -> list[str]:
    """The net momentum the stochastic collisions gave the particles (real pairs give none)."""
    from eulag.coupling import COLLISION_MOMENTUM_TOL, recent_collision_momentum

    cm = recent_collision_momentum(h.collision_momentum)
    if not case.physics.inter_particle_collisions or not math.isfinite(cm):
        return []
    flag = (f"; WARNING: more than {100 * COLLISION_MOMENTUM_TOL:g} %" if abs(cm) >= COLLISION_MOMENTUM_TOL
            else "")
    return [f"  collisions   net momentum {100 * cm:+.2g} % of the particle inflow (final passes; real "
            f"collision pairs give none{flag})"]


def _collision_force_line(case, ds) -> list[str]:
    """The pipe integral of the collisions' net force on the particles, x, y, z, with its
    standard error (zero in the mean for momentum-conserving collisions)."""
    if "particle_collision_force_total_x" not in ds:
        return []
    tot = [float(ds[f"particle_collision_force_total_{c}"]) for c in "xyz"]
    se = [float(ds[f"particle_collision_force_total_{c}_stderr"]) for c in "xyz"]
    parts = ", ".join(f"{t:+.3g} ± {e:.2g}" for t, e in zip(tot, se))
    return [f"  collisions   net force on the particles (x, y, z) = ({parts}) N "
            f"(physics.partner_momentum = {case.physics.partner_momentum})"]


def _final(field) -> float:
    res = list(field.residuals)
    return float(res[-1]) if res else math.nan


def _summary(case, mesh, field, out, timings, t_write, ds=None) -> str:
    """A short human-readable summary of a single-phase run."""
    import numpy as np
    from fluids.friction import Colebrook

    from eulag import check

    nx, nr, nt = mesh.shape
    re_b = case.reynolds_number
    f_ref = Colebrook(re_b, 0.0)
    i = nx - 1  # outlet station (the only one in periodic mode)
    f_d = float(np.asarray(field.friction_factor).reshape(nx)[i])
    dpdx = float(np.asarray(field.pressure_gradient).reshape(nx)[i])
    yp = np.asarray(field.wall_yplus).reshape(nx, nt)[i]
    where = "fully developed" if mesh.mode == "periodic" else f"at x = {float(mesh.x[i]):.4g} m"
    lines = [
        f"eulag {eulag.__version__}: case {case.name} (single-phase, {mesh.mode}), Re = {re_b:.4g}",
        f"  cells        {nx} x {nr} x {nt} = {nx * nr * nt}",
        f"  gas solver   {'converged' if field.converged else 'NOT converged'} in "
        f"{field.iterations} iterations, final residual {_final(field):.2e}",
        f"  wall y+      {yp.mean():.1f} (min {yp.min():.1f}, max {yp.max():.1f}) {where}",
        f"  -dp/dx       {dpdx:.4g} Pa/m {where}",
        f"  friction f_D {f_d:.5f} vs Colebrook (smooth) {f_ref:.5f}: {100 * (f_d / f_ref - 1):+.1f} %",
        *[ln for ln in [check.total_pressure_drop_line(ds)] if ln],
        f"  wall time    mesh {timings['mesh']:.2f} s, gas solve {timings['gas_solve']:.2f} s, "
        f"write {t_write:.2f} s",
        f"  written      {out}",
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# eulag check, cases, export
# ---------------------------------------------------------------------------

def cmd_check(args) -> int:
    """The resolved case and its derived numbers (eulag.check); runs nothing."""
    from eulag import check

    args.parcels = None
    case = _load_case(args)
    if not isinstance(case, Case):  # a dense-phase model's own report (validated as it loaded)
        from eulag import runs

        print(runs.model_check_report(case))
        return EXIT_OK
    print(check.check_report(case))
    return EXIT_OK


def cmd_cases(args) -> int:
    """The packaged cases by name, with their description."""
    from eulag import runs

    rows = []
    for name, path in runs.packaged_cases().items():
        try:
            case = runs.load_case(path)
            text = getattr(case, "description", None) or getattr(case, "data", {}).get("description", "")
        except runs.RunError as exc:
            text = f"(invalid: {exc})"
        rows.append((name, str(path.relative_to(CASES_DIR)), " ".join(str(text).split())))
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    for name, rel, text in rows:
        print(f"{name:{w0}s}  {rel:{w1}s}  {text}")
    return EXIT_OK


def _check_dataset_path(path: Path) -> None:
    if path.is_dir():
        raise _Fail(f"{path}: is a directory; allowed: a dataset file (.nc)", EXIT_BAD_INPUT)
    if not path.is_file():
        raise _Fail(f"{path}: no such dataset file", EXIT_BAD_INPUT)


def cmd_export(args) -> int:
    """A dataset's cell fields on the 3-D pipe as a VTK structured (.vts) or unstructured (.vtu)
    grid (eulag.export)."""
    from eulag import export

    src = Path(args.dataset)
    _check_dataset_path(src)
    try:
        written = export.export_vts(src, Path(args.target))
    except (ValueError, export.ExportError) as exc:
        raise _Fail(" ".join(str(exc).split()), EXIT_BAD_INPUT) from None
    print(written if written is not None else args.target)
    return EXIT_OK


# ---------------------------------------------------------------------------
# eulag sweep
# ---------------------------------------------------------------------------

def cmd_sweep(args) -> int:
    """Whole cases one after another, or as Dask tasks (eulag.sweep); exit 2 on bad input
    before any case starts, 1 if a case failed or did not converge (see the summary)."""
    from eulag import sweep

    _check_dask(args)
    try:
        entries = sweep.plan_sweep(args.cases, args.output_dir, parcels=args.parcels)
    except sweep.SweepInputError as exc:
        raise _Fail(str(exc), EXIT_BAD_INPUT) from None
    say = None if args.quiet else (lambda line: print(line, flush=True))
    client = None
    rows = None
    numba_threads = None
    try:
        if any(not e.finished for e in entries):
            client = _dask_client(args)
        if client is not None:
            from eulag.distributed import describe

            numba_threads = 1  # one numba thread per Dask worker thread
            if say:
                say(describe(client))
        rows = sweep.run_sweep(entries, client, numba_threads=numba_threads, progress=say,
                               summary_dir=args.output_dir)
    except Exception as exc:
        from eulag.distributed import DaskConnectionError

        if isinstance(exc, DaskConnectionError):
            raise _Fail(f"sweep: {exc}") from None
        raise
    finally:
        _close_dask(client)
        if rows is None:  # interrupted or lost: the summary of what is known
            rows = [sweep.summary_row(e.name, None, e.output, sweep.NOT_RUN, "") for e in entries]
            for i, e in enumerate(entries):
                if e.output.is_file():
                    try:
                        rows[i] = sweep.read_row(e, sweep.FINISHED_EARLIER if e.finished else sweep.RAN)
                    except Exception:  # noqa: BLE001
                        pass
        csv_path, md_path = sweep.write_summary(rows, args.output_dir)
    if say:
        say(f"summary: {csv_path} and {md_path}")
    failed = [r["case"] for r in rows if r["status"] == sweep.FAILED]
    unconverged = [r["case"] for r in rows if r["status"] != sweep.FAILED and r["converged"] is not True]
    if failed or unconverged:
        parts = []
        if failed:
            parts.append(f"{len(failed)} failed ({', '.join(failed)})")
        if unconverged:
            parts.append(f"{len(unconverged)} did not converge ({', '.join(unconverged)})")
        raise _Fail(f"sweep of {len(rows)} cases: {'; '.join(parts)}; see {md_path}")
    return EXIT_OK


# ---------------------------------------------------------------------------
# eulag plot
# ---------------------------------------------------------------------------

def cmd_plot(args) -> int:
    """Figures of a dataset; bad input (missing/unreadable file, x outside the pipe, -o not
    a directory) exits 2 before anything is drawn; the figures appear all together or not
    at all (eulag.plots.plot_all)."""
    path = Path(args.dataset)
    _check_dataset_path(path)
    if args.output and Path(args.output).exists() and not Path(args.output).is_dir():
        raise _Fail(f"-o {args.output}: exists and is not a directory; allowed: a directory",
                    EXIT_BAD_INPUT)
    import xarray as xr

    from eulag import analysis, plots

    try:
        with xr.open_dataset(path) as opened:
            ds = opened.load()
    except Exception as exc:
        raise _Fail(f"{path}: cannot be read as a NetCDF dataset ({short_reason(exc)})", EXIT_BAD_INPUT) from None
    problem = plots.dataset_problem(ds)
    if problem is not None:
        raise _Fail(f"{path}: {problem}", EXIT_BAD_INPUT)
    model = str(ds.attrs.get("model", "euler-lagrange"))
    if model == "dem-darcy" and args.x is not None:
        raise _Fail(f"--x {args.x:g}: a dem-darcy (slug) dataset has no cross-section station (its figures "
                    "span the tube and the run's time); allowed: no --x", EXIT_BAD_INPUT)
    if model == "two-fluid" and args.x is not None and ds.sizes.get("x", 0) <= 1:
        raise _Fail(f"--x {args.x:g}: a fully developed two-fluid section has no axial position (the same at "
                    "every x); allowed: no --x", EXIT_BAD_INPUT)
    try:
        analysis.check_station(ds, args.x)
    except ValueError as exc:
        raise _Fail(f"--x: {exc}", EXIT_BAD_INPUT) from None
    ds.encoding["source"] = str(path)
    written = plots.plot_all(ds, x=args.x, outdir=args.output)
    for p in written:
        print(p)
    return EXIT_OK


# ---------------------------------------------------------------------------

def main(argv: list[str] | None = None) -> int:
    """Entry point of ``eulag``; returns the exit status."""
    try:
        args = _build_parser().parse_args(argv)
        return args.func(args)
    except _Fail as exc:
        print(f"eulag: error: {exc}", file=sys.stderr)
        return exc.status
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else EXIT_OK
    except BrokenPipeError:  # the reader of stdout went away (e.g. `eulag study --help | head`)
        return EXIT_OK
    except KeyboardInterrupt:
        print("eulag: error: interrupted; no dataset written (a coupled, slug or two-fluid run keeps the "
              "checkpoint of its last complete pass or interval beside the output: run it again with --resume "
              "to continue)", file=sys.stderr)
        return 130
    except Exception as exc:  # one line, never a half-written file (writes are atomic)
        if os.environ.get("EULAG_DEBUG"):
            raise
        msg = " ".join(f"{type(exc).__name__}: {exc}".split())
        print(f"eulag: error: {msg} (set EULAG_DEBUG=1 for the traceback)", file=sys.stderr)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
