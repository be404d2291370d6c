"""Anderson mixing (Walker & Ni 2011, type II) of the coupling loop's relaxed sources: trial code.
Env AA_M (depth, default 5), AA_GMAX (restart when sum|gamma| exceeds, default 10), AA_START (first
pass mixed, default 12). The collision statistics and the returned acceleration relax as shipped."""
import os, math
import numpy as np
import eulag.coupling as C

M = int(os.environ.get("AA_M", "5"))
GMAX = float(os.environ.get("AA_GMAX", "10"))
START = int(os.environ.get("AA_START", "12"))
_orig = C.CouplingLoop._relax


def _carried(self):
    prev = dict(self.sources)
    k = np.where(prev["k"] < 0.0, prev["k"] * (self.gas.k / prev["k_ref"]), prev["k"])
    return prev["momentum"], k


def _relax(self, comp, sample, alpha):
    new, residual = _orig(self, comp, sample, alpha)
    st = getattr(self, "_aa", None)
    if st is None:
        st = self._aa = {"X": [], "F": [], "alpha": None, "pass": None, "log": []}
    if st["pass"] == self.pass_index and st["X"]:  # a retry of this pass at a smaller alpha
        st["X"].pop(); st["F"].pop()
    st["pass"] = self.pass_index
    if self.sources is None or self.phase != "early" or self.pass_index < START:
        st["X"].clear(); st["F"].clear()
        return new, residual
    if st["alpha"] != alpha:
        st["X"].clear(); st["F"].clear()
        st["alpha"] = alpha
    mom, k = _carried(self)
    x = np.concatenate([mom.ravel(), k.ravel()])
    g = np.concatenate([comp["momentum"].ravel(), comp["k"].ravel()])
    f = g - x
    scale_m = np.sqrt(np.mean(comp["momentum"] ** 2)); scale_k = np.sqrt(np.mean(comp["k"] ** 2))
    sm = np.where(np.isfinite(comp["se_momentum"]), comp["se_momentum"], 0.0)
    sk = np.where(np.isfinite(comp["se_k"]), comp["se_k"], 0.0)
    sm = np.maximum(sm, C._FLOOR * scale_m + 1e-300); sk = np.maximum(sk, C._FLOOR * scale_k + 1e-300)
    w = 1.0 / np.concatenate([sm.ravel(), sk.ravel()])
    X, F = st["X"], st["F"]
    xnew = x + alpha * f
    gamma = None
    if X:
        dX = np.stack([x - X[-1]] + [X[i + 1] - X[i] for i in range(len(X) - 1)][::-1], axis=1)
        dF = np.stack([f - F[-1]] + [F[i + 1] - F[i] for i in range(len(F) - 1)][::-1], axis=1)
        A = dF * w[:, None]
        b = f * w
        AtA = A.T @ A
        lam = 1e-10 * np.trace(AtA)
        gamma = np.linalg.solve(AtA + lam * np.eye(AtA.shape[0]), A.T @ b)
        if np.sum(np.abs(gamma)) > GMAX:
            st["log"].append((self.pass_index, "restart", gamma.tolist()))
            X.clear(); F.clear()
            gamma = None
        else:
            xnew = xnew - (dX + alpha * dF) @ gamma
    X.append(x); F.append(f)
    if len(X) > M:
        X.pop(0); F.pop(0)
    n_m = mom.size
    new["momentum"] = xnew[:n_m].reshape(mom.shape)
    new["k"] = xnew[n_m:].reshape(k.shape)
    print(f"   AA pass {self.pass_index} alpha {alpha:g} depth {len(X)} gamma "
          + ("-" if gamma is None else " ".join(f"{v:+.3f}" for v in gamma)), flush=True)
    return new, residual


C.CouplingLoop._relax = _relax
print("anderson depth", M, "gmax", GMAX, flush=True)
