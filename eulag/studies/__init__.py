"""The validation and verification studies: ``eulag study NAME [--quick]``.

    eulag study tsuji-morikawa            [--quick] [-o DIR] [--resume] [--report] [--quiet] [--parcels N]
    eulag study scenes                    [--quick] [-o DIR] [--resume] [--report] [--quiet] [--parcels N]
                                          [--only a,c]
    eulag study error-runtime CASE.toml   [--quick] [-o DIR] [--resume] [--report] [--quiet]
    eulag study stability                 [--quick] [-o DIR] [--resume] [--report] [--quiet] [--parcels N]
                                          [--only ...]
    eulag study ding-friction             [--quick] [-o DIR] [--resume] [--report] [--quiet]
                                          [--only MODELS] [--rates LIST]
    eulag study strauss                   [--quick] [-o DIR] [--resume] [--report] [--quiet] [--long]
                                          [--only GROUPS] [--feeds LIST] [--velocities LIST] [--window S]
                                          [--from-state PATH]

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
  to what a study extracts from a dataset must bump the version. A run too long to finish
  at once is committed with its checkpoint (``<run>.nc.checkpoint``, results/README.md), which
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

Modules: :mod:`.runner` (running one case: resume, records, failed records, the "unfinished"
rows of ``--report``), :mod:`.report` (the generated README.md and CSV tables, machine info,
settings text), :mod:`.profiles` (profiles along the diameter, deviations, Pareto front), and
one module per study: :mod:`.tsuji_morikawa`, :mod:`.scenes`, :mod:`.error_runtime`,
:mod:`.stability`.
"""

from __future__ import annotations

import sys
import time
from typing import Callable

from .ablation import ablation_cases, study_scenes_ablation
from .ding_friction import study_cases as ding_friction_cases, study_ding_friction
from .error_runtime import Setting, error_runtime_plan, study_error_runtime
from .profiles import diameter_profile, pareto_front, profile_deviation, provenance, read_measurements
from .report import Column, machine_info, markdown_table, table_frame, write_csv, write_report
from .runner import (BASE_CASE, EXIT_BAD_INPUT, QUICK_NUMERICS, RECORD_VERSION, STABILITY_QUICK, STUDY_NUMERICS,
                     RunRecord, _BadInput, _output_dir, checkpoint_of, read_record, resumable_checkpoint,
                     run_case, run_time, write_record)
from .scenes import scene_cases, study_scenes
from .stability import stability_cases, study_stability
from .strauss import study_cases as strauss_cases, study_strauss
from .tsuji_morikawa import study_tsuji_morikawa, tsuji_morikawa_cases

# helpers the tests reach as ``studies.<name>`` (not part of the API)
from .report import _settings_text  # noqa: F401, E402
from .runner import _base_case, _canonical, _gas_not_converged, _quick, _resumed_part  # noqa: F401, E402
from .stability import _floored_cell, _floored_where  # noqa: F401, E402

__all__ = ["add_arguments", "STUDIES", "BASE_CASE", "QUICK_NUMERICS", "STABILITY_QUICK", "STUDY_NUMERICS",
           "RECORD_VERSION", "RunRecord", "run_case", "run_time", "read_record", "write_record",
           "checkpoint_of", "resumable_checkpoint", "machine_info", "Column", "table_frame",
           "markdown_table", "write_csv", "write_report", "diameter_profile", "profile_deviation",
           "pareto_front", "provenance", "read_measurements", "Setting", "error_runtime_plan",
           "scene_cases", "stability_cases", "tsuji_morikawa_cases", "study_error_runtime", "study_scenes",
           "study_stability", "study_tsuji_morikawa", "ablation_cases", "study_scenes_ablation",
           "ding_friction_cases", "study_ding_friction", "strauss_cases", "study_strauss"]

