import sys, json, time, numpy as np
from eulag.config import Case, CASES_DIR
from eulag.studies.ablation import PROXY_NUMERICS
from eulag import coupling
scene, flag, seed = sys.argv[1], sys.argv[2] == 'second', int(sys.argv[3])
coupling.RETURN_FROM_SECOND_PASS = flag
path = CASES_DIR / ('tsuji_morikawa_200um.toml' if scene == 'base' else f'scenes/scene_{scene}.toml')
c = Case.from_toml(path).replace(numerics={**PROXY_NUMERICS, 'max_passes': 80, 'seed': seed})
loop = coupling.CouplingLoop(c)
t = time.perf_counter()
for st in loop:
    pass
h = loop.history
out = dict(scene=scene, flag=sys.argv[2], seed=seed, passes=loop.pass_index, converged_at=loop.converged_at, converged=loop.converged,
           dpdx_last=h.pressure_gradient[-1], dpdx_mean_final=float(np.mean(h.pressure_gradient[-3:])),
           cm=[round(v, 4) for v in h.collision_momentum], time=time.perf_counter() - t)
print(json.dumps(out))
open(f'{scene}_{sys.argv[2]}_{seed}.json', 'w').write(json.dumps(out))
