"""The drift-correction table of README.md from the run records beside this script:
``<form>/<run>.record.json`` with form = lagrangian | particle | none, the runs of
``eulag study scenes-ablation`` (proxies, PROXY_NUMERICS) named in README.md.

    python results/scenes-ablation/drift-correction/table.py
"""

import json
from pathlib import Path

HERE = Path(__file__).parent
FORMS = (("lagrangian", "(1 − R_L) T_L (default)"), ("particle", "(1 − R_P) T_L (former default)"),
         ("none", "no drift term (the paper's eq. 12)"))


def main():
    print("| scene | drift term | cells (replicas) | sin2θ/cosθ index | u_y signs bottom→top | main pair | "
          "strength [% U0] | interior max [% U0] | axis k / single-phase | −dp/dx [Pa/m] | converged | passes | commit |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for scene in "ceh":
        for form, text in FORMS:
            for f in sorted((HERE / form).glob(f"proxy_{scene}__*.record.json")):
                r = json.loads(f.read_text())
                m = r.get("metrics", {})
                conv = "yes" if r.get("status") == "converged" else "no (40 passes)"
                print(f"| {scene} | {text} | {m.get('pattern_cells_sym')} | {m.get('pattern_index')} | "
                      f"{m.get('uy_pattern')} | {m.get('sense')} | {m.get('strength'):.2f} | {m.get('interior'):.2f} | "
                      f"{m.get('k_axis'):.2f} | {m.get('dpdx'):.1f} | {conv} | {r.get('passes')} | {m.get('commit')} |")


if __name__ == "__main__":
    main()
