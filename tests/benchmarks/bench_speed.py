"""The speed figures of the Euler–Lagrange code, on one machine in one run.

    python tests/benchmarks/bench_speed.py [--only kernel,gas,base,paper,scene] [--scene e[,f,...]]
                                           [--scene-checkpoint PATH] [--base-checkpoint PATH]
                                           [--parcels-final 240000] [--paper-axial-cells 200]
                                           [--out DIR]

Parts (each printed as it finishes, then together in one table with the machine):

* ``kernel``: particle kernel parcel-steps per second per core, full physics and drag +
  gravity + Langevin + walls on the bench's one-station section, and the full physics on the
  studies' 400 × 20 × 40 grid (``python -m particles.bench``: one thread, interleaved rounds,
  compile time apart).
* ``gas``: gas-solve time per coupling pass on the base case's and on scene h's relaxed
  particle sources at the studies' grid (``tests/benchmarks/bench_gas_scene.py``; from the
  checkpoints given, else from passes it runs itself).
* ``base``: passes and wall time to convergence of the base case
  (cases/tsuji_morikawa_200um.toml) on its default numerics.
* ``paper``: the same at the paper's resolution: 200 axial × 20 × 40 = 160,000 cells (the
  reference paper's count; ``--paper-axial-cells 400`` gives the studies' 320,000),
  ``--parcels-final`` parcels in the final passes (default 240,000).
* ``scene``: passes and wall time to convergence of secondary-flow scenes (``--scene``, one or
  several of a–h separated by commas, default e) at the studies' grid with ``--parcels-final``
  parcels in the final passes, one after the other.

The coupled runs go through ``eulag.runs.execute`` (as ``eulag run``) after a tiny run that
compiles the particle kernels of their physics options (reported apart). Datasets are written
to ``--out`` (default a temporary folder). ``base`` takes minutes, ``paper`` and ``scene`` up
to hours on two cores: select parts with ``--only``.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PARTS = ("kernel", "gas", "base", "paper", "scene")
SCENES = tuple("abcdefgh")


def _machine() -> str:
    import numba

    return (f"{platform.node()}, {os.cpu_count()} logical cores, {platform.processor() or platform.machine()}, "
            f"python {platform.python_version()}, numba {numba.__version__}, "
            f"load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}")


def _subprocess(args: list[str]) -> str:
    """Run a benchmark script, echo its output, return it."""
    print("$ " + " ".join(args), flush=True)
    out = subprocess.run([sys.executable, *args], capture_output=True, text=True, check=False)
    print(out.stdout, end="", flush=True)
    if out.returncode != 0:
        print(out.stderr, end="", file=sys.stderr, flush=True)
        return f"failed (exit status {out.returncode})"
    return out.stdout


def _coupled(label: str, case, out: Path) -> dict:
    """Passes and wall time to convergence of ``case`` (kernels compiled beforehand)."""
    from eulag.runs import execute
    from eulag.studies.runner import _warm_up

    t0 = time.perf_counter()
    _warm_up(case)
    compile_s = time.perf_counter() - t0
    n = case.numerics
    print(f"{label}: {n.axial_cells} x {n.radial_cells} x {n.azimuthal_cells} cells, "
          f"{n.parcels_start} -> {n.parcels} parcels, at most {n.max_passes} passes "
          f"(kernels compiled in {compile_s:.0f} s)", flush=True)
    t0 = time.perf_counter()
    result = execute(case, out / f"{case.name}.nc",
                     progress=lambda s: print(f"  pass {s.index}: residual {s.residual:.3g}, "
                                              f"-dp/dx {s.pressure_gradient:.4g} Pa/m", flush=True))
    wall = time.perf_counter() - t0
    ds = result.dataset
    row = {"part": label, "passes": int(ds.attrs.get("coupling_passes", 0)), "wall_s": wall,
           "converged": result.converged, "dpdx": float(ds["pressure_gradient_history"].values[-1]),
           "gas_s": float(ds.attrs.get("time_gas_solve", float("nan"))),
           "particles_s": float(ds.attrs.get("time_lagrangian", float("nan"))),
           "after_gas_s": float(ds.attrs.get("time_lagrangian_after_gas", float("nan")))}
    print(f"{label}: {'converged' if result.converged else 'not converged'} in {row['passes']} passes, "
          f"{wall:.0f} s (gas {row['gas_s']:.0f} s, particles {_particles(row)}), "
          f"-dp/dx {row['dpdx']:.4g} Pa/m; {result.stop_reason}", flush=True)
    return row


def _particles(row) -> str:
    """The particle time, and the part of it after the gas solves when passes were streamed
    beside them (particles.stream)."""
    text = f"{row['particles_s']:.0f} s"
    if row["after_gas_s"] < 0.99 * row["particles_s"]:
        text += f", {row['after_gas_s']:.0f} s of it after the gas solves"
    return text


def _choices(option: str, text: str, allowed, what: str) -> list[str] | None:
    """The comma-separated items of ``text``; None (after one line on stderr) if any is not allowed."""
    items = [x.strip() for x in text.split(",") if x.strip()]
    bad = [x for x in items if x not in allowed]
    if bad or not items:
        print(f"bench_speed: error: {option} {text}: unknown {what} {', '.join(bad) or '(none)'}; "
              f"allowed: {', '.join(allowed)}", file=sys.stderr)
        return None
    return items


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default=",".join(PARTS), help=f"comma-separated parts of {', '.join(PARTS)}")
    ap.add_argument("--scene", default="e", help="the scenes of 'scene': one or several of a-h, comma-separated")
    ap.add_argument("--scene-checkpoint", type=Path, help="scene h coupling checkpoint for 'gas'")
    ap.add_argument("--base-checkpoint", type=Path, help="base-case coupling checkpoint for 'gas'")
    ap.add_argument("--parcels-final", type=int, default=240_000, help="final-pass parcels of 'paper' and 'scene'")
    ap.add_argument("--paper-axial-cells", type=int, default=200,
                    help="axial cells of 'paper' (x 20 x 40; 200: the paper's 160,000 cells)")
    ap.add_argument("--out", type=Path, help="folder for the datasets (default: a temporary folder)")
    a = ap.parse_args(argv)
    parts = _choices("--only", a.only, PARTS, "part")
    scenes = _choices("--scene", a.scene, SCENES, "scene")
    if parts is None or scenes is None:
        return 2
    from eulag.config import CASES_DIR, Case

    print(f"machine: {_machine()}", flush=True)
    out = a.out or Path(tempfile.mkdtemp(prefix="eulag-bench-"))
    out.mkdir(parents=True, exist_ok=True)
    lines = []
    if "kernel" in parts:
        text = _subprocess(["-m", "particles.bench"])
        lines += ["kernel: " + ln.strip() for ln in text.splitlines() if "per core" in ln]
    if "gas" in parts:
        args = [str(HERE / "bench_gas_scene.py")]
        if a.scene_checkpoint:
            args += ["--scene-checkpoint", str(a.scene_checkpoint)]
        if a.base_checkpoint:
            args += ["--base-checkpoint", str(a.base_checkpoint)]
        text = _subprocess(args)
        lines += ["gas: " + ln.strip() for ln in text.splitlines() if " s" in ln and "solve" in ln]
    base = Case.from_toml(CASES_DIR / "tsuji_morikawa_200um.toml")
    rows = []
    if "base" in parts:
        rows.append(_coupled("base case, default numerics", base, out))
    if "paper" in parts:
        paper = base.replace(name="base_paper_resolution",
                             numerics={"axial_cells": a.paper_axial_cells, "radial_cells": 20, "azimuthal_cells": 40,
                                       "parcels": a.parcels_final,
                                       "parcels_start": min(base.numerics.parcels_start, a.parcels_final)})
        rows.append(_coupled("base case, paper resolution", paper, out))
    for name in (scenes if "scene" in parts else []):
        scene = Case.from_toml(CASES_DIR / "scenes" / f"scene_{name}.toml")
        scene = scene.replace(numerics={"parcels": a.parcels_final,
                                        "parcels_start": min(scene.numerics.parcels_start, a.parcels_final)})
        rows.append(_coupled(f"scene {name}", scene, out))
    print("\nsummary")
    print(f"  machine: {_machine()}")
    for ln in lines:
        print(f"  {ln}")
    for r in rows:
        print(f"  {r['part']}: {'converged' if r['converged'] else 'NOT converged'} in {r['passes']} passes, "
              f"{r['wall_s']:.0f} s (gas {r['gas_s']:.0f} s, particles {_particles(r)}), "
              f"-dp/dx {r['dpdx']:.4g} Pa/m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
