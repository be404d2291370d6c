"""Seed replicas of a scene proxy: python run_seeds.py OUTDIR [SCENE [LABELS]] (default: c; eulag, magnus_lift=false, langevin_drift_correction=false)."""
import json, sys
from pathlib import Path
from eulag import runs
from eulag.studies.ablation import ablation_cases
from eulag.studies.ablation import extract_metrics
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path('.')
SCENE = sys.argv[2] if len(sys.argv) > 2 else 'c'
labels = sys.argv[3].split(',') if len(sys.argv) > 3 else ['eulag', 'magnus_lift=false', 'langevin_drift_correction=false']
for seed in (2, 3):
    for name, scene, label, case in ablation_cases(False, SCENE, labels):
        case = case.replace(name=f"{name}__seed{seed}", numerics={'seed': seed})
        f = out / f"{name}__seed{seed}.nc"
        res = runs.execute(case, f, resume=True)
        m = extract_metrics(res.dataset, case)
        row = {'label': label, 'seed': seed, 'converged': res.converged,
               **{k: m.get(k) for k in ('pattern_cells_sym', 'pattern_index', 'uy_pattern', 'sense', 'strength',
                                        'interior', 'dpdx', 'k_axis')}}
        print(json.dumps(row), flush=True)
        with open(out / 'rows.jsonl', 'a') as fh:
            fh.write(json.dumps(row) + '\n')
