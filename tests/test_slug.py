"""The coupled slug model (eulag.slug) and the tent transfer (dem.transfer):

- a uniform packing gives a uniform porosity at every node, wall nodes included, equal to its
  true solids fraction N V_p / (A_t L) (the wall correction of the node volumes);
- the transferred grain velocity of a uniformly moving packing is that velocity;
- interpolation back to the grains reproduces a linear field;
- case validation: one-line errors naming section.key;
- the periodic CI case runs: no grain lost, overlaps below 1 % of d, self-describing dataset;
- kill after a checkpoint + resume gives the uninterrupted result bit for bit.
"""

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import xarray as xr
import pytest

from dem import FEED, FREE, TentTransfer
from eulag import slug
from tests.slug_support import killed_after_checkpoint

CASES = Path(__file__).resolve().parents[1] / "cases" / "slug"
RT, R = 3.5e-3, 0.7e-3


def _uniform_centres(n, length, rng):
    rc = RT - R
    r = rc * np.sqrt(rng.uniform(size=n))
    th = rng.uniform(0, 2 * np.pi, n)
    return np.column_stack([rng.uniform(0, length, n), r * np.cos(th), r * np.sin(th)])


@pytest.mark.parametrize("ny", [2, 3])
def test_uniform_packing_gives_uniform_porosity(ny):
    rng = np.random.default_rng(11)
    length, n = 0.07, 2_000_000  # centres may overlap: only their density matters here
    pos = _uniform_centres(n, length, rng)
    tr = TentTransfer(20, ny, length, RT, R, periodic=True)
    vel = np.tile([0.3, -0.1, 0.05], (n, 1))
    phi, u = tr.porosity_velocity(pos, vel, np.full(n, FREE, dtype=np.int8))
    true_solid = n * (4 / 3 * math.pi * R**3) / (math.pi * RT**2 * length)
    # each node sees ~n/(20 ny²) grains spread over its tent: relative noise ≲ 1 %
    assert np.allclose(1 - phi, true_solid, rtol=0.025)
    assert abs((1 - phi).mean() / true_solid - 1) < 0.005
    assert np.allclose(u, [0.3, -0.1, 0.05], rtol=1e-12)


def test_uniform_packing_up_to_the_outlet_gives_uniform_porosity_at_the_end_nodes():
    """An open tube: a uniform packing from the feed zone (x < 0, FEED grains) up to the outlet
    (grains beyond L are gone) gives its true solids fraction at the inlet and the outlet node
    too; the outlet node's volume is the part of its tent inside the tube (it read 0.875 of the
    solids with the full tent)."""
    rng = np.random.default_rng(13)
    length, n = 0.07, 2_000_000
    tr = TentTransfer(20, 2, length, RT, R)
    pos = _uniform_centres(n, length + tr.lx, rng)
    pos[:, 0] -= tr.lx  # x in [−l_x, L): the feed zone holds the packing's continuation
    status = np.where(pos[:, 0] < 0.0, FEED, FREE).astype(np.int8)
    phi, _ = tr.porosity_velocity(pos, np.zeros((n, 3)), status)
    true_solid = n * (4 / 3 * math.pi * R**3) / (math.pi * RT**2 * (length + tr.lx))
    ratio = (1 - phi) / true_solid
    assert np.allclose(ratio, 1, rtol=0.02)  # ~25,000 centres per node
    assert abs(ratio[-1].mean() - 1) < 0.01 and abs(ratio[0].mean() - 1) < 0.01


def _wall_centres(n, length, rng):
    """Centres on the circle the centres can reach, r = R_t − R: the extreme of a real packing's
    crowding against the wall (38–44 % of a relaxed packing's centres lie within 0.1 d of it)."""
    th = rng.uniform(0, 2 * np.pi, n)
    rc = RT - R
    return np.column_stack([rng.uniform(0, length, n), rc * np.cos(th), rc * np.sin(th)])


