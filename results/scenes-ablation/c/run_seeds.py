"""Seed replicas of the scene-c proxy: eulag, magnus_lift=false, langevin_drift_correction=false."""
import json, sys
from pathlib import Path
from eulag import runs
from eulag.studies.ablation import ablation_cases
from eulag.studies.patterns import pattern_columns
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path('.')
labels = ['eulag', 'magnus_lift=false', 'langevin_drift_correction=false']
for seed in (2, 3):
    for name, scene, label, case in ablation_cases(False, 'c', labels):
        case = case.replace(name=f"{name}__seed{seed}", numerics={'seed': seed})
        f = out / f"{name}__seed{seed}.nc"
        res = runs.execute(case, f, resume=True)
        pc = pattern_columns(res.dataset, 3.56)
        row = {'label': label, 'seed': seed, 'converged': res.converged, **pc}
        print(json.dumps(row), flush=True)
        with open(out / 'rows.jsonl', 'a') as fh:
            fh.write(json.dumps(row) + '\n')
