"""Drag zones, kinetic theory, wall condition and inlet correlations of the two-fluid model
(Ding et al. 2024) against independent references: Ergun's packed-bed Δp and the standard
drag curve from the ``fluids`` package, and the published formulas evaluated by hand."""

import math

import numpy as np
import pytest
from fluids.drag import v_terminal
from fluids.packed_bed import Ergun
from scipy.optimize import brentq

from tfm.drag import ergun_1952, mckeen_pugsley_2003, three_zone_drag, wen_yu_1966
from tfm.inlet import hinkle_1953_solids_velocity, hinkle_particle_diameter, inlet_solids_fraction
from tfm.kinetic import (
    gidaspow_conductivity,
    gidaspow_viscosity,
    lun_bulk_viscosity,
    lun_dissipation,
    lun_solids_pressure,
    savage_radial_distribution,
    strain_rate_invariant,
)
from tfm.wall import schneiderbauer_mu0, schneiderbauer_wall_heat_flux, schneiderbauer_wall_shear

RHO_G, MU_G = 32.7, 1.78e-5  # nitrogen, 2.92 MPa, 300 K
G = 9.80665


# ---------------------------------------------------------------- drag
@pytest.mark.parametrize("voidage, vs", [(0.40, 0.01), (0.45, 0.05), (0.55, 0.2)])
def test_ergun_zone_vs_fluids_packed_bed_dp(voidage, vs):
    """A fixed bed: the gas momentum balance 0 = −α_g dp/dx − β (u_g − 0) with u_g = U/α_g
    gives −dp/dx = β U / α_g², which must be Ergun's packed-bed law."""
    d = 160e-6
    beta = three_zone_drag(1.0 - voidage, RHO_G, MU_G, d, vs / voidage)
    dpdx = beta * vs / voidage**2
    assert float(dpdx) == pytest.approx(Ergun(dp=d, voidage=voidage, vs=vs, rho=RHO_G, mu=MU_G, L=1.0), rel=1e-10)


@pytest.mark.parametrize("d, rho_s, rho_g, mu_g", [(160e-6, 1650.0, RHO_G, MU_G), (50e-6, 2500.0, 1.2, 1.8e-5),
                                                    (1e-3, 1000.0, 1.2, 1.8e-5)])
def test_dilute_zone_terminal_velocity_vs_fluids_standard_curve(d, rho_s, rho_g, mu_g):
    """Single particle (α_s → 0): β v_t/α_s = (ρ_s − ρ_g) g.  The Wen–Yu zone uses the
    Schiller–Naumann C_D, which follows the standard curve (fluids' Clift fit) within a few %."""
    a = 1e-9
    v = brentq(lambda v: three_zone_drag(a, rho_g, mu_g, d, v) * v / a - (rho_s - rho_g) * G, 1e-8, 50.0)
    ref = v_terminal(D=d, rhop=rho_s, rho=rho_g, mu=mu_g, Method="Clift")
    assert v == pytest.approx(ref, rel=0.04)


def test_dilute_zone_stokes_limit_by_hand():
    # Stokes: v_St = (rho_s - rho_g) g d^2 / (18 mu) = 2498.8 * 9.80665 * 1e-10 / 3.24e-4 = 7.56322e-3 m/s;
    # at Re = 1.2 * 1e-5 * 7.53e-3 / 1.8e-5 = 5.02e-3 Schiller-Naumann adds 0.15 Re^0.687 = 3.94e-3
    d, rho_s = 10e-6, 2500.0
    v = brentq(lambda v: wen_yu_1966(1e-9, 1.2, 1.8e-5, d, v) * v / 1e-9 - (rho_s - 1.2) * G, 1e-9, 1.0)
    assert v == pytest.approx(2498.8 * G * 1e-10 / 3.24e-4 / 1.00394, rel=2e-4)


