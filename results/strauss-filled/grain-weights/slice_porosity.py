"""The slug catalogue's slice porosity against the paper's volume-weighted slices (SMH §3.2).

    python results/strauss-filled/grain-weights/slice_porosity.py   (from the repository root)

Strauß et al. measure slugs on slices of 3.5 mm, "the contribution of a particle weighed by the
volume occupied by that particle within a given slice". eulag's catalogue takes the gas cells'
porosity (the tent transfer with the grains' normalised weights, `dem.transfer`) averaged over
the cross-section. For the filled tube of results/strauss/state_horizontal_t13.25.npz, on the
shipped horizontal case, this prints both per slice where either is below 0.7, their largest
difference, and the runs of slices below the catalogue's 0.6 (first slice, length in slices,
smallest porosity) by either measure. The exact slice volumes are `dem.sections.slab_volume`.
"""

import math
import tomllib

import numpy as np

from dem.sections import slab_volume
from eulag import slug as S

CASE = "results/strauss-filled/grain-weights/cross-section/vs1_10s.toml"

c = S.validate_slug_case(tomllib.loads(open(CASE, encoding="utf-8").read()))
sim = S._Simulation(c)
state, _ = S.read_state(c["initial"]["state"], c)
sim.start_from(state)
g, grid = sim.grains, sim.grid
n = g.n
phi, _ = sim.transfer.porosity_velocity(g.pos[:n], g.vel[:n], g.status[:n])
phi_grid = (phi * grid.area[None]).sum(axis=(1, 2)) / grid.cross_area
x = g.pos[:n][g.status[:n] == sim.FREE, 0]
lx = grid.lx
solid = np.array([slab_volume(x - (i + 0.5) * lx, 0.5 * sim.d, lx).sum() for i in range(grid.nx)])
phi_exact = 1.0 - solid / (math.pi * sim.Rt ** 2 * lx)


def runs(p, limit=S.SLUG_POROSITY):
    out, i = [], 0
    while i < len(p):
        if p[i] < limit:
            j = i
            while j + 1 < len(p) and p[j + 1] < limit:
                j += 1
            out.append((i, j - i + 1, round(float(p[i:j + 1].min()), 3)))
            i = j + 1
        else:
            i += 1
    return out


print(f"state t = 13.25 s, {x.size} grains in the tube, slices of {1e3 * lx:.2f} mm")
print("slice  gas cells  volume-weighted")
for i in np.flatnonzero(np.minimum(phi_grid, phi_exact) < 0.7):
    print(f"{i:5d}  {phi_grid[i]:9.3f}  {phi_exact[i]:15.3f}")
print(f"largest difference where either is below 0.7: "
      f"{np.abs(phi_grid - phi_exact)[np.minimum(phi_grid, phi_exact) < 0.7].max():.3f}; "
      f"tube mean {phi_grid.mean():.4f} against {phi_exact.mean():.4f}")
print(f"runs below {S.SLUG_POROSITY} (first slice, slices, smallest porosity):")
print(f"  gas cells:       {runs(phi_grid)}")
print(f"  volume-weighted: {runs(phi_exact)}")
