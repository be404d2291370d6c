"""Verification by manufactured solutions (laminar viscosity, central differencing).

Cross-section: a divergence-free cross-flow from the stream function psi = a (1 - rho^2)^2 y,
which crosses the pipe centre horizontally, an asymmetric axial velocity and a smooth
pressure; the forcing is the residual of the exact solution in the model equations,
computed here from the closed forms by 4th-order finite differences (independent of the
solver's operators).  Axial march: a manufactured developing flow u_x = 2U(1 - rho^2) +
U eps(x) (1 - rho^2)(1 - 3 rho^2) with the radial inflow continuity demands.
"""

import numpy as np
import pytest

from rans import GasProperties, PipeMesh, Sources, solve

RHO, MU, R, UB = 1.0, 0.1, 0.5, 0.1
A_PSI, P0 = 0.4, 0.02


def exact(y, z):
    rho2 = (y * y + z * z) / R**2
    ux = 2 * UB * (1 - rho2) * (1 + 0.3 * y / R)
    # psi = a (1 - rho^2)^2 y ; u_y = d psi/dz, u_z = -d psi/dy
    uy = A_PSI * 2 * (1 - rho2) * (-2 * z / R**2) * y
    uz = -A_PSI * ((1 - rho2) ** 2 + y * 2 * (1 - rho2) * (-2 * y / R**2))
    p = P0 * (y * z / R**2 + 0.5 * np.sin(2.0 * y / R))
    return ux, uy, uz, p


def d1(fun, y, z, axis, h=1e-4):
    e = (h, 0.0) if axis == "y" else (0.0, h)
    return (-fun(y + 2 * e[0], z + 2 * e[1]) + 8 * fun(y + e[0], z + e[1]) - 8 * fun(y - e[0], z - e[1])
            + fun(y - 2 * e[0], z - 2 * e[1])) / (12 * h)


def lap(fun, y, z, h=1e-3):
    out = 0.0
    for e in ((h, 0.0), (0.0, h)):
        out = out + (-fun(y + 2 * e[0], z + 2 * e[1]) + 16 * fun(y + e[0], z + e[1]) - 30 * fun(y, z)
                     + 16 * fun(y - e[0], z - e[1]) - fun(y - 2 * e[0], z - 2 * e[1])) / (12 * h * h)
    return out


G_EXACT = 0.05  # -dp/dx [Pa/m]


def forcing(y, z):
    comp = [lambda a, b, i=i: exact(a, b)[i] for i in range(4)]
    _, uy, uz, _ = exact(y, z)
    conv = [RHO * (uy * d1(c, y, z, "y") + uz * d1(c, y, z, "z")) for c in comp[:3]]
    sx = conv[0] - MU * lap(comp[0], y, z) - G_EXACT
    fy = conv[1] - MU * lap(comp[1], y, z) + d1(comp[3], y, z, "y")
    fz = conv[2] - MU * lap(comp[2], y, z) + d1(comp[3], y, z, "z")
    return sx, fy, fz


def mesh(nr, nt, mode="periodic", nx=1, length=1.0):
    return PipeMesh(diameter=2 * R, length=length, mode=mode, x_edges=np.linspace(0, length, nx + 1),
                    r_edges=np.linspace(0.0, R, nr + 1), nt=nt)


def cross_section_errors(nr, nt):
    m = mesh(nr, nt)
    s = Sources.zeros(m)
    sx, fy, fz = forcing(m.y, m.z)
    s.momentum[0, 0], s.momentum[1, 0], s.momentum[2, 0] = sx, fy, fz
    f = solve(m, GasProperties(RHO, MU), UB, sources=s, laminar=True, momentum_scheme="central", tol=1e-12)
    ux, uy, uz, _ = exact(m.y, m.z)
    w = m.cell_area / m.cell_area.sum()
    err = {}
    for name, num, ex in (("ux", f.ux[0], ux), ("uy", f.uy[0], uy), ("uz", f.uz[0], uz)):
        e = num - ex
        err[name] = (np.sqrt((w * e * e).sum()), np.abs(e).max())
    err["G"] = (abs(f.pressure_gradient[0] - G_EXACT),) * 2
    return err


GRIDS = [(12, 24), (24, 48), (48, 96)]


@pytest.fixture(scope="module")
def mms_errors():
    return [cross_section_errors(*g) for g in GRIDS]


def _orders(errs, name, norm):
    e = np.array([er[name][norm] for er in errs])
    return e, np.log2(e[:-1] / e[1:])


