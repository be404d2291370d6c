"""Stiffness independence on the periodic one-slug case: k_n = 500, 1000, 2500 N/m (5×), 1.5 s each.

    python results/strauss/run_stiffness.py K_N_PER_M [END_S]   # one line of stiffness_periodic_slug.jsonl
"""

import json
import sys
import tomllib
from pathlib import Path

from eulag.slug import run_slug, summarize

CASE = Path(__file__).resolve().parents[2] / "cases" / "slug" / "periodic_slug.toml"


def main():
    k = float(sys.argv[1])
    end = float(sys.argv[2]) if len(sys.argv) > 2 else 1.5
    with open(CASE, "rb") as fh:
        case = tomllib.load(fh)
    case["grains"]["stiffness_N_m"] = k
    case["numerics"]["end_time_s"] = end
    ds = run_slug(case, Path(f"stiff_{k:g}.nc"), progress=False)
    s = summarize(ds, x_window=(0.0, 0.07), t_min=0.2)
    s.update(k=k, wall=ds.attrs["wall_time_s"], max_overlap=float(ds.max_overlap_per_d.max()), lost=int(ds.grains_lost))
    print(json.dumps(s), flush=True)


if __name__ == "__main__":
    main()