@pytest.mark.parametrize("weights", ["grain", "tent"])
def test_grains_at_the_wall_deposit_their_volume(weights):
    """With each grain's cross-section weights normalised ("grain", the default) a packing gives
    its true solids fraction at every node whatever the radial distribution of its centres;
    the plain tent weights ("tent") lose the part of a wall grain's tent that lies beyond the
    nodes and leave the nodes too porous."""
    rng = np.random.default_rng(5)
    length, n = 0.07, 2_000_000  # centres may overlap: only their density matters here
    pos = _wall_centres(n, length, rng)
    tr = TentTransfer(20, 2, length, RT, R, periodic=True, weights=weights)
    phi, _ = tr.porosity_velocity(pos, np.zeros((n, 3)), np.full(n, FREE, dtype=np.int8))
    true_solid = n * (4 / 3 * math.pi * R**3) / (math.pi * RT**2 * length)
    ratio = (1 - phi) / true_solid
    if weights == "grain":
        assert abs(ratio.mean() - 1) < 1e-12  # every grain deposits V_p exactly (periodic in x)
        assert np.allclose(ratio, 1, rtol=0.015)  # ~25,000 centres per node: ≲ 1 % noise
    else:
        assert ratio.mean() < 0.85  # wall grains deposit only part of their volume


def test_interpolation_to_grains_reproduces_linear_field():
    rng = np.random.default_rng(2)
    length = 0.07
    tr = TentTransfer(20, 2, length, RT, R)
    pos = _uniform_centres(1000, length, rng)
    pos[:, 0] = rng.uniform(0.5 * tr.lx, length - 0.5 * tr.lx, 1000)  # between the first and last node
    xn = (np.arange(20) + 0.5) * tr.lx
    field = np.broadcast_to((3.0 + 50.0 * xn)[:, None, None, None], (20, 2, 2, 1)).copy()
    out = tr.to_grains(pos, np.full(1000, FREE, dtype=np.int8), field)
    assert np.allclose(out[:, 0], 3.0 + 50.0 * pos[:, 0], rtol=1e-12)


def test_printed_interpolation_is_the_plain_tent_sum():
    """eq. 9 as printed (``grain_interpolation = "printed"``): a uniform field reaches a grain times
    its cross-section tent sum, f(y)·Σ f(z); at the bottom of the 2 × 2 grid (y = −(R_t − R),
    z = 0) that is (1 − (R_t/2 − R)/(R_t)) · 1 = 0.70 for the paper's tube; the default
    normalised interpolation returns the field itself."""
    length = 0.07
    pos = np.array([[0.035, -(RT - R), 0.0], [0.035, 0.0, 0.0], [0.035, -0.5 * (RT - R), 0.3 * RT]])
    status = np.full(3, FREE, dtype=np.int8)
    field = np.full((20, 2, 2, 1), 7.0)
    lt = RT  # node spacing across: D_t / 2
    s_bottom = 1 - (RT - R - 0.5 * lt) / lt  # the lower node row's tent at y = -(R_t - R); the upper's is 0
    printed = TentTransfer(20, 2, length, RT, R, periodic=True, interpolation="printed").to_grains(pos, status, field)
    normal = TentTransfer(20, 2, length, RT, R, periodic=True).to_grains(pos, status, field)
    assert np.allclose(normal[:, 0], 7.0, rtol=1e-12)
    assert printed[0, 0] == pytest.approx(7.0 * s_bottom, rel=1e-12) and 0.69 < s_bottom < 0.71
    assert printed[1, 0] == pytest.approx(7.0, rel=1e-12)  # inside the node square the tents sum to one
    assert printed[2, 0] == pytest.approx(7.0, rel=1e-12)
    with pytest.raises(ValueError, match="interpolation = 'cubic': allowed normalised, printed"):
        TentTransfer(20, 2, length, RT, R, interpolation="cubic")


def test_the_case_key_reaches_the_transfer():
    case = _short_periodic()
    assert slug._Simulation(slug.validate_slug_case(case)).transfer.normalise
    case["numerics"]["grain_interpolation"] = "printed"
    assert not slug._Simulation(slug.validate_slug_case(case)).transfer.normalise


def _case(name):
    with open(CASES / f"{name}.toml", "rb") as fh:
        return tomllib.load(fh)


@pytest.mark.parametrize("name", ["strauss_horizontal", "strauss_vertical", "periodic_slug"])
def test_packaged_cases_validate(name):
    c = slug.validate_slug_case(_case(name))
    assert c["model"] == "dem-darcy"


