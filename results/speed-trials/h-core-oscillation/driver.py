"""Proxy of scene h (eulag.studies.ablation.PROXY_NUMERICS): the coupling loop pass by pass,
with the per-pass correlation of the normalised source changes with the previous pass's and
the gas k at the station (x = 3.55 m; axis ring, section mean, wall ring).

    python driver.py VARIANT SCENE SEED MAX_PASSES [THRESHOLD]     (from the repository root)

VARIANT: ``base`` the loop as shipped; ``corr`` alpha is not halved while the last pass's
correlation is above THRESHOLD (-1: never halved); ``a0.15`` the case's relaxation 0.15.
Environment: RG=<gain> sets coupling.RETURNED_GAIN; DISC=1 physics.partner_momentum =
"discarded"; KNONE=1 physics.k_source_scaling = "none"; W1=1 numerics.drag_implicit_weight = 1.
Trial code, not part of the product."""
import sys, json, math, time
import numpy as np
from eulag.config import Case
from eulag import coupling
from eulag.studies.ablation import PROXY_NUMERICS

variant, scene, seed, maxp = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
thr = float(sys.argv[5]) if len(sys.argv) > 5 else 0.1
base = Case.from_toml(f"cases/scenes/scene_{scene}.toml")
num = dict(PROXY_NUMERICS); num["max_passes"] = maxp; num["seed"] = seed
if variant.startswith("a0"): num["relaxation"] = float(variant[1:])
case = base.replace(numerics=num)
import os
if os.environ.get("RG"): coupling.RETURNED_GAIN = float(os.environ["RG"])
if os.environ.get("KNONE"): case = case.replace(physics={"k_source_scaling": "none"})
if os.environ.get("W1"): case = case.replace(numerics={"drag_implicit_weight": 1.0})
if os.environ.get("DISC"): case = case.replace(physics={"partner_momentum": "discarded"})

class Loop(coupling.CouplingLoop):
    corr = []
    _z = None
    def _relax(self, comp, sample, alpha):
        new, res = super()._relax(comp, sample, alpha)
        if self.sources is not None:
            # recompute z as in the parent
            prev = dict(self.sources)
            prev["k"] = np.where(prev["k"] < 0.0, prev["k"] * (self.gas.k / prev["k_ref"]), prev["k"])
            fac = alpha * math.sqrt(2.0 / (2.0 - alpha))
            ratios = []
            for d, se in ((new["momentum"] - prev["momentum"], comp["se_momentum"]), (new["k"] - prev["k"], comp["se_k"])):
                scale = np.sqrt(np.mean(new["momentum"] ** 2)) if d.ndim == 4 else np.sqrt(np.mean(new["k"] ** 2))
                noise = np.where(np.isfinite(se), fac * se, 0.0)
                noise = np.maximum(noise, coupling._FLOOR * scale + 1e-300)
                ratios.append((d / noise).ravel())
            z = np.concatenate(ratios)
            c = math.nan
            if self._z is not None:
                c = float(np.corrcoef(z, self._z)[0, 1])
            self._z = z
            self.corr.append(c)
        else:
            self.corr.append(math.nan)
        return new, res
    def _adapt_relaxation(self):
        if variant == "corr" and len(self.corr) and self.corr[-1] > thr:
            # the loop's changes persist from pass to pass: a systematic approach, which a
            # halved alpha would only slow
            r = np.asarray(self.history.residual[self.alpha_changed_at:], float)
            r = r[np.isfinite(r)]
            w = coupling._STAGNATION_WINDOW
            if r.size >= 2 * w and np.all(r[-w:] >= case.numerics.coupling_tolerance):
                return
        return super()._adapt_relaxation()

t0 = time.time()
loop = Loop(case)
loop.progress = None
rows = []
for st in loop:
    c = loop.corr[-1] if loop.corr else math.nan
    rows.append((st.index, st.relaxation, st.residual, st.pressure_gradient, c, st.phase))
    g = loop.gas; ix = -5
    kax = float(np.mean(g.k[ix, 0])); kwall = float(np.mean(g.k[ix, -1])); kmean = float(np.mean(g.k[ix]))
    fl = int(np.sum(g.floored)) if g.floored is not None else 0
    src = loop.sources
    sx = float(np.sum(src["momentum"][0])) if src else 0.0
    sk = float(np.sum(src["k"])) if src else 0.0
    print(f"{st.index:3d} a={st.relaxation:.3g} res={st.residual:.3f} dp={st.pressure_gradient:.2f} corr={c:.3f} kax={kax:.4f} kmean={kmean:.4f} kwall={kwall:.3f} fl={fl} Sx={sx:.4g} Sk={sk:.4g} {st.phase} t={time.time()-t0:.0f}", flush=True)
print("stop:", loop.stop_reason, "converged_at", loop.converged_at, "time", round(time.time() - t0))
json.dump({"rows": rows, "stop": loop.stop_reason, "converged_at": loop.converged_at,
           "time": time.time() - t0}, open(f"results/speed-trials/h-core-oscillation/{scene}_{variant}_{seed}.json", "w"))
