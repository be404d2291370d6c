"""Shared numba flags of the collision kernels (one place, as STYLE.md suggests).

JIT_FLAGS     every jitted function: compiled once, cached on disk.
KERNEL_FLAGS  functions that take arrays but never allocate one: compiled without the numba
              runtime's reference counting (``_nrt=False``).  Measured reason: every array
              argument of a call that LLVM does not inline costs an atomic incref/decref pair,
              ~10 ns here; the stochastic collision kernel with nine array arguments spent
              ~120 of its ~150 ns per call on it (``python -m collisions.bench``).  Such a
              function must not create arrays (numba refuses to compile it if it does).
"""

JIT_FLAGS = {"cache": True}
KERNEL_FLAGS = {"cache": True, "_nrt": False}