def test_cross_section_operator_is_second_order_in_l2_norm(mms_errors):
    for name in ("ux", "uy", "uz", "G"):
        e, order = _orders(mms_errors, name, 0)
        assert np.all(order >= 1.8), (name, e, order)


def test_cross_section_operator_is_second_order_in_max_norm(mms_errors):
    """Max norm (issue 2: >= 1.8).  The largest errors sit near the axis; without the
    deferred correction of the radial-face gradient (Section.radial_gradient_correction) the
    wedge ring keeps an O(1) truncation error and u_x, u_z reach only 1.74-1.84 here."""
    for name in ("ux", "uy", "uz"):
        e, order = _orders(mms_errors, name, 1)
        assert np.all(order >= 1.8), (name, e, order)


def test_radial_gradient_correction_is_exact_for_quadratics():
    """The corrected radial-face derivative of phi = r^2 equals 2 r_f on every corrected face
    (the two-point difference alone is off by the centre-to-face offset)."""
    from rans.operators import Section

    for m in (mesh(12, 16), PipeMesh.build(0.0305, 1.0, "periodic", 1, 20, 16)):  # uniform, wall-clustered
        s = Section(m)
        r2 = (m.r[:, None] ** 2 * np.ones(m.nt)).ravel()
        f = s.corrected_faces
        assert f.size == (m.nr - 3) * m.nt  # all radial faces but the two next to the wall ring
        g2 = (r2[s.N[f]] - r2[s.P[f]]) / s.delta[f]
        g = g2 + s._corr @ r2
        rf = m.r_edges[1:][f // m.nt]
        assert np.allclose(g, 2 * rf, rtol=1e-10, atol=0)
        assert np.abs(g2 - 2 * rf).max() > 1e-3 * rf.max()


def test_axial_march_is_second_order():
    """BDF2 march of a manufactured developing flow u_x = 2U(1 - rho^2) + U eps(x) (1 - rho^2)(1 - 3 rho^2)
    with the radial inflow continuity demands; the cross-section fixed, the solution at a
    fixed x (quadratic interpolation between stations) from nx = 10, 20, 40, 80 gives the
    observed order from successive differences."""
    L, lam = 0.3, 0.1

    def fields(x, y, z):
        rho2 = (y * y + z * z) / R**2
        eps, deps = 0.3 * np.exp(-x / lam), -0.3 / lam * np.exp(-x / lam)
        ux = 2 * UB * (1 - rho2) + UB * eps * (1 - rho2) * (1 - 3 * rho2)
        ur_over_r = -UB * deps * (1 - rho2) ** 2 / 2.0  # u_r = -U eps' R rho (1 - rho^2)^2 / 2
        return ux, ur_over_r * y, ur_over_r * z

    def at(m, field, xi):
        i = np.searchsorted(m.x, xi)
        xs = m.x[i - 1:i + 2]
        w = [np.prod([(xi - xs[b]) / (xs[a] - xs[b]) for b in range(3) if b != a]) for a in range(3)]
        return sum(w[a] * field[i - 1 + a] for a in range(3))

    outs = []
    for nx in (10, 20, 40, 80):
        m = mesh(8, 16, "developing", nx=nx, length=L)
        s = Sources.zeros(m)
        h = 1e-5
        for i, x in enumerate(m.x):
            y, z = m.y, m.z
            u = fields(x, y, z)
            dudx = [(fields(x + h, y, z)[c] - fields(x - h, y, z)[c]) / (2 * h) for c in range(3)]
            for c in range(3):
                comp = lambda a, b, c=c: fields(x, a, b)[c]  # noqa: E731
                conv = RHO * (u[0] * dudx[c] + u[1] * d1(comp, y, z, "y") + u[2] * d1(comp, y, z, "z"))
                s.momentum[c, i] = conv - MU * lap(comp, y, z) - (G_EXACT if c == 0 else 0.0)
        f = solve(m, GasProperties(RHO, MU), UB, sources=s, laminar=True, momentum_scheme="central", tol=1e-13,
                  station_iterations=(3, 200), cross_flow_solver="coupled",
                  inlet_profile=lambda y, z: fields(0.0, y, z))
        assert f.converged
        outs.append(at(m, f.ux, 0.25))
    d = np.array([np.abs(outs[i] - outs[i + 1]).max() for i in range(3)])
    order = np.log2(d[:-1] / d[1:])
    assert np.all(np.abs(order - 2.0) < 0.3), order
