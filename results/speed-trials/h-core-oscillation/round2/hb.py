"""Heavy-ball momentum on the relaxed sources: new += MU * (change of the relaxed sources over
the previous pass).  Env HB_MU."""
import os
import numpy as np
import eulag.coupling as C

MU = float(os.environ.get("HB_MU", "0.5"))
_orig = C.CouplingLoop._relax


def _relax(self, comp, sample, alpha):
    new, residual = _orig(self, comp, sample, alpha)
    st = getattr(self, "_hb", None)
    if self.sources is None:
        return new, residual
    cur = {"momentum": self.sources["momentum"], "k": self.sources["k"]}
    if st is not None and st["pass"] == self.pass_index:  # a retry within the pass
        st = st["before"]
    else:
        st = {"pass": self.pass_index, "before": st}
        self._hb = st
    if self._hb["before"] is not None and "stash" in self._hb["before"]:
        old = self._hb["before"]["stash"]
        for key in ("momentum", "k"):
            new[key] = new[key] + MU * (cur[key] - old[key])
    self._hb["stash"] = {k: v.copy() for k, v in cur.items()}
    return new, residual


C.CouplingLoop._relax = _relax
print("heavy ball mu", MU, flush=True)