def test_mckeen_zone_by_hand():
    # alpha_s 0.2, rho_g 1, mu 1e-5, d 1e-4, slip 0.1: Re = 0.8*1*1e-4*0.1/1e-5 = 0.8
    # (17.3/0.8 + 0.336) * 0.2 * 1 * 0.1 / 1e-4 * 0.8^-1.8 = 21.961 * 200 * 1.494348 = 6563.4
    assert float(mckeen_pugsley_2003(0.2, 1.0, 1e-5, 1e-4, 0.1)) == pytest.approx(6563.4, rel=1e-4)
    assert float(mckeen_pugsley_2003(0.2, 1.0, 1e-5, 1e-4, 0.1, scale=0.25)) == pytest.approx(6563.4 / 4, rel=1e-4)


def test_three_zone_picks_each_law_and_blend_is_continuous():
    d, slip = 160e-6, 0.5
    for a_s, law in [(0.45, ergun_1952), (0.25, mckeen_pugsley_2003), (0.05, wen_yu_1966)]:
        assert float(three_zone_drag(a_s, RHO_G, MU_G, d, slip)) == pytest.approx(float(law(a_s, RHO_G, MU_G, d, slip)))
    a = np.linspace(0.02, 0.6, 20001)
    piece = three_zone_drag(a, RHO_G, MU_G, d, slip)
    smooth = three_zone_drag(a, RHO_G, MU_G, d, slip, blend_width=0.01)
    jump_piece = np.max(np.abs(np.diff(np.log(piece))))
    jump_smooth = np.max(np.abs(np.diff(np.log(smooth))))
    assert jump_piece > 0.5       # the printed law jumps (by a factor e^0.5 or more) at a switch
    assert jump_smooth < 1e-2     # the blend does not
    # far from the switches the blend is the printed law
    far = (np.abs(a - 0.4) > 0.06) & (np.abs(a - 0.1) > 0.06)
    assert np.allclose(smooth[far], piece[far], rtol=1e-2)


# ---------------------------------------------------------------- kinetic theory
def test_savage_g0_by_hand():
    # (1 - 7*0.5/16) / (1 - 0.5/0.63)^2 = 0.78125 / 0.2063492^2 = 0.78125 / 0.04258 = 18.3478
    assert float(savage_radial_distribution(0.5)) == pytest.approx(18.3478, rel=1e-5)
    assert float(savage_radial_distribution(0.0)) == 1.0


def test_ktgf_closures_by_hand():
    # alpha 0.3, rho_s 1500, d 1e-4, Theta 0.01, g0 2, e 0.7 ; sqrt(Theta/pi) = 0.05641896, sqrt(pi Theta) = 0.1772454
    a, rs, d, th, g0, e = 0.3, 1500.0, 1e-4, 0.01, 2.0, 0.7
    # p_s = 0.3*1500*0.01*(1 + 2*1.7*0.3*2) = 4.5 * 3.04 = 13.68
    assert float(lun_solids_pressure(a, rs, th, g0, e)) == pytest.approx(13.68, rel=1e-12)
    # lambda = 4/3 * 0.3*1500*1e-4*2*1.7 * 0.05641896 = 0.204 * 0.05641896 = 0.01150947
    assert float(lun_bulk_viscosity(a, rs, d, th, g0, e)) == pytest.approx(0.01150947, rel=1e-6)
    # mu_col = 0.8*0.153*0.05641896 = 0.00690568 ; mu_kin = 1.5*0.1772454/97.92 * 1.816^2 = 0.00895430
    assert float(gidaspow_viscosity(a, rs, d, th, g0, e)) == pytest.approx(0.00690568 + 0.00895430, rel=1e-5)
    # kappa = 22.5*0.1772454/1305.6 * 2.224^2 + 2*1500*1e-4*0.09*2*1.7*0.05641896 = 0.0151083 + 0.00517926
    assert float(gidaspow_conductivity(a, rs, d, th, g0, e)) == pytest.approx(0.0151083 + 0.00517926, rel=1e-5)
    # gamma = 12*0.51*2*1500*0.09*0.001/(1e-4*1.7724539) = 1.6524/1.7724539e-4 = 9322.67
    assert float(lun_dissipation(a, rs, d, th, g0, e)) == pytest.approx(9322.67, rel=1e-6)


def test_strain_rate_invariant_simple_shear_and_expansion():
    g = np.zeros((3, 3))
    g[0, 1] = 3.0
    assert float(strain_rate_invariant(g)) == pytest.approx(4.5)  # ½ (du/dy)^2
    assert float(strain_rate_invariant(np.eye(3))) == pytest.approx(0.0)  # isotropic expansion: no deviator


