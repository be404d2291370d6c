"""Dask scale-out (eulag.distributed, eulag.sweep): equality with local runs, faults, sweeps.

One LocalCluster of 2 worker processes (1 thread each) serves the module; its workers compile
the super-batch driver once (numba cannot cache the parallel driver) and keep it.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dask.distributed")

import particles  # noqa: E402
from eulag import cli, sweep  # noqa: E402
from eulag import coupling  # noqa: E402
from eulag.config import Case  # noqa: E402
from eulag.coupling import CouplingError, CouplingLoop  # noqa: E402
from eulag.runs import run  # noqa: E402
from eulag.distributed import DaskConnectionError, DaskTracker, dask_client  # noqa: E402

from .test_coupling import SMALL, data_vars_equal, small_case  # noqa: E402

# four super-batches in the early passes (1000 parcels / 200 per batch, 2 batches each) and
# four in the final passes (1500 parcels), so two workers share every pass
SPLIT = {"numerics.batches_per_superbatch": 2}


@pytest.fixture(scope="module")
def client():
    with dask_client(local_workers=2) as c:
        c.wait_for_workers(2, timeout=60)
        yield c


@pytest.fixture
def fresh_client():
    """A cluster of its own for a test that kills a worker: the module's cluster does not depend
    on the nanny restarting it (once not back within 180 s on a loaded machine)."""
    with dask_client(local_workers=2) as c:
        c.wait_for_workers(2, timeout=60)
        yield c


@pytest.fixture(scope="module")
def local_ds():
    return run(small_case(**SPLIT))


def _pids(client):
    return client.run(os.getpid)


# ---------------------------------------------------------------------------- equality
def test_plan_gives_several_superbatches():
    case = small_case(**SPLIT)
    n = case.numerics
    for parcels in (n.parcels_start, n.parcels):
        _, _, supers = particles.batch_plan(parcels, particles.TrackSettings(
            batch_size=n.batch_size, batches_per_superbatch=n.batches_per_superbatch))
        assert len(supers) >= 3


def test_dask_two_workers_equal_local(client, local_ds):
    tracker = DaskTracker(client)
    ds = run(small_case(**SPLIT), tracker=tracker)
    assert tracker.passes == ds.sizes["iteration"] and tracker.tasks >= 3 * tracker.passes
    data_vars_equal(local_ds, ds)
    assert int(ds["converged"]) == int(local_ds["converged"])


def test_dask_one_worker_equals_two(client, local_ds):
    one = sorted(client.scheduler_info()["workers"])[0]
    seen = set()

    def pin(futures, pass_index):  # every super-batch on the same worker
        for f in futures:
            seen.update(w for w, keys in client.processing().items() if f.key in keys)

    tracker = DaskTracker(client, after_submit=pin, workers=[one])
    ds = run(small_case(**SPLIT), tracker=tracker)
    assert seen <= {one}
    data_vars_equal(local_ds, ds)


def test_pass_equal_for_any_superbatch_order(client):
    """A single pass with inter-particle collisions: local == Dask, bit for bit."""
    loop = CouplingLoop(small_case(**SPLIT))
    loop.step()  # gas + first pass: cell statistics exist now
    args = (loop.mesh, loop.gas, loop.spec, loop.physics)
    kw = dict(parcels=1500, seed=3, pass_index=7, stats=loop.stats, settings=loop.settings)
    a = particles.track(*args, **kw)
    b = DaskTracker(client)(*args, **kw)
    for name in ("total", "var", "cov"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.counts == b.counts and a.counts["particle_collisions"] > 0


def test_cli_run_on_a_scheduler_equals_local(tmp_path, client, local_ds, capsys):
    """eulag run --scheduler ADDRESS (the module's cluster): the same dataset as a local run."""
    case = _write_case(tmp_path / "c.toml", SMALL["name"], 3, max_passes=6, batches_per_superbatch=2)
    out = tmp_path / "c.nc"
    status = cli.main(["run", str(case), "-o", str(out), "--scheduler", client.scheduler.address])
    err = capsys.readouterr().err
    assert "Dask scheduler" in err and "2 workers" in err
    # the small case does not converge in its 6 passes: exit 1, the dataset written all the same
    assert status == 1 and "not converged when max_passes = 6 was reached" in err.strip().splitlines()[-1]
    import xarray as xr

    with xr.open_dataset(out) as ds:
        data_vars_equal(local_ds, ds.load())


# ---------------------------------------------------------------------------- sweeps
def _write_case(path, name, seed, **numerics):
    d = {k: dict(v) if isinstance(v, dict) else v for k, v in SMALL.items()}
    d["name"] = name
    d["numerics"]["seed"] = seed
    d["numerics"]["max_passes"] = 16  # converges in 8-12 passes (seeds 3-6)
    d["numerics"].update(numerics)
    lines = [f'name = "{name}"']
    for section, values in d.items():
        if not isinstance(values, dict):
            continue
        lines.append(f"[{section}]")
        for k, v in values.items():
            lines.append(f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {v!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_sweep_resumes_without_rerunning_finished_cases(tmp_path, client, capsys):
    cases = [_write_case(tmp_path / f"c{i}.toml", f"sweep_{i}", seed) for i, seed in enumerate((3, 4, 5))]
    out = tmp_path / "out"
    # the "interrupted" sweep: only the first case got done (locally, one after another)
    assert cli.main(["sweep", str(cases[0]), "-o", str(out), "--quiet"]) == 0
    first = out / "sweep_0.nc"
    stamp = first.stat().st_mtime_ns
    assert (out / "sweep_summary.csv").is_file()
    # the whole sweep again, on the Dask cluster: case 0 is not run again
    entries = sweep.plan_sweep([str(c) for c in cases], out)
    assert [e.finished for e in entries] == [True, False, False]
    rows = sweep.run_sweep(entries, client, numba_threads=1)
    sweep.write_summary(rows, out)
    assert first.stat().st_mtime_ns == stamp
    assert [r["status"] for r in rows] == ["finished earlier", "ran", "ran"]
    for r in rows:
        assert r["converged"] is True and r["passes"] >= 3 and r["pressure_gradient"] > 0
        assert r["solids_pressure_drop_ratio"] > 1.0 and Path(r["output"]).is_file()
    table = sweep.read_summary(out / "sweep_summary.csv")
    assert [r["case"] for r in table] == ["sweep_0", "sweep_1", "sweep_2"]
    md = (out / "sweep_summary.md").read_text()
    assert md.count("| sweep_") == 3 and "finished earlier" in md
    # the cases a sweep ran equal single runs of them (case 1 vs a direct run)
    import xarray as xr

    with xr.open_dataset(out / "sweep_1.nc") as ds1:
        ref = run(small_case(**{"numerics.seed": 4, "numerics.max_passes": 16}))
        data_vars_equal(ref, ds1.load())
    # everything finished: the CLI sweep runs nothing and succeeds
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*.nc")}
    capsys.readouterr()
    assert cli.main(["sweep", *map(str, cases), "-o", str(out)]) == 0
    assert "finished earlier" in capsys.readouterr().out
    assert stamps == {p: p.stat().st_mtime_ns for p in out.glob("*.nc")}


def test_sweep_bad_input_exit_2_before_any_work(tmp_path, capsys):
    good = _write_case(tmp_path / "good.toml", "good", 3)
    out = tmp_path / "out"
    assert cli.main(["sweep", str(good), str(tmp_path / "missing.toml"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "missing.toml: no such case file" in err
    bad = tmp_path / "bad.toml"
    bad.write_text(good.read_text().replace("diameter = 0.0305", "diameter = -1.0"))
    assert cli.main(["sweep", str(good), str(bad), "-o", str(out)]) == 2
    assert "pipe.diameter" in capsys.readouterr().err
    twin = _write_case(tmp_path / "twin.toml", "good", 4)
    assert cli.main(["sweep", str(good), str(twin), "-o", str(out)]) == 2
    assert "also the name of" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())
    # a checkpoint left by another case (here: another --parcels) is refused before any work
    out.mkdir(exist_ok=True)
    other = Case.from_toml(good).replace(numerics={"parcels": 1200})
    meta = {"version": coupling.CHECKPOINT_VERSION, "case": other.to_attrs()}  # as CouplingLoop writes it
    with open(out / "good.nc.checkpoint", "wb") as fh:
        np.savez(fh, meta=np.frombuffer(json.dumps(meta, default=coupling._json_default).encode(), dtype=np.uint8))
    assert cli.main(["sweep", str(good), "-o", str(out)]) == 2
    assert "checkpoint of a different case" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["good.nc.checkpoint"]


def test_dask_option_without_dask_is_bad_input(tmp_path, monkeypatch, capsys):
    from eulag import distributed

    def missing():
        raise distributed.DaskUnavailable(distributed.INSTALL_HINT)

    monkeypatch.setattr(distributed, "require_dask", missing)
    case = _write_case(tmp_path / "c.toml", "c", 3)
    for argv in (["run", str(case), "-o", str(tmp_path / "c.nc"), "--dask-local", "2"],
                 ["sweep", str(case), "-o", str(tmp_path), "--scheduler", "tcp://127.0.0.1:1"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "pip install '.[dask]'" in err
    assert not (tmp_path / "c.nc").exists()
    assert cli.main(["run", str(case), "--dask-local", "2", "--scheduler", "tcp://x:1"]) == 2


def test_unreachable_scheduler_one_line(tmp_path, capsys, monkeypatch):
    from eulag import distributed

    monkeypatch.setattr(distributed, "CONNECT_TIMEOUT", 2.0)
    case = _write_case(tmp_path / "c.toml", "c", 3)
    status = cli.main(["run", str(case), "-o", str(tmp_path / "c.nc"), "--quiet",
                       "--scheduler", f"tcp://127.0.0.1:{_free_port()}"])
    err = capsys.readouterr().err.strip()
    assert status == 1 and err.count("\n") == 0 and "cannot connect to the Dask scheduler" in err


# ---------------------------------------------------------------------------- faults
def test_worker_killed_mid_pass_same_result(fresh_client, local_ds):
    """SIGKILL of a worker that runs (or holds the result of) a super-batch of pass 3 before the
    client fetched it: Dask runs that super-batch again and the dataset is the same."""
    client = fresh_client
    killed = {}

    def kill_one(futures, pass_index):
        if pass_index != 3 or killed:
            return
        pids = _pids(client)
        ours = {f.key for f in futures}
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            victims = {}
            for w, keys in client.processing().items():
                victims.setdefault(w, set()).update(ours & set(keys))
            for key, ws in client.who_has(futures).items():
                for w in ws:
                    victims.setdefault(w, set()).add(key)
            victims = {w: k for w, k in victims.items() if k}
            if victims:
                w, keys = next(iter(victims.items()))
                os.kill(pids[w], signal.SIGKILL)
                killed.update(worker=w, pid=pids[w], keys=keys)
                return
            time.sleep(0.002)

    tracker = DaskTracker(client, after_submit=kill_one)
    ds = run(small_case(**SPLIT), tracker=tracker)
    assert killed, "no worker was killed"
    data_vars_equal(local_ds, ds)
    # the killed worker's super-batches were computed again: by Dask (they went to "processing"
    # twice) or, if the scattered inputs died with the worker, submitted again by the tracker
    story = [t[1:] if t[0] == "scheduler" else t for t in client.story(*killed["keys"])]
    again = [k for k in killed["keys"] if sum(1 for t in story if t[0] == k and t[2] == "processing") >= 2]
    assert again or tracker.resubmitted, story


def _drop_replica(dask_scheduler, key, worker):
    """Scheduler side: forget ``worker``'s replica of ``key`` (what the active memory manager
    does to replicas no waiting task needs).  The check and the removal run in one call on the
    scheduler's loop; a replica the memory manager is dropping at that moment (the scheduler's
    bookkeeping then raises KeyError) is the state the test wants, so it is left to it."""
    ts, ws = dask_scheduler.tasks.get(key), dask_scheduler.workers.get(worker)
    if ts is None or ws is None or ws not in ts.who_has:
        return False
    try:
        dask_scheduler.request_remove_replicas(worker, [key], stimulus_id="eulag-test")
    except KeyError:
        return False
    return True


def _holders(dask_scheduler, key):
    ts = dask_scheduler.tasks.get(key)
    return [] if ts is None else sorted(ws.address for ws in ts.who_has)


def _dependencies(dask_scheduler, keys):
    """The dependencies of ``keys`` once the scheduler knows all of them (None before)."""
    if any(k not in dask_scheduler.tasks for k in keys):
        return None
    return sorted({d.key for k in keys for d in dask_scheduler.tasks[k].dependencies})


def test_worker_killed_with_the_last_copy_of_the_inputs_same_result(fresh_client, local_ds):
    """The worker killed mid-pass held the only replica of the scattered pass inputs: the
    unfetched super-batches are cancelled ("already forgotten"), the tracker submits them again
    with the inputs scattered anew, and the dataset is the same (a failure seen in CI:
    the active memory manager had dropped the other replica)."""
    client = fresh_client
    killed = {}

    def kill_holder(futures, pass_index):
        # the moment of the CI failure: one worker still runs a super-batch, the other has
        # none left (so the active memory manager may drop its replica of the inputs)
        if pass_index < 3 or killed:
            return
        pids = _pids(client)
        ours = {f.key for f in futures}
        deadline = time.monotonic() + 30
        while (deps := client.run_on_scheduler(_dependencies, keys=sorted(ours))) is None:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        [shared] = deps
        while time.monotonic() < deadline and not all(f.done() for f in futures):
            running = {w: ours & set(keys) for w, keys in client.processing().items()}
            busy = [w for w, keys in running.items() if keys]
            if len(busy) == 1 and len(running) == 2:
                [victim] = busy
                [idle] = [w for w in running if w != victim]
                if idle in client.run_on_scheduler(_holders, key=shared):
                    client.run_on_scheduler(_drop_replica, key=shared, worker=idle)
                os.kill(pids[victim], signal.SIGKILL)
                killed.update(worker=victim, pid=pids[victim], pass_index=pass_index)
                return
            time.sleep(0.001)

    tracker = DaskTracker(client, after_submit=kill_holder)
    ds = run(small_case(**SPLIT), tracker=tracker)
    assert killed, "no worker was killed"
    assert tracker.resubmitted > 0
    data_vars_equal(local_ds, ds)


def test_resubmit_rounds_bounded(client):
    """Inputs lost again and again: after ``resubmit_rounds`` the pass stops with the Dask
    connection error (the scheduler is fine, so the message names the cancellation)."""
    loop = CouplingLoop(small_case(**SPLIT))
    loop.step()
    args = (loop.mesh, loop.gas, loop.spec, loop.physics)
    kw = dict(parcels=1000, seed=3, pass_index=7, stats=loop.stats, settings=loop.settings)

    class Cancelling(DaskTracker):
        def _submit(self, inputs, tag, indices, held):
            futures = super()._submit(inputs, tag, indices, held)
            client.cancel(list(futures.values()), reason="eulag-test")
            return futures

    tracker = Cancelling(client, resubmit_rounds=2)
    with pytest.raises(DaskConnectionError, match="cancelled"):
        tracker(*args, **kw)
    _, _, supers = particles.batch_plan(1000, loop.settings)
    assert tracker.resubmitted == 2 * len(supers) and tracker.passes == 0


def test_lost_scheduler_clear_error_checkpoint_intact(tmp_path, local_ds):
    """A scheduler of our own (subprocess) killed during pass 2: DaskConnectionError, the
    checkpoint of pass 1 untouched, and a resumed run ends with the uninterrupted numbers."""
    port = _free_port()
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", str(port),
                              "--no-dashboard", "--host", "127.0.0.1"], env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", f"tcp://127.0.0.1:{port}",
                               "--nthreads", "1", "--no-dashboard", "--no-nanny"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    case = small_case(**SPLIT)
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()  # pass 1 (here, locally): its checkpoint is written
    before = ckpt.read_bytes()
    killed = []
    try:
        with dask_client(scheduler=f"tcp://127.0.0.1:{port}", timeout=60) as c:
            c.wait_for_workers(1, timeout=60)

            def kill_scheduler(futures, pass_index):
                assert not any(f.done() for f in futures)
                sched.kill()
                killed.append(pass_index)

            loop.tracker = DaskTracker(c, after_submit=kill_scheduler)
            with pytest.raises(DaskConnectionError, match="pass 2: lost the Dask scheduler") as err:
                loop.run()
            assert isinstance(err.value, CouplingError) and "\n" not in str(err.value)
    finally:
        for p in (sched, worker):
            p.kill()
            p.wait()
    assert killed == [2] and loop.pass_index == 2
    assert ckpt.read_bytes() == before  # the checkpoint of the last complete pass, intact
    assert not list(tmp_path.glob("*.tmp*"))
    ds = run(case, tmp_path / "out.nc", resume=True)
    data_vars_equal(local_ds, ds)


def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ---------------------------------------------------------------------------- slow
@pytest.mark.slow
def test_cli_run_dask_local_equals_local(tmp_path):
    case = _write_case(tmp_path / "c.toml", "c", 3)
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    for tag, extra in (("local", []), ("dask", ["--dask-local", "2"])):
        r = subprocess.run([sys.executable, "-m", "eulag", "run", str(case), "-o", str(tmp_path / f"{tag}.nc"),
                            "--quiet", *extra], env=env, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
    import xarray as xr

    with xr.open_dataset(tmp_path / "local.nc") as a, xr.open_dataset(tmp_path / "dask.nc") as b:
        data_vars_equal(a.load(), b.load())


@pytest.mark.slow
def test_sweep_subprocess_killed_and_resumed(tmp_path):
    cases = [_write_case(tmp_path / f"c{i}.toml", f"kill_{i}", seed) for i, seed in enumerate((3, 4, 5))]
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "eulag", "sweep", *map(str, cases), "-o", str(out), "--quiet"]
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first = out / "kill_0.nc"
    deadline = time.monotonic() + 300
    while not first.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    assert first.exists() and not (out / "kill_2.nc").exists(), "the sweep was not killed mid-way"
    stamp = first.stat().st_mtime_ns
    r = subprocess.run(cmd + ["--dask-local", "2"], env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert first.stat().st_mtime_ns == stamp
    rows = sweep.read_summary(out / "sweep_summary.csv")
    assert [r["status"] for r in rows] == ["finished earlier", "ran", "ran"]


@pytest.mark.slow
def test_sweep_worker_killed_during_a_case_resumes_it(tmp_path, fresh_client):
    """A worker killed while it runs a case (after the case's first checkpoint): Dask runs the
    case task again, it continues from the checkpoint and ends with the uninterrupted numbers."""
    client = fresh_client
    cases = [_write_case(tmp_path / f"c{i}.toml", f"wk_{i}", seed) for i, seed in enumerate((3, 4))]
    out = tmp_path / "out"
    entries = sweep.plan_sweep([str(c) for c in cases], out)
    ckpt = out / "wk_0.nc.checkpoint"
    import threading

    killed = {}

    def killer():
        pids = _pids(client)
        deadline = time.monotonic() + 120
        while not ckpt.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        for w, keys in client.processing().items():
            if any("eulag-case-wk_0" in k for k in keys):
                os.kill(pids[w], signal.SIGKILL)
                killed["worker"] = w
                return

    t = threading.Thread(target=killer)
    t.start()
    rows = sweep.run_sweep(entries, client, numba_threads=1)
    t.join()
    assert killed, "the worker running wk_0 was not killed"
    assert [r["status"] for r in rows] == ["ran", "ran"]
    import xarray as xr

    with xr.open_dataset(out / "wk_0.nc") as ds:
        data_vars_equal(run(small_case(**{"numerics.max_passes": 16})), ds.load())
