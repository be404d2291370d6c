"""How many grains of a filled tube the plain tent sums of eq. 9 reach with weights summing to
less than one: the grains in the tube of results/strauss/state_horizontal_t13.25.npz (3,056
grains, the filled tube the study continues from), on the paper's 150 x 2 x 2 grid.  The sum of
each grain's weights is the printed interpolation (dem.transfer, ``interpolation = "printed"``)
of a field of ones; the tube is taken as periodic so that the axial factor is one everywhere
and only the cross-section remains.

    python results/strauss-filled/grain-weights/tent_sum_share.py   (from the repository root)
"""

from pathlib import Path

import numpy as np

from dem import FREE
from dem.transfer import TentTransfer

STATE = Path(__file__).resolve().parents[2] / "strauss" / "state_horizontal_t13.25.npz"
L, RT, R = 0.525, 3.5e-3, 0.7e-3  # tube length and radius, grain radius [m] (SMH §3)

with np.load(STATE, allow_pickle=False) as z:
    pos, status = z["g_pos"], z["g_status"]
inside = (status == FREE) & (pos[:, 0] >= 0.0) & (pos[:, 0] < L)
tr = TentTransfer(150, 2, L, RT, R, periodic=True, interpolation="printed")
s = tr.to_grains(pos[inside], status[inside], np.ones((150, 2, 2, 1)))[:, 0]
below = s < 1.0 - 1e-12
print(f"grains in the tube {inside.sum()}; outside the square of the node rows {np.mean(below):.3f}; "
      f"cross-section tent sum: mean {s.mean():.3f}, min {s.min():.3f}, share below 0.9 {np.mean(s < 0.9):.3f}")
