"""The nodes' porosity of a relaxed packing with either tent weights (dem.transfer).

    python results/strauss-filled/grain-weights/porosity_check.py   (from the repository root)

900 grains relaxed in a periodic 7 cm segment of the 7 mm tube (dem.feed.relaxed_packing,
seed 3), on the paper's gas grid (2 x 2 nodes of 3.5 mm across, 20 along): the true porosity, the
nodes' mean, smallest and largest with each weighting, and the share of the centres within
0.1 d of the circle they can reach (r = R_t - R).
"""

import math

import numpy as np

from dem import FREE, TentTransfer
from dem.feed import relaxed_packing

RT, D = 3.5e-3, 1.4e-3
R = 0.5 * D
L, N = 0.07, 900

pos = relaxed_packing(N, L, RT, D, 937.0, 1000.0, 3)
true = 1.0 - N * (4.0 / 3.0 * math.pi * R**3) / (math.pi * RT**2 * L)
r = np.hypot(pos[:, 1], pos[:, 2])
print(f"true porosity {true:.4f}; centres within 0.1 d of r = R_t - R: {np.mean(r > RT - R - 0.1 * D):.2f}")
for weights in ("grain", "tent"):
    tr = TentTransfer(20, 2, L, RT, R, periodic=True, weights=weights)
    phi, _ = tr.porosity_velocity(pos, np.zeros((N, 3)), np.full(N, FREE, dtype=np.int8))
    print(f"{weights:5s}: nodes' porosity mean {phi.mean():.4f}, smallest {phi.min():.3f}, largest {phi.max():.3f}")
