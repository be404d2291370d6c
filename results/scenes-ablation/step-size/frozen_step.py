"""The particle step at frozen gas: one Lagrangian pass in the gas of a coupling checkpoint's
relaxed sources (the gas its next pass would run in) with its collision statistics, tracked at
several step factors with the same seed, so that only the step differs (the coupled runs of
this folder also differ in their random paths and in where the loop stopped).

    python frozen_step.py CHECKPOINT FACTORS [--rule default|paper] [--parcels N]

CHECKPOINT: a coupling checkpoint of any case (its case is read from it); FACTORS: comma-separated
step factors.  Prints one markdown row per factor: steps, wall rebounds and inter-particle
collisions per parcel, the section-integrated axial momentum source (minus the fluid impulse
on the particles), the vertical fluid impulse, and the axial momentum the wall and the
inter-particle collisions take from the particles.
"""
import argparse
import dataclasses
import time

import numpy as np

from eulag.config import Case
from eulag.coupling import CouplingLoop, read_checkpoint

ap = argparse.ArgumentParser()
ap.add_argument("checkpoint")
ap.add_argument("factors")
ap.add_argument("--rule", default=None)
ap.add_argument("--parcels", type=int, default=None)
ap.add_argument("--seed", type=int, default=7)
a = ap.parse_args()

meta, _ = read_checkpoint(a.checkpoint)
case = Case.from_attrs(meta["case"])
loop = CouplingLoop(case, checkpoint=a.checkpoint, resume=True)
# a finished run's checkpoint holds the solve on the final passes' averaged sources, not the gas
# its statistics were sampled in; the solve on the relaxed sources is that gas (to the tolerance)
gas, _, _ = loop._solve_gas(loop._gas_sources(loop.sources))
phys = loop.physics if a.rule is None else dataclasses.replace(loop.physics, step_rule=a.rule)
parcels = a.parcels or case.numerics.parcels_start
print(f"checkpoint {a.checkpoint}: pass {meta['pass_index']}, grid {'x'.join(map(str, loop.mesh.shape))}, "
      f"{parcels} parcels, step rule {phys.step_rule}, seed {a.seed}")
print("| step factor | steps / parcel | wall rebounds / parcel | collisions / parcel | axial momentum "
      "source [N] | vertical fluid impulse [N] | wall, axial [N] | collisions, axial [N] | time [s] |")
print("|---|---|---|---|---|---|---|---|---|")
for f in (float(v) for v in a.factors.split(",")):
    settings = dataclasses.replace(loop.settings, step_factor=f)
    t = time.perf_counter()
    s = loop.tracker(loop.mesh, gas, loop.spec, phys, parcels=parcels, seed=a.seed, pass_index=10_000,
                     stats=loop.stats, settings=settings)
    if case.numerics.mirror_symmetry:
        s = s.mirror_symmetrised()
    t = time.perf_counter() - t
    b, c = s.budget, s.counts
    n = c["injected"]
    sx = float(np.sum(s.momentum_source(0) * s.volume))
    print(f"| {f:g} | {c['steps'] / n:.0f} | {c['wall_rebounds'] / n:.3f} | {c['particle_collisions'] / n:.1f} | "
          f"{sx:.4f} | {b['fluid_impulse'][1]:.4f} | {b['wall_collisions'][0]:.4f} | "
          f"{b['particle_collisions'][0]:.4f} | {t:.0f} |", flush=True)