@pytest.mark.parametrize("section,key,value,msg", [
    ("grains", "restitution", 1.5, "grains.restitution = 1.5: allowed"),
    ("gas", "inlet", "piston", "gas.inlet = 'piston': allowed 'flux' | 'source'"),
    ("numerics", "porosity_weights", "volume", "numerics.porosity_weights = 'volume': allowed 'grain' | 'tent'"),
    ("numerics", "grain_interpolation", "cubic",
     "numerics.grain_interpolation = 'cubic': allowed 'normalised' | 'printed'"),
    ("numerics", "cells_x", 2.5, "numerics.cells_x = 2.5: allowed an integer"),
    ("tube", "orientation", "inclined", "tube.orientation = 'inclined': allowed"),
    ("feed", "colour", 1, "feed.colour = 1: allowed keys"),
    ("grains", "tangential_damping_ratio", 2.0, "grains.tangential_damping_ratio = 2.0: allowed < 1.74 at"),
    ("numerics", "overlap_limit", 0, "numerics.overlap_limit = 0.0: allowed 0.0 < value <= 1.0"),
    ("numerics", "cross_section_pixels", 21, "numerics.cross_section_pixels = 21: allowed an integer from 2 to 20"),
    ("numerics", "cross_section_pixels", 1, "numerics.cross_section_pixels = 1: allowed an integer from 2 to 20"),
    ("numerics", "cross_section_at", 0.0, "numerics.cross_section_at = 0.0: allowed 0.003333 <= value <= 0.9967"),
    # with 3 gas cells across the 7 mm tube the porosity fell below 0.2 and Delta p halved; 4: clipped throughout
    ("numerics", "cells_across", 3, "numerics.cells_across = 3: allowed <= tube.diameter_m / (2.5 grains.diameter_m) = 2"),
    ("numerics", "cells_x", 2, "numerics.cells_x = 2: allowed an integer >= 3"),
    ("numerics", "cells_across", 7, "numerics.cells_across = 7: allowed <= 6 (with more cells across, the corner"),
    # 10 cells of 52.5 mm: the 14 mm feed blocks do not fill the inlet node's tent before the inlet
    ("numerics", "cells_x", 10, "feed.block_length_m = 0.014: allowed >= half a gas cell"),
    ("numerics", "steps_per_contact", 2, "numerics.steps_per_contact = 2: allowed a number of DEM steps per contact at "
     "which the default grains.tangential_damping_ratio"),
    ("initial", "plug_length_m", 0.05, "initial.plug_length_m = 0.05: allowed 0.0 (not set) for a tube that is not "
     "periodic"),
])
def test_validation_one_line_errors(section, key, value, msg):
    case = _case("strauss_horizontal")
    case.setdefault(section, {})[key] = value
    with pytest.raises(ValueError) as err:
        slug.validate_slug_case(case)
    assert str(err.value).startswith(msg) and "\n" not in str(err.value)


def _short_periodic(end=0.02, ckpt=0.01):
    case = _case("periodic_slug")
    case["numerics"].update(end_time_s=end, checkpoint_interval_s=ckpt, output_interval_s=0.005)
    return case


