"""The nodes' porosity of relaxed packings with either tent weights (dem.transfer).

    python results/strauss-filled/grain-weights/porosity_check.py   (from the repository root)

800 and 900 grains relaxed in a periodic 7 cm segment of the 7 mm tube
(dem.feed.relaxed_packing, seed 3), on the paper's gas grid (2 x 2 nodes of 3.5 mm across, 20
along). Printed: the sum of the 2 x 2 cross-section tents on the circle the centres can reach
(r = R_t - R; 1 away from the wall), and per packing the true porosity, the share of the centres
within 0.1 d of that circle, the nodes' mean, smallest and largest porosity with each weighting,
and the Carman-Kozeny resistance per grain at the nodes' mean porosity over that at the true
one, (1 - phi)/phi^3 (Darcy drag V_p grad P/(1 - phi) with kappa = d^2 phi^3/(180 (1 - phi)^2)).
"""

import math

import numpy as np

from dem import FREE, TentTransfer
from dem.feed import relaxed_packing

RT, D = 3.5e-3, 1.4e-3
R = 0.5 * D
L = 0.07


def tent(s):
    return np.clip(1.0 - np.abs(s), 0.0, None)


th = np.linspace(0.0, 2.0 * np.pi, 3601)
y, z = (RT - R) * np.sin(th), (RT - R) * np.cos(th)
nodes = np.array([-0.5 * RT, 0.5 * RT])
ssum = sum(tent((y - nb) / RT) for nb in nodes) * sum(tent((z - nc) / RT) for nc in nodes)
print(f"sum of the cross-section tents at r = R_t - R: {ssum.min():.3f}-{ssum.max():.3f}")


def resistance(phi):
    return (1.0 - phi) / phi**3


for n in (800, 900):
    pos = relaxed_packing(n, L, RT, D, 937.0, 1000.0, 3)
    true = 1.0 - n * (4.0 / 3.0 * math.pi * R**3) / (math.pi * RT**2 * L)
    r = np.hypot(pos[:, 1], pos[:, 2])
    print(f"{n} grains: true porosity {true:.4f}; centres within 0.1 d of r = R_t - R: "
          f"{np.mean(r > RT - R - 0.1 * D):.2f}")
    for weights in ("grain", "tent"):
        tr = TentTransfer(20, 2, L, RT, R, periodic=True, weights=weights)
        phi, _ = tr.porosity_velocity(pos, np.zeros((n, 3)), np.full(n, FREE, dtype=np.int8))
        print(f"  {weights:5s}: nodes' porosity mean {phi.mean():.4f}, smallest {phi.min():.3f}, "
              f"largest {phi.max():.3f}; resistance per grain {resistance(phi.mean()) / resistance(true):.3f} "
              f"of the true porosity's")
