"""Anderson mixing of the coupling loop's relaxed sources with the least-squares problem posed on
block means (trial code, not the product).

Walker & Ni (2011) type II, as ../h-anderson/anderson.py, but gamma minimises the residual of the
sources averaged over coarse blocks of cells (axial x radial x azimuthal groups), each block mean
weighted by its own standard error. The per-cell problem of ../h-anderson was dominated by the
passes' sampling noise (gamma came out as a running mean); a block of n cells carries 1/sqrt(n) of
a cell's noise, while a large-scale slow mode keeps its amplitude.

Env: AA_M depth (default 3), AA_START first mixed pass (default 8), AA_GMAX restart bound on
sum|gamma| (default 10), AA_BLOCKS "gx,gr,gt" block counts (default 8,2,4), AA_KEEP_ALPHA=1 keeps
the history when alpha changes (default: restart).
"""
import os
import numpy as np
import eulag.coupling as C

M = int(os.environ.get("AA_M", "3"))
GMAX = float(os.environ.get("AA_GMAX", "10"))
START = int(os.environ.get("AA_START", "8"))
GX, GR, GT = (int(v) for v in os.environ.get("AA_BLOCKS", "8,2,4").split(","))
KEEP_ALPHA = os.environ.get("AA_KEEP_ALPHA") == "1"
_orig = C.CouplingLoop._relax


def _blocks(a):
    """Block means (and block-summed squares with sq=True) of an (nx, nr, nt) array."""
    nx, nr, nt = a.shape
    ix = np.minimum(np.arange(nx) * GX // nx, GX - 1)
    ir = np.minimum(np.arange(nr) * GR // nr, GR - 1)
    it = np.minimum(np.arange(nt) * GT // nt, GT - 1)
    out = np.zeros((GX, GR, GT))
    cnt = np.zeros((GX, GR, GT))
    np.add.at(out, (ix[:, None, None], ir[None, :, None], it[None, None, :]), a)
    np.add.at(cnt, (ix[:, None, None], ir[None, :, None], it[None, None, :]), 1.0)
    return out, cnt


def _project(fields):
    """fields: list of (nx, nr, nt) arrays -> concatenated block sums."""
    return np.concatenate([_blocks(a)[0].ravel() for a in fields])


def _carried(self):
    prev = dict(self.sources)
    k = np.where(prev["k"] < 0.0, prev["k"] * (self.gas.k / prev["k_ref"]), prev["k"])
    return prev["momentum"], k


def _relax(self, comp, sample, alpha):
    new, residual = _orig(self, comp, sample, alpha)
    st = getattr(self, "_aa", None)
    if st is None:
        st = self._aa = {"X": [], "F": [], "P": [], "alpha": None, "pass": None}
    if st["pass"] == self.pass_index and st["X"]:  # a retry of this pass at a smaller alpha
        st["X"].pop(); st["F"].pop(); st["P"].pop()
    st["pass"] = self.pass_index
    if self.sources is None or self.phase != "early" or self.pass_index < START:
        st["X"].clear(); st["F"].clear(); st["P"].clear()
        return new, residual
    if st["alpha"] != alpha and not KEEP_ALPHA:
        st["X"].clear(); st["F"].clear(); st["P"].clear()
    st["alpha"] = alpha
    mom, k = _carried(self)
    x = np.concatenate([mom.ravel(), k.ravel()])
    g = np.concatenate([comp["momentum"].ravel(), comp["k"].ravel()])
    f = g - x
    fm = comp["momentum"] - mom
    fk = comp["k"] - k
    # block noise: sqrt(sum se^2) over the block (cells independent)
    sm = np.where(np.isfinite(comp["se_momentum"]), comp["se_momentum"], 0.0)
    sk = np.where(np.isfinite(comp["se_k"]), comp["se_k"], 0.0)
    noise = np.sqrt(_project([sm[0] ** 2, sm[1] ** 2, sm[2] ** 2, sk ** 2]))
    scale_m = np.sqrt(np.mean(comp["momentum"] ** 2)); scale_k = np.sqrt(np.mean(comp["k"] ** 2))
    _, cnt = _blocks(k)
    floor = np.concatenate([C._FLOOR * scale_m * np.sqrt(cnt.ravel())] * 3
                           + [C._FLOOR * scale_k * np.sqrt(cnt.ravel())]) + 1e-300
    w = 1.0 / np.maximum(noise, floor)
    p = _project([fm[0], fm[1], fm[2], fk]) * w
    X, F, P = st["X"], st["F"], st["P"]
    xnew = x + alpha * f
    gamma = None
    if X:
        dX = np.stack([x - X[-1]] + [X[i + 1] - X[i] for i in range(len(X) - 1)][::-1], axis=1)
        dF = np.stack([f - F[-1]] + [F[i + 1] - F[i] for i in range(len(F) - 1)][::-1], axis=1)
        A = np.stack([p - P[-1]] + [P[i + 1] - P[i] for i in range(len(P) - 1)][::-1], axis=1)
        AtA = A.T @ A
        lam = 1e-8 * np.trace(AtA)
        gamma = np.linalg.solve(AtA + lam * np.eye(AtA.shape[0]), A.T @ p)
        fit = 1.0 - np.sum((p - A @ gamma) ** 2) / np.sum(p ** 2)
        if np.sum(np.abs(gamma)) > GMAX:
            print(f"   AA pass {self.pass_index} restart gamma " + " ".join(f"{v:+.3f}" for v in gamma), flush=True)
            X.clear(); F.clear(); P.clear()
            gamma = None
        else:
            xnew = xnew - (dX + alpha * dF) @ gamma
    X.append(x); F.append(f); P.append(p)
    if len(X) > M + 1:
        X.pop(0); F.pop(0); P.pop(0)
    n_m = mom.size
    new["momentum"] = xnew[:n_m].reshape(mom.shape)
    new["k"] = xnew[n_m:].reshape(k.shape)
    print(f"   AA pass {self.pass_index} alpha {alpha:g} depth {len(X) - 1} |p| {np.sqrt(np.mean(p*p)):.2f} gamma "
          + ("-" if gamma is None else " ".join(f"{v:+.3f}" for v in gamma) + f" fit {fit:.2f}"), flush=True)
    return new, residual


C.CouplingLoop._relax = _relax
print("coarse anderson depth", M, "start", START, "blocks", (GX, GR, GT), "gmax", GMAX,
      "keep_alpha", KEEP_ALPHA, flush=True)
