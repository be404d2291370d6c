"""Time per call of the cross-section operators the station iteration calls most.

    python tests/benchmarks/bench_section_ops.py

On the studies' 20 x 40 section (cases/scenes/scene_h.toml): face interpolation, transport
coefficients (upwind, hybrid), reconstruction, gradient and normal difference, each timed
over 20,000 calls after a first (compiling) one, in microseconds per call.  Run it from a
checkout of another commit (``PYTHONPATH=<checkout>``) to compare versions.
"""

from __future__ import annotations

import timeit

import numpy as np

from eulag.config import CASES_DIR, Case
from eulag.coupling import build_mesh


def main():
    case = Case.from_toml(CASES_DIR / "scenes" / "scene_h.toml")
    sec = build_mesh(case).geometry()
    rng = np.random.default_rng(0)
    phi = rng.random(sec.n)
    flux = rng.standard_normal(sec.nf) * 1e-3
    g = sec.interp(phi)
    wall = np.zeros(sec.wall.size)
    calls = [("interp", lambda: sec.interp(phi)),
             ("transport, upwind", lambda: sec.transport(flux, g, "upwind")),
             ("transport, hybrid", lambda: sec.transport(flux, g, "hybrid")),
             ("reconstruct", lambda: sec.reconstruct(g, wall)),
             ("gradient (wall value 0)", lambda: sec.gradient(phi, 0.0)),
             ("normal difference", lambda: sec.normal_difference(phi))]
    print(f"section {sec.nr} x {sec.nt}: {sec.n} cells, {sec.nf} faces; microseconds per call")
    for name, fn in calls:
        fn()
        n = 20000
        print(f"  {name}: {timeit.timeit(fn, number=n) / n * 1e6:.2f}")


if __name__ == "__main__":
    main()
