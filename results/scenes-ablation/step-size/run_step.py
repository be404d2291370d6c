"""Step-size convergence of the 50 um scene-e proxy: the default and the paper's step rule at
step factors 0.5 (the ablation's runs) and below.  Usage: python run_step.py RULE FACTOR"""
import json, sys, time
from pathlib import Path
from eulag.config import CASES_DIR, Case
from eulag.studies.ablation import PROXY_NUMERICS, extract_metrics
from eulag import runs

rule, factor = sys.argv[1], float(sys.argv[2])
scene = sys.argv[3] if len(sys.argv) > 3 else "e"
base = Case.from_toml(CASES_DIR / "scenes" / f"scene_{scene}.toml").replace(numerics={**PROXY_NUMERICS, "max_passes": 80})
name = f"proxy_{scene}__step_rule-{rule}__step_factor-{factor:g}"
case = base.replace(name=name, numerics={"step_rule": rule, "step_factor": factor})
out = Path(__file__).parent / f"{name}.nc"
t = time.perf_counter()
res = runs.execute(case, out, resume=True)
m = extract_metrics(res.dataset, case)
stop = str(res.dataset.attrs.get("stop_reason", ""))
m.update(time=time.perf_counter() - t, converged=stop.startswith("converged"), stop_reason=stop,
         passes=int(res.dataset.sizes.get("iteration", 0)))
Path(out.with_suffix(".json")).write_text(json.dumps(m, indent=1, default=str))
print(name, json.dumps({k: m[k] for k in ("cells", "sense", "strength", "interior", "dpdx", "k_axis", "coll_y", "converged", "passes", "time")}, default=str))