def test_periodic_case_runs_without_losses(tmp_path):
    ds = slug.run_slug(_short_periodic(), tmp_path / "p.nc", progress=False)
    assert int(ds.grains_lost) == 0 and ds.attrs["grains_lost"] == 0
    assert float(ds.max_overlap_per_d.max()) < 0.01
    assert ds.sizes["time"] == 4 and ds.sizes["x"] == 20
    for v in ds.data_vars.values():
        assert "units" in v.attrs and "long_name" in v.attrs
    assert (ds.grains_in_tube == ds.grains_in_tube[0]).all()  # periodic: nothing enters or leaves
    assert float(ds.pressure_drop[-1]) > 0
    # the stored pressure is the total one: it falls along the tube by the recorded drop, and
    # across the slug (the dense slices) it falls (Darcy: the gas pushes the plug downstream)
    p, x = ds.gas_pressure.values[-1], ds.x.values
    dx = x[1] - x[0]
    drop_cells = p[0] - p[-1] + (p[-1] - p[-2] + p[1] - p[0]) / 2  # inlet face to outlet face, linear ends
    assert abs(drop_cells - float(ds.pressure_drop[-1])) < 0.1 * float(ds.pressure_drop[-1]), (drop_cells,)
    dense = ds.porosity.values[-1] < slug.SLUG_POROSITY
    grad = np.gradient(p, dx)
    assert grad[dense].mean() < 0 and grad[dense].mean() < grad[~dense].mean()
    assert not (tmp_path / "p.nc.checkpoint").exists()
    # the recorded cross-section (SMH Figs. 17-19): finite, a solids fraction, and the layers'
    # grains those of the slice, whose solids volume the image holds
    sec = ds.section_solids_fraction.values
    assert sec.shape == (4, 14, 14) and np.isfinite(sec).all() and sec.min() >= 0 and sec.max() <= 1.0 + 1e-9
    assert ds.attrs["section_x_m"] == 0.5 * float(slug.validate_slug_case(_short_periodic())["tube"]["length_m"])
    assert np.isfinite(ds.layer_velocity.values).all() and np.isfinite(ds.layer_velocity_rms.values).all()
    # the image holds the volume of the slice's grains: those with centres in it (layer_grains), give
    # or take the parts of grains straddling its two faces (at most ~ the grains within d/2 of them)
    from dem.sections import pixel_inside_fraction

    vp = math.pi / 6 * 1.4e-3 ** 3
    inside = pixel_inside_fraction(3.5e-3, 14)
    vol = (sec * inside * 0.5e-3 ** 2 * 3.5e-3).sum(axis=(1, 2)) / vp
    n_slice = ds.layer_grains.sum("layer").values
    assert (n_slice > 20).all() and np.all(np.abs(vol - n_slice) < 0.35 * n_slice), (vol, n_slice)
    # the catalogue's slug velocity of SMH §3.2 / Fig. 10: each record's one slug (the slices below
    # φ = 0.6) has the largest slice grain velocity of the record's stored fields
    assert ds.sizes["slug"] == ds.sizes["time"]
    for i in range(ds.sizes["time"]):
        phi, u = ds.porosity.values[i], ds.grain_velocity.values[i]
        dense = phi < slug.SLUG_POROSITY
        assert dense.any() and not dense.all()
        assert float(ds.slug_max_velocity[i]) == u[dense].max()
        assert float(ds.slug_min_porosity[i]) == phi.min()


def test_an_overlap_beyond_the_limit_is_an_unconverged_run():
    """A run whose largest overlap goes beyond numerics.overlap_limit ends with converged = false
    and says how far and when; within the limit it is finished."""
    case = _short_periodic(end=0.01)
    ds = slug.run_slug(case, None, progress=False)
    worst = float(ds.max_overlap_per_d.max())
    assert ds.attrs["converged"] == "true" and ds.attrs["stop_reason"] == "finished" and 0 < worst < 0.05
    case["numerics"]["overlap_limit"] = 0.5 * worst
    ds = slug.run_slug(case, None, progress=False)
    assert ds.attrs["converged"] == "false"
    assert ds.attrs["stop_reason"].startswith(f"finished, but the largest grain overlap reached {100 * worst:.3g} % of "
                                              f"d (numerics.overlap_limit {100 * 0.5 * worst:g} %, first exceeded at t =")


