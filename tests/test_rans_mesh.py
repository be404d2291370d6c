"""Mesh geometry and point location of rans.PipeMesh."""

import math

import numpy as np
import pytest

from rans import PipeMesh, locate_cell


@pytest.mark.parametrize("nr,nt", [(8, 16), (20, 40), (33, 12)])
def test_cell_area_sums_to_pipe_section(nr, nt):
    m = PipeMesh.build(0.0305, 4.0, "developing", axial_cells=10, radial_cells=nr, azimuthal_cells=nt)
    assert m.cell_area.sum() == pytest.approx(math.pi * m.radius**2, rel=1e-13)
    assert m.volume.sum() == pytest.approx(math.pi * m.radius**2 * 4.0, rel=1e-12)


@pytest.mark.parametrize("D,U,yplus", [(0.0305, 10.0, 30.0), (0.0305, 50.0, 30.0), (0.3, 50.0, 50.0), (0.0305, 10.0, 60.0)])
def test_wall_cell_centre_at_target_yplus_for_colebrook_friction_velocity(D, U, yplus):
    from fluids.friction import Colebrook

    rho, mu = 1.205, 1.81e-5
    m = PipeMesh.build(D, 1.0, "periodic", radial_cells=20, azimuthal_cells=16, first_cell_yplus=yplus,
                       bulk_velocity=U, density=rho, viscosity=mu)
    u_tau = U * math.sqrt(Colebrook(rho * U * D / mu, 0.0) / 8.0)
    assert m.wall_distance * u_tau * rho / mu == pytest.approx(yplus, rel=1e-9)
    assert np.all(np.diff(m.r_edges) > 0)


def test_mesh_is_mirror_symmetric_about_vertical_diameter():
    m = PipeMesh.build(0.0305, 1.0, "periodic", radial_cells=10, azimuthal_cells=24)
    th = np.sort(np.mod(np.pi - m.theta, 2 * np.pi))
    np.testing.assert_allclose(th, np.sort(m.theta), atol=1e-13)


def test_locate_matches_brute_force_search():
    m = PipeMesh.build(0.0305, 4.0, "developing", axial_cells=40, radial_cells=12, azimuthal_cells=20)
    rng = np.random.default_rng(3)
    n = 20000
    r = m.radius * np.sqrt(rng.random(n)) * 0.999999
    th = 2 * np.pi * rng.random(n)
    x = 4.0 * rng.random(n)
    y, z = r * np.sin(th), r * np.cos(th)
    i, j, k = m.locate(x, y, z)
    assert np.all(m.x_edges[i] <= x) and np.all(x <= m.x_edges[i + 1])
    assert np.all(m.r_edges[j] <= r + 1e-15) and np.all(r <= m.r_edges[j + 1] + 1e-15)
    assert np.all(m.theta_edges[k] <= th + 1e-12) and np.all(th <= m.theta_edges[k + 1] + 1e-12)
    # outside points
    io, _, _ = m.locate(np.array([1.0, -0.1]), np.array([m.radius * 1.01, 0.0]), np.array([0.0, 0.0]))
    assert np.all(io == -1)
    # the compiled kernel agrees with its Python version
    assert locate_cell.py_func(1.0, y[0], z[0], 4.0, 40, m.r_edges, 20) == locate_cell(1.0, y[0], z[0], 4.0, 40, m.r_edges, 20)


def test_ring_growth_and_the_fewest_rings_that_keep_it():
    from rans.mesh import MAX_RING_GROWTH, radial_edges, radial_growth, rings_for_growth

    radius, wall = 0.15, 4.72e-4  # the 0.3 m pipe at Re = 1e6, wall cell centre at y+ = 30
    for n in (3, 5, 6, 12):
        sizes = np.diff(radial_edges(radius, n, wall))
        q = sizes[:-1] / sizes[1:]
        assert radial_growth(radius, n, wall) == pytest.approx(q.max(), rel=1e-12)
        # geometric from the ring next to the wall ring (as thick as it) inward
        assert np.allclose(q[:-1], q[0], rtol=1e-6) and q[-1] == pytest.approx(1.0, rel=1e-9)
    n = rings_for_growth(radius, wall)
    assert radial_growth(radius, n, wall) <= MAX_RING_GROWTH < radial_growth(radius, n - 1, wall)
    assert n == 6  # growth 3.9 on 6 rings, 6.4 on 5
    assert radial_growth(0.01525, 20, 5e-4) == pytest.approx(1.0, abs=0.05)  # the base case: near uniform
