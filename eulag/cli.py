"""The ``eulag`` command line (DESIGN.md, "Command line").

    eulag run CASE.toml [-o out.nc] [--parcels N] [--resume] [--quiet]
    eulag plot out.nc [--x 3.56] [-o figs/]                     (not available yet)
    eulag study NAME [CASE.toml] [--quick]                       (not available yet)
    eulag sweep CASES...                                         (not available yet)

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
    run.set_defaults(func=cmd_run)

    plot = sub.add_parser("plot", help="figures from a dataset (not available yet)")
    plot.add_argument("dataset", metavar="OUT.nc")
    plot.add_argument("--x", type=float)
    plot.add_argument("-o", "--output")
    plot.set_defaults(func=_not_yet("eulag plot"))

    study = sub.add_parser("study", help="studies (not available yet)")
    study.add_argument("name")
    study.add_argument("case", nargs="?")
    study.add_argument("--quick", action="store_true")
    study.set_defaults(func=_not_yet("eulag study"))

    sweep = sub.add_parser("sweep", help="run several cases (not available yet)")
    sweep.add_argument("cases", nargs="+")
    sweep.set_defaults(func=_not_yet("eulag sweep"))
    return ap


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
    if case.particles is not None:
        raise _Fail(f"{args.case}: the particle phase is not in eulag {eulag.__version__} yet; "
                    "only single-phase cases (no [particles]) can be run")
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
