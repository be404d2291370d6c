import numpy as np, json, sys, glob
from eulag.config import Case
from eulag.coupling import build_mesh
with np.load("/tmp/fx/h.ckpt", allow_pickle=False) as z:
    m = json.loads(bytes(z["meta"]).decode())
mesh = build_mesh(Case.from_attrs(m["case"]))
V = np.asarray(mesh.volume).reshape(400, 20, 40)
files = sorted(glob.glob("/tmp/fx/frozen_*_30000_*.npz"))
for f in files:
    d = np.load(f)
    mo = (d["momentum"] * V).reshape(3, -1).sum(-1)
    k = (d["k"] * V).sum()
    # lower-half vs upper-half vertical source at the station region
    ix = slice(350, 360)
    sy = d["momentum"][1, ix] * V[ix]
    print(f.split("frozen_")[1][:-4].ljust(40), "Sx %.4f Sy %.4f Sk %.4f  drag %.3f" % (mo[0], mo[1], k, (d["drag"] * V).sum()), " station Sy %.5f" % sy.sum())
