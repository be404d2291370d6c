"""The table of README.md from the runs' metrics in this folder:

    python results/scenes-ablation/ingredients/table.py

Each run RUN has RUN.metrics.json (``results/scenes-ablation/section_metrics.py RUN.nc``) and
RUN.forcing.json (``forcing.py RUN.nc``) beside its case file scene_RUN.toml; the pass count
comes from RUN.summary.txt (the run's printed summary).
"""

import json
import re
from pathlib import Path

HERE = Path(__file__).parent

WHAT = {"magnus_off": "`physics.magnus_lift = false`",
        "saffman_off": "`physics.saffman_mei_lift = false`",
        "rotation_off": "`physics.rotation = false` (no Magnus lift, no spin in the collisions)",
        "grid400": "14 × 28 = 392 cells per cross-section (the paper: 400)",
        "grid400_seed2": "14 × 28 cells, `numerics.seed = 2`"}


def row(run: str) -> str:
    m = json.loads((HERE / f"{run}.metrics.json").read_text())
    f = json.loads((HERE / f"{run}.forcing.json").read_text())
    summary = (HERE / f"{run}.summary.txt").read_text()
    passes = re.search(r"passes\s+(\d+)", summary).group(1)
    fw, fs = f["force_window"], f["force_station"]
    scene, _, variant = run.partition("_")
    return (f"| {scene} | {WHAT[variant]} | {m['cells_sym']} | {m['index']} | {m['uy_pattern']} | "
            f"{m['sense']} | {m['strength']:.3g} | {m['interior']} | "
            f"{m['impacts_upper_over_lower']:.2f} | {100 * m['particles_upper_half']:.0f} % | "
            f"{fs['count_symmetrised']}, {fs['mode_index']:.2f} | "
            f"{fw['count_symmetrised']}, {fw['mode_index']:.2f}, {fw['main_pair_sense']} | "
            f"{m['dpdx']:.1f} | {passes} |")


def main():
    runs = sorted(p.name[:-len(".metrics.json")] for p in HERE.glob("*.metrics.json"))
    print("| scene | what differs from the shipped scene | cells (symmetrised; replicas) | "
          "sin2θ/cosθ index | u_y signs bottom→top | main pair | strength [% U0] | "
          "interior max [% U0] | wall impacts upper/lower | particles in the upper half | "
          "force at 3.555 m: cells, index | force over 2.56–3.56 m: cells, index, main pair | "
          "−dp/dx at 3.555 m [Pa/m] | passes |")
    print("|" + "---|" * 14)
    for run in runs:
        print(row(run))


if __name__ == "__main__":
    main()
