"""Lagrangian passes on a Dask cluster (dask.distributed), bit-identical to local runs.

    from eulag.distributed import DaskTracker, dask_client
    with dask_client(local_workers=2) as client:          # or scheduler="tcp://host:8786"
        ds = eulag.runs.run(case, "out.nc", tracker=DaskTracker(client))

A pass is split into the super-batches fixed by the case (``particles.batch_plan``: they
depend on the parcel count and ``numerics.batch_size`` / ``batches_per_superbatch``, never on
the worker count).  Per pass the tracker

1. builds the pass inputs once on the client (``particles.tracking.prepare_pass``: the gas
   field table, the previous pass's cell statistics, the parameter vector, the batch plan,
   the physics switches) and scatters them once, broadcast to every worker;
2. submits one task per super-batch (``particles.tracking.run_superbatch``), each of which
   folds its batches in batch order and returns its (totals, squares, cross) arrays;
3. folds the super-batch results on the client in super-batch index order
   (``fold_superbatches``) and builds the ``Sample`` exactly as ``particles.track`` does.

The random streams are keyed by (seed, pass, parcel id), so which worker runs a super-batch,
or how often it is re-run after a worker died (Dask does that by itself), does not change a
single bit; nor does submitting them again when a dead worker took the last copy of the
scattered inputs with it (``DaskTracker._results``).  On mixed hardware set
``NUMBA_CPU_NAME=generic`` on every worker (and the client) so all of them compile the same
machine code.

A lost scheduler (or connection) during a pass raises :class:`DaskConnectionError`, a
:class:`eulag.coupling.CouplingError`: the coupling loop has not touched its state or its
checkpoint for that pass, so the checkpoint of the last complete pass stays intact and
``eulag run --resume`` continues from it.
"""

from __future__ import annotations

import contextlib
import logging
import time
import uuid

import numpy as np

import particles
from eulag.coupling import CouplingError
from particles.tracking import fold_superbatches, make_sample, prepare_pass, run_superbatch

__all__ = ["DaskTracker", "DaskConnectionError", "DaskUnavailable", "dask_client", "make_client",
           "require_dask", "superbatch_task", "set_numba_threads", "INSTALL_HINT"]

INSTALL_HINT = "Dask is not installed; install it with: pip install '.[dask]'"
CONNECT_TIMEOUT = 20.0  # s, to reach a scheduler given by address


class DaskUnavailable(ImportError):
    """dask.distributed cannot be imported (the ``dask`` extra is not installed)."""


class DaskConnectionError(CouplingError):
    """The Dask scheduler (or the connection to it) was lost, or could not be reached."""


def require_dask():
    """Import and return ``dask.distributed``; :class:`DaskUnavailable` with the install hint."""
    try:
        import dask.distributed as dd
    except ImportError:
        raise DaskUnavailable(INSTALL_HINT) from None
    return dd


def make_client(scheduler=None, local_workers=None, *, threads_per_worker=1, memory_limit="auto",
                timeout=None):
    """A ``dask.distributed.Client``: of an existing scheduler at ``scheduler`` (an address such
    as ``tcp://10.0.0.5:8786``), or of a new ``LocalCluster`` with ``local_workers`` worker
    processes of ``threads_per_worker`` threads each (``timeout``: seconds to reach the
    scheduler, default :data:`CONNECT_TIMEOUT`).  The caller closes the client and, for a
    local cluster, ``client.cluster`` (or uses :func:`dask_client`)."""
    if (scheduler is None) == (local_workers is None):
        raise ValueError("give exactly one of scheduler (an address) and local_workers (a count)")
    dd = require_dask()
    if scheduler is not None:
        timeout = CONNECT_TIMEOUT if timeout is None else timeout
        try:
            return dd.Client(scheduler, timeout=timeout)
        except (OSError, TimeoutError) as exc:
            raise DaskConnectionError(f"cannot connect to the Dask scheduler at {scheduler} within "
                                      f"{timeout:g} s ({_oneline(exc)})") from None
        except ValueError as exc:  # e.g. an unknown protocol in the address
            raise ValueError(f"--scheduler {scheduler}: {_oneline(exc)}") from None
    if int(local_workers) < 1:
        raise ValueError(f"local_workers = {local_workers}: allowed an integer >= 1")
    cluster = dd.LocalCluster(n_workers=int(local_workers), threads_per_worker=int(threads_per_worker),
                              processes=True, dashboard_address=":0", memory_limit=memory_limit,
                              silence_logs=logging.ERROR)
    return dd.Client(cluster)


