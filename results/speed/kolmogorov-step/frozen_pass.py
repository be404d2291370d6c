"""One pass of scene h in a frozen gas, step rule default against the T_L of the step bounded below
by the Kolmogorov time sqrt(nu/eps): time, segments, and the sources cell by cell against their errors."""
import time, dataclasses, numpy as np, numba
from eulag.config import Case
from eulag.coupling import CouplingLoop
from particles.tracking import track
from particles import layout as L
case = Case.from_file("cases/scenes/scene_h.toml").replace(
    numerics={"parcels": 6000, "parcels_start": 6000, "max_passes": 4, "average_passes": 1})
loop = CouplingLoop(case, stream=False)
for _ in range(2):
    loop.step()
res = {}
for rule in ("default", "kolmogorov", "default", "kolmogorov"):
    ph = dataclasses.replace(loop.physics, step_rule=rule)
    for seed in (1, 2):
        t = time.perf_counter()
        s = track(loop.mesh, loop.gas, loop.spec, ph, parcels=30000, seed=seed, pass_index=5, stats=loop.stats, settings=loop.settings)
        w = time.perf_counter() - t
        if (rule, seed) not in res:
            res[(rule, seed)] = s
        print(f"{rule:10s} seed {seed}: {w:6.1f} s, segments/parcel {s.visits.sum() / 30000:8.0f}", flush=True)
    if len(res) == 4:
        break
x = np.asarray(loop.mesh.x)
def comp(a, b, label):
    out = []
    for name, f, fe in (("S_x", lambda s: s.momentum_source(0), lambda s: s.momentum_source_stderr(0)),
                        ("S_y", lambda s: s.momentum_source(1), lambda s: s.momentum_source_stderr(1)),
                        ("S_z", lambda s: s.momentum_source(2), lambda s: s.momentum_source_stderr(2)),
                        ("S_k", lambda s: s.k_source, lambda s: s.k_source_stderr),
                        ("conc", lambda s: s.concentration, lambda s: s.concentration_stderr)):
        fa, fb = f(a), f(b)
        fa = fa() if callable(fa) else fa; fb = fb() if callable(fb) else fb
        ea, eb = fe(a), fe(b)
        ea = ea() if callable(ea) else ea; eb = eb() if callable(eb) else eb
        den = np.sqrt(ea ** 2 + eb ** 2)
        ok = den > 0
        z = np.where(ok, (fa - fb) / np.where(ok, den, 1), 0.0)
        vol = np.asarray(a.volume)
        regions = []
        for x0, x1 in ((0, 0.5), (0.5, 4.0), (3.5, 3.6)):
            m = (x >= x0) & (x < x1)
            ia, ib = (fa * vol)[m].sum(), (fb * vol)[m].sum()
            ie = np.sqrt(((ea * vol)[m] ** 2).sum() + ((eb * vol)[m] ** 2).sum())
            regions.append(f"[{x0}-{x1}] {ia:.4g} vs {ib:.4g} ({(ia - ib) / ie:+.1f} se)")
        out.append(f"  {name}: cell RMS of diff/se {np.sqrt(np.mean(z[ok] ** 2)):.2f}; integrals " + "; ".join(regions))
    print(label); print("\n".join(out), flush=True)
comp(res[("default", 1)], res[("default", 2)], "default seed 1 vs default seed 2 (noise)")
comp(res[("kolmogorov", 1)], res[("kolmogorov", 2)], "kolmogorov seed 1 vs kolmogorov seed 2 (noise)")
comp(res[("default", 1)], res[("kolmogorov", 2)], "default seed 1 vs kolmogorov seed 2 (independent seeds)")
comp(res[("default", 2)], res[("kolmogorov", 1)], "default seed 2 vs kolmogorov seed 1 (independent seeds)")
comp(res[("default", 1)], res[("kolmogorov", 1)], "default vs kolmogorov, seed 1 (shared draws until the paths part)")
comp(res[("default", 2)], res[("kolmogorov", 2)], "default vs kolmogorov, seed 2 (shared draws until the paths part)")
