"""A Lagrangian pass tracked while the gas march that feeds it is still running.

The developing gas solve marches downstream and never returns to a station it has finished
(``rans.solve(..., on_station=...)``); the tracking kernel sweeps each batch downstream window
by window (``TrackSettings.window_stations``; ``particles.kernel``).  A :class:`StreamedPass`
receives the march's stations one by one, builds the rows of the field table (and the
partners' Stokes numbers, ``physics.partner_correlation = "cell"``) that they complete, and
sweeps the windows of its first super-batch in a thread of its own as soon as the rows a parcel
of the window can read are there; the other super-batches follow once the march is complete.
While the march runs the pass uses one numba thread, so the march keeps a core; after it, all
of them.

What a parcel of window w reads: the table rows of the stations of the window, and of the one
where its last step ends, each row also taking the gas of its two neighbours (axial central
differences).  With the default step rule a step is limited by the axial cell-crossing time at
its start, so that station is nearly always the first of window w + 1; the pass waits for the
table rows up to ``ROW_MARGIN`` stations beyond the window.  Nothing bounds a step absolutely
(a parcel can speed up during a step; the paper's step rule has no crossing limit), so the rows
not yet built hold NaN, and after every call the pass checks that no parcel read one: none
suspended or stopped where its fields take such a row, none lost, and, at the end, every sum
and parcel state finite (a NaN field read leaves a NaN in the parcel's state or sums).  A pass
that fails the check raises :class:`StreamOvershoot`: its caller tracks it again in the
finished field (the coupling loop then stops streaming).

The result is :func:`particles.tracking.track`'s in the finished gas field, bit for bit, for
any thread count: every batch performs the same operations in the same order whatever the
ranges of windows it is swept in (``kernel.make_window_tracker``), the batches are folded in
batch order, and the table rows equal those of ``FieldTable.from_gas`` (``fields.table_rows``).
:meth:`finish` compares the streamed gas with the solve's field.
"""

from __future__ import annotations

import threading
import time

import numba
import numpy as np

from .fields import NT, FieldTable, table_problem, table_rows
from .kernel import NSTATE, NSUSP, SU_ACTIVE, SU_POS, make_window_tracker, fold_batches
from .layout import CS_ST, NACC, P_WINDOW, S_LOST, S_STUCK
from .tracking import (TrackSettings, _check_variant, make_sample, prepare_pass, run_superbatch,
                       stokes_of_cells)

__all__ = ["StreamedPass", "ROW_MARGIN", "StreamCancelled", "StreamOvershoot"]

#: table rows beyond a window's last station that must be built before the window is swept
ROW_MARGIN = 3
#: windows swept in one call while the march runs (so that the pass takes up all threads soon
#: after the march ends)
WINDOWS_PER_CALL = 4


class StreamCancelled(Exception):
    """The streamed pass was cancelled (its gas solve failed or its inputs changed)."""


class StreamOvershoot(RuntimeError):
    """A parcel of the streamed pass reached fields the march had not delivered when it got
    there: the pass must be tracked again in the finished field."""


