"""Shared numba flags of the dem kernels.

JIT_FLAGS        serial kernels, cached on disk, fastmath, error model and nrt stated (jitcache's).
PARALLEL_FLAGS   kernels with a ``prange`` over grains or nodes.  Every such loop writes only the
                 entries of its own index (grain i or node column j): no shared ``+=``, so the
                 result does not depend on the thread count (bit-identical for 1 and N threads).
"""

from jitcache import JIT_FLAGS, guard_numba_cache

__all__ = ["JIT_FLAGS", "PARALLEL_FLAGS"]

guard_numba_cache()  # numba's on-disk cache: no stale kernels, no clashing writers (jitcache)

PARALLEL_FLAGS = {**JIT_FLAGS, "parallel": True}