def test_a_stored_run_beyond_the_overlap_limit_is_judged_again(tmp_path, capsys):
    """A dataset written before numerics.overlap_limit existed says converged = true; on reuse it
    is judged by today's rule, so it is not taken as a finished run: eulag run --resume, the
    sweep and the studies (one rule, ``runs.takes_as_finished``) run the case again."""
    import re
    from types import SimpleNamespace

    from eulag import runs, studies
    from eulag.cli import main
    from eulag.output import is_converged
    from eulag.sweep import plan_sweep

    text = (CASES / "periodic_slug.toml").read_text()
    text, n = re.subn(r"(?m)^end_time_s = [0-9.]+", "end_time_s = 0.01", text)
    assert n == 1
    (tmp_path / "p.toml").write_text(text)
    assert main(["run", str(tmp_path / "p.toml"), "-o", str(tmp_path / "p.nc"), "--quiet", "--no-plots"]) == 0
    with xr.open_dataset(tmp_path / "p.nc") as stored:
        ds = stored.load()
    assert is_converged(ds)
    ds["max_overlap_per_d"].values[0] = 0.37  # as a jammed tube's, in a run stored as finished
    ds.to_netcdf(tmp_path / "p.nc")
    with xr.open_dataset(tmp_path / "p.nc") as stored:
        assert stored.attrs["converged"] == "true" and not is_converged(stored)
    assert slug.verdict(ds)[1].startswith("finished, but the largest grain overlap reached 37 % of d")
    case = runs.load_case(tmp_path / "p.toml")
    assert not plan_sweep([tmp_path / "p.toml"], tmp_path)[0].finished
    calls = []

    def counted(*a, **kw):
        calls.append(a)
        return real(*a, **kw)
    real = runs.execute
    runs.execute = counted
    try:
        studies.run_case(SimpleNamespace(resume=True, quiet=True), "p", case, tmp_path, "p")
    finally:
        runs.execute = real
    assert len(calls) == 1  # run again, as eulag run --resume does below
    ds.to_netcdf(tmp_path / "p.nc")  # the stored run once more
    assert main(["run", str(tmp_path / "p.toml"), "-o", str(tmp_path / "p.nc"), "--resume", "--quiet",
                 "--no-plots"]) == 0
    with xr.open_dataset(tmp_path / "p.nc") as rerun:
        assert is_converged(rerun) and float(rerun["max_overlap_per_d"][0]) < 0.05
    # a run that today's code itself judged unconverged is finished: running it again gives the
    # same, so the three front-ends keep it
    (tmp_path / "q.toml").write_text(re.sub(r'(?m)^name = .*$', 'name = "q"',
                                            text.replace("[numerics]", "[numerics]\noverlap_limit = 1e-6", 1)))
    assert main(["run", str(tmp_path / "q.toml"), "-o", str(tmp_path / "q.nc"), "--quiet", "--no-plots"]) == 1
    stamp = (tmp_path / "q.nc").stat().st_mtime_ns
    assert runs.dataset_state(tmp_path / "q.nc", runs.load_case(tmp_path / "q.toml")) == "unconverged"
    assert plan_sweep([tmp_path / "q.toml"], tmp_path)[0].finished
    assert main(["run", str(tmp_path / "q.toml"), "-o", str(tmp_path / "q.nc"), "--resume", "--quiet",
                 "--no-plots"]) == 1
    assert (tmp_path / "q.nc").stat().st_mtime_ns == stamp  # reused, not run again


def test_resume_after_kill_is_bit_identical(tmp_path, monkeypatch):
    """kill -9 after a checkpoint + --resume gives the uninterrupted result bit for bit.  The same
    checkpoint without the cross-section records (as written before they existed) resumes too:
    its records carry zeros flagged section_recorded = 0 (every float finite, as the dataset
    schema asks), the records after it the section, and the layer averages take only those."""
    case = _short_periodic(end=0.03, ckpt=0.01)
    full = slug.run_slug(case, tmp_path / "a.nc", progress=False)
    ckpt = killed_after_checkpoint(case, tmp_path / "b.nc", monkeypatch, n=2)
    assert ckpt.exists()
    old_ckpt = slug.checkpoint_path(tmp_path / "c.nc")
    with np.load(ckpt) as z:
        old = {k: z[k] for k in z.files if k not in ("rec_section", "rec_layer_n", "rec_layer_u", "rec_layer_rms",
                                                     "rec_section_ok")}
    with open(old_ckpt, "wb") as fh:
        np.savez(fh, **old)
    with np.load(ckpt) as z:
        before = json.loads(str(z["scalars"]))["wall_time_s"]  # the killed session's wall time
    resumed = slug.run_slug(case, tmp_path / "b.nc", resume=True, progress=False)
    for name, v in full.data_vars.items():
        if name == "gas_solve_share":  # wall-clock
            continue
        assert np.array_equal(v.values, resumed[name].values, equal_nan=True), name
    assert resumed.attrs["wall_time_s"] > before > 0  # every session of the run counts

    resumed = slug.run_slug(case, tmp_path / "c.nc", resume=True, progress=False)
    flag = resumed.section_recorded.values
    assert list(flag) == [0, 0, 0, 0, 1, 1] and list(full.section_recorded.values) == [1] * 6
    for v in ("section_solids_fraction", "layer_grains", "layer_velocity", "layer_velocity_rms"):
        assert np.isfinite(resumed[v].values).all() and (resumed[v].values[:4] == 0).all()
        assert np.array_equal(resumed[v].values[4:], full[v].values[4:])
    assert np.array_equal(resumed.porosity.values, full.porosity.values)
    both = slug.cross_section_layers(full, t_min=0.021)
    part = slug.cross_section_layers(resumed, t_min=0.0)
    assert part.attrs["records_slug"] + part.attrs["records_between"] == 2
    for v in ("velocity_slug", "grains_slug", "velocity_between"):
        assert np.array_equal(both[v].values, part[v].values, equal_nan=True)


