"""Swing of the returned partner momentum on a cheap proxy of the base case.
Usage: python run_swing.py TAG [key=value ...]  (numerics/physics overrides as sec.key=value)"""
import json, sys, time
from pathlib import Path
from eulag.config import CASES_DIR, Case
from eulag.coupling import CouplingLoop
tag = sys.argv[1]
over = {}
import eulag.coupling as _cp
for kv in sys.argv[2:]:
    k, v = kv.split("=")
    sec, key = k.split(".")
    if sec == "coupling":
        setattr(_cp, key, float(v))
        continue
    try:
        v = json.loads(v)
    except Exception:
        pass
    over.setdefault(sec, {})[key] = v
base = Case.from_toml(CASES_DIR / "tsuji_morikawa_200um.toml")
num = {"axial_cells": 40, "radial_cells": 10, "azimuthal_cells": 20, "parcels": 8000,
       "parcels_start": 8000, "batch_size": 250, "max_passes": 100}
num.update(over.pop("numerics", {}))
phys = {"partner_momentum": "returned"}
phys.update(over.pop("physics", {}))
case = base.replace(name=f"swing_{tag}", numerics=num, physics=phys, **over)
out = Path(__file__).parent / f"swing_{tag}.jsonl"
out.unlink(missing_ok=True)
loop = CouplingLoop(case)
t0 = time.perf_counter()
def prog(s):
    h = loop.history
    cm = h.collision_momentum[-1] if h.collision_momentum else float("nan")
    rec = {"pass": s.index, "cm": cm, "dpdx": s.pressure_gradient, "alpha": s.relaxation,
           "res": s.residual, "t": time.perf_counter() - t0}
    with out.open("a") as f:
        f.write(json.dumps(rec) + "\n")
loop.progress = prog
loop.run()
print("passes", len(loop.history.residual), "stop", getattr(loop, "stop_reason", None), flush=True)
