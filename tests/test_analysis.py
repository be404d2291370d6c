"""eulag.analysis against analytic fields on the real polar mesh: stream function of two- and
four-cell secondary flows, cell counts (also with noise and with a divergent part), secondary
flow strength, vertical-diameter cells, wall-impact split, section means, pressure drop."""

import math

import numpy as np
import pytest
import xarray as xr

import rans
from eulag import analysis as an

D, L, U_B = 0.0305, 4.0, 10.0
R = D / 2


def mesh(nr=12, nt=24, mode="periodic", nx=20):
    return rans.PipeMesh.build(D, L, mode=mode, axial_cells=nx, radial_cells=nr, azimuthal_cells=nt)


def synthetic_dataset(m, **cell_vars):
    """A dataset with the schema's coordinates for mesh m; cell_vars name -> (nr, nt) array
    (repeated over x) or (nx, nr, nt) array. No r_edge / theta_edge coordinates: readers must
    derive the geometry from y, z and cell_area."""
    nx = m.x.size
    data = {}
    for name, v in cell_vars.items():
        v = np.asarray(v, dtype=float)
        if v.ndim == 2:
            v = np.broadcast_to(v, (nx,) + v.shape)
        data[name] = (("x", "r", "theta"), np.array(v))
    coords = {"x": m.x, "r": m.r, "theta": m.theta, "y": (("r", "theta"), m.y),
              "z": (("r", "theta"), m.z), "cell_area": (("r", "theta"), m.cell_area)}
    attrs = {"case.name": "synthetic", "gas.bulk_velocity": U_B, "pipe.length": L,
             "pipe.diameter": D, "pipe.mode": m.mode, "gas.density": 1.205}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def psi_two_cell(r, t, a=0.02 * U_B * R):
    """psi = a (1 - rho^2)^2 rho cos(theta), rho = r/R: two cells mirror-symmetric about the
    vertical diameter, flow downward along it (u_y = -a/R on the axis). Returns psi and its
    derivatives d psi/dr, d psi/d theta."""
    rho = r / R
    f = (1 - rho**2) ** 2
    return (a * f * rho * np.cos(t),
            a * ((1 - rho**2) ** 2 - 4 * rho**2 * (1 - rho**2)) / R * np.cos(t),
            -a * f * rho * np.sin(t))


def psi_four_cell(r, t, a=0.02 * U_B * R):
    """psi = a (1 - rho^2)^2 rho^2 sin(2 theta): four cells."""
    rho = r / R
    f = (1 - rho**2) ** 2
    return (a * f * rho**2 * np.sin(2 * t),
            a * (2 * rho * (1 - rho**2) ** 2 - 4 * rho**3 * (1 - rho**2)) / R * np.sin(2 * t),
            2 * a * f * rho**2 * np.cos(2 * t))


def velocity_from_psi(m, psi_fn):
    """Cartesian (u_y, u_z) at the cell centres from u_r = (1/r) psi_theta, u_theta = -psi_r."""
    r, t = m.r[:, None], m.theta[None, :]
    psi, psi_r, psi_t = psi_fn(r, t)
    ur, ut = psi_t / r, -psi_r
    return ur * np.sin(t) + ut * np.cos(t), ur * np.cos(t) - ut * np.sin(t), psi


def secondary_dataset(m, psi_fn, noise=0.0, seed=0, divergent=0.0):
    uy, uz, psi = velocity_from_psi(m, psi_fn)
    if noise:
        rng = np.random.default_rng(seed)
        top = np.hypot(uy, uz).max()
        uy = uy + noise * top * rng.standard_normal(uy.shape)
        uz = uz + noise * top * rng.standard_normal(uz.shape)
    if divergent:  # uniform radial outflow u_r = c r (irrotational), c R = divergent * U_b
        c = divergent * U_B / R
        uy, uz = uy + c * m.y, uz + c * m.z
    ux = 1.2 * U_B * (1 - m.r[:, None] / R) ** (1 / 7) * np.ones((1, m.nt))
    return synthetic_dataset(m, gas_ux=ux, gas_uy=uy, gas_uz=uz), psi


# ---------------------------------------------------------------------------