def test_resume_refuses_a_checkpoint_of_another_case(tmp_path, monkeypatch):
    """A checkpoint stores its case: --resume with an edited case stops with one line instead of
    continuing the other case's grains (a later end time is the same case, continued)."""
    from eulag import runs

    case = _short_periodic(end=0.03, ckpt=0.01)
    ckpt = killed_after_checkpoint(case, tmp_path / "c.nc", monkeypatch)
    assert slug.checkpoint_problem(ckpt, case) is None
    longer = _short_periodic(end=0.04, ckpt=0.01)
    assert slug.checkpoint_problem(ckpt, longer) is None
    other = _short_periodic(end=0.03, ckpt=0.01)
    other["grains"]["friction"] = 0.3
    differs = "checkpoint of a different case (grains.friction = 0.5 in the checkpoint, 0.3 in this case)"
    assert slug.checkpoint_problem(ckpt, other) == differs
    with pytest.raises(ValueError, match="checkpoint of a different case"):
        slug.run_slug(other, tmp_path / "c.nc", resume=True, progress=False)
    mc = runs.ModelCase("dem-darcy", "c", other)
    assert runs.checkpoint_state(ckpt, mc)[2] == differs
    assert runs.checkpoint_state(ckpt, runs.ModelCase("dem-darcy", "c", case))[2] is None


def _short_fed(end):
    """The horizontal case on a 7 cm tube (the study's quick geometry), fed from empty."""
    case = _case("strauss_horizontal")
    case["tube"]["length_m"] = 0.07
    case["numerics"].update(cells_x=20, end_time_s=end, output_interval_s=0.005, checkpoint_interval_s=0.01)
    return case


def test_run_continued_from_a_state_equals_the_uninterrupted_run(tmp_path, monkeypatch):
    """initial.state: a run continued from the saved state of another at t = 0.01 s, with the same
    parameters, repeats the uninterrupted run's records after 0.01 s bit for bit (a state is a
    checkpoint without its records); with another friction it runs from the same grains; a state
    of a different tube or an end time before the state's stops with one line."""
    full = slug.run_slug(_short_fed(0.02), tmp_path / "full.nc", progress=False)
    killed_after_checkpoint(_short_fed(0.02), tmp_path / "first.nc", monkeypatch)
    state = slug.save_state(tmp_path / "first.nc.checkpoint", tmp_path / "state.npz")
    assert state.stat().st_size < (tmp_path / "first.nc.checkpoint").stat().st_size
    cont = _short_fed(0.02)
    cont["initial"] = {"state": str(state)}
    assert slug.state_time(cont) == pytest.approx(0.01)
    ds = slug.run_slug(cont, tmp_path / "cont.nc", progress=False)
    later = full.sel(time=slice(0.0101, None))
    assert ds.sizes["time"] == later.sizes["time"] == 2
    for name in ("porosity", "pressure_drop", "grain_velocity", "grains_in_tube"):
        assert np.array_equal(later[name].values, ds[name].values, equal_nan=True), name
    other = _short_fed(0.02)
    other["initial"] = {"state": str(state)}
    other["grains"]["friction"] = 0.2
    assert slug.run_slug(other, None, progress=False).sizes["time"] == 2
    # another feed rate: the feed goes on from where it stood, at the new speed
    faster = _short_fed(0.02)
    faster["initial"] = {"state": str(state)}
    faster["feed"]["mass_flow_kg_h"] = 4 * 2.49
    c_old, c_new = slug.validate_slug_case(_short_fed(0.02)), slug.validate_slug_case(faster)
    sim = slug._Simulation(c_new)
    sim.start_from(slug.read_state(str(state), c_new)[0])
    v_old = slug._Simulation(c_old).v_feed
    assert sim.v_feed == pytest.approx(4 * v_old)
    assert sim.feed_origin == (pytest.approx(v_old * 0.01), 100)
    fast = slug.run_slug(faster, None, progress=False)
    assert fast.sizes["time"] == 2
    assert np.isfinite(fast["outflow_mass_rate"].values).all()  # the rate counts from the state's time
    bad = _short_fed(0.02)
    bad["initial"] = {"state": str(state)}
    bad["tube"]["length_m"] = 0.08
    with pytest.raises(ValueError, match=r"^initial.state = .*written with tube.length_m = 0.07, this case has 0.08; allowed") as err:
        slug.validate_slug_case(bad)
    assert "\n" not in str(err.value)
    early = _short_fed(0.01)
    early["initial"] = {"state": str(state)}
    with pytest.raises(ValueError, match=r"^numerics.end_time_s = 0.01: the state .* allowed > "):
        slug.validate_slug_case(early)


