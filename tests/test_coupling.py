"""The coupling loop: bookkeeping, history, checkpoint/resume equality, physics switches."""

import json
import math

import numpy as np
import pytest

from eulag.config import Case, CaseError
from eulag.coupling import CouplingLoop
from eulag.runs import run

SMALL = {
    "name": "small_coupled",
    "pipe": {"diameter": 0.0305, "length": 0.5, "mode": "periodic"},
    "gas": {"density": 1.205, "viscosity": 1.81e-5, "bulk_velocity": 10.0, "inlet_k": 1.0},
    "particles": {"diameter": 100e-6, "density": 1020.0, "mass_loading": 0.2},
    "walls": {"roughness_angle_std_deg": 3.0},
    "numerics": {"radial_cells": 8, "azimuthal_cells": 16, "parcels": 1500, "parcels_start": 1000,
                 "max_passes": 6, "average_passes": 2, "batch_size": 200, "seed": 3},
}


def small_case(**changes):
    d = {k: dict(v) if isinstance(v, dict) else v for k, v in SMALL.items()}
    for key, value in changes.items():
        section, leaf = key.split(".")
        d.setdefault(section, {})[leaf] = value
    return Case.from_dict(d)


def data_vars_equal(a, b):
    skip = {"time_gas_solve_pass", "time_lagrangian_pass"}
    for name in a.data_vars:
        if name in skip:
            continue
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


@pytest.fixture(scope="module")
def uninterrupted():
    return run(small_case())


def test_loop_history_and_bookkeeping(uninterrupted):
    ds = uninterrupted
    n = ds.sizes["iteration"]
    assert 3 <= n <= 6
    assert np.all(ds.parcels_lost.values == 0)
    assert np.isnan(ds.residual.values[0]) and np.all(np.isfinite(ds.residual.values[1:]))
    assert ds.parcels.values[-1] == 1500 and ds.parcels.values[0] == 1000
    assert ds.attrs["parcels_injected_final"] == ds.attrs["parcels_exited_final"] + ds.attrs["parcels_stuck_final"]
    # the particles add to the pressure drop and carry their mass flow through the section
    assert float(ds.solids_pressure_drop_ratio) > 1.0
    mdot = 0.2 * 1.205 * 10.0 * np.pi * 0.0305**2 / 4
    flux = float((ds.particle_mass_flux.isel(x=0) * ds.cell_area).sum())
    assert flux == pytest.approx(mdot, rel=2e-3)
    assert float(ds.particle_concentration_stderr.max()) > 0
    # the stochastic collision partners conserve momentum on average: at this loading their net
    # axial momentum is a small fraction of the particles' inflow
    cm = ds.collision_momentum_history.values
    assert np.all(np.isfinite(cm)) and np.all(np.abs(cm) < 0.05), cm


def test_resume_from_checkpoint_gives_the_same_dataset(tmp_path, uninterrupted):
    case = small_case()
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()
    loop.step()
    del loop  # "killed" after the second pass
    told = []
    resumed = run(case, tmp_path / "out.nc", resume=True, notify=told.append)
    assert told[0] == f"resuming from {ckpt} after pass 2 (early passes)", told
    data_vars_equal(uninterrupted, resumed)
    # the wall time counts every session: the resumed run's total holds the passes before it
    t = resumed.attrs
    assert t["time_total"] >= t["time_gas_solve"] + t["time_lagrangian"] > 0, t
    assert "time_compile" not in t


@pytest.mark.parametrize("changes", [{}, {"physics.partner_correlation": "cell", "numerics.max_passes": 8}])
def test_passes_streamed_beside_the_gas_march_give_the_same_dataset(changes):
    """A developing pipe: each pass tracked beside the gas march that feeds it (particles.stream)
    gives the dataset of the passes tracked after it, bit for bit; the pass after the loop
    converges, streamed with the early passes' parcel count, is tracked again.  A run held to
    one thread does not stream and gives the same dataset (with the default options: the
    thread count does not depend on them)."""
    from eulag.output import coupled_dataset

    import numba

    case = small_case(**{"pipe.mode": "developing", "numerics.axial_cells": 12, **changes})
    runs = []
    modes = ((False, 2), (True, 2), (True, 1)) if not changes else ((False, 2), (True, 2))
    for stream, threads in modes:
        old = numba.get_num_threads()
        try:
            numba.set_num_threads(threads)
            loop = CouplingLoop(case, stream=stream)
            loop.run()
        finally:
            numba.set_num_threads(old)
        runs.append((loop, coupled_dataset(loop)))
    (plain, a), (streamed, b) = runs[:2]
    if len(runs) > 2:
        one_thread, c = runs[2]
        assert one_thread.streamed == 0  # a run held to one thread keeps to it
        data_vars_equal(a, c)
    assert plain.streamed == 0 and streamed.streamed >= len(streamed.history.residual) - 3
    assert streamed.timings["lagrangian_after_gas"] < streamed.timings["lagrangian"]
    data_vars_equal(a, b)


@pytest.mark.parametrize("stop", ["after pass 2", "in pass 2's march"])
def test_a_run_stopped_while_a_pass_is_streamed_resumes_to_the_uninterrupted_dataset(tmp_path, monkeypatch, stop):
    """A developing run ended (killed, or its loop left) with the next pass streamed beside the
    march: after a pass, or in the middle of a march (an interrupt from the station callback,
    with the pass being streamed half tracked).  The checkpoint of the last complete pass
    carries nothing of the streamed pass, and the resumed run gives the uninterrupted run's
    dataset, bit for bit."""
    import numba

    from eulag.output import coupled_dataset
    from particles.stream import StreamedPass

    if numba.get_num_threads() < 2:
        pytest.skip("streaming needs two numba threads")
    case = small_case(**{"pipe.mode": "developing", "numerics.axial_cells": 12})
    ref = CouplingLoop(case, stream=True).run()
    assert ref.streamed > 0
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt, stream=True)
    loop.step()
    if stop == "after pass 2":
        loop.step()
        assert loop._stream is not None  # pass 3 was streamed beside pass 2's march (it may be done)
        loop.close()  # the run ends here; the streamed pass is lost
        done = 2
    else:
        station = StreamedPass.station

        def interrupted(self, i, *args):
            station(self, i, *args)
            if i == 6:
                raise KeyboardInterrupt

        monkeypatch.setattr(StreamedPass, "station", interrupted)
        with pytest.raises(KeyboardInterrupt):
            loop.step()  # stopped in pass 2's gas march, pass 3 streamed beside it
        monkeypatch.undo()
        loop.close()
        done = 1
    told = []
    resumed = run(case, tmp_path / "out.nc", resume=True, notify=told.append)
    assert told[0] == f"resuming from {ckpt} after pass {done} (early passes)", told
    data_vars_equal(coupled_dataset(ref), resumed)


def test_a_void_streamed_pass_is_tracked_again_and_streaming_stops(monkeypatch):
    """A streamed pass whose parcels reached rows the march had not built (forced here with a
    negative margin) is tracked again in the finished field: the dataset is the one of the
    passes tracked after their gas solves, and the run says so."""
    import time

    import particles.stream as stream_mod
    from eulag.output import coupled_dataset

    case = small_case(**{"pipe.mode": "developing", "numerics.axial_cells": 12, "numerics.max_passes": 4})
    plain = CouplingLoop(case, stream=False).run()
    monkeypatch.setattr(stream_mod, "ROW_MARGIN", -4)
    station = stream_mod.StreamedPass.station

    def slow_station(self, *args):  # a march slower than the particles, as in the scenes
        time.sleep(0.02)
        station(self, *args)

    monkeypatch.setattr(stream_mod.StreamedPass, "station", slow_station)
    told = []
    loop = CouplingLoop(case, stream=True, notify=told.append).run()
    assert loop.streamed == 0 and not loop.stream_passes
    assert any("tracked again in the finished gas field" in t for t in told), told
    data_vars_equal(coupled_dataset(plain), coupled_dataset(loop))


