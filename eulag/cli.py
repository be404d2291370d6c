"""The ``eulag`` command line (DESIGN.md, "Command line").

    eulag run CASE.toml [-o out.nc] [--parcels N] [--resume] [--quiet]
                        [--dask-local N | --scheduler ADDRESS]
    eulag plot out.nc [--x 3.56] [-o figs/]
    eulag study NAME [CASE.toml] [--quick]
    eulag sweep CASES... [-o DIR] [--dask-local N | --scheduler ADDRESS] [--parcels N] [--quiet]

The Dask options (docs/scale_out.md) need the ``dask`` extra (``pip install '.[dask]'``).

Exit status: 0 done, 2 bad input (case file, arguments), 1 anything else; every failure
prints one line ``eulag: error: <what>`` on stderr and leaves no output file behind.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import eulag
from eulag.config import Case, CaseError

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
    run.add_argument("case", metavar="CASE.toml", help="case file")
    run.add_argument("-o", "--output", metavar="OUT.nc",
                     help="output dataset (default: <case name>.nc in the current directory)")
    run.add_argument("--parcels", type=_positive_int, metavar="N",
                     help="parcels per Lagrangian pass in the final passes (overrides numerics.parcels)")
    run.add_argument("--resume", action="store_true",
                     help="continue from the checkpoint beside the output; succeed at once if the "
                          "output is already a finished run of the same case")
    run.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    run.add_argument("--no-plots", action="store_true",
                     help="gas-particle cases: do not write the figures (eulag plot) beside the dataset")
    _add_dask_arguments(run, "the Lagrangian passes' super-batches")
    run.set_defaults(func=cmd_run)

    plot = sub.add_parser("plot", help="figures (PNG) from a dataset: section, profiles, convergence")
    plot.add_argument("dataset", metavar="OUT.nc", help="dataset written by 'eulag run'")
    plot.add_argument("--x", type=float, metavar="X",
                      help="axial station [m] (default: the first pipe.sections entry)")
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
    sweep.add_argument("cases", nargs="+", metavar="CASE.toml", help="case files (distinct case names)")
    sweep.add_argument("-o", "--output-dir", metavar="DIR", default=".",
                       help="directory of the datasets, checkpoints and sweep_summary.csv/.md "
                            "(default: the current directory; created if missing)")
    sweep.add_argument("--parcels", type=_positive_int, metavar="N",
                       help="parcels per Lagrangian pass in the final passes, for every case")
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
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer; allowed: an integer >= 1") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is out of range; allowed: an integer >= 1")
    return value


def _not_yet(what: str):
    def run(args) -> int:
        raise _Fail(f"{what} is not available in eulag {eulag.__version__} yet")
    return run


# ---------------------------------------------------------------------------
# eulag run
# ---------------------------------------------------------------------------

def _load_case(args) -> Case:
    case = Case.from_toml(args.case)
    if args.parcels is not None:
        n = case.numerics
        case = case.replace(numerics={"parcels": args.parcels,
                                      "parcels_start": min(n.parcels_start, args.parcels)})
    return case


def _output_path(args, case: Case) -> Path:
    out = Path(args.output) if args.output else Path(f"{case.name}.nc")
    if out.exists() and out.is_dir():
        raise _Fail(f"-o {out}: is a directory; allowed: a file path", EXIT_BAD_INPUT)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise _Fail(f"-o {out}: directory {parent} does not exist; allowed: a path in an existing "
                    "directory", EXIT_BAD_INPUT)
    if not os.access(parent, os.W_OK):
        raise _Fail(f"-o {out}: directory {parent} is not writable", EXIT_BAD_INPUT)
    return out


def _finished_run(out: Path, case: Case) -> bool:
    """True if ``out`` is a converged dataset of this same case (for --resume)."""
    if not out.is_file():
        return False
    import xarray as xr

    try:
        with xr.open_dataset(out) as ds:
            attrs = dict(ds.attrs)
    except Exception as exc:
        raise _Fail(f"--resume: {out} exists but cannot be read ({exc})") from None
    try:
        same = Case.from_attrs(attrs) == case
    except CaseError:
        same = False
    if not same:
        raise _Fail(f"--resume: {out} holds a different case; allowed: the output of this case, "
                    "or run without --resume to overwrite", EXIT_BAD_INPUT)
    return attrs.get("converged") == "true"


def cmd_run(args) -> int:
    t_start = time.perf_counter()
    try:
        case = _load_case(args)
    except CaseError as exc:
        raise _Fail(str(exc), EXIT_BAD_INPUT) from None
    out = _output_path(args, case)
    _check_dask(args)
    if case.particles is not None:
        return _run_coupled(args, case, out, t_start)
    if args.resume and _finished_run(out, case):
        if not args.quiet:
            print(f"{out}: already a finished run of case {case.name}; nothing to do")
        return EXIT_OK

    import rans
    from eulag.output import gas_dataset, write_dataset

    timings = {}
    t0 = time.perf_counter()
    mesh = rans.PipeMesh.build(
        diameter=case.pipe.diameter, length=case.pipe.length, mode=case.pipe.mode,
        axial_cells=case.numerics.axial_cells, radial_cells=case.numerics.radial_cells,
        azimuthal_cells=case.numerics.azimuthal_cells,
        first_cell_yplus=case.numerics.first_cell_yplus, bulk_velocity=case.gas.bulk_velocity,
        density=case.gas.density, viscosity=case.gas.viscosity)
    timings["mesh"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    gas = rans.GasProperties(density=case.gas.density, viscosity=case.gas.viscosity)
    try:
        field = rans.solve(mesh, gas, bulk_velocity=case.gas.bulk_velocity,
                           inlet_k=case.gas.inlet_k, inlet_epsilon=case.gas.inlet_epsilon,
                           sources=None, tol=case.numerics.gas_tolerance,
                           max_iterations=case.numerics.gas_max_iterations,
                           progress=not args.quiet and sys.stderr.isatty())
    except rans.SolverDivergence as exc:
        raise _Fail(str(exc) or "the gas solver diverged") from None
    timings["gas_solve"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start

    ds = gas_dataset(case, mesh, field, timings=timings)
    t0 = time.perf_counter()
    write_dataset(ds, out)
    t_write = time.perf_counter() - t0

    if not args.quiet:
        print(_summary(case, mesh, field, out, timings, t_write))
    if not field.converged:
        raise _Fail(f"the gas solver did not converge in {field.iterations} iterations (final "
                    f"residual {_final(field):.3g} > gas_tolerance {case.numerics.gas_tolerance:g}); "
                    f"{out} was written with converged = false")
    return EXIT_OK


def _run_coupled(args, case: Case, out: Path, t_start: float) -> int:
    """A gas-particle case: the coupling loop with a checkpoint beside the output."""
    ckpt = Path(str(out) + ".checkpoint")
    if args.resume and not ckpt.exists() and _finished_run(out, case):
        if not args.quiet:
            print(f"{out}: already a finished run of case {case.name}; nothing to do")
        return EXIT_OK
    if not args.resume and ckpt.exists():
        ckpt.unlink()  # a fresh run starts from scratch

    import rans
    from eulag.coupling import CouplingError, CouplingLoop
    from eulag.output import coupled_dataset, write_dataset

    client, tracker = _dask_tracker(args)  # before the progress bar: it prints the cluster line
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=case.numerics.max_passes, desc=case.name, unit="pass", file=sys.stderr,
                   dynamic_ncols=True)

    def progress(state):
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(f"residual {state.residual:.3g}, -dp/dx {state.pressure_gradient:.4g} Pa/m, "
                                f"{state.parcels} parcels, {state.phase}")

    try:
        def notify(text):
            if bar is not None:
                bar.write(f"{case.name}: {text}", file=sys.stderr)

        loop = CouplingLoop(case, checkpoint=ckpt, resume=args.resume, progress=progress, tracker=tracker,
                            notify=notify)
        if bar is not None and loop.pass_index:
            bar.update(loop.pass_index)
        loop.run()
    except CouplingError as exc:
        raise _Fail(f"{exc} (checkpoint of the last complete pass: {ckpt})") from None
    except rans.SolverDivergence as exc:
        raise _Fail(f"{exc} (checkpoint of the last complete pass: {ckpt})") from None
    finally:
        if bar is not None:
            bar.close()
        _close_dask(client)
    loop.timings["total"] = time.perf_counter() - t_start
    ds = coupled_dataset(loop)
    write_dataset(ds, out)
    figures = []
    if not args.no_plots:
        from eulag import plots

        try:
            figures = plots.plot_all(out)
        except Exception as exc:  # the dataset is written; a figure failing must not hide it
            print(f"eulag: figures not written ({exc}); the dataset {out} is complete", file=sys.stderr)
    if not args.quiet:
        print(_coupled_summary(case, loop, ds, out))
        if figures:
            print(f"  figures      {Path(figures[0]).parent}/ ({len(figures)} PNG)")
    if not loop.converged:
        raise _Fail(f"the coupling did not converge in {len(loop.history.residual)} passes (final residual "
                    f"{loop.history.residual[-1]:.3g}); {out} was written with converged = false")
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
        f"final residual {h.residual[-1]:.3g}, relaxation {h.relaxation[-1]:g}",
        f"  -dp/dx       {float(np.mean(ds.pressure_gradient)):.4g} Pa/m (single-phase "
        f"{float(np.mean(ds.pressure_gradient_single_phase)):.4g}); dp ratio "
        f"{float(ds.solids_pressure_drop_ratio):.4g}, lambda_Z {float(ds.additional_pressure_loss_coefficient):.4g}",
        f"  secondary    {strength}",
        f"  parcels      {int(h.parcels[-1])} per final pass; lost {int(sum(h.lost))}, stuck {int(sum(h.stuck))}",
        *_collision_momentum_line(case, h),
        *_collision_force_line(case, ds),
        f"  wall time    gas {t.get('gas_solve', 0):.1f} s, Lagrangian {t.get('lagrangian', 0):.1f} s, "
        f"checkpoints {t.get('checkpoint', 0):.1f} s, total {t.get('total', 0):.1f} s",
        f"  written      {out}",
    ]
    return "\n".join(lines)


def _collision_momentum_line(case, h) -> list[str]:
    """The net momentum the stochastic collisions gave the particles (real pairs give none)."""
    from eulag.coupling import COLLISION_MOMENTUM_TOL, recent_collision_momentum

    cm = recent_collision_momentum(h.collision_momentum)
    if not case.physics.inter_particle_collisions or not math.isfinite(cm):
        return []
    flag = (f"; WARNING: more than {100 * COLLISION_MOMENTUM_TOL:g} %" if abs(cm) >= COLLISION_MOMENTUM_TOL
            else "")
    return [f"  collisions   net momentum {100 * cm:+.2g} % of the particle inflow (final passes; real "
            f"collision pairs give none, README \"Coupling\" 6{flag})"]


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


def _summary(case, mesh, field, out, timings, t_write) -> str:
    """A short human-readable summary of a single-phase run."""
    import numpy as np
    from fluids.friction import Colebrook

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
        f"  wall time    mesh {timings['mesh']:.2f} s, gas solve {timings['gas_solve']:.2f} s, "
        f"write {t_write:.2f} s",
        f"  written      {out}",
    ]
    return "\n".join(lines)


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
                        rows[i] = sweep._read_row(e, sweep.FINISHED_EARLIER if e.finished else sweep.RAN)
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
    if not path.is_file():
        raise _Fail(f"{path}: no such dataset file", EXIT_BAD_INPUT)
    if args.output and Path(args.output).exists() and not Path(args.output).is_dir():
        raise _Fail(f"-o {args.output}: exists and is not a directory; allowed: a directory",
                    EXIT_BAD_INPUT)
    import xarray as xr

    from eulag import analysis, plots

    try:
        with xr.open_dataset(path) as opened:
            ds = opened.load()
    except Exception as exc:
        raise _Fail(f"{path}: cannot be read as a NetCDF dataset ({exc})", EXIT_BAD_INPUT) from None
    missing = [v for v in ("gas_ux", "y", "z", "cell_area") if v not in ds.variables]
    if missing:
        raise _Fail(f"{path}: not an eulag dataset (no {', '.join(missing)})", EXIT_BAD_INPUT)
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
    except KeyboardInterrupt:
        print("eulag: error: interrupted; no output written", file=sys.stderr)
        return 130
    except Exception as exc:  # one line, never a half-written file (writes are atomic)
        if os.environ.get("EULAG_DEBUG"):
            raise
        msg = " ".join(f"{type(exc).__name__}: {exc}".split())
        print(f"eulag: error: {msg} (set EULAG_DEBUG=1 for the traceback)", file=sys.stderr)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
