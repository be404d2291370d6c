"""The scene-h proxy with the paper's step rule, run up to 80 passes (the ablation's run stopped
unconverged at 40)."""
import json, time
from pathlib import Path
from eulag.config import CASES_DIR, Case
from eulag.studies.ablation import PROXY_NUMERICS, extract_metrics
from eulag import runs

base = Case.from_toml(CASES_DIR / "scenes" / "scene_h.toml").replace(numerics=PROXY_NUMERICS)
name = "proxy_h__step_rule-paper__max_passes-80"
case = base.replace(name=name, numerics={"step_rule": "paper", "max_passes": 80})
out = Path(__file__).parent / f"{name}.nc"
t = time.perf_counter()
res = runs.execute(case, out, resume=True, notify=print,
                   progress=lambda s: print(f"pass {s.index}: -dp/dx {s.pressure_gradient:.2f}", flush=True) if hasattr(s, "index") else None)
m = extract_metrics(res.dataset, case)
m.update(time=time.perf_counter() - t, stop_reason=str(res.dataset.attrs.get("stop_reason")))
Path(out.with_suffix(".json")).write_text(json.dumps(m, indent=1, default=str))
print(name, json.dumps({k: m[k] for k in ("cells", "sense", "strength", "interior", "dpdx", "k_axis", "coll_y", "stop_reason", "time")}, default=str))