@contextlib.contextmanager
def dask_client(scheduler=None, local_workers=None, **kw):
    """Context manager around :func:`make_client`; closes the client and a local cluster."""
    client = make_client(scheduler, local_workers, **kw)
    cluster = client.cluster if local_workers is not None else None
    try:
        yield client
    finally:
        with contextlib.suppress(Exception):
            client.close(timeout=10)
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=10)


def set_numba_threads(n):
    """Use ``n`` numba threads in the calling thread (capped at NUMBA_NUM_THREADS; None: leave)."""
    if n is None:
        return
    import numba

    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


def superbatch_task(inputs, isb, numba_threads=1):
    """The task of one super-batch: ``run_superbatch(inputs, isb)`` with ``numba_threads``."""
    set_numba_threads(numba_threads)
    return run_superbatch(inputs, isb)


def _oneline(exc, limit=160):
    text = " ".join(str(exc).split())
    if len(text) > limit:
        text = text[: limit - 3] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _cancelled():
    import asyncio
    import concurrent.futures

    return (concurrent.futures.CancelledError, asyncio.CancelledError)


def _connection_errors():
    import asyncio

    from distributed.comm.core import CommClosedError

    # a lost scheduler cancels every future of the client (FutureCancelledError, a
    # concurrent.futures.CancelledError, reason "scheduler-connection-lost")
    return (OSError, CommClosedError, *_cancelled(), asyncio.TimeoutError, TimeoutError)


