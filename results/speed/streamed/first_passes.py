"""Per-pass wall time of scene SCENE's first N passes, passes tracked after / beside the gas march."""
import sys, time, json
import numba
from eulag.config import Case
from eulag.coupling import CouplingLoop
scene, npass, mode = sys.argv[1], int(sys.argv[2]), sys.argv[3]
case = Case.from_file(f"cases/scenes/scene_{scene}.toml")
case = case.replace(numerics={"max_passes": npass + 1, "average_passes": 1, "parcels": 30000})
loop = CouplingLoop(case, stream=(mode == "stream"))
t0 = time.perf_counter(); rows = []
for i in range(npass):
    t = time.perf_counter(); st = loop.step()
    rows.append((st.index, round(time.perf_counter() - t, 2), round(st.times["gas_solve"], 2), round(st.times["lagrangian"], 2), st.pressure_gradient))
    print(mode, rows[-1], flush=True)
print(mode, "total", round(time.perf_counter() - t0, 1), json.dumps({k: round(v, 1) for k, v in loop.timings.items()}), "streamed", loop.streamed, flush=True)
