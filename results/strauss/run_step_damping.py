"""DEM step and tangential damping on the periodic one-slug case, 1.5 s each.

    python results/strauss/run_step_damping.py STEPS_PER_CONTACT TANGENTIAL_DAMPING_RATIO [END_S]
    # one line of step_damping_periodic_slug.jsonl

numerics.steps_per_contact = N (the DEM step t_c/N) and grains.tangential_damping_ratio = γ_t/γ_n
changed in cases/slug/periodic_slug.toml (``run_stiffness.run_periodic``).
"""

import json
import sys

from run_stiffness import run_periodic


def main():
    n, r = int(sys.argv[1]), float(sys.argv[2])
    end = float(sys.argv[3]) if len(sys.argv) > 3 else 1.5
    s = run_periodic({("numerics", "steps_per_contact"): n, ("grains", "tangential_damping_ratio"): r},
                     f"per_N{n}_r{r:g}.nc", end)
    s.update(N=n, r=r)
    print(json.dumps({k: v for k, v in s.items() if isinstance(v, (int, float, str))}), flush=True)


if __name__ == "__main__":
    main()