class DaskTracker:
    """A tracker for ``eulag.coupling.CouplingLoop(..., tracker=...)``: the signature and results
    of :func:`particles.track`, the super-batches run as tasks on ``client``'s workers.

    numba_threads : numba threads per task on the worker (default 1: one thread per Dask
        thread, the right choice for workers started with one thread per core; None leaves
        numba's default, all cores of the worker's machine).
    retries : extra attempts of a task that *raised* (a dead worker is handled by Dask itself,
        up to ``distributed.scheduler.allowed-failures`` times per task).
    after_submit : callable(list of futures, pass_index) called once the tasks of a pass are
        submitted (monitoring; the tests use it to kill a worker mid-pass).
    workers : addresses of the workers allowed to run the super-batches (None: any).
    resubmit_rounds : how often a pass submits its unfetched super-batches again after the
        cluster lost the scattered pass inputs with a dead worker (see :meth:`_results`).
    """

    def __init__(self, client, *, numba_threads=1, retries=0, after_submit=None, workers=None,
                 resubmit_rounds=3):
        self.client = client
        self.workers = list(workers) if workers is not None else None
        self.numba_threads = numba_threads
        self.retries = retries
        self.after_submit = after_submit
        self.resubmit_rounds = int(resubmit_rounds)
        self.passes = 0
        self.tasks = 0
        self.resubmitted = 0  # super-batches submitted again after their inputs were lost

    def __call__(self, mesh, gas, spec, physics=particles.PhysicsOptions(), *, parcels, seed=1,
                 pass_index=0, stats=None, settings=particles.TrackSettings()):
        t0 = time.perf_counter()
        inputs = prepare_pass(mesh, gas, spec, physics, parcels=parcels, seed=seed,
                              pass_index=pass_index, stats=stats, settings=settings)
        tag = f"eulag-pass{int(pass_index)}-{uuid.uuid4().hex[:12]}"
        held = []  # futures (scattered inputs, super-batches) to release when the pass ends
        try:
            try:
                totals, squares, cross = fold_superbatches(inputs, self._results(inputs, tag, pass_index, held))
            except _connection_errors() as exc:
                raise DaskConnectionError(
                    f"pass {pass_index}: lost the Dask scheduler or the connection to it "
                    f"({_oneline(exc)}); the pass was abandoned") from None
            except Exception as exc:
                dd = require_dask()
                if isinstance(exc, dd.KilledWorker):
                    raise CouplingError(f"pass {pass_index}: a super-batch task killed its worker "
                                        f"again and again ({_oneline(exc)})") from None
                raise
        finally:
            for f in held:
                with contextlib.suppress(Exception):
                    f.release()
        self.passes += 1
        self.tasks += inputs.superbatches
        return make_sample(mesh, spec, inputs, totals, squares, cross,
                           wall_time=time.perf_counter() - t0)

    def _submit(self, inputs, tag, indices, held):
        """Scatter the pass inputs (broadcast) and submit the super-batches ``indices``."""
        client = self.client
        [shared] = client.scatter([inputs], broadcast=True, hash=False, workers=self.workers)
        held.append(shared)
        futures = {isb: client.submit(superbatch_task, shared, isb, self.numba_threads,
                                      key=f"{tag}-superbatch-{isb}", pure=False, retries=self.retries,
                                      workers=self.workers, allow_other_workers=False)
                   for isb in indices}
        held.extend(futures.values())
        return futures

    def _submit_again(self, inputs, tag, indices, held, attempts=10, wait=1.0):
        """:meth:`_submit` after a lost worker: the scatter may still address the dead worker
        until the scheduler has removed it, so a failed scatter is tried again (``attempts``
        times, ``wait`` seconds apart) before the connection error is raised."""
        for attempt in range(attempts):
            try:
                return self._submit(inputs, tag, indices, held)
            except _connection_errors():
                if attempt == attempts - 1 or self.client.status != "running":
                    raise
                time.sleep(wait)

    def _results(self, inputs, tag, pass_index, held):
        """Results in super-batch index order, each released on the cluster once fetched.

        A worker that dies while it runs a super-batch is handled by Dask (the task runs again
        elsewhere).  If it held the last replica of the scattered inputs (Dask's active memory
        manager drops replicas that no waiting task needs), the super-batches not yet fetched
        are cancelled ("already forgotten") although the scheduler is fine: they are submitted
        again, with the inputs scattered anew, up to :attr:`resubmit_rounds` times.  A lost
        scheduler ("scheduler-connection-lost") is raised to the caller.
        """
        futures = self._submit(inputs, tag, range(inputs.superbatches), held)
        if self.after_submit is not None:
            self.after_submit(list(futures.values()), pass_index)
        rounds = 0
        for isb in range(inputs.superbatches):
            while True:
                f = futures[isb]
                try:
                    r = f.result()
                    break
                except _cancelled() as exc:
                    reason = getattr(exc, "reason", "unknown")
                    if (reason == "scheduler-connection-lost" or self.client.status != "running"
                            or rounds >= self.resubmit_rounds):
                        raise
                    rounds += 1
                    for g in held:
                        with contextlib.suppress(Exception):
                            g.release()
                    held.clear()
                    futures.update(self._submit_again(inputs, f"{tag}-again{rounds}",
                                                      range(isb, inputs.superbatches), held))
                    self.resubmitted += inputs.superbatches - isb
            if f.status != "finished":  # pragma: no cover - defensive
                raise CouplingError(f"pass {pass_index}, super-batch {isb}: task ended as {f.status}")
            f.release()
            yield r


def describe(client):
    """One line: the scheduler address and the workers (count, threads)."""
    try:
        info = client.scheduler_info()
        workers = info.get("workers", {})
        threads = sum(w.get("nthreads", 0) for w in workers.values())
        return f"Dask scheduler {client.scheduler.address}: {len(workers)} workers, {threads} threads"
    except Exception as exc:  # noqa: BLE001 - informational only
        return f"Dask client ({_oneline(exc)})"


def results_equal(a, b):
    """True if two Samples carry bit-identical sums (total, var, cov; NaN equal to NaN)."""
    return all(np.array_equal(getattr(a, n), getattr(b, n), equal_nan=True) for n in ("total", "var", "cov"))
