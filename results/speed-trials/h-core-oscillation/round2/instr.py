"""Wraps CouplingLoop._relax to print the residual's parts and the correlation of successive
normalised changes (systematic > 0, noise ~ -alpha/2)."""
import math
import numpy as np
import eulag.coupling as C

_orig = C.CouplingLoop._relax
_prev = {}

def _relax(self, comp, sample, alpha):
    new, residual = _orig(self, comp, sample, alpha)
    if self.sources is None:
        return new, residual
    prev = self.sources
    fac = alpha * math.sqrt(2.0 / (2.0 - alpha))
    parts = {}
    zs = []
    for name, d, se, ref in (("mx", new["momentum"][0] - prev["momentum"][0], comp["se_momentum"][0], new["momentum"]),
                             ("my", new["momentum"][1] - prev["momentum"][1], comp["se_momentum"][1], new["momentum"]),
                             ("mz", new["momentum"][2] - prev["momentum"][2], comp["se_momentum"][2], new["momentum"]),
                             ("k", new["k"] - np.where(prev["k"] < 0, prev["k"] * (self.gas.k / prev["k_ref"]), prev["k"]), comp["se_k"], new["k"])):
        scale = np.sqrt(np.mean(ref ** 2))
        noise = np.maximum(np.where(np.isfinite(se), fac * se, 0.0), C._FLOOR * scale + 1e-300)
        z = (d / noise).ravel()
        parts[name] = float(np.sqrt(np.mean(z * z)))
        zs.append(z)
    z = np.concatenate(zs)
    v = comp["visits"].ravel()
    dense = np.tile(v >= 300, 4)
    sparse = np.tile(v < 20, 4)
    share_dense = float(np.sum(z[dense] ** 2) / np.sum(z * z))
    share_sparse = float(np.sum(z[sparse] ** 2) / np.sum(z * z))
    corr = math.nan
    if "z" in _prev:
        a, b = _prev["z"], z
        corr = float(np.corrcoef(a, b)[0, 1])
    _prev["z"] = z
    print(f"   PARTS pass {self.pass_index} alpha={alpha:g} " + " ".join(f"{k}={v:.3g}" for k, v in parts.items())
          + f" dense_share={share_dense:.2f} sparse_share={share_sparse:.2f} corr_prev={corr:+.3f}", flush=True)
    return new, residual

C.CouplingLoop._relax = _relax
