"""Stiffness independence on the periodic one-slug case: k_n = 500, 1000, 2500 N/m (5×), 1.5 s each.

    python results/strauss/run_stiffness.py K_N_PER_M [END_S]   # one line of stiffness_periodic_slug.jsonl
"""

import json
import sys
import tomllib
from pathlib import Path

from eulag.slug import run_slug, summarize

CASE = Path(__file__).resolve().parents[2] / "cases" / "slug" / "periodic_slug.toml"


def run_periodic(changes, out, end=1.5):
    """Run cases/slug/periodic_slug.toml with ``changes`` {(section, key): value} until ``end`` [s]
    into ``out``; its slug statistics over the whole tube from t = 0.2 s, with the wall time, the
    largest overlap / d and the grains lost."""
    with open(CASE, "rb") as fh:
        case = tomllib.load(fh)
    for (sec, key), value in changes.items():
        case[sec][key] = value
    case["numerics"]["end_time_s"] = end
    ds = run_slug(case, Path(out), progress=False)
    s = summarize(ds, x_window=(0.0, 0.07), t_min=0.2)
    s.update(wall=ds.attrs["wall_time_s"], max_overlap=float(ds.max_overlap_per_d.max()), lost=int(ds.grains_lost))
    return s


def main():
    k = float(sys.argv[1])
    end = float(sys.argv[2]) if len(sys.argv) > 2 else 1.5
    s = run_periodic({("grains", "stiffness_N_m"): k}, f"stiff_{k:g}.nc", end)
    s.update(k=k)
    print(json.dumps(s), flush=True)


if __name__ == "__main__":
    main()
