"""How much less margin a packing leaves the viscous tangential force than a single pair contact.

    python results/strauss/tangential_stability.py [STATE.npz]   (default: state_horizontal_t13.25.npz)

`dem.stability.damping_factor` (λ_max of the tangential damping over a single pair's 7 γ_t/m) for
the grains of a saved state with every contact sticking (the worst case: contacts at the Coulomb
cap drop out) and for small configurations; `eulag.slug.TANGENTIAL_PACKING_FACTOR` is the first.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np

from dem.stability import damping_factor

HERE = Path(__file__).resolve().parent


def main():
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "state_horizontal_t13.25.npz"
    st = np.load(path, allow_pickle=True)
    case = json.loads(str(st["case_json"]))
    d, rt = case["grains"]["diameter_m"], 0.5 * case["tube"]["diameter_m"]
    pos = st["g_pos"][st["g_status"] == 0]
    print(f"{path.name}: {len(pos)} grains, λ_max / pair = {damping_factor(pos, d, rt):.3f}")
    r = 0.5 * d
    for name, p in (("pair", [[0, 0, 0], [0.999 * d, 0, 0]]),
                    ("grain on the wall", [[0, -rt + r - 1e-9, 0]]),
                    ("two grains on the wall", [[0, -rt + r - 1e-9, 0], [0.999 * d, -rt + r - 1e-9, 0]]),
                    ("chain of 8 on the wall", [[k * 0.999 * d, -rt + r - 1e-9, 0] for k in range(8)])):
        print(f"{name}: λ_max / pair = {damping_factor(np.array(p, float), d, rt):.3f}")


if __name__ == "__main__":
    main()