def test_ring_edges_from_cell_area_vs_mesh():
    m = mesh(12, 24)
    ds = synthetic_dataset(m)
    geo = an.polar_section(ds)
    np.testing.assert_allclose(geo.r_edges, m.r_edges, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(geo.theta_edges, m.theta_edges, atol=1e-12)
    np.testing.assert_allclose(geo.r, m.r, rtol=1e-12)
    assert geo.radius == pytest.approx(R, rel=1e-12)


@pytest.mark.parametrize("nr, nt", [(12, 24), (12, 26), (24, 48)])
def test_stream_function_vs_analytic_two_cell(nr, nt):
    m = mesh(nr, nt)
    ds, psi = secondary_dataset(m, psi_two_cell)
    got = an.stream_function(ds)
    # wall ring is ~0.1 R thick (y+ = 30), which limits the accuracy near the wall
    assert np.abs(got - psi).max() < 0.05 * np.abs(psi).max()
    # sign convention: psi > 0 (counter-clockwise looking downstream) in the right cell
    assert got[m.z > 0.3 * R].min() > 0 and got[m.z < -0.3 * R].max() < 0


def test_stream_function_vs_analytic_four_cell():
    m = mesh(12, 24)
    ds, psi = secondary_dataset(m, psi_four_cell)
    got = an.stream_function(ds)
    assert np.abs(got - psi).max() < 0.08 * np.abs(psi).max()


def test_stream_function_ignores_divergent_part():
    """A uniform radial outflow (irrotational, as from -du_x/dx in a developing pipe) 2.5 times
    stronger than the secondary flow leaves psi unchanged."""
    m = mesh(12, 24)
    base, _ = secondary_dataset(m, psi_two_cell)
    mixed, _ = secondary_dataset(m, psi_two_cell, divergent=0.05)
    np.testing.assert_allclose(an.stream_function(mixed), an.stream_function(base),
                               atol=1e-12 * np.abs(an.stream_function(base)).max())
    assert an.recirculation_cells(mixed) == 2


@pytest.mark.parametrize("nt", [24, 26])
def test_recirculation_cells_two_four_zero(nt):
    m = mesh(12, nt)
    assert an.recirculation_cells(secondary_dataset(m, psi_two_cell)[0]) == 2
    assert an.recirculation_cells(secondary_dataset(m, psi_four_cell)[0]) == 4
    zero = synthetic_dataset(m, gas_ux=np.ones((m.nr, m.nt)), gas_uy=np.zeros((m.nr, m.nt)),
                             gas_uz=np.zeros((m.nr, m.nt)))
    assert an.recirculation_cells(zero) == 0
    only_divergent = synthetic_dataset(m, gas_ux=np.ones((m.nr, m.nt)), gas_uy=0.1 * m.y / R,
                                       gas_uz=0.1 * m.z / R)
    assert an.recirculation_cells(only_divergent) == 0


@pytest.mark.parametrize("seed", range(4))
def test_recirculation_cells_robust_to_5_percent_noise(seed):
    m = mesh(12, 24)
    ds, _ = secondary_dataset(m, psi_two_cell, noise=0.05, seed=seed)
    n, cells = an.recirculation_cells(ds, details=True)
    assert n == 2
    assert sorted(c["sign"] for c in cells) == [-1, 1]
    # the counter-clockwise cell is the right one (z > 0)
    assert next(c for c in cells if c["sign"] > 0)["z"] > 0
    ds4, _ = secondary_dataset(m, psi_four_cell, noise=0.05, seed=seed)
    assert an.recirculation_cells(ds4) == 4


def test_count_cells_connects_across_axis_and_theta_wrap():
    nr, nt = 4, 8
    psi = np.zeros((nr, nt))
    psi[0, :] = 1.0                  # every innermost wedge: one region through the axis
    psi[3, [7, 0]] = -1.0            # sectors 7 and 0 touch through the periodic wrap
    cells = an.count_cells(psi)
    assert len(cells) == 2
    assert {c["sign"]: c["cells"] for c in cells} == {1: nt, -1: 2}


def test_secondary_flow_strength_of_solid_body_rotation():
    """u_theta = Omega r: the largest in-plane speed is Omega r of the outermost ring centre."""
    m = mesh(12, 24)
    omega = 20.0  # s-1
    uy, uz = omega * m.z, -omega * m.y  # counter-clockwise (z right, y up)
    ds = synthetic_dataset(m, gas_ux=np.ones_like(uy), gas_uy=uy, gas_uz=uz)
    assert an.secondary_flow_strength(ds) == pytest.approx(100 * omega * m.r[-1] / U_B, rel=1e-12)
    # cell-mean vorticity of a solid-body rotation, counter-clockwise here, away from the wall ring
    w = an.vorticity(ds)
    np.testing.assert_allclose(w[:-1], 2 * omega, rtol=1e-10)  # du_y/dz - du_z/dy = +2 Omega


def test_gas_maximum_half():
    m = mesh(12, 24)
    base = 10 * (1 - m.r[:, None] / R) ** (1 / 7) * np.ones((1, m.nt))
    low = synthetic_dataset(m, gas_ux=base * (1 - 0.1 * m.y / R))
    up = synthetic_dataset(m, gas_ux=base * (1 + 0.1 * m.y / R))
    sym = synthetic_dataset(m, gas_ux=base)
    assert an.gas_maximum_half(low) == "lower"
    assert an.gas_maximum_half(up) == "upper"
    assert an.gas_maximum_half(sym) == "neither"


@pytest.mark.parametrize("nt", [24, 26])
def test_vertical_profile_picks_the_cells_on_the_vertical_diameter(nt):
    """nt = 24: theta = 90 and 270 deg are sector faces (mean of the two sectors); nt = 26:
    they are sector mid-lines (that sector's value)."""
    m = mesh(12, nt)
    nr = m.nr
    field = 1000.0 * np.arange(nt)[None, :] + np.arange(nr)[:, None]  # 1000 k + j
    ds = synthetic_dataset(m, particle_ux=field)
    y, v = an.vertical_profile(ds, "particle_ux")
    np.testing.assert_allclose(y, np.concatenate([-m.r[::-1], m.r]), rtol=1e-12)
    if nt == 24:   # faces between sectors 5|6 (90 deg) and 17|18 (270 deg)
        top, bottom = 5500.0, 17500.0
    else:          # sector 6 centred on 90 deg, sector 19 on 270 deg
        top, bottom = 6000.0, 19000.0
    np.testing.assert_allclose(v[nr:], top + np.arange(nr))
    np.testing.assert_allclose(v[:nr], bottom + np.arange(nr)[::-1])


def test_vertical_profile_is_nan_aware():
    m = mesh(12, 24)
    field = 1000.0 * np.arange(24)[None, :] + np.arange(m.nr)[:, None]
    field[:, 5] = np.nan              # one of the two sectors beside 90 deg: use the other
    field[3, 17] = field[3, 18] = np.nan   # both sectors beside 270 deg in ring 3: NaN
    ds = synthetic_dataset(m, particle_ux=field)
    y, v = an.vertical_profile(ds, "particle_ux")
    np.testing.assert_allclose(v[m.nr:], 6000.0 + np.arange(m.nr))
    bottom = v[:m.nr][::-1]
    assert np.isnan(bottom[3]) and np.isfinite(np.delete(bottom, 3)).all()


def test_wall_impact_rates_upper_lower_split():
    m = mesh(8, 24, mode="developing", nx=4)
    upper = np.sin(m.theta) > 0
    rate = np.where(upper, 3.0, 1.0)[None, :] * (1.0 + np.arange(4))[:, None]  # x-dependent
    ds = synthetic_dataset(m)
    ds["wall_collision_rate"] = (("x", "theta"), rate)
    got = an.wall_impact_rates(ds)
    assert got["upper"] == pytest.approx(3.0 * 2.5) and got["lower"] == pytest.approx(2.5)
    at = an.wall_impact_rates(ds, x=m.x[0])
    assert at == pytest.approx({"upper": 3.0, "lower": 1.0})


def test_section_mean_area_weighted():
    m = mesh(12, 24)
    ones_top = np.where(m.y > 0, 1.0, 0.0)
    ds = synthetic_dataset(m, a=ones_top, b=np.where(m.y > 0, 2.0, np.nan), c=m.y)
    assert an.section_mean(ds, "a") == pytest.approx(0.5, rel=1e-12)
    assert an.section_mean(ds, "b") == pytest.approx(2.0, rel=1e-12)    # NaN cells skipped
    assert an.section_mean(ds, "c") == pytest.approx(0.0, abs=1e-15)
    assert an.section_mean(ds, "a", weight="a") == pytest.approx(1.0)   # weighted by itself


def test_section_nearest_station_and_out_of_range():
    m = mesh(8, 16, mode="developing", nx=20)
    ds = synthetic_dataset(m, a=np.ones((m.nr, m.nt)))
    assert float(an.section(ds, 3.56)["x"]) == pytest.approx(m.x[np.argmin(abs(m.x - 3.56))])
    with pytest.raises(ValueError, match="outside the pipe"):
        an.section(ds, 4.5)
    with pytest.raises(ValueError, match="outside the pipe"):
        an.section(ds, -0.1)
    periodic = synthetic_dataset(mesh(8, 16), a=np.ones((8, 16)))
    assert an.section(periodic, 3.56).sizes.get("x") is None


def test_pressure_drop_summary_computed_and_stored():
    m = mesh(8, 16, mode="developing", nx=4)
    ds = synthetic_dataset(m)
    ds["pressure_gradient"] = ("x", np.full(4, 150.0))
    ds["pressure_gradient_single_phase"] = ("x", np.full(4, 100.0))
    ds.attrs["particles.mass_loading"] = 2.0
    s = an.pressure_drop_summary(ds)
    assert s["source"] == "computed"
    assert s["solids_pressure_drop_ratio"] == pytest.approx(1.5)
    # lambda_Z = (dp/dx - dp/dx_gas) D / (eta rho U^2 / 2)
    assert s["additional_pressure_loss_coefficient"] == pytest.approx(
        50.0 * D / (2.0 * 0.5 * 1.205 * U_B**2))
    ds["solids_pressure_drop_ratio"] = 1.7
    ds["additional_pressure_loss_coefficient"] = 0.004
    s = an.pressure_drop_summary(ds)
    assert s["source"] == "dataset"
    assert (s["solids_pressure_drop_ratio"], s["additional_pressure_loss_coefficient"]) == (1.7, 0.004)
    assert math.isfinite(s["pressure_gradient"])
