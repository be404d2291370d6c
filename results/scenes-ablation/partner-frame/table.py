"""The table of README.md from the runs' metrics (runs/*.json, one per proxy run):

    python results/scenes-ablation/partner-frame/table.py
"""

import json
from pathlib import Path

HERE = Path(__file__).parent
ORDER = {"eulag": 0, "cartesian": 0, "polar": 1, "full": 2, "response": 3}
WHAT = {"eulag": "the defaults", "cartesian": "the defaults (trial tree)",
        "polar": "partners per component in the cell's (x, r, θ) frame (trial, `polar_trial.patch`)",
        "full": "`physics.partner_covariance = \"full\"`",
        "response": "`physics.langevin_drift_form = \"response\"`"}


def main():
    rows = []
    for f in sorted(HERE.glob("runs/*.json")):
        d = json.loads(f.read_text())
        scene, label, seed = f.stem.split("_")
        rows.append((scene, ORDER[label], int(seed[1:]), label, d))
    print("| scene | variant | seed | cells (symmetrised; replicas) | sin2θ/cosθ index | u_y signs bottom→top "
          "| main pair | strength [% U0] | interior max [% U0] | −dp/dx [Pa/m] | particles in the upper half "
          "| converged | run time [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for scene, _, seed, label, d in sorted(rows, key=lambda r: r[:3]):
        print(f"| {scene} | {WHAT[label]} | {seed} | {d['cells_sym']} | {d['index']} | {d['uy_pattern']} | {d['sense']} "
              f"| {d['strength']:.3g} | {d['interior']} | {d['dpdx']:.1f} | {100 * d['particles_upper_half']:.0f} % "
              f"| {d['converged']} | {d['time']:.0f} |")


if __name__ == "__main__":
    main()