def test_checkpoint_without_a_newer_history_record_resumes(tmp_path):
    """A checkpoint written before a history record was added resumes, the record NaN for its passes."""
    case = small_case(**{"numerics.max_passes": 3})
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()
    with np.load(ckpt) as z:
        data = {k: z[k] for k in z.files if k != "hist_collision_momentum"}
    np.savez(ckpt, **data)
    ckpt.with_suffix(".checkpoint.npz").replace(ckpt)
    resumed = CouplingLoop(case, checkpoint=ckpt, resume=True)
    assert resumed.pass_index == 1 and np.isnan(resumed.history.collision_momentum[0])
    resumed.step()
    assert np.isfinite(resumed.history.collision_momentum[1])


def test_checkpoint_from_before_the_linearised_drag_resumes(tmp_path):
    """A checkpoint without the drag coefficient and its reference velocity (before 6f43b6b)
    resumes: the next pass's part is linearised about the gas it was sampled in."""
    case = small_case(**{"numerics.max_passes": 4})
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()
    with np.load(ckpt) as z:
        assert "src_drag" in z.files and "src_u_ref" in z.files
        data = {k: z[k] for k in z.files if k not in ("src_drag", "src_u_ref")}
    np.savez(ckpt, **data)
    ckpt.with_suffix(".checkpoint.npz").replace(ckpt)
    resumed = CouplingLoop(case, checkpoint=ckpt, resume=True)
    assert "drag" not in resumed.sources
    old = resumed.sources["momentum"].copy()
    u_before = np.stack([resumed.gas.ux, resumed.gas.uy, resumed.gas.uz])
    resumed.step()
    s, a = resumed.last_sample, resumed.alpha
    np.testing.assert_allclose(resumed.sources["drag"], a * s.drag_coefficient, rtol=1e-12)
    u_new = np.stack([resumed.gas.ux, resumed.gas.uy, resumed.gas.uz])
    want = (1 - a) * old + a * np.stack([s.momentum_source(c) for c in range(3)]) \
        + a * s.drag_coefficient * (u_before - u_new)
    np.testing.assert_allclose(resumed.sources["momentum"], want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


def test_checkpoint_from_before_the_partner_correlation_key_resumes(tmp_path):
    """A checkpoint of v0.1.0's layout, without the case key physics.partner_correlation and
    without the statistics' Stokes-number column (CS_ST), is the same case at the key's
    default, resumes, and gains the column from its statistics and gas (cell_stokes)."""
    import json

    from particles import cell_stokes
    from particles.layout import CS_ST, NCS

    case = small_case(**{"numerics.max_passes": 4})
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()
    with np.load(ckpt) as z:
        data = {k: z[k] for k in z.files}
    assert data["stats"].shape[1] == NCS
    meta = json.loads(bytes(data["meta"]).decode())
    assert meta["case"].pop("physics.partner_correlation") == "particle"
    data["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    data["stats"] = data["stats"][:, :CS_ST]
    np.savez(ckpt, **data)
    ckpt.with_suffix(".checkpoint.npz").replace(ckpt)
    resumed = CouplingLoop(case, checkpoint=ckpt, resume=True)
    assert resumed.stats.shape[1] == NCS
    np.testing.assert_array_equal(resumed.stats[:, CS_ST], cell_stokes(resumed.stats, resumed.gas, resumed.spec))
    np.testing.assert_array_equal(resumed.stats[:, :CS_ST], data["stats"])
    resumed.step()  # and the tracker takes them
    with pytest.raises(Exception, match="different case"):  # the key at another value is another case
        CouplingLoop(small_case(**{"numerics.max_passes": 4, "physics.partner_correlation": "cell"}),
                     checkpoint=ckpt, resume=True)


def test_cell_partner_correlation_takes_the_gas_of_the_pass():
    """With physics.partner_correlation = "cell" the tracker gets the cells' Stokes number
    with T_L of the gas it tracks in, not of the gas the statistics were taken in.  (What the
    loop hands to the tracker; the passes themselves are tracked by the kernel of the
    default correlation, which the other tests of this module compile, and the kernel's use
    of the cells' Stokes number is tested in test_particles_tracking.py.)"""
    import dataclasses

    from particles import cell_stokes
    from particles.layout import CS_ST

    loop = CouplingLoop(small_case(**{"physics.partner_correlation": "cell"}))
    assert loop.physics.partner_correlation == "cell"
    seen = []
    track = loop.tracker

    def spy(mesh, gas, spec, physics, *, stats=None, **kw):
        assert physics.partner_correlation == "cell"
        if stats is not None:
            seen.append((stats[:, CS_ST].copy(), cell_stokes(stats, gas, spec), loop.stats[:, CS_ST].copy()))
        return track(mesh, gas, spec, dataclasses.replace(physics, partner_correlation="particle"), stats=stats,
                     **kw)

    loop.tracker = spy
    for _ in range(3):
        loop.step()
    assert len(seen) == 2  # passes 2 and 3 (the first has no statistics)
    for given, want, kept in seen:
        np.testing.assert_array_equal(given, want)
        assert not np.allclose(given, kept, rtol=1e-3)  # the statistics' own were of another gas


def test_checkpoint_of_an_older_result_layout_is_refused(tmp_path):
    """Averaged passes stored with another tracker layout (the counters grew in 996d988) would
    fail later with a shape error: refused at once, with the remedy."""
    case = small_case(**{"physics.coupling": "one-way"})  # every pass is averaged at once
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()
    with np.load(ckpt) as z:
        data = {k: z[k] for k in z.files}
    assert "window_0" in data
    for i in range(3):
        data[f"window_{i}"] = data[f"window_{i}"][:-1]
    np.savez(ckpt, **data)
    ckpt.with_suffix(".checkpoint.npz").replace(ckpt)
    with pytest.raises(RuntimeError, match="older version"):
        CouplingLoop(case, checkpoint=ckpt, resume=True)


def test_checkpoint_of_another_case_is_refused(tmp_path):
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(small_case(), checkpoint=ckpt)
    loop.step()
    with pytest.raises(RuntimeError, match="different case"):
        CouplingLoop(small_case(**{"numerics.seed": 4}), checkpoint=ckpt, resume=True)


def test_resume_with_a_raised_pass_limit_gives_the_uninterrupted_dataset(tmp_path, uninterrupted):
    """Checkpointed under numerics.max_passes = 4 after pass 2 (still early), resumed under the
    limit 6 of the uninterrupted run: the same dataset (the old limit never acted)."""
    ckpt = tmp_path / "out.nc.checkpoint"
    loop = CouplingLoop(small_case(**{"numerics.max_passes": 4}), checkpoint=ckpt)
    loop.step()
    loop.step()
    assert loop.phase == "early"
    del loop
    told = []
    resumed = run(small_case(), tmp_path / "out.nc", resume=True, notify=told.append)
    assert any("max_passes = 6" in t and "was 4" in t for t in told), told
    data_vars_equal(uninterrupted, resumed)


def test_pass_limit_changes_that_would_have_acted_are_refused(tmp_path):
    from eulag import coupling

    ckpt = tmp_path / "out.nc.checkpoint"
    case = small_case(**{"numerics.max_passes": 4})
    loop = CouplingLoop(case, checkpoint=ckpt)
    loop.step()
    loop.step()
    meta, residual = coupling.read_checkpoint(ckpt)
    assert coupling.checkpoint_problem(meta, residual, case) is None
    assert coupling.checkpoint_problem(meta, residual, small_case(**{"numerics.max_passes": 9})) is None
    # pass 2 done, average_passes 2: a limit of 3 would have made pass 2 a final pass
    assert "final passes before pass 2" in coupling.checkpoint_problem(
        meta, residual, small_case(**{"numerics.max_passes": 3}))
    assert "done 7 passes" in coupling.checkpoint_problem(dict(meta, pass_index=7), residual, small_case())
    forced = dict(meta, phase="final", converged=False)
    assert "started by the limit 4" in coupling.checkpoint_problem(forced, residual, small_case())
    # the recovery gate: limit 40 -> 80 (average 2, W = 4) differs at passes 35-38; residuals
    # below the tolerance before them refuse, above it do not
    w = coupling._STAGNATION_WINDOW
    old = small_case(**{"numerics.max_passes": 40})
    new = small_case(**{"numerics.max_passes": 80})
    tol = new.numerics.coupling_tolerance
    later = dict(meta, pass_index=36, case=json.loads(json.dumps(old.to_attrs(), default=coupling._json_default)))
    above = np.full(36, 1.2 * tol)
    assert coupling.checkpoint_problem(later, above, new) is None
    below = above.copy()
    below[34 - w:34] = 0.5 * tol  # passes 31-34: what the judgement at pass 35 saw
    assert "raising the relaxation" in coupling.checkpoint_problem(later, below, new)
    assert coupling.checkpoint_problem(meta, residual, small_case(**{"numerics.seed": 4})) == (
        "checkpoint of a different case (numerics.seed = 3 in the checkpoint, 4 in this case)")
    with pytest.raises(RuntimeError, match="final passes before pass 2"):
        CouplingLoop(small_case(**{"numerics.max_passes": 3}), checkpoint=ckpt, resume=True)


def test_one_way_coupling_leaves_the_gas_alone():
    ds = run(small_case(**{"physics.coupling": "one-way"}))
    assert float(np.abs(ds.source_ux).max()) == 0.0
    assert float(ds.solids_pressure_drop_ratio) == pytest.approx(1.0, abs=1e-12)
    assert int(ds["converged"]) == 1
    assert ds.sizes["iteration"] == 2  # the final passes only


def test_relaxation_carries_the_previous_sinks_to_the_present_turbulence():
    """The k sinks act as linear sinks S k/k_ref: what is relaxed is the rate S/k_ref, so a
    pass whose sink rate is unchanged leaves the relaxed rate unchanged even when k has fallen."""
    import dataclasses

    loop = CouplingLoop(small_case())
    loop.step()
    loop.step()
    prev = loop.sources
    assert np.any(prev["k"] < 0)
    loop.gas = dataclasses.replace(loop.gas, k=0.5 * prev["k_ref"], epsilon=0.25 * prev["eps_ref"])
    comp = {"momentum": prev["momentum"], "k": 0.5 * prev["k"],
            "se_momentum": np.ones_like(prev["momentum"]), "se_k": np.ones_like(prev["k"])}
    new, _ = loop._relax(comp, None, 0.3)
    sink = prev["k"] < 0
    np.testing.assert_allclose(new["k"][sink] / new["k_ref"][sink], prev["k"][sink] / prev["k_ref"][sink],
                               rtol=1e-12)
    # the dissipation source is not relaxed: the gas solve forms C_eps3 (eps/k) S_k itself
    assert "epsilon" not in new
    src = loop._gas_sources(new)
    assert src.c_eps3 == loop.case.physics.c_eps3 and not np.any(src.epsilon)


def test_residual_noise_of_a_cell_the_particles_left_is_its_sampling_noise():
    """numerics.residual_noise = "batch-visits": a cell with no visits in the pass, whose relaxed
    source S then decays by α S, counts as noise, α S / (α sqrt(2/(2 − α)) |S| / sqrt(0 + 1)) =
    sqrt((2 − α)/2) per component, where the batch floor (1 % of the RMS source) makes it a large
    ratio; with many visits the floor is the batch one."""
    alpha = 0.3
    out = {}
    for mode in ("batch", "batch-visits"):
        loop = CouplingLoop(small_case(**{"numerics.residual_noise": mode}))
        loop.step()
        prev = loop.sources
        cell = tuple(int(v[0]) for v in np.nonzero(np.all(prev["momentum"] != 0.0, axis=0) & (prev["k"] != 0.0)))
        # the k sinks are carried to the present k as the loop does (the relaxation test above)
        k_now = np.where(prev["k"] < 0.0, prev["k"] * (loop.gas.k / prev["k_ref"]), prev["k"])
        comp = {"momentum": prev["momentum"].copy(), "k": k_now,
                "se_momentum": np.full_like(prev["momentum"], np.nan), "se_k": np.full_like(prev["k"], np.nan),
                "visits": np.full(prev["k"].shape, 1e30)}
        comp["momentum"][(slice(None),) + cell] = 0.0
        comp["k"][cell] = 0.0
        comp["visits"][cell] = 0.0
        out[mode] = loop._relax(comp, None, alpha)[1]
        if mode == "batch-visits":
            n = 4 * prev["k"].size  # three momentum components and k in every cell
            assert out[mode] == pytest.approx(math.sqrt(4 * (2 - alpha) / 2 / n), rel=1e-9)
            comp["visits"][cell] = 1e30  # well sampled: the batch floor alone
            assert loop._relax(comp, None, alpha)[1] == pytest.approx(out["batch"], rel=1e-12)
    assert out["batch"] > 10 * out["batch-visits"]


@pytest.mark.parametrize("weight", [1.0, 0.6])
def test_the_relaxed_momentum_source_is_kept_as_applied_in_the_new_gas(weight):
    """Linearised drag: the gas solve applies S_used + β_used (U_ref − U); what the loop keeps
    after it is that source in the new gas field (U_ref = the new U); β_used = w α β_pass with
    w = numerics.drag_implicit_weight (default 1), the blend of the explicit sources unchanged."""
    loop = CouplingLoop(small_case(**{"numerics.drag_implicit_weight": weight}))
    loop.step()
    first = loop.sources
    beta1 = loop.last_sample.drag_coefficient
    np.testing.assert_allclose(first["drag"], weight * 0.3 * beta1, rtol=1e-12)
    for c, name in enumerate(("ux", "uy", "uz")):
        np.testing.assert_array_equal(first["u_ref"][c], getattr(loop.gas, name))
    held = {k: v.copy() for k, v in first.items()}
    loop.step()
    s2 = loop.last_sample
    mom2 = np.stack([s2.momentum_source(c) for c in range(3)])
    blended = 0.7 * held["momentum"] + 0.3 * mom2
    drag = weight * 0.3 * s2.drag_coefficient  # only the pass's part α S_pass is linearised
    np.testing.assert_allclose(loop.sources["drag"], drag, rtol=1e-12)
    u_new = np.stack([loop.gas.ux, loop.gas.uy, loop.gas.uz])
    applied = blended + drag * (held["u_ref"] - u_new)
    np.testing.assert_allclose(loop.sources["momentum"], applied, rtol=1e-12, atol=1e-12 * np.abs(applied).max())
    assert np.abs(u_new - held["u_ref"]).max() > 1e-3  # the gas moved, so the two differ
    # (that the linearised source keeps the explicit one's solution: tests/test_rans_pipe_flow.py)


def test_the_drag_implicit_weight_keeps_a_stiff_mode_damped():
    """numerics.drag_implicit_weight is refused at 0.5 and below (a stiff mode would no longer be
    damped: −(1 − w)/w per pass) and above 1, with the key named."""
    for bad in (0.5, 0.3, 1.01):
        with pytest.raises(CaseError, match="numerics.drag_implicit_weight"):
            small_case(**{"numerics.drag_implicit_weight": bad})
    assert small_case(**{"numerics.drag_implicit_weight": 0.6}).to_attrs()["numerics.drag_implicit_weight"] == 0.6


def test_seen_energy_of_tracers_matches_the_gas_k_in_the_core():
    """physics.k_source_scaling = "seen-energy" rescales S_k by k/k_seen: for tracers in fully
    developed flow the Langevin fluctuations they see carry the local k (factor ~ 1)."""
    import particles
    import rans

    case = small_case()
    mesh = PipeMesh_from(case)
    gas = rans.solve(mesh, rans.GasProperties(1.205, 1.81e-5), 10.0, 1.0)
    spec = particles.ParticleSpec(10e-6, 1020.0, 0.01, 10.0, 0.5, 0.0)
    s = particles.track(mesh, gas, spec, particles.PhysicsOptions(inter_particle_collisions=False),
                        parcels=4000, seed=2, pass_index=1)
    ratio = s.seen_k / gas.k
    core = np.zeros(mesh.shape, bool)
    core[:, : mesh.nr // 2, :] = True
    ok = core & (s.visits >= 200)
    assert ok.sum() > 0.5 * core.sum()
    med = np.median(ratio[ok])
    assert 0.85 < med < 1.15, med  # measured 0.97-1.00 per ring (200 um: 0.98-1.04)


def PipeMesh_from(case):
    from eulag.coupling import build_mesh

    return build_mesh(case)


def test_collision_statistics_are_relaxed_like_the_sources():
    from eulag.coupling import _relax_statistics
    from particles.layout import CS_N, CS_OK, CS_RMS, CS_U, CS_WM, NCS

    old = np.zeros((3, NCS))
    new = np.zeros((3, NCS))
    old[:, CS_OK] = [1, 1, 0]
    new[:, CS_OK] = [1, 0, 1]
    old[:, CS_N], new[:, CS_N] = [1e9, 2e9, 0], [3e9, 0, 5e9]
    old[:, CS_U], new[:, CS_U] = [10.0, 9.0, 0], [12.0, 0, 8.0]
    old[:, CS_RMS], new[:, CS_RMS] = [0.3, 0.2, 0], [0.4, 0, 0.5]
    old[:, CS_WM + 2], new[:, CS_WM + 2] = [100.0, 50.0, 0], [300.0, 0, 20.0]
    out = _relax_statistics(old, new, 0.25)
    # sampled in both: the 0.75/0.25 blend, rms through the variances; the mean velocity (and
    # spin) with weight 0.5 at least: blended at α its approach to the particles is too slow
    assert out[0, CS_N] == pytest.approx(0.75e9 + 0.75e9)
    assert out[0, CS_U] == pytest.approx(0.5 * 10 + 0.5 * 12)
    assert out[0, CS_WM + 2] == pytest.approx(0.5 * 100 + 0.5 * 300)
    assert out[0, CS_RMS] == pytest.approx(np.sqrt(0.75 * 0.09 + 0.25 * 0.16))
    # sampled once: that sample's row, flagged usable
    np.testing.assert_array_equal(out[1], old[1])
    np.testing.assert_array_equal(out[2], new[2])
    assert np.all(out[:, CS_OK] == 1)


@pytest.mark.parametrize("residuals, halved", [
    ([3.0, 2.6, 2.4, 2.5, 2.3, 2.4, 2.5, 2.2], True),     # stuck near 2.2-2.6: halve
    ([3.0, 2.6, 2.4, 2.5, 2.0, 1.9, 1.8, 1.7], False),    # still falling by > 10 %
    ([3.0, 2.6, 2.4, 2.5, 2.3, 1.2, 2.5, 2.2], False),    # once below the tolerance 1.5
    ([3.0, 2.6, 2.4, 2.5, 2.3, 2.4, 2.5], False),         # too few passes to judge
])
def test_relaxation_is_halved_when_the_residual_stagnates(residuals, halved):
    told = []
    loop = CouplingLoop(small_case(**{"numerics.coupling_tolerance": 1.5}), notify=told.append)
    loop.history.residual = [float("nan")] + residuals
    loop.pass_index = len(loop.history.residual) + 1
    loop._adapt_relaxation()
    assert loop.alpha == (0.15 if halved else 0.3)
    # the user is told when it happens, not only in the next pass line
    assert [("halved to 0.15" in t) for t in told] == ([True] if halved else [])
    if halved:
        # the next judgement waits for 2 W passes at the new relaxation
        loop.history.residual += [2.3]
        loop.pass_index += 1
        loop._adapt_relaxation()
        assert loop.alpha == 0.15


@pytest.mark.parametrize("dp, alpha, drifting", [
    ([34.2, 28.3, 34.9, 39.2, 43.7, 47.5, 51.6, 59.2], 0.3, True),    # scene g, passes 2-9
    ([64.4, 64.8, 65.1, 65.3, 65.5, 65.7, 65.9, 66.1], 0.15, True),   # f, passes 15-22: 2 % to come
    ([72.7, 73.0, 73.2, 73.4, 73.5, 73.6, 73.8, 73.9], 0.3, False),   # eta = 10: 0.5 % to come
    ([86.7, 40.2, 144.1, 25.7, 119.4, 43.7, 107.1, 47.0], 0.3, False),  # an oscillation
    ([62.1, 75.7, 63.2, 67.6, 69.9, 70.8, 73.7, 74.7], 0.3, False),   # a trend within the scatter
    ([65.3, 67.2, 67.1, 67.5, 68.2, 68.7, 69.2], 0.15, False),        # too few passes
])
def test_steady_drift_of_the_pressure_gradient(dp, alpha, drifting):
    """Windows of -dp/dx from the runs (results/README.md): a drift above 3 standard errors
    with more than 1 % still to come at this α."""
    from eulag.coupling import steady_drift

    trend = steady_drift(dp, alpha, 8)
    assert (trend is not None) == drifting
    if drifting:
        assert trend == pytest.approx(np.polyfit(np.arange(8.0), dp, 1)[0])


def test_relaxation_is_kept_while_the_pressure_gradient_drifts():
    """The stagnation rule does not halve α while -dp/dx follows a steady drift (the residual
    then measures the approach, not only the noise); it does once the drift has stopped."""
    told = []
    loop = CouplingLoop(small_case(**{"numerics.coupling_tolerance": 1.5}), notify=told.append)
    stuck = [2.5, 2.3, 2.4, 2.5, 2.2, 2.4, 2.4, 2.3]
    loop.history.residual = [float("nan")] + stuck
    loop.history.pressure_gradient = [14.9, 34.2, 28.3, 34.9, 39.2, 43.7, 47.5, 51.6, 59.2]
    loop.pass_index = 10
    loop._adapt_relaxation()
    assert loop.alpha == 0.3
    assert len(told) == 1 and "drifts steadily" in told[0] and "kept at 0.3" in told[0]
    loop.history.residual.append(2.4)             # still drifting: kept, told only once per α
    loop.history.pressure_gradient.append(62.5)
    loop.pass_index += 1
    loop._adapt_relaxation()
    assert loop.alpha == 0.3 and len(told) == 1
    loop.history.residual += stuck                # the drift has stopped: halved
    loop.history.pressure_gradient += [73.6, 73.9, 73.7, 73.8, 73.9, 73.8, 73.9, 73.9]
    loop.pass_index += 8
    loop._adapt_relaxation()
    assert loop.alpha == 0.15 and "halved to 0.15" in told[-1]


def _judge(loop, residuals):
    """The passes with ``residuals`` have run: α is judged before the next one."""
    loop.history.residual += residuals
    loop.pass_index = len(loop.history.residual) + 1
    loop._adapt_relaxation()
    return loop.alpha


@pytest.mark.parametrize("residuals, cap, max_passes, raised", [
    ([1.2, 1.1, 1.3, 1.0], 0.3, 40, True),     # noise below the tolerance 1.5: back to 0.3
    ([1.2, 1.6, 1.3, 1.0], 0.3, 40, False),    # one of the last W above the tolerance
    ([1.2, 1.3, 1.0], 0.3, 40, False),         # too few passes at this α to judge
    ([1.2, 1.1, 1.3, 1.0], 0.15, 40, False),   # the gas solve failed at 0.3: stays
    ([1.2, 1.1, 1.3, 1.0], 0.3, 20, False),    # 20 - 3 final - pass 14: < W early passes left
])
def test_relaxation_is_raised_again_when_the_residual_is_below_the_tolerance(residuals, cap, max_passes, raised):
    """The recovery rule (coupling module docstring): α halved by the stagnation rule is
    doubled again, once, when the residual sits below the tolerance but the loop has not
    converged."""
    told = []
    loop = CouplingLoop(small_case(**{"numerics.coupling_tolerance": 1.5, "numerics.max_passes": max_passes,
                                      "numerics.average_passes": 3}), notify=told.append)
    loop.history.residual = [float("nan"), 2.3, 2.4, 2.2, 2.5, 2.3, 2.4, 2.5, 2.2]
    loop.alpha, loop.alpha_changed_at, loop.alpha_cap = 0.15, 9, cap
    assert _judge(loop, residuals) == (0.3 if raised else 0.15)
    assert [("raised again to 0.3" in t) for t in told] == ([True] if raised else [])
    if raised:
        # stagnating again at the recovered α halves it for good
        assert _judge(loop, [2.3, 2.4, 2.2, 2.5, 2.3, 2.4, 2.5, 2.2]) == 0.15
        assert _judge(loop, [1.2, 1.1, 1.3, 1.0]) == 0.15


def test_the_recovery_doubles_alpha_once():
    """0.3 -> 0.15 -> 0.075 by the stagnation rule: the recovery goes back to 0.15 only, not on
    to 0.3, an α that already stagnated."""
    loop = CouplingLoop(small_case(**{"numerics.coupling_tolerance": 1.5, "numerics.max_passes": 40}))
    loop.history.residual = [float("nan")] + [2.3] * 16
    loop.alpha, loop.alpha_changed_at = 0.075, 17
    assert _judge(loop, [1.2, 1.1, 1.3, 1.0]) == 0.15
    assert _judge(loop, [1.2, 1.1, 1.3, 1.0]) == 0.15


def test_a_failed_gas_solve_caps_the_recovery(monkeypatch):
    """An α whose gas solve failed is never tried again by the recovery rule."""
    import rans

    loop = CouplingLoop(small_case())
    orig = loop._solve_gas
    calls = []

    def solve_gas(sources, **kwargs):
        calls.append(sources is not None)
        if sources is not None and len(calls) == 2:
            raise rans.SolverDivergence("gas solve diverged: u_x = -1 (test)")
        return orig(sources, **kwargs)

    monkeypatch.setattr(loop, "_solve_gas", solve_gas)
    loop.step()
    loop.step()
    assert loop.alpha == loop.alpha_cap == 0.15


def test_the_pressure_gradient_drift_uses_the_smallest_relaxation_of_its_window():
    """-dp/dx rising by 1 Pa/m per pass at 100 Pa/m: at α = 0.15 throughout, 1 x 0.85/0.15 =
    5.7 % to come; when the first passes of the window ran at 0.075 (α just raised), the
    slower approach measured there counts: 1 x 0.925/0.075 = 12.3 %."""
    from eulag.coupling import pressure_gradient_to_come

    dp = [96.0, 97.0, 98.0, 99.0, 100.0]
    trend, to_come, alpha = pressure_gradient_to_come(dp, [0.15] * 5)
    assert trend == pytest.approx(1.0) and alpha == 0.15
    assert to_come == pytest.approx(0.85 / 0.15 / 100.0)
    trend, to_come, alpha = pressure_gradient_to_come(dp, [0.3, 0.075, 0.075, 0.15, 0.15])
    assert alpha == 0.075 and to_come == pytest.approx(0.925 / 0.075 / 100.0)


def test_a_slow_geometric_drift_of_the_pressure_gradient_is_not_taken_for_convergence():
    """-dp/dx = 100 - 10 r^n with r = 0.97 at α = 0.3: after 12 passes it creeps by 0.21 Pa/m
    per pass with 7.2 Pa/m still to come.  (1 - α)/α would say 0.5 % (converged); the
    contraction shown by the last eight passes gives the true ~7.7 %."""
    from eulag.coupling import _geometric_ahead, pressure_gradient_to_come

    n = np.arange(12)
    dp = 100.0 - 10.0 * 0.97**n
    rel = [0.3] * 12
    truth = (100.0 - dp[-1]) / dp[-1]
    trend, to_come, alpha = pressure_gradient_to_come(dp, rel)
    assert abs(trend) * (0.7 / 0.3) / dp[-1] < 0.01  # what the relaxation alone would say
    assert to_come == pytest.approx(truth, rel=0.05)
    assert _geometric_ahead(dp, rel) == pytest.approx(0.97 / 0.03, rel=1e-6)
    # a drift that is not slowing down (rising increments) is never converged
    assert pressure_gradient_to_come(100.0 + 0.05 * n**2, rel)[1] == math.inf
    # noise about a level, an oscillation, or α changed in the window: the α estimate stands
    noisy = 100.0 + 0.05 * np.random.default_rng(4).standard_normal(12)
    assert _geometric_ahead(noisy, rel) is None
    assert _geometric_ahead(100.0 + (-1.0) ** n * 0.97**n, rel) is None
    assert _geometric_ahead(dp, [0.15] * 6 + [0.3] * 6) is None


def test_each_pass_reports_the_phase_it_ran_in():
    """The pass at which the loop converges ran with the early parcels and is reported early;
    the final passes (the case's parcels) final."""
    loop = CouplingLoop(small_case(**{"numerics.coupling_tolerance": 1000.0, "numerics.max_passes": 20}))
    states = []
    while not loop.finished:
        states.append(loop.step())
    assert loop.converged_at is not None and loop.converged_at < 18  # converged, not forced
    assert [s.phase for s in states] == ["final" if s.parcels == 1500 else "early" for s in states]
    assert states[-1].phase == "final" and states[0].phase == "early"


def test_a_turned_swing_of_the_pressure_gradient_is_bounded_by_its_range():
    """A slow oscillation about the converged state steepens after its turn, which the
    contraction estimate reads as unbounded, and is flat at its extremes, which the trend
    reads as converged.  Once the last sixteen passes show the swing turn (significant trends
    of opposite sign in two of their quarters), its range is the change to come: 0.44 % for
    scene a's swing (converged at every pass), 4.4 % for one ten times larger (at no pass); a
    creep that speeds up without turning stays unbounded, noise about a level is no swing."""
    from eulag.coupling import _geometric_ahead, _swing_range, pressure_gradient_to_come

    n = np.arange(30)
    rel = [0.3] * 30
    rng = np.random.default_rng(7)
    small = 63.45 + 0.14 * np.sin(2.0 * np.pi * n / 18.0) + 0.003 * rng.standard_normal(30)
    large = 63.45 + 1.4 * np.sin(2.0 * np.pi * n / 18.0) + 0.03 * rng.standard_normal(30)
    for h, lo, hi in ((small, 0.003, 0.01), (large, 0.03, 0.1)):
        unbounded = 0
        for k in range(16, 31):
            swing = _swing_range(h[:k])
            assert swing == pytest.approx(np.ptp(h[k - 16:k]))
            unbounded += _geometric_ahead(h[:k], rel[:k]) == math.inf
            assert lo < pressure_gradient_to_come(h[:k], rel[:k])[1] < hi
        assert unbounded > 0  # the case the range replaces
    creep = 100.0 + 0.05 * n[:16] ** 2
    assert _swing_range(creep) is None
    assert pressure_gradient_to_come(creep, rel[:16])[1] == math.inf
    noise = 100.0 + 0.05 * rng.standard_normal((200, 16))
    assert sum(_swing_range(v) is not None for v in noise) <= 3


def test_collision_statistics_keep_the_case_relaxation_when_alpha_is_lowered():
    # α lowered for the gas (0.075) must not freeze the partner statistics at the first passes'
    from particles.layout import CS_N, CS_OK, NCS

    loop = CouplingLoop(small_case(**{"numerics.relaxation": 0.3}))
    old, new = np.zeros((2, NCS)), np.zeros((2, NCS))
    old[:, CS_OK] = new[:, CS_OK] = 1
    old[:, CS_N], new[:, CS_N] = 10.0, 6.0
    loop.stats = old
    loop.pass_index = 2   # the statistics held are the collision-free first pass's: replaced
    np.testing.assert_array_equal(loop._next_statistics(new), new)
    loop.pass_index = 5
    loop.alpha = 0.075
    assert loop.statistics_weight() == 0.3
    out = loop._next_statistics(new)
    np.testing.assert_allclose(out[:, CS_N], 0.7 * 10.0 + 0.3 * 6.0)
    loop.alpha = 0.5     # a larger α (a case relaxing faster) is used as it is
    assert loop.statistics_weight() == 0.5


def test_a_failing_gas_solve_is_retried_with_half_the_relaxation_and_the_user_is_told():
    import rans

    told = []
    loop = CouplingLoop(small_case(), notify=told.append)
    orig = loop._solve_gas
    with_sources = []

    def flaky(sources, **kwargs):
        if sources is not None:
            with_sources.append(1)
            if len(with_sources) == 1:
                raise rans.SolverDivergence("k = nan at x = 0.1 m (test)")
        return orig(sources, **kwargs)

    loop._solve_gas = flaky
    state = loop.step()
    assert loop.alpha == 0.15 and state.relaxation == 0.15 and len(with_sources) == 2
    assert told == ["pass 1: gas solve with source relaxation 0.3 failed (k = nan at x = 0.1 m (test)); "
                    "retrying with 0.15"]


def test_a_failed_developing_march_goes_straight_to_a_smaller_source_relaxation(monkeypatch):
    """The march retries a failing station itself; the loop does not march again with more
    k-eps relaxation (that would repeat the station's attempts), it halves α."""
    import rans

    loop = CouplingLoop(small_case(**{"pipe.mode": "developing", "pipe.length": 0.2,
                                      "numerics.axial_cells": 10}))
    assert loop.mesh.mode == "developing"
    real = rans.solve
    calls = []

    def solve(*args, **kwargs):
        if args[5] is not None:
            calls.append(kwargs["turbulence_relaxation"])
            if len(calls) == 1:
                raise rans.SolverDivergence("epsilon = inf (test)")
        return real(*args, **kwargs)

    monkeypatch.setattr(rans, "solve", solve)
    loop.step()
    assert calls == [1.0, 1.0] and loop.alpha == 0.15


@pytest.mark.parametrize("diameter, lo, hi", [
    # continuous OU limit 1; the frozen-u'_F steps (dt ~ 0.5 T_L) give (1 - e^-h)/h ~ 0.79
    (1e-6, 0.72, 1.05),    # measured 0.83 (interquartile 0.79-0.86)
    (10e-6, 0.9, 1.15),    # measured 1.04 (0.99-1.09)
])
def test_k_sink_of_small_particles_matches_the_langevin_two_fluid_result(diameter, lo, hi):
    """With a first-order Langevin seen velocity, a particle's slip dissipates
    <u'_F (u_F - u_p)>/tau_p = 2k/(T_L + tau_p) per unit mass (two-fluid: k - k_fp =
    k tau_p/(T_L + tau_p)), so S_k -> -2 c_p k/(T_L + tau_p), which stays finite for tracers
    (tau_p -> 0): the reason the 1 µm stability case loses its turbulence (eulag study stability,
    "The 1 µm tracers"). Heavier particles fall below T_L through crossing trajectories, so the
    check is for tau_p << T_L only."""
    import particles
    import rans
    from particles.kernel import C_T

    case = small_case()
    mesh = PipeMesh_from(case)
    mu = 1.81e-5
    gas = rans.solve(mesh, rans.GasProperties(1.205, mu), 10.0, 1.0)
    spec = particles.ParticleSpec(diameter, 1020.0, 0.01, 10.0, 0.5, 0.0)
    s = particles.track(mesh, gas, spec, particles.PhysicsOptions(inter_particle_collisions=False),
                        parcels=3000, seed=2, pass_index=1)
    t_l = C_T * (2.0 / 3.0) * gas.k / gas.epsilon
    tau_p = 1020.0 * diameter**2 / (18.0 * mu)
    want = -2.0 * s.concentration * gas.k / (t_l + tau_p)
    core = np.zeros(mesh.shape, bool)
    core[:, : mesh.nr // 2, :] = True
    ok = core & (s.visits >= 200)
    assert ok.sum() > 0.5 * core.sum()
    ratio = np.median(s.k_source[ok] / want[ok])
    assert lo < ratio < hi, ratio


def test_with_the_partner_momentum_returned_convergence_waits_for_the_net_collision_momentum_to_vanish():
    """physics.partner_momentum = "returned" is an integral controller, and the loop swings
    about the balance (the base case, 100 passes: -0.083 of the inflow at pass 10, +0.017 at 30,
    within +-0.004 from 51).  collision_momentum_balance must not pass the swing for noise, at
    its turning points (where the trend criterion is met) nor at its zero crossings (where a
    window mean or a trend line's end vanishes), and must pass the settled noise."""
    from eulag.coupling import COLLISION_BALANCE_PASSES, collision_momentum_balance, convergence_criteria

    rng = np.random.default_rng(5)
    p = np.arange(120, dtype=float)
    noise = 0.0015
    passed_swing, passed_noise, draws = 0, 0, 200
    for _ in range(draws):
        swing = 0.12 * np.exp(-p / 14.0) * np.cos(2.0 * np.pi * p / 40.0 + 0.3)
        h = list(swing + noise * rng.normal(size=p.size))
        h[0] = 0.0
        # while the swing's envelope over the window is above 5 noise levels: never passed
        for m in range(14, 120):
            if 0.12 * np.exp(-(m - COLLISION_BALANCE_PASSES) / 14.0) > 5.0 * noise:
                passed_swing += collision_momentum_balance(h[:m]) < 1.0
        # pure noise about zero: passed in most windows
        passed_noise += collision_momentum_balance([0.0, 0.1] + list(noise * rng.normal(size=12))) < 1.0
    assert passed_swing == 0
    assert passed_noise > 0.75 * draws
    # a steady offset of 4 noise levels is not a balance
    assert collision_momentum_balance([0.0, 0.1] + list(0.006 + noise * rng.normal(size=12))) > 1.0
    assert collision_momentum_balance([0.0, 0.1, 0.01]) == math.inf  # too few passes to judge
    assert collision_momentum_balance([0.0] * 14) == 0.0  # nothing to return

    loop = CouplingLoop(small_case())
    h = loop.history
    h.residual = [math.nan] + [1.0] * 13
    h.pressure_gradient = [61.0] * 14
    h.relaxation = [0.3] * 14
    h.mass_balance = [0.0] * 14
    h.collision_momentum = [0.0, 0.2] + [-0.03] * 12  # settled (no trend), but not balanced
    names = [c.name for c in convergence_criteria(h, True, 1.5)]
    assert "collision_momentum_balance" not in names  # the partners' impulse discarded: a level is reported
    crit = {c.name: c for c in convergence_criteria(h, True, 1.5, returned=True)}
    assert crit["collision_momentum_to_come"].met and not crit["collision_momentum_balance"].met


def test_convergence_waits_for_the_collision_momentum_to_settle():
    """Sources and pressure gradient settled, but the fictitious partners' momentum still
    changing by 0.5 % of the particle inflow per pass (eta = 10 at 'convergence' before this
    check): not converged.  A steady level is the model's and is reported, not waited for."""
    from eulag.coupling import collision_momentum_settled

    # still decaying by 1-3 % of the inflow per pass (eta = 10, frozen gas: 0.28, 0.25, ...)
    assert not collision_momentum_settled([0.0, 0.3, 0.28, 0.25, 0.23, 0.21, 0.19, 0.17])
    assert not collision_momentum_settled([0.0, 0.3, 0.13, 0.125, 0.12, 0.115, 0.11, 0.105])
    # the collision-free first pass and the second's spike do not count: not yet six passes
    assert not collision_momentum_settled([0.0, 0.1, 0.03, 0.03, 0.03, 0.03])
    # a steady level with pass-to-pass noise (the 200x10x20 base case: -0.033 to -0.038)
    assert collision_momentum_settled([0.0, 0.1, -0.033, -0.034, -0.0339, -0.0347, -0.0354, -0.0339])
    assert collision_momentum_settled([0.0, 0.2, 0.011, 0.006, 0.009, 0.007, 0.010, 0.008])
    assert collision_momentum_settled([0.0, 0.3, 0.12, 0.12, 0.121, 0.119, 0.12, 0.12])  # reported
    assert collision_momentum_settled([0.0] * 8)                          # two-way: no collisions
    assert not collision_momentum_settled([0.0, 0.01, 0.01])              # too few passes to judge
    assert collision_momentum_settled([math.nan] * 3)                     # not recorded

    # the partners' impulse discarded: a steady level is the model's (returned, it must vanish)
    loop = CouplingLoop(small_case(**{"physics.partner_momentum": "discarded"}))
    loop.gas = type("G", (), {"converged": True})()
    h = loop.history
    h.residual = [math.nan, 2.0, 1.2, 1.1, 1.0]
    h.pressure_gradient = [60.0, 61.0, 61.0, 61.0, 61.0]
    h.relaxation = [0.3] * 5
    h.mass_balance = [0.0] * 5
    h.collision_momentum = [0.0, 0.2, 0.005, 0.004, 0.006, 0.005, 0.004, 0.005]
    assert loop._converged_now()
    h.collision_momentum = [0.0, 0.2, 0.14, 0.135, 0.13, 0.125, 0.12, 0.115]
    assert not loop._converged_now()


def test_the_relaxation_state_survives_a_checkpoint(tmp_path):
    """α, the pass it last changed at, the recovery cap and whether the recovery was used are
    restored on resume (they decide the next passes' α)."""
    ck = tmp_path / "run.nc.checkpoint"
    loop = CouplingLoop(small_case(), checkpoint=ck)
    loop.step()
    loop.alpha, loop.alpha_changed_at, loop.alpha_cap, loop.recovered = 0.075, 1, 0.15, True
    loop._save()
    back = CouplingLoop(small_case(), checkpoint=ck, resume=True)
    assert (back.alpha, back.alpha_changed_at, back.alpha_cap, back.recovered) == (0.075, 1, 0.15, True)


def test_collision_momentum_beyond_the_limit_in_three_passes():
    """The guard on the collision model's momentum error: three passes in a row beyond ±0.5 of
    the inflow (the first two passes do not count); the 1 µm tracers' history stops it."""
    from eulag.coupling import collision_momentum_excessive

    tracers = [0.0, 3.103, 0.137, 1.075, 1.497, 1.729]      # stability run tracers_1um, passes 1-6
    assert collision_momentum_excessive(tracers) == pytest.approx(np.mean(tracers[-3:]))
    assert collision_momentum_excessive(tracers[:5]) is None       # two passes beyond: not yet
    assert collision_momentum_excessive([0.0, 0.76, 0.26, 0.26, 0.23]) is None  # scene h
    assert collision_momentum_excessive([0.0, 3.1, -0.6, 0.9, -0.7]) is None  # no one sign
    assert collision_momentum_excessive([0.0, 0.2, -0.73, -1.0, -1.23]) == pytest.approx(-2.96 / 3)  # 20 deg
    assert collision_momentum_excessive([0.0, 3.1, 0.9, 0.2, 0.9, 0.8]) is None
    assert collision_momentum_excessive([0.0, 3.1, 0.9, 0.9]) is None   # passes 3-4 only


def test_the_loop_stops_on_the_collision_momentum_guard(monkeypatch, tmp_path):
    """Wired into the loop: with the limit set to -inf (any level counts as positive excess)
    a four-way run stops at pass 5 with the diagnosis, leaves its checkpoint at pass 4, and a
    resume stops at pass 5 again."""
    import json

    import eulag.coupling as coupling

    monkeypatch.setattr(coupling, "COLLISION_MOMENTUM_LIMIT", -math.inf)
    case = small_case(**{"numerics.max_passes": 8})
    ckpt = tmp_path / "c.checkpoint"
    loop = CouplingLoop(case, checkpoint=ckpt)
    with pytest.raises(coupling.CouplingError, match=r"pass 5: the stochastic inter-particle collisions") as info:
        loop.run()
    assert 'physics.partner_correlation = "cell"' in str(info.value)  # the remedy found for tracers
    assert "\n" not in str(info.value)
    assert len(loop.history.collision_momentum) == 5
    with np.load(ckpt) as z:
        assert json.loads(bytes(z["meta"]).decode())["pass_index"] == 4
    again = CouplingLoop(case, checkpoint=ckpt, resume=True)
    assert again.pass_index == 4
    with pytest.raises(coupling.CouplingError, match=r"pass 5: "):
        again.run()


@pytest.mark.parametrize("setting, tolerance, retried", [
    ("always", 1.5, [True, True, True]),
    # single-phase solve, then the first two passes: the first pass has no residual (NaN), the
    # second's is well above 1e-3 and below 1000
    ("near-convergence", 1e-3, [True, False, False]),
    ("near-convergence", 1000.0, [True, False, True]),
])
def test_the_gas_march_retries_stalled_stations_as_the_case_says(monkeypatch, setting, tolerance, retried):
    """numerics.gas_station_retries = "near-convergence" lets the developing march keep a stalled
    station's first attempt while the coupling residual is above its tolerance; the single-phase
    solve and every solve within the tolerance retry as before."""
    calls = _two_passes_gas_calls(monkeypatch, **{"numerics.gas_station_retries": setting,
                                                  "numerics.coupling_tolerance": tolerance})
    assert [c["station_retries"] for c in calls] == retried


def _two_passes_gas_calls(monkeypatch, **keys):
    """The keyword arguments of every rans.solve call of two coupling passes of a short
    developing pipe (small_case with ``keys``): the single-phase solve and one per pass."""
    import rans

    loop = CouplingLoop(small_case(**{"pipe.mode": "developing", "pipe.length": 0.2,
                                      "numerics.axial_cells": 10, **keys}))
    real = rans.solve
    calls = []

    def solve(*args, **kwargs):
        calls.append(kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(rans, "solve", solve)
    loop.step()
    loop.step()
    return calls


@pytest.mark.parametrize("tolerance, early", [(1e-3, [1e-6, 1e-3, 1e-3]), (1000.0, [1e-6, 1e-3, 1e-6])])
def test_the_early_gas_solves_take_the_looser_tolerance_the_case_gives(monkeypatch, tolerance, early):
    """numerics.gas_tolerance_early: the gas solves of sources whose coupling residual is above
    coupling_tolerance (and of the first pass, which has none) take it; the single-phase solve
    and every solve within the coupling tolerance take gas_tolerance."""
    calls = _two_passes_gas_calls(monkeypatch, **{"numerics.gas_tolerance_early": 1e-3,
                                                  "numerics.coupling_tolerance": tolerance})
    assert [c["tol"] for c in calls] == early
    default = CouplingLoop(small_case(**{"pipe.mode": "developing", "pipe.length": 0.2,
                                         "numerics.axial_cells": 10}))
    assert default.case.numerics.gas_tolerance_early is None
    assert default.case.to_attrs()["numerics.gas_tolerance_early"] == "numerics.gas_tolerance"


def test_replica_pressure_gradients_give_the_averaged_solve_an_error_bar(tmp_path, uninterrupted):
    """One gas solve on each final pass's own sources gives −dp/dx(x) per final pass: the solve on
    their averaged sources lies within their spread (the solve is close to linear in sources that
    differ by noise), and a resumed finished run keeps them."""
    ds = uninterrupted
    rep = ds["replica_pressure_gradient"]
    assert rep.dims == ("replica", "x") and rep.sizes["replica"] == 2
    assert rep.attrs["units"] == "Pa m-1" and np.all(np.isfinite(rep.values))
    lo, hi = rep.values.min(axis=0), rep.values.max(axis=0)
    dp = ds["pressure_gradient"].values
    assert np.all(hi > lo), "two final passes with different parcels cannot give identical sources"
    assert np.all((dp >= lo - 0.1 * (hi - lo)) & (dp <= hi + 0.1 * (hi - lo))), (dp, lo, hi)
    case = small_case()
    out = tmp_path / "out.nc"
    first = run(case, out)
    again = run(case, out, resume=True)  # the checkpoint of a finished run: the same dataset
    np.testing.assert_array_equal(first["replica_pressure_gradient"].values,
                                  again["replica_pressure_gradient"].values)
    np.testing.assert_array_equal(first["replica_pressure_gradient"].values, rep.values)


def test_run_summary_prints_each_final_pass_pressure_gradient(tmp_path):
    from eulag.cli import _coupled_summary
    from eulag.runs import execute

    case = small_case()
    res = execute(case, tmp_path / "out.nc")
    text = _coupled_summary(case, res.loop, res.dataset, tmp_path / "out.nc")
    line = next(ln for ln in text.splitlines() if "each final pass alone" in ln)
    means = res.dataset["replica_pressure_gradient"].values.mean(axis=1)
    assert line.endswith(", ".join(f"{v:.4g}" for v in means) + " Pa/m"), line


def test_a_diverging_final_solve_keeps_the_relaxed_iterate_and_reports_the_run_unconverged(tmp_path, monkeypatch):
    """Should the gas solve on the final passes' averaged sources fail (unrelaxed, their noise
    can reverse the flow over a dense bottom layer), the passes are not lost: the dataset keeps
    the relaxed iterate after the last final pass as its gas field (its -dp/dx is the loop's
    last), says so, and the run is not converged, with the solver's message and the unmet
    criteria in its stop reason; a resumed finished run gives the same dataset; a loop that
    had converged says so."""
    import rans

    orig = CouplingLoop._solve_gas
    failed = []

    def solve_gas(self, sources, final=False, **kwargs):
        if final and len(failed) < self.pass_index:  # each run's first final solve: the averaged one
            failed.extend([True] * (self.pass_index - len(failed)))
            raise rans.SolverDivergence("gas solve diverged: u_x = -7.2 at x = 0.55 m (test)")
        return orig(self, sources, final=final, **kwargs)

    monkeypatch.setattr(CouplingLoop, "_solve_gas", solve_gas)
    out = tmp_path / "out.nc"
    ds = run(small_case(), out)
    assert failed and out.exists() and int(ds["converged"].values) == 0
    reason = str(ds.attrs["stop_reason"])
    assert reason.startswith("not converged: max_passes = 6 was reached (") and "averaged sources failed" in reason
    assert "u_x = -7.2" in reason and "relaxed iterate after the last final pass" in reason
    assert "residual" in reason or "pressure_gradient" in reason, reason  # the unmet criteria
    assert ds.attrs["final_solve_failure"] == "gas solve diverged: u_x = -7.2 at x = 0.55 m (test)"
    assert ds.attrs["gas_field"].startswith("relaxed iterate after the last final pass")
    # the relaxed iterate's -dp/dx is the one the loop recorded after its last pass
    assert float(ds["pressure_gradient"].mean()) == pytest.approx(float(ds["pressure_gradient_history"][-1]), rel=1e-9)
    again = run(small_case(), out, resume=True)
    data_vars_equal(ds, again)
    assert again.attrs["stop_reason"] == reason and again.attrs["gas_field"] == ds.attrs["gas_field"]

    # a loop that converged before its final solve failed says so
    monkeypatch.setattr(CouplingLoop, "_converged_now", lambda self: self.pass_index >= 2)
    failed.clear()
    ds2 = run(small_case(), tmp_path / "conv.nc")
    assert int(ds2["converged"].values) == 0
    assert str(ds2.attrs["stop_reason"]).startswith("not converged: the loop converged after pass 2, but the gas "
                                                    "solve on the 2 final passes' averaged sources failed")


def test_a_final_pass_whose_own_solve_fails_is_named_in_the_dataset(tmp_path, monkeypatch):
    """A replica (the gas solved on one final pass's sources alone, behind the error bars) whose
    solve fails is left out, and the dataset says which final pass and why: the attribute
    replica_solve_failures and the replica variables' long names; a resumed finished run
    gives the same."""
    import rans

    orig = CouplingLoop._solve_gas
    calls = []

    def solve_gas(self, sources, final=False, **kwargs):
        if final:
            calls.append(self.pass_index)
            if len(calls) == 2:  # the averaged sources first, then the first final pass's own
                raise rans.SolverDivergence("gas solve diverged: u_x = -3.1 at x = 0.25 m (test)")
        return orig(self, sources, final=final, **kwargs)

    monkeypatch.setattr(CouplingLoop, "_solve_gas", solve_gas)
    out = tmp_path / "out.nc"
    ds = run(small_case(), out)
    n = int(ds.attrs["final_passes_averaged"])
    assert n >= 2 and len(calls) == n + 1
    assert ds.attrs["replica_solve_failures"] == f"final pass 1 of {n}: gas solve diverged: u_x = -3.1 at x = 0.25 m (test)"
    assert ds["replica_pressure_gradient"].shape[0] == n - 1 and ds["replica_gas_ux"].shape[0] == n - 1
    note = f"({n - 1} of the {n} final passes: the solves on the others' sources failed"
    assert note in ds["replica_pressure_gradient"].attrs["long_name"] and note in ds["replica_gas_uy"].attrs["long_name"]
    assert "final_solve_failure" not in ds.attrs and ds.attrs["gas_field"] == "solve on the averaged sources of the final passes"
    again = run(small_case(), out, resume=True)
    data_vars_equal(ds, again)
    assert again.attrs["replica_solve_failures"] == ds.attrs["replica_solve_failures"]

    # no failure, no attribute and no note
    monkeypatch.setattr(CouplingLoop, "_solve_gas", orig)
    clean = run(small_case(), tmp_path / "clean.nc")
    assert "replica_solve_failures" not in clean.attrs
    assert "failed" not in clean["replica_pressure_gradient"].attrs["long_name"]


def test_resume_takes_a_finished_unconverged_run_whose_checkpoint_is_gone_as_finished(tmp_path, monkeypatch, capsys):
    """--resume on an output that holds this case's finished run reuses it whether it converged
    or not (running it again gives the same; the studies and the sweep take it as finished
    too): without its checkpoint nothing is computed again, and the verdict stays not converged
    (the CLI's exit status 1)."""
    from pathlib import Path

    from eulag.cli import main
    from eulag.runs import execute

    case = small_case(**{"numerics.coupling_tolerance": 0.001})  # cannot converge in 6 passes
    out = tmp_path / "out.nc"
    first = execute(case, out)
    assert not first.converged and first.stop_reason.startswith("not converged")
    Path(str(out) + ".checkpoint").unlink()

    def recompute(self):
        raise AssertionError("a finished run was computed again")

    monkeypatch.setattr(CouplingLoop, "run", recompute)
    again = execute(case, out, resume=True)
    assert again.reused and not again.converged and again.stop_reason == first.stop_reason
    data_vars_equal(first.dataset, again.dataset)

    lines = [f"name = \"{case.name}\""]
    for section, values in SMALL.items():
        if isinstance(values, dict):
            lines.append(f"[{section}]")
            for k, v in values.items():
                lines.append(f"{k} = {json.dumps(v)}")
    lines.append("coupling_tolerance = 0.001")
    toml = tmp_path / "small.toml"
    toml.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    status = main(["run", str(toml), "-o", str(out), "--resume", "--quiet"])
    err = capsys.readouterr().err
    assert status == 1 and "converged = false" in err and "not converged" in err, err


def test_parcels_stopped_by_the_residence_cap_keep_the_run_unconverged():
    """A residence-time cap shorter than the transit stops every parcel: the particle mass never
    reaches the outlet, and the mass-balance criterion (|in - out| / in) says so."""
    from eulag.runs import UnconvergedRunWarning

    with pytest.warns(UnconvergedRunWarning, match="mass_balance 1 >= 0.01"):
        ds = run(small_case(**{"numerics.residence_cap": 0.01, "numerics.max_passes": 5}))
    assert ds.attrs["parcels_exited_final"] == 0 and ds.attrs["parcels_stuck_final"] > 0
    assert not bool(ds.converged)
    assert "mass_balance 1 >= 0.01" in ds.attrs["stop_reason"], ds.attrs["stop_reason"]


def test_a_different_case_is_named_by_the_keys_that_differ(uninterrupted):
    """--resume against another case's output or checkpoint names the keys that differ, with the
    stored and the present value (eulag.config.case_differences)."""
    from eulag import runs

    assert runs.case_difference(dict(uninterrupted.attrs), small_case()) == ""
    other = small_case(**{"numerics.seed": 4, "numerics.parcels": 2000})
    assert runs.case_difference(dict(uninterrupted.attrs), other) == (
        "numerics.parcels = 1500 stored, 2000 in this case; numerics.seed = 3 stored, 4 in this case")
