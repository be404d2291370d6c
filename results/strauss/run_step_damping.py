"""DEM step and tangential damping on the periodic one-slug case, 1.5 s each.

    python results/strauss/run_step_damping.py STEPS_PER_CONTACT TANGENTIAL_DAMPING_RATIO [END_S]
    # one line of step_damping_periodic_slug.jsonl

numerics.steps_per_contact = N (the DEM step t_c/N) and grains.tangential_damping_ratio = γ_t/γ_n
changed in cases/slug/periodic_slug.toml; slug statistics over the whole tube from t = 0.2 s.
"""

import json
import sys
import tomllib
from pathlib import Path

from eulag.slug import run_slug, summarize

CASE = Path(__file__).resolve().parents[2] / "cases" / "slug" / "periodic_slug.toml"


def main():
    n, r = int(sys.argv[1]), float(sys.argv[2])
    end = float(sys.argv[3]) if len(sys.argv) > 3 else 1.5
    with open(CASE, "rb") as fh:
        case = tomllib.load(fh)
    case["numerics"]["steps_per_contact"] = n
    case["grains"]["tangential_damping_ratio"] = r
    case["numerics"]["end_time_s"] = end
    ds = run_slug(case, Path(f"per_N{n}_r{r:g}.nc"), progress=False)
    s = summarize(ds, x_window=(0.0, 0.07), t_min=0.2)
    s.update(N=n, r=r, wall=ds.attrs["wall_time_s"], max_overlap=float(ds.max_overlap_per_d.max()),
             lost=int(ds.grains_lost))
    print(json.dumps({k: v for k, v in s.items() if isinstance(v, (int, float, str))}), flush=True)


if __name__ == "__main__":
    main()
