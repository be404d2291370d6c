"""How many grains of a filled tube the plain tent sums of eq. 9 reach with weights summing to
less than one: the grains in the tube of results/strauss/state_horizontal_t13.25.npz (3,056
grains, the filled tube the study continues from), on the paper's 2 x 2 cross-section grid
(node rows at |y|, |z| = D_t/4 = 1.75 mm, spacing 3.5 mm).

    python results/strauss-filled/grain-weights/tent_sum_share.py   (from the repository root)
"""

from pathlib import Path

import numpy as np

from dem import FREE

STATE = Path(__file__).resolve().parents[2] / "strauss" / "state_horizontal_t13.25.npz"
L, RT = 0.525, 3.5e-3
LT = RT  # node spacing across the 2 x 2 grid: D_t / 2

with np.load(STATE, allow_pickle=False) as z:
    pos, status = z["g_pos"], z["g_status"]
inside = (status == FREE) & (pos[:, 0] >= 0.0) & (pos[:, 0] < L)
y, zc = np.abs(pos[inside, 1]), np.abs(pos[inside, 2])
half = 0.5 * LT  # the node rows
s = np.minimum(1.0, 1.0 - (y - half) / LT) * np.minimum(1.0, 1.0 - (zc - half) / LT)
print(f"grains in the tube {inside.sum()}; outside the square of the node rows {np.mean(s < 1):.3f}; "
      f"cross-section tent sum: mean {s.mean():.3f}, min {s.min():.3f}, share below 0.9 {np.mean(s < 0.9):.3f}")
