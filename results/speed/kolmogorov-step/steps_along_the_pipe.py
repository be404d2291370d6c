"""Where a pass of scene h spends its steps: segments sampled per parcel per station, and the
step limits of the default rule (T_L, axial crossing, 0.1/f_coll) along the pipe."""
import numpy as np, numba
from eulag.config import Case
from eulag.coupling import CouplingLoop
from particles.tracking import track
from particles import layout as L
case = Case.from_file("cases/scenes/scene_h.toml").replace(
    numerics={"parcels": 6000, "parcels_start": 6000, "max_passes": 4, "average_passes": 1})
loop = CouplingLoop(case, stream=False)
for _ in range(2):
    loop.step()
s = track(loop.mesh, loop.gas, loop.spec, loop.physics, parcels=30000, seed=1, pass_index=5, stats=loop.stats,
          settings=loop.settings)
v = s.visits.reshape(loop.mesh.shape).sum(axis=(1, 2)) / 30000
wn = s._acc(L.A_WN).reshape(loop.mesh.shape).sum(axis=(1, 2))  # sum N dt over the section
g = loop.gas
k = np.asarray(g.k).reshape(loop.mesh.shape); e = np.asarray(g.epsilon).reshape(loop.mesh.shape)
vol = np.asarray(loop.mesh.volumes()).reshape(loop.mesh.shape) if hasattr(loop.mesh, "volumes") else None
st = np.asarray(loop.stats)
print("CS columns:", [n for n in dir(L) if n.startswith("CS_")])
for name in [n for n in dir(L) if n.startswith("CS_")]:
    pass
freq = None
for cand in ("CS_FREQ", "CS_FC", "CS_F"):
    if hasattr(L, cand):
        freq = st[:, getattr(L, cand)].reshape(loop.mesh.shape); print("freq column", cand); break
x = np.asarray(loop.mesh.x)
print(" x [m]   segs/parcel/station   T_L=0.24(2k/3)/eps median [ms]   k axis   0.1/f median [ms]")
for i in list(range(0, 40, 4)) + list(range(40, 400, 40)):
    tl = np.median(0.24 * (2.0 * k[i] / 3.0) / e[i]) * 1e3  # T_L = C_T (2k/3)/eps, as the kernel
    fc = (np.median(0.1 / np.maximum(freq[i], 1e-9)) * 1e3) if freq is not None else float('nan')
    print(f"{x[i]:6.3f} {v[i]:10.1f} {tl:12.2f} {k[i,0,0]:10.3f} {fc:12.3f}")
print("total segments per parcel", v.sum(), "first 76 stations", v[:76].sum())