STUDIES = ("tsuji-morikawa", "scenes", "scenes-ablation", "error-runtime", "stability", "ding-friction", "strauss")


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

    p = sub.add_parser("scenes-ablation", help="each departure from the reference paper's model switched "
                                               "alone, on proxies of scenes b, c, d, e, g, h")
    _common(p, "scenes-ablation", only="comma-separated scenes, e.g. b,d (default: b,c,d,e,g,h)")
    p.add_argument("--variants", metavar="LIST",
                   help="comma-separated variants (default: every departure and 'paper'; also "
                        "saffman_mei_lift=false, magnus_lift=false, langevin_drift_form=particle; "
                        "the output table lists the labels)")
    p.set_defaults(func=_entry(study_scenes_ablation))

    p = sub.add_parser("error-runtime", help="error of the section profiles against wall time "
                                             "(grids, parcels, step factor, step rule)")
    p.add_argument("case", metavar="CASE.toml", help="the case studied (e.g. cases/tsuji_morikawa_200um.toml)")
    _common(p, "error-runtime")
    p.set_defaults(func=_entry(study_error_runtime))

    p = sub.add_parser("stability", help="stiff and extreme cases: converged, or a clear diagnosis")
    _common(p, "stability", only="comma-separated case names to run (default: all)")
    p.set_defaults(func=_entry(study_stability))

    p = sub.add_parser("ding-friction", help="dense-phase two-fluid model: five gas rates x three frictional-"
                                             "stress models against Ding et al. (2024)")
    _common(p, "ding-friction", only="comma-separated friction models, e.g. berzi,dartevelle (default: all three)")
    p.add_argument("--rates", metavar="LIST",
                   help="comma-separated supplementary gas rates of cases/two_fluid (default: 0.4,0.6,0.8,1.0,1.2; "
                        "quick: 0.8)")
    p.set_defaults(func=_entry(study_ding_friction))

    p = sub.add_parser("strauss", help="dense-phase DEM-Darcy slug conveying: characteristic curves, mass flux, "
                                       "viscosity, friction and the vertical tube against Strauss et al. (2006)")
    _common(p, "strauss", only="comma-separated groups: default, curves, mass-flux, viscosity, friction, "
                               "vertical, long (default: all but long)")
    p.add_argument("--long", action="store_true", help="also the 22.5 s statistics run (hours)")
    p.add_argument("--feeds", metavar="LIST", help="feed rates [kg/h] of the characteristic curves (default 2.49,9.95)")
    p.add_argument("--velocities", metavar="LIST",
                   help="superficial gas velocities [m/s] of the characteristic curves (default 0.2,...,5)")
    p.add_argument("--window", type=float, metavar="S",
                   help="simulated time of every run but the long one [s] (default: the case files' 4 s; "
                        "with --from-state: after the state's time, default 3 s)")
    p.add_argument("--from-state", metavar="PATH",
                   help="start the horizontal runs from this filled-tube state (eulag.slug.save_state of a "
                        "run's checkpoint) instead of an empty tube; the vertical and long runs are left out")
    p.set_defaults(func=_entry(study_strauss))


def _common(p, name: str, only: str | None = None) -> None:
    if only is not None:
        p.add_argument("--only", metavar="LIST", help=only)
    p.add_argument("--quick", action="store_true",
                   help="tiny grids, few parcels, two passes (checks the machinery; not results). A "
                        "first run compiles a particle kernel per physics-option set, 1-2.5 min each from a "
                        "cold numba cache (scenes-ablation: about 10 min)")
    p.add_argument("-o", "--output-dir", metavar="DIR", default=None,
                   help=f"output folder (default: results/{name}/)")
    p.add_argument("--resume", action="store_true",
                   help="keep finished runs, continue interrupted ones from their checkpoints")
    p.add_argument("--report", action="store_true",
                   help="run nothing: write the table from the datasets, records and checkpoints "
                        "already in the output folder (an unfinished run's row says how far it got); "
                        "refused, leaving the folder as it is, when its runs are of other cases or it "
                        "keeps none")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    if name not in ("error-runtime", "ding-friction", "strauss"):  # an axis there; no parcels in dense models
        p.add_argument("--parcels", type=_positive_int, metavar="N",
                       help="parcels per pass in the final passes of every run (a lighter full-mode "
                            "study; the stability study's 1e6-parcel case keeps its count)")
    p.set_defaults(study_name=name)


def _positive_int(text: str) -> int:
    from eulag.arguments import positive_int

    return positive_int(text)


def _entry(study: Callable) -> Callable:
    def func(args) -> int:
        t0 = time.perf_counter()
        made = []  # the output folders this call creates: removed again, empty, on bad input
        try:
            outdir = _output_dir(args, made)
            return study(args, outdir, t0)
        except _BadInput as exc:
            for folder in reversed(made):
                try:
                    folder.rmdir()  # only if still empty
                except OSError:
                    break
            print(f"eulag: error: {' '.join(str(exc).split())}", file=sys.stderr)
            return EXIT_BAD_INPUT
    return func