@pytest.mark.parametrize("section,key,other", [("initial", "state", None),
                                               ("numerics", "grain_interpolation", "printed"),
                                               ("numerics", "overlap_limit", None),
                                               ("numerics", "cross_section_at", 0.25),
                                               ("numerics", "cross_section_pixels", 20)])
def test_cases_stored_before_a_key_existed_are_the_same_case(tmp_path, section, key, other):
    """A dataset or checkpoint of a run made before a key existed (its stored case has no such
    key) is the same case as today's with the key at the value those runs had -- initial.state
    = "" (an empty tube), numerics.grain_interpolation = "normalised" -- so --resume keeps it;
    with the key at another value it is a different case."""
    import json

    case = _short_periodic()
    old = slug.validate_slug_case(case)
    del old[section][key]
    assert slug.same_case({"case": json.dumps(old)}, case)
    ckpt = tmp_path / "old.checkpoint"
    stored = dict(old, numerics={k: v for k, v in old["numerics"].items() if k != "end_time_s"})
    with open(ckpt, "wb") as fh:  # np.savez would append .npz to a path name
        np.savez(fh, case_json=np.array(json.dumps(stored, sort_keys=True)))
    assert slug.checkpoint_problem(ckpt, case) is None
    if other is not None:
        # stored with the key at the former value, as runs of the key's first version were
        key_set = dict(stored, **{section: dict(stored[section], **{key: slug.validate_slug_case(case)[section][key]})})
        with open(ckpt, "wb") as fh:
            np.savez(fh, case_json=np.array(json.dumps(key_set, sort_keys=True)))
        assert slug.checkpoint_problem(ckpt, case) is None
        case[section][key] = other
        assert not slug.same_case({"case": json.dumps(old)}, case)
        assert slug.checkpoint_problem(ckpt, case).startswith(f"checkpoint of a different case ({section}.{key} = ")
    other = _short_periodic()
    other["grains"]["friction"] = 0.3
    assert slug.checkpoint_problem(ckpt, other).startswith("checkpoint of a different case (grains.friction")


def test_feed_block_shorter_than_three_search_cells_is_one_line_error():
    case = _case("strauss_horizontal")
    case["feed"]["block_length_m"] = 0.004
    with pytest.raises(ValueError, match=r"^feed.block_length_m = 0.004: allowed >= 0.00504 m") as err:
        slug.validate_slug_case(case)
    assert "\n" not in str(err.value)


