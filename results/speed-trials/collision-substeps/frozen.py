"""One Lagrangian pass in the frozen gas and collision statistics of a coupling checkpoint.

    python frozen.py CKPT PARCELS RULE[@FACTOR],... [SEED]

RULE: a numerics.step_rule ("default", "paper", or the trial's "collision-substeps");
FACTOR: numerics.step_factor.  Environment: PM = physics.partner_momentum for the pass
("discarded" / "returned"); EULAG_SUBSTEP_TRAJ, EULAG_WALL_APPROACH: the trial kernel's switches
(kernel.patch).  Prints the particle momentum budget [N] and saves the sampled sources.
"""
import dataclasses
import json
import os
import sys
import time

import numpy as np

from eulag.config import Case
from eulag.coupling import CouplingLoop

ck, parcels, rules = sys.argv[1], int(sys.argv[2]), sys.argv[3].split(",")
seed = int(sys.argv[4]) if len(sys.argv) > 4 else 1
with np.load(ck, allow_pickle=False) as z:
    case = Case.from_attrs(json.loads(bytes(z["meta"]).decode())["case"])
loop = CouplingLoop(case, checkpoint=ck, resume=True)
print("loaded pass", loop.pass_index, flush=True)
for rr in rules:
    rule, _, fac = rr.partition("@")
    extra = {"partner_momentum": os.environ["PM"]} if "PM" in os.environ else {}
    phys = dataclasses.replace(loop.physics, step_rule=rule, **extra)
    settings = dataclasses.replace(loop.settings, step_factor=float(fac)) if fac else loop.settings
    label = rr
    if rule != "default":
        label += ("~" + os.environ["EULAG_SUBSTEP_TRAJ"]) if "EULAG_SUBSTEP_TRAJ" in os.environ else ""
        label += "+wa" if os.environ.get("EULAG_WALL_APPROACH") == "1" else ""
    label += ("#" + os.environ["PM"]) if "PM" in os.environ else ""
    t = time.perf_counter()
    s = loop.tracker(loop.mesh, loop.gas, loop.spec, phys, parcels=parcels, seed=seed, pass_index=500 + seed,
                     stats=loop.stats, settings=settings)
    dt = time.perf_counter() - t
    c = s.counts
    b = s.budget
    print(label, f"time {dt:.1f} s, steps per parcel {c['steps'] / parcels:.0f}, "
                 f"collisions per parcel {c['particle_collisions'] / parcels:.1f}", flush=True)
    for i, ax in ((1, "y"), (0, "x")):
        print(f"  budget {ax}:", {k: round(float(v[i]), 5) for k, v in b.items() if hasattr(v, "__len__")})
    s = s.mirror_symmetrised()
    src = loop._computed_sources(s)
    np.savez(f"/tmp/fx/frozen_{label}_{parcels}_{seed}.npz",
             **{k: np.asarray(v) for k, v in src.items() if v is not None})