# ---------------------------------------------------------------- wall
def test_schneiderbauer_mu0_and_shear_by_hand():
    # mu0 = 3.5 * 1.5/1.3 * 0.5 = 2.0192308
    assert schneiderbauer_mu0(0.5, 0.5, 0.3) == pytest.approx(2.0192308, rel=1e-7)
    # u_sw 0.2, Theta 0.01: ubar = 0.2/(sqrt(0.02)*2.0192308) = 0.2/0.2855619 = 0.7003724; erf = 0.678058
    # tau = -(0.75*0.5*0.5*1500*10*0.01*0.678058 + 0.5*30) = -(19.07038 + 15) = -34.07038
    tau = schneiderbauer_wall_shear(0.2, 0.5, 1500.0, 10.0, 0.01, 30.0)
    assert float(tau) == pytest.approx(-34.07038, rel=1e-5)
    assert float(schneiderbauer_wall_shear(-0.2, 0.5, 1500.0, 10.0, 0.01, 30.0)) == pytest.approx(34.07038, rel=1e-5)


def test_schneiderbauer_heat_flux_no_slip_by_hand():
    # u = 0, Theta 0.01: pre = 0.5*1500*10*0.75*0.1/(2.5066283*4.0772929) = 55.03763
    # first = 0.5*0.01*(5.25 - 12.115385 - 9.173909) = -0.08019647 ; second = 4.0772929*0.1*0.1*0.125 = 0.00509662
    # q = -55.03763 * (-0.08019647 + 0.00509662) = 4.13333
    assert float(schneiderbauer_wall_heat_flux(0.0, 0.5, 1500.0, 10.0, 0.01, 0.0)) == pytest.approx(4.13333, rel=1e-5)


# ---------------------------------------------------------------- inlet / inference
TABLE1 = np.array([  # Q_s m3/h, U_g m/s, M_s kg/s, alpha_s inlet, u_s inlet m/s
    [0.40, 4.71, 0.213, 0.318, 4.43], [0.60, 5.62, 0.206, 0.286, 5.30], [0.80, 6.43, 0.194, 0.245, 6.09],
    [1.00, 7.24, 0.181, 0.199, 6.79], [1.20, 8.10, 0.168, 0.184, 7.72]])


def test_table1_inference_diameter_density_size():
    q, ug, ms, a_in, us = TABLE1.T
    # U_g rises 4.2 m/s per m3/h: D = sqrt(4/(pi*3600*4.2)) = 9.18 mm if Q_s is at line pressure
    slope = np.polyfit(q, ug, 1)[0]
    assert slope == pytest.approx(4.2, abs=1e-9)
    assert math.sqrt(4.0 / (math.pi * 3600.0 * slope)) == pytest.approx(9.18e-3, abs=1e-5)
    # eq. 23 per row: rho_s D^2 = 4 M_s/(alpha pi u_s) = 0.151 ... 0.193 kg/m; row 3: 0.1655 -> 1655 kg/m3 at D = 10 mm
    rd2 = 4.0 * ms / (a_in * math.pi * us)
    assert rd2.min() == pytest.approx(0.1506, abs=5e-4) and rd2.max() == pytest.approx(0.1925, abs=5e-4)
    assert inlet_solids_fraction(0.194, 1650.0, 6.09, 0.010) == pytest.approx(0.245, abs=1e-3)
    # eq. 22 inverted with D = 10 mm, rho_s = 1650: d_s = 139 ... 189 µm, row 3: 159 µm
    d = hinkle_particle_diameter(us / ug, 1650.0, RHO_G, 0.010)
    assert d.min() == pytest.approx(139e-6, abs=1.5e-6) and d.max() == pytest.approx(189e-6, abs=1.5e-6)
    assert hinkle_1953_solids_velocity(6.43, 160e-6, 1650.0, RHO_G, 0.010) == pytest.approx(6.09, abs=0.01)


@pytest.mark.parametrize("module", ["tfm.drag", "tfm.kinetic", "tfm.friction", "tfm.wall", "tfm.inlet"])
def test_docstring_examples_run(module):
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0
