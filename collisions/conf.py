"""Shared numba flags of the collision kernels (kept in one place).

JIT_FLAGS     every jitted function: compiled once, cached on disk.
KERNEL_FLAGS  functions that take arrays but never allocate one: compiled without the numba
              runtime's reference counting (``_nrt=False``).  Measured reason: every array
              argument of a call that LLVM does not inline costs an atomic incref/decref pair,
              ~10 ns here; the stochastic collision kernel with nine array arguments spent
              ~120 of its ~150 ns per call on it (``python -m collisions.bench``).  Such a
              function must not create arrays (numba refuses to compile it if it does).
"""

import os

JIT_FLAGS = {"cache": True}
KERNEL_FLAGS = {"cache": True, "_nrt": False}


def _serialise_numba_cache():
    """Make numba's on-disk cache safe for processes compiling at the same time.

    ``IndexDataCacheFile.save`` reads the index, picks the first free data-file number, and
    writes both back, unlocked: two processes compiling different variants of one function
    (eulag's kernels are closures built per option set) can both pick number N, and the index
    entry that survives may point at the other variant's code, so that, e.g., a four-way pass is
    served the tracking kernel compiled without inter-particle collisions.  Saves and loads
    hold an exclusive lock on a file in the cache directory (POSIX; elsewhere unchanged), and
    every batch of a pass reports the option set it was compiled for (particles.tracking).
    """
    try:
        import fcntl

        from numba.core import caching
    except ImportError:
        return
    cls = caching.IndexDataCacheFile
    if getattr(cls, "_eulag_serialised", False):
        return

    def locked(method):
        def wrapper(self, *args, **kwargs):
            try:
                fh = open(os.path.join(self._cache_path, ".eulag-numba-cache.lock"), "a")
            except OSError:  # a read-only cache location: numba itself will not write there
                return method(self, *args, **kwargs)
            with fh:
                fcntl.flock(fh, fcntl.LOCK_EX)
                return method(self, *args, **kwargs)
        return wrapper

    cls.save = locked(cls.save)
    cls.load = locked(cls.load)
    cls._eulag_serialised = True


_serialise_numba_cache()
