"""numba's on-disk cache, made safe for the project's compiled packages.

Infrastructure below every package: each compiled package (``rans``, ``particles``,
``collisions``, ``dem``) takes its numba flags from here (``JIT_FLAGS``) and installs these
guards on import (:func:`guard_numba_cache`; once per process):

* **Flags stated, not inherited.** A function whose fastmath, error model or reference
  counting is not set takes them from the first jitted caller that compiles it, and keeps that
  compilation (in memory and on disk) for every later caller.  The tracking kernel's loop runs
  with fast-math flags (``collisions.conf.LOOP_FLAGS``): the collision helpers, the forces, the
  random numbers and ``rans.mesh.cell_index`` were compiled with them when the tracker came
  first in a process, without them when a test or another kernel had called them first.  A
  four-way test pass differed by 7 · 10⁻¹⁶ (relative) after five collision helpers had been
  called from Python before it, 1–4 · 10⁻¹⁵ after the collision or tracking tests, and by up
  to 3–4 · 10⁻¹¹ between processes with other histories (Dask workers against the local
  process).  ``JIT_FLAGS`` states all three (no fast-math, Python's error model, reference
  counting on; ``collisions.conf`` gives every dilute-phase kernel the loop's fast-math flags
  and error model), so every function is compiled the same whoever calls it first.
* **The flags in the cache key.** numba's cache key holds no options: one function compiled
  with two flag sets (``dem.transfer``'s serial and parallel transfers) shares one entry, which
  serves whichever was saved first.  The key of every function of the compiled packages also
  holds its dispatcher's options and numba's compile settings from the environment
  (``NUMBA_OPT``, ``NUMBA_BOUNDSCHECK``, ``NUMBA_DEBUGINFO``).

* **Stale kernels.** numba keys a cached function by its own bytecode and closure and
  invalidates it when *its own* source file changes; code it calls or inlines from other files
  is not part of the key.  A tracking kernel (``particles/kernel.py``) is assembled from the
  motion step, the wall and collision kernels and the random numbers of four other files; after
  an edit of one of them, numba loaded the kernel compiled from the former code: with the
  collision partners' correlation R(St) = exp(−0.56 St^0.4) instead of −0.55 in
  ``collisions/interparticle.py`` a four-way pass from the existing cache gave the former
  result bit for bit (37,898 collisions), from an empty cache another one (37,913 collisions,
  sources 0.26 % apart).  The cache index of every function defined in the compiled packages'
  files now carries a digest of their sources (every ``.py`` file of ``PROJECT_PACKAGES``) in
  its source stamp: after any edit numba discards the index and compiles afresh (reusing the
  data files, so the cache does not grow), and a cache filled by other code is never served.
* **Writers at the same time.** ``IndexDataCacheFile.save`` reads the index, picks the first
  free data-file number, and writes both back, unlocked: two processes compiling different
  variants of one function (the tracking kernels are closures built per option set) can both
  pick number N, and the index entry that survives may point at the other variant's code, so
  that, e.g., a four-way pass is served the tracking kernel compiled without inter-particle
  collisions.  Saves and loads hold an exclusive lock on a file in the cache directory (POSIX;
  elsewhere unchanged), and every batch of a pass reports the option set it was compiled for
  (particles.tracking).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
from pathlib import Path

#: the options every numba function of the compiled packages states: without them numba takes
#: fastmath, error_model and reference counting (nrt) from the first caller that compiles it
EXPLICIT_FLAGS = {"fastmath": False, "error_model": "python", "_nrt": True}
#: a plain compiled function, cached on disk
JIT_FLAGS = {"cache": True, **EXPLICIT_FLAGS}

#: the packages with numba functions: theirs carry the source digest in their cache stamp, and
#: their sources make it (darcy, tfm and eulag compile nothing)
PROJECT_PACKAGES = ("rans", "particles", "collisions", "dem")


def _package_dir(pkg: str) -> Path:
    """The directory the package ``pkg`` is imported from (an installed copy or a source tree:
    wherever its import resolves in this process)."""
    mod = sys.modules.get(pkg)
    spec = mod.__spec__ if mod is not None and mod.__spec__ is not None else importlib.util.find_spec(pkg)
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(f"jitcache: package {pkg!r} not found")
    return Path(list(spec.submodule_search_locations)[0]).resolve()


def source_digest(root: Path | None = None) -> str:
    """sha256 over the path and bytes of every ``.py`` file of ``PROJECT_PACKAGES``, under
    ``root`` if given, else where each package is imported from; raises if it finds none."""
    h = hashlib.sha256()
    n = 0
    for pkg in PROJECT_PACKAGES:
        d = Path(root) / pkg if root is not None else _package_dir(pkg)
        for f in sorted(d.glob("*.py")):
            h.update(f"{pkg}/{f.name}\0".encode())
            h.update(f.read_bytes())
            h.update(b"\0")
            n += 1
    if n == 0:
        raise RuntimeError(f"jitcache: no source files of {PROJECT_PACKAGES} under {root}")
    return h.hexdigest()


def _ours(py_func) -> bool:
    """Whether ``py_func`` is defined in a file of one of the compiled packages (by the
    package directory's name, wherever it is installed; also when its module runs as
    ``__main__``)."""
    try:
        f = Path(py_func.__code__.co_filename)
    except AttributeError:
        return False
    return f.parent.name in PROJECT_PACKAGES and (f.parent / "__init__.py").is_file()


def guard_numba_cache():
    """Install the guards of the module docstring (idempotent).  The digest goes into the
    source stamp of the functions' cache index, which numba compares on every load: an index
    written from other sources is discarded and its data files are reused, so the cache does not
    grow with every edit.  The options go into each entry's key."""
    try:
        import numba  # noqa: F401 - the guard has nothing to do without numba
    except ImportError:
        return
    from numba.core import caching  # a numba without these internals fails here, loudly
    from numba.core.dispatcher import Dispatcher

    if not getattr(caching.Cache, "_eulag_digest", None):
        digest = source_digest()
        init = caching.Cache.__init__
        index_key = caching.Cache._index_key
        enable_caching = Dispatcher.enable_caching

        def init_stamped(self, py_func):
            init(self, py_func)
            if _ours(py_func):
                self._cache_file._source_stamp = (self._cache_file._source_stamp, digest)

        def keyed(self, sig, codegen):
            key = index_key(self, sig, codegen)
            if _ours(self._py_func):
                return key[:-1] + (tuple(key[-1]) + (getattr(self, "_eulag_options", ""), _compile_settings()),)
            return key

        def caching_with_options(self):
            enable_caching(self)
            self._cache._eulag_options = _options_key(self.targetoptions)

        caching.Cache.__init__ = init_stamped
        caching.Cache._index_key = keyed
        caching.Cache._eulag_digest = digest
        Dispatcher.enable_caching = caching_with_options
    _serialise_writers(caching)


def _compile_settings():
    """numba's process-wide settings that change the compiled code (read from the environment:
    ``NUMBA_OPT``, ``NUMBA_BOUNDSCHECK``, ``NUMBA_DEBUGINFO``), as a string: a kernel compiled
    unoptimised or with bounds checks for debugging is not served to a normal run."""
    from numba.core import config
    return f"opt={config.OPT};boundscheck={config.BOUNDSCHECK};debuginfo={config.DEBUGINFO_DEFAULT}"


def _options_key(options):
    """The dispatcher's options as a string that is the same in every process (a set, e.g. of
    fast-math flags, in sorted order: its own order follows the string hashes of the process)."""
    def canonical(v):
        return repr(sorted(v)) if isinstance(v, (set, frozenset)) else repr(v)
    return ";".join(f"{k}={canonical(v)}" for k, v in sorted(options.items()))


def _serialise_writers(caching):
    try:
        import fcntl
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
