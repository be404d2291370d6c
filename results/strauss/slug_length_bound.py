"""How long can a slug of the paper's grain count be? The paper's slug criterion against its numbers:

    python results/strauss/slug_length_bound.py

Strauß, McNamara & Herrmann count a slice (3.5 mm of tube) as part of a slug while its porosity
is below 0.6, and give 470-500 grains per slug beside a slug length of 4-8 cm. A run of slices
that are all below φ = 0.6 holds at least 0.4 of its volume in grains, so N grains make a slug no
longer than L_max = N V_p / (0.4 A) (A the tube's cross-section, V_p a grain's volume); at the
slugs' mean porosity φ̄ the length is N V_p / ((1 − φ̄) A). The script prints both for the
paper's grain counts (tube and grain diameters from the run's case), and the mean porosity of the slugs of the 22.5 s run (its record: mean
grains per slug and mean length, slugs of ≥ 100 grains centred in 15-40 cm, t ≥ 6 s).
"""

import json
import math
from pathlib import Path

from eulag.slug import SLUG_POROSITY as PHI_SLUG   # the paper's slug criterion, phi < 0.6

HERE = Path(__file__).parent
RECORD = HERE / "strauss__vs-1.0__feed-2.49__t-22.5.record.json"


def main():
    record = json.loads(RECORD.read_text())
    case, m = json.loads(record["case"]), record["metrics"]
    area = math.pi * case["tube"]["diameter_m"] ** 2 / 4.0
    vp = math.pi * case["grains"]["diameter_m"] ** 3 / 6.0
    n_run, l_run = m["slug_grains"], m["slug_length_m"]
    phi_run = 1.0 - n_run * vp / (l_run * area)
    print(f"tube cross-section {area:.4e} m2, grain volume {vp:.4e} m3")
    print(f"22.5 s run: {n_run:.0f} grains per slug, length {100 * l_run:.2f} cm -> mean slug porosity {phi_run:.3f}")
    for n in (470, 500):
        l_max = n * vp / ((1.0 - PHI_SLUG) * area)
        l_run_phi = n * vp / ((1.0 - phi_run) * area)
        print(f"{n} grains (paper): at most {100 * l_max:.2f} cm with every slice below phi = {PHI_SLUG}; "
              f"{100 * l_run_phi:.2f} cm at the run's mean slug porosity {phi_run:.3f}")
    for length in (0.04, 0.08):
        n_min = (1.0 - PHI_SLUG) * area * length / vp
        print(f"a {100 * length:.0f} cm slug (paper) holds at least {n_min:.0f} grains")


if __name__ == "__main__":
    main()
