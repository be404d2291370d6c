"""Shared numba flags of the collision kernels (kept in one place).

JIT_FLAGS     every jitted function: compiled once, cached on disk, its flags stated (jitcache),
              with the loop's arithmetic (LOOP_FLAGS below).
KERNEL_FLAGS  functions that take arrays but never allocate one: compiled without the numba
              runtime's reference counting (``_nrt=False``).  Measured reason: every array
              argument of a call that LLVM does not inline costs an atomic incref/decref pair,
              ~10 ns here; the stochastic collision kernel with nine array arguments spent
              ~120 of its ~150 ns per call on it (``python -m collisions.bench``).  Such a
              function must not create arrays (numba refuses to compile it if it does).
inlined(f)    a copy of the kernel ``f`` that numba inlines into its caller (``inline="always"``,
              at numba-IR level) — used at the few call sites of the tracking step that run every
              step (the motion step, the field interpolation, the segment walk, the stochastic
              collision).  Measured reason: a call that LLVM does not inline passes every array
              argument as its expanded struct (a 4-D field table is 13 machine words), and these
              calls took about a sixth of a step; inlined, the full-physics kernel runs 3.85
              instead of 3.22 M parcel-steps/s per core with bit-identical results
              (``python -m particles.bench``).  The cost is compile time (type inference of the
              inlined body once per call site), so rare call sites (injection, the wall path)
              keep the plain call.
LOOP_FLAGS    the tracking kernel's parcel loop (with what is inlined into it and, so that they
              are compiled alike whoever calls them first, every other kernel here): numpy's
              error model (a division by zero gives inf/NaN, which the loop's
              finiteness check reports as a lost parcel, instead of a branch before every
              division) and three of LLVM's fast-math flags: ``contract`` (fused multiply-add),
              ``arcp`` (a reciprocal reused for divisions by the same value) and ``nsz``
              (the sign of zero ignored).  Not ``nnan``/``ninf`` (the finiteness checks must
              stay), not ``reassoc`` or ``afn``.  These change results by round-off only:
              within one round-off of each operation, the same for any thread count.  Measured:
              3.85 → 4.1 M parcel-steps/s per core.
"""

from numba import njit

from jitcache import JIT_FLAGS, guard_numba_cache

#: numpy's error model and the three fast-math flags of the parcel loop (LOOP_FLAGS), stated
#: for every kernel of the dilute phase (collisions, particles): the helpers the loop calls are
#: compiled with the loop's arithmetic whoever calls them first (jitcache: numba would give
#: them the first caller's flags).  Measured on the 2-core machine, idle (``python -m
#: particles.bench``: full physics, drag only, studies' grid): 3.14, 3.77 and 2.06 M
#: parcel-steps/s per core with these flags, 2.79, 3.58 and 2.01 M with numba's defaults on
#: the helpers (3.10, 3.89 and 2.12 M when the helpers took them from the loop unstated).
FAST_FLAGS = {"error_model": "numpy", "fastmath": {"contract", "arcp", "nsz"}}
JIT_FLAGS = {**JIT_FLAGS, **FAST_FLAGS}  # cached, with fastmath, error model and nrt stated
KERNEL_FLAGS = {**JIT_FLAGS, "_nrt": False}
LOOP_FLAGS = KERNEL_FLAGS


def inlined(kernel):
    """The numba kernel ``kernel`` (a dispatcher compiled with KERNEL_FLAGS) recompiled to be
    inlined at numba-IR level where it is called (module docstring)."""
    return njit(inline="always", **KERNEL_FLAGS)(kernel.py_func)


guard_numba_cache()  # numba's on-disk cache: no stale kernels, no clashing writers (jitcache)