class StreamedPass:
    """One pass of :func:`particles.tracking.track` fed by a gas march in progress.

    Arguments as :func:`~particles.tracking.track` (``gas_props`` the gas properties instead
    of the gas field, which does not exist yet); ``partner_stokes``: fill the statistics' CS_ST
    column with :func:`~particles.tracking.stokes_of_cells` of the streamed gas, as the coupling
    loop does for ``partner_correlation = "cell"``; ``threads``: numba threads once the march
    is complete (default: the creating thread's).  Pass :meth:`station` to ``rans.solve`` as
    ``on_station``; then :meth:`finish` with the solve's field, or :meth:`cancel`;
    :meth:`result` waits for the :class:`~particles.tracking.Sample`.
    """

    def __init__(self, mesh, gas_props, spec, physics, *, parcels, seed, pass_index, stats=None,
                 settings=TrackSettings(), partner_stokes=False, threads=None):
        if mesh.mode != "developing":
            raise ValueError(f"a streamed pass needs a developing (marched) mesh, not {mesh.mode!r}")
        nx, nr, nt = mesh.shape
        self.mesh = mesh
        self.spec = spec
        self.gas_props = gas_props
        self.key = None  # what the caller streams it for (compared before using the result)
        self.gas = None  # the solve's field, once finish() has checked it
        self._sec = mesh.geometry()
        self._gas = {v: np.empty((nx, nr, nt)) for v in ("ux", "uy", "uz", "k", "eps")}
        # NaN until built: a read of a row not yet built leaves a trace
        self.table = FieldTable.on_mesh(mesh, gas_props, np.full((nx, nr, nt, NT), np.nan),
                                        np.full((nx, NT), np.nan))
        if stats is not None:
            stats = np.array(stats, dtype=np.float64, copy=True)
        self._partner_stokes = bool(partner_stokes and stats is not None)
        if self._partner_stokes:
            stats[:, CS_ST] = np.nan  # built with the table rows
        self.inputs = prepare_pass(mesh, None, spec, physics, parcels=parcels, seed=seed,
                                   pass_index=pass_index, stats=stats, settings=settings,
                                   table=self.table, gas_props=gas_props)
        self._threads = numba.get_num_threads() if threads is None else int(threads)
        self._cond = threading.Condition()
        self._stations = 0  # gas stations received
        self._rows = 0  # table rows (and statistics rows) built
        self._done = False  # the march is complete and checked
        self._finished = False  # finish() was called
        self._cancelled = False
        self._problem = ""  # why the streamed gas cannot be tracked in
        self._error = None
        self._sample = None
        self.wall_time = 0.0
        self.windows_beside_march = 0  # windows of the first super-batch swept before the march ended
        self._thread = threading.Thread(target=self._run, name=f"streamed pass {pass_index}", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ the gas side
    def station(self, i, ux, uy, uz, k, eps):
        """Station i of the march is final (``rans.solve``'s ``on_station``)."""
        if self._cancelled:
            return
        nx, nr, nt = self.mesh.shape
        if i != self._stations:
            self._fail(RuntimeError(f"the march delivered station {i} after {self._stations - 1}"))
            return
        for name, v in (("ux", ux), ("uy", uy), ("uz", uz), ("k", k), ("eps", eps)):
            self._gas[name][i] = np.asarray(v).reshape(nr, nt)
        self._stations = i + 1
        hi = nx if i + 1 == nx else i  # row j takes the gas of station j + 1
        if hi > self._rows:
            self._build_rows(self._rows, hi)

    def _build_rows(self, j0, j1):
        g = self._gas
        tab = self.table.values
        table_rows(self._sec, self.mesh.x, g["ux"], g["uy"], g["uz"], g["k"], g["eps"], j0, j1, tab,
                   self.table.axis)
        problem = table_problem(tab[j0:j1], g["k"][j0:j1], g["eps"][j0:j1])
        if self._partner_stokes:
            nc = self.mesh.nr * self.mesh.nt
            st = self.inputs.stats
            c0, c1 = j0 * nc, j1 * nc
            st[c0:c1, CS_ST] = stokes_of_cells(st[c0:c1], g["ux"][j0:j1].ravel(), g["uy"][j0:j1].ravel(),
                                               g["uz"][j0:j1].ravel(), g["k"][j0:j1].ravel(),
                                               g["eps"][j0:j1].ravel(), self.gas_props, self.spec)
        with self._cond:
            if problem and not self._problem:
                self._problem = problem
            self._rows = j1
            self._cond.notify_all()

    def finish(self, gas):
        """The march is complete and gave ``gas``: check that it is what was streamed."""
        self._finished = True
        same = self._stations == self.mesh.nx and all(
            np.array_equal(self._gas[a], np.asarray(getattr(gas, b)).reshape(self.mesh.shape))
            for a, b in (("ux", "ux"), ("uy", "uy"), ("uz", "uz"), ("k", "k"), ("eps", "epsilon")))
        if not same:
            self._fail(RuntimeError("the streamed gas differs from the solve's field (stations "
                                    f"{self._stations} of {self.mesh.nx}); the streamed pass is void"))
            return
        self.gas = gas
        with self._cond:
            self._done = True
            self._cond.notify_all()

    def cancel(self, wait=False):
        """Stop the pass (its gas solve failed, or it is not needed); ``wait``: until its thread
        has left the kernel."""
        with self._cond:
            self._cancelled = True
            self._cond.notify_all()
        if wait:
            self._thread.join()

    def _fail(self, err):
        with self._cond:
            if self._error is None:
                self._error = err
            self._cancelled = True
            self._cond.notify_all()

    # ------------------------------------------------------------------ the particle side
    def result(self):
        """The pass's :class:`~particles.tracking.Sample` (waits for it; None if cancelled);
        raises what stopped it (:class:`StreamOvershoot`: track the pass again).  Call
        :meth:`finish` or :meth:`cancel` first."""
        if not (self._finished or self._cancelled):
            raise RuntimeError("StreamedPass.result() before finish() or cancel(): it would wait for ever")
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._sample

    def _wait_rows(self, need):
        """Wait for ``need`` table rows; returns (rows built, march complete)."""
        with self._cond:
            while True:
                if self._cancelled:
                    raise StreamCancelled()
                if self._problem and self._rows >= need:
                    raise ValueError(self._problem)
                if self._done or self._rows >= need:
                    return self._rows, self._done
                self._cond.wait()

    def _run(self):
        try:
            t0 = time.perf_counter()
            numba.set_num_threads(1)
            self._sample = self._track()
            self.wall_time = time.perf_counter() - t0
            self._sample.wall_time = self.wall_time
        except StreamCancelled:
            pass
        except BaseException as err:  # handed to result()
            self._fail(err)

    def _track(self):
        inputs = self.inputs
        nx = self.mesh.nx
        per = int(inputs.prm[P_WINDOW])
        if per <= 0 or per >= nx:
            per = nx
        nwin = (nx + per - 1) // per

        def need(w):
            return nx if w + 1 >= nwin else min(nx, (w + 1) * per + ROW_MARGIN)

        track_windows = make_window_tracker(inputs.physics)
        t = inputs.table
        sl = inputs.supers[0]
        starts, counts = inputs.starts[sl], inputs.counts[sl]
        nbat = len(starts)
        npar = int(counts.sum())
        scratch = np.zeros((nbat, inputs.size))
        states = np.full((npar, NSTATE), np.nan)  # a row is written when its parcel ends
        susp = np.zeros((npar, NSUSP))
        totals = np.zeros(inputs.size)
        squares = np.zeros(inputs.size)
        cross = np.zeros(inputs.ncell * NACC)
        w = 0
        full = False
        while w < nwin:
            rows, done = self._wait_rows(need(w))
            if done and not full:
                numba.set_num_threads(self._threads)
                full = True
            w1 = w + 1
            limit = nwin if done else min(nwin, w + WINDOWS_PER_CALL)
            while w1 < limit and need(w1) <= rows:
                w1 += 1
            track_windows(starts, counts, inputs.seed, inputs.pass_index, t.x_edges, t.r_edges, t.r_centres,
                          inputs.nt, t.length, t.radius, t.nu, t.x_centres, t.values, t.axis, inputs.stats,
                          inputs.prm, scratch, states, susp, w, w1)
            if rows < nx:
                self._check_reach(susp, states, t.x_centres[rows - 1], w1, rows)
            if not done:
                self.windows_beside_march = w1
            w = w1
        fold_batches(scratch, nbat, totals, squares, cross, inputs.ncell)
        _check_variant(totals, nbat, track_windows.eulag_variant)
        if not (np.isfinite(totals).all() and np.isfinite(states).all()):
            raise StreamOvershoot("the streamed pass's first super-batch has non-finite sums or parcel "
                                  "states: a parcel read fields the march had not delivered yet (or a parcel "
                                  "was lost)")
        del scratch, susp
        if not full:
            self._wait_rows(nx)
            numba.set_num_threads(self._threads)
        for isb in range(1, inputs.superbatches):
            if self._cancelled:
                raise StreamCancelled()
            r = run_superbatch(inputs, isb)
            totals += r[0]
            squares += r[1]
            cross += r[2]
        with self._cond:  # the march's last rows are built before finish() is called
            if not self._done:
                while not (self._done or self._cancelled):
                    self._cond.wait()
            if self._cancelled:
                raise StreamCancelled()
        return make_sample(self.mesh, self.spec, inputs, totals, squares, cross)



    @staticmethod
    def _check_reach(susp, states, x_limit, w1, rows):
        """Raise StreamOvershoot if a parcel of the call that ended at window w1 read a table row
        not yet built (``rows`` built; a point at x reads the rows of the station centres around
        it, so x must stay below the centre of the last one built, ``x_limit``): a parcel
        suspended or stopped beyond it, or one lost."""
        status = states[:, 14]
        if np.any(status == S_LOST):
            raise StreamOvershoot(f"a parcel of the streamed pass was lost before window {w1}")
        active = susp[:, SU_ACTIVE] != 0.0
        stopped = status == S_STUCK
        x = np.concatenate((susp[active, SU_POS], states[stopped, 0]))
        if x.size and x.max() >= x_limit:
            raise StreamOvershoot(
                f"a parcel of the streamed pass stood at x = {x.max():.6g} m after window {w1 - 1}, "
                f"where its fields take table rows beyond the {rows} the march had delivered")
