"""Shared numba flags of the dem kernels.

JIT_FLAGS        serial kernels, cached on disk.
PARALLEL_FLAGS   kernels with a ``prange`` over grains or nodes.  Every such loop writes only the
                 entries of its own index (grain i or node column j): no shared ``+=``, so the
                 result does not depend on the thread count (bit-identical for 1 and N threads).
"""

from jitcache import JIT_FLAGS, guard_numba_cache

guard_numba_cache()  # numba's on-disk cache: no stale kernels, no clashing writers (jitcache)

JIT_FLAGS = dict(JIT_FLAGS)  # cached, with fastmath, error model and nrt stated (jitcache)
PARALLEL_FLAGS = {**JIT_FLAGS, "parallel": True}
