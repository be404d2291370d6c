"""The generated files of a study: its table as Markdown (in ``README.md``) and CSV, the
machine and code it ran on, the settings paragraph, and the figure helpers every study uses.

A table is a list of :class:`Column` (CSV key, Markdown header, cell format) and a list of row
dicts. :func:`table_frame` makes the one :class:`pandas.DataFrame` of it: its raw values (a
non-finite float or None is an empty cell) go to the CSV with ``DataFrame.to_csv``; the
Markdown table shows its values formatted by the columns ("—" for an empty cell).
"""

from __future__ import annotations

import math
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import eulag
from eulag.analysis import attr as _attr
from eulag.config import Case, _public_fields

from .runner import QUICK_NUMERICS, STABILITY_QUICK, RunRecord, refuse_report_of_nothing


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
    """One column of a study table: ``key`` of the row dicts (and CSV header), ``header`` of the
    Markdown table, ``fmt`` the format of a Markdown cell."""

    key: str
    header: str
    fmt: str = "{}"

    def cell(self, row: dict) -> str:
        return self.format(row.get(self.key))

    def format(self, v) -> str:
        """The Markdown cell of the value ``v`` ("—": none, or a non-finite number)."""
        if v is None:
            return "—"
        if isinstance(v, float) and not math.isfinite(v):
            return "—"
        try:
            return self.fmt.format(v)
        except (ValueError, TypeError):
            return str(v)


def _csv_value(v):
    """A table value as the CSV holds it: None for an empty cell (None, NaN, inf), floats as
    Python floats (written in their shortest round-trip form), anything else unchanged."""
    if isinstance(v, float):
        return float(v) if math.isfinite(v) else None
    return v


def table_frame(columns: list[Column], rows: list[dict]):
    """The table as a :class:`pandas.DataFrame`, one column per :class:`Column` (named by its
    key, object dtype: integers stay integers beside empty cells), empty cells as None."""
    import pandas as pd

    return pd.DataFrame([[_csv_value(row.get(c.key)) for c in columns] for row in rows],
                        columns=[c.key for c in columns], dtype=object)


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def markdown_table(columns: list[Column], rows: list[dict]) -> str:
    """The table in Markdown (GitHub pipe table; cells formatted by the columns, "|" escaped).
    (``DataFrame.to_markdown`` would need ``tabulate`` and pads the cells; this keeps the
    generated README.md tables as they are.)"""
    frame = table_frame(columns, rows)
    lines = ["| " + " | ".join(c.header for c in columns) + " |",
             "|" + "|".join("---" for _ in columns) + "|"]
    for values in frame.itertuples(index=False, name=None):
        lines.append("| " + " | ".join(_md_escape(c.format(v)) for c, v in zip(columns, values)) + " |")
    return "\n".join(lines)


def write_csv(path: Path, columns: list[Column], rows: list[dict]) -> Path:
    """The table as CSV (header: the column keys; empty cells for None and non-finite numbers;
    CRLF line ends, as the csv module writes them), written atomically."""
    from eulag.output import atomic_write

    frame = table_frame(columns, rows)
    return atomic_write(path, lambda tmp: frame.to_csv(tmp, index=False, na_rep="", lineterminator="\r\n"))


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


#: study options with a value that the generated READMEs' command repeats
_VALUE_OPTIONS = ("only", "variants", "feeds", "velocities", "window", "from_state", "rates", "parcels")


def study_command(study: str, args) -> str:
    """The command line of a study invocation as its generated README states it."""
    parts = [f"eulag study {study}"]
    if getattr(args, "case", None):
        parts.append(str(args.case))
    for flag in ("quick", "long"):
        if getattr(args, flag, False):
            parts.append(f"--{flag}")
    for opt in _VALUE_OPTIONS:
        v = getattr(args, opt, None)
        if v is not None:
            parts.append(f"--{opt.replace('_', '-')} {v:g}" if isinstance(v, float) else f"--{opt.replace('_', '-')} {v}")
    for flag in ("resume", "report"):
        if getattr(args, flag, False):
            parts.append(f"--{flag}")
    return " ".join(parts)


def write_report(outdir: Path, study: str, args, *, title: str, intro: list[str],
                 columns: list[Column], rows: list[dict], figures: list[Path],
                 sections: list[tuple[str, str]] = (), t_start: float, settings: str,
                 records: list[RunRecord] = ()) -> Path:
    """README.md of a study folder (generated) and the CSV of its table."""
    from eulag.output import atomic_write

    refuse_report_of_nothing(args, records, outdir)

    csv_path = write_csv(outdir / f"{study}.csv", columns, rows)
    m = machine_info()
    quick = bool(getattr(args, "quick", False))
    cmd = study_command(study, args)
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
            # (none without inter-particle collisions: a record may hold 0 there)
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
            "Model constants are the paper's (docs/physics.md, \"Departures from the reference paper\"); "
            "nothing is tuned to the measurements.")
    if quick:
        text += (f" Quick mode replaces the numerics of every case by {QUICK_NUMERICS} (the stability "
                 f"study further by {STABILITY_QUICK}; error-runtime varies grid, parcels and step).")
    return text


def draw_figures(makers, *args) -> list:
    """Call each figure maker ``make(*args)`` and collect the paths they return (None: no
    figure); a maker that fails is one warning line on stderr, never the loss of a table."""
    import sys

    out = []
    for make in makers:
        try:
            p = make(*args)
        except Exception as exc:  # noqa: BLE001 - a figure must not lose the table
            print(f"eulag: warning: {make.__name__}: {type(exc).__name__}: {exc}", file=sys.stderr)
            p = None
        if p is not None:
            out.append(p)
    return out


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
        print(f"eulag: warning: figures of {_attr(ds, 'case.name')}: {type(exc).__name__}: {exc}",
              file=sys.stderr)
        return []