def test_coupled_loop_one_and_two_threads_bit_identical(tmp_path):
    """The prange kernels (numerics.parallel = true) on 1 and 2 threads and the serial kernels
    give the same dataset bit for bit."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    out = []
    for parallel, threads in ((False, 1), (True, 1), (True, 2)):
        case = _short_periodic(end=0.01, ckpt=0.01)
        case["numerics"]["parallel"] = parallel
        numba.set_num_threads(threads)
        try:
            ds = slug.run_slug(case, tmp_path / f"t{parallel}{threads}.nc", progress=False)
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        out.append(ds)
    for ds in out[1:]:
        for name in ("porosity", "grain_velocity", "gas_pressure", "pressure_drop", "max_overlap_per_d"):
            assert np.array_equal(out[0][name].values, ds[name].values), name


def test_summarize_recovers_the_speed_of_a_synthetic_slug():
    """A catalogue of one slug moving at 0.3 m/s in a periodic 7 cm tube (wrapping round)."""
    import json

    import xarray as xr

    t = np.arange(1, 101) * 0.01
    xpos = (0.01 + 0.3 * t) % 0.07
    case = slug.validate_slug_case(_case("periodic_slug"))
    x = (np.arange(20) + 0.5) * 0.0035
    ds = xr.Dataset(
        {"pressure_drop": ("time", np.full(100, 50.0)), "grains_in_tube": ("time", np.full(100, 644)),
         "slug_time": ("slug", t), "slug_position": ("slug", xpos), "slug_grains": ("slug", np.full(100, 400)),
         "slug_min_porosity": ("slug", np.full(100, 0.5)), "slug_length": ("slug", np.full(100, 0.03)),
         "slug_max_velocity": ("slug", np.full(100, 0.2)),
         "porosity": (("time", "x"), np.ones((100, 20))), "grain_velocity": (("time", "x"), np.zeros((100, 20))),
         "gas_pressure": (("time", "x"), np.zeros((100, 20)))},
        coords={"time": t, "x": x}, attrs={"case": json.dumps(case)})
    s = slug.summarize(ds, x_window=(0.0, 0.07))
    assert s["slug_velocity_m_s"] == pytest.approx(0.3, rel=1e-9)
    assert s["pressure_drop_per_length_Pa_m"] == pytest.approx(50.0 / 0.07)
    prof = slug.slug_profiles(ds, x_window=(0.0, 0.07))
    assert np.allclose(prof.porosity, 1.0) and prof.samples.min() == 100


def test_gas_force_sums_to_minus_grad_p_times_volume():
    """Summed over a uniform packing, F_i = −V_p ∇P/(1 − φ_i) gives −∇P × the tube volume (the
    Darcy drag per unit volume of the mixture), not −∇P × the solids volume."""
    rng = np.random.default_rng(5)
    length, n = 0.07, 300_000
    pos = _uniform_centres(n, length, rng)
    v_p_scaled = 0.5 * math.pi * RT**2 * length / n  # points weighted as grains of this volume: φ = 0.5
    tr = TentTransfer(20, 2, length, RT, R, periodic=True)
    tr.v_grain = v_p_scaled
    status = np.full(n, FREE, dtype=np.int8)
    phi, _ = tr.porosity_velocity(pos, np.zeros_like(pos), status)
    grad = np.zeros(phi.shape + (3,))
    grad[..., 0] = -2000.0
    f = slug.gas_force_on_grains(tr, pos, status, grad, phi, v_p_scaled, 0.05)
    total = f.sum(axis=0)
    assert total[0] == pytest.approx(2000.0 * math.pi * RT**2 * length, rel=0.01)
    assert abs(total[1]) < 1e-12 and abs(total[2]) < 1e-12


def test_a_grid_whose_porosity_was_clipped_is_not_a_valid_result(tmp_path):
    """The node porosity is clipped at PHI_FLOOR (denser than any packing of spheres) only when the
    tent transfer does not resolve the grid: such a run ends unconverged, saying why."""
    ds = slug.run_slug(_short_periodic(end=0.01), None, progress=False)
    assert slug.verdict(ds) == (True, "finished")
    ds.attrs["porosity_clipped_cells"] = 12
    ok, why = slug.verdict(ds)
    assert not ok and "fell below 0.2" in why and "12 node-steps" in why


def test_a_stored_case_is_judged_not_validated_by_later_rules():
    """The verdict of a stored slug dataset reads its overlap limit without validating the stored
    case, so a dataset written before a validation rule (here cells_across = 3 in the paper's tube)
    is judged, not refused as unreadable."""
    stored = slug.validate_slug_case(_short_periodic())
    stored["numerics"]["cells_across"] = 3
    assert slug.overlap_limit(stored) == stored["numerics"]["overlap_limit"]
    del stored["numerics"]["overlap_limit"]
    assert slug.overlap_limit(stored) == slug.DEFAULTS["numerics"]["overlap_limit"]
