"""Frictional stress models of Ding et al. (2024), eqs. (13)–(19), against their published
formulas evaluated by hand, and the ordering of the paper's Fig. 7."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tfm.friction import (
    berzi_2011_pressure,
    cap_viscosity,
    dartevelle_2004_pressure,
    dartevelle_2004_viscosity,
    frictional_stress,
    johnson_jackson_1987_pressure,
    modified_berzi_viscosity,
    srivastava_sundaresan_2003_pressure,
    srivastava_sundaresan_2003_viscosity,
)
from tfm.parameters import SolidsParameters

PHI = math.radians(32.0)
# sin 32° = 0.5299192642, sin² = 0.2808144266  (tables)
SIN = 0.5299192642
SIN2 = 0.2808144266


def test_friction_angle_is_converted_from_degrees_once():
    # sin(32 rad) = 0.551 would be a plausible-looking wrong value
    assert math.sin(SolidsParameters().phi_i) == pytest.approx(SIN, abs=1e-9)


# ---------------------------------------------------------------- Dartevelle, eqs. 13-14
def test_dartevelle_pressure_vs_eq13_by_hand():
    # alpha = 0.5: 1000 (0.1/0.13)^3 = 1000 * 0.4551661356 = 455.1661 Pa
    assert float(dartevelle_2004_pressure(0.5)) == pytest.approx(455.1661356, rel=1e-9)
    # alpha = 0.45: 1000 (0.05/0.18)^3 = 1000 * 0.0214334705 = 21.4335 Pa
    assert float(dartevelle_2004_pressure(0.45)) == pytest.approx(21.4334705, rel=1e-8)
    assert float(dartevelle_2004_pressure(0.4)) == 0.0
    assert float(dartevelle_2004_pressure(0.3)) == 0.0


def test_dartevelle_viscosity_vs_eq14_by_hand():
    # p_f = 100 Pa, S:S = 2 s-2, Theta = 1e-6 m2 s-2, d = 1e-4 m (Theta/d^2 = 100 s-2), div = -3 s-1
    # den = sqrt(2 * 0.2808144266 * 102 + 9) = sqrt(66.28614303) = 8.1416303
    # mu = 100 * 0.2808144266 / 8.1416303 = 3.449118 Pa s
    mu = dartevelle_2004_viscosity(100.0, PHI, 2.0, 1e-6, 1e-4, -3.0)
    assert float(mu) == pytest.approx(3.449118, rel=1e-6)


# ---------------------------------------------------------------- Srivastava-Sundaresan, eqs. 15-17
def test_johnson_jackson_pc_vs_eq15_by_hand():
    # Fr 0.05 Pa, r 2, s 5: alpha 0.5 -> 0.05 * 0.01 / 0.13^5 = 5e-4 / 3.71293e-5 = 13.46645 Pa
    assert float(johnson_jackson_1987_pressure(0.5)) == pytest.approx(13.46645, rel=1e-6)
    # alpha 0.45 -> 0.05 * 0.0025 / 0.18^5 = 1.25e-4 / 1.889568e-4 = 0.6615268 Pa
    assert float(johnson_jackson_1987_pressure(0.45)) == pytest.approx(0.6615268, rel=1e-6)


def test_srivastava_sundaresan_compression_vs_eq16_17_by_hand():
    # compression (div = -0.5 s-1): n = 1.03; S:S = 1 s-2, Theta = 0
    # scale = sqrt2 * 1.03 * 0.5299192642 * 1 = 0.7718929
    # p_f/p_c = (1 + 0.5/0.7718929)^0.03 = 1.6477517^0.03 = 1.0150952
    pc = 10.0
    pf = srivastava_sundaresan_2003_pressure(pc, PHI, 1.0, 0.0, 1e-4, -0.5)
    assert float(pf) == pytest.approx(10.150952, rel=1e-6)
    # mu_f = pf sin(phi)/(sqrt2 * 1) * [1.03 - 0.03 * (1.0150952)^(1/0.03)]
    #      (1.0150952)^(33.333) = 1.6477517 -> bracket = 1.03 - 0.0494326 = 0.9805674
    #      = 10.150952 * 0.5299192642 / 1.4142136 * 0.9805674 = 3.729761 Pa s
    mu = srivastava_sundaresan_2003_viscosity(pf, pc, PHI, 1.0, 0.0, 1e-4, -0.5)
    assert float(mu) == pytest.approx(3.729761, rel=1e-5)


def test_srivastava_sundaresan_dilation_vs_eq16_by_hand_and_guard():
    # dilation (div = +0.5 s-1): n = sqrt3/(2 sin phi) = 1.6342585
    # scale = sqrt2 * 1.6342585 * 0.5299192642 = 1.2247449 (= sqrt(3/2))
    # p_f/p_c = (1 - 0.5/1.2247449)^0.6342585 = 0.5917517^0.6342585
    #         = exp(0.6342585 * ln 0.5917517) = exp(-0.3327780) = 0.7169311
    pf = srivastava_sundaresan_2003_pressure(10.0, PHI, 1.0, 0.0, 1e-4, 0.5)
    assert float(pf) == pytest.approx(7.169311, rel=1e-6)
    # strong dilation (dilation term > 1): p_f = 0, and mu_f = 0
    pf = srivastava_sundaresan_2003_pressure(10.0, PHI, 1.0, 0.0, 1e-4, 2.0)
    assert float(pf) == 0.0
    assert float(srivastava_sundaresan_2003_viscosity(pf, 10.0, PHI, 1.0, 0.0, 1e-4, 2.0)) == 0.0


def test_srivastava_sundaresan_viscosity_never_negative_under_strong_compression():
    div = -np.logspace(-2, 4, 50)
    pf = srivastava_sundaresan_2003_pressure(10.0, PHI, 1.0, 0.0, 1e-4, div)
    mu = srivastava_sundaresan_2003_viscosity(pf, 10.0, PHI, 1.0, 0.0, 1e-4, div)
    assert np.all(mu >= 0.0)
    # the cap p_f/p_c <= (n/(n-1))^(n-1) = (1.03/0.03)^0.03 = exp(0.03 ln 34.33333) = 1.111915 binds at strong compression
    assert pf.max() == pytest.approx(10.0 * 1.111915, rel=1e-6)


def test_pc_linearised_below_packing_is_continuous_and_finite():
    d = 0.01
    a_lin = 0.62
    below = johnson_jackson_1987_pressure(a_lin - 1e-9, delta=d)
    above = johnson_jackson_1987_pressure(a_lin + 1e-9, delta=d)
    assert float(above) == pytest.approx(float(below), rel=1e-5)
    # tangent: p(0.62) = 0.05 * 0.22^2 / 0.01^5 = 2.42e7 Pa; slope = p (2/0.22 + 5/0.01) = 1.23200e10 Pa
    assert float(johnson_jackson_1987_pressure(0.62, delta=d)) == pytest.approx(2.42e7, rel=1e-9)
    assert float(johnson_jackson_1987_pressure(0.64, delta=d)) == pytest.approx(2.42e7 + 1.2320e10 * 0.02, rel=1e-4)
    assert np.isfinite(johnson_jackson_1987_pressure(0.7, delta=d))


# ---------------------------------------------------------------- modified Berzi, eqs. 18-19
def test_berzi_pressure_vs_eq18_by_hand():
    # f0 = a (alpha - 0.4)/(0.63 - alpha); alpha 0.5: 1.8e-6 * 0.1/0.13 = 1.3846154e-6
    # p_f = f0 k_n/d_s with k_n = 720 Pa m, d_s = 160e-6 m (k_n/d_s = 4.5e6 Pa): 6.230769 Pa
    assert float(berzi_2011_pressure(0.5, 720.0 / 160e-6)) == pytest.approx(6.230769, rel=1e-6)
    assert float(berzi_2011_pressure(0.39, 4.5e6)) == 0.0


def test_berzi_viscosity_is_eq19():
    # p_f 10 Pa, S:S 0.5, Theta 0, div 0: 10 * 0.2808144266 / sqrt(2 * 0.2808144266 * 0.5) = 5.299193 Pa s
    assert float(modified_berzi_viscosity(10.0, PHI, 0.5, 0.0, 1e-4, 0.0)) == pytest.approx(5.299193, rel=1e-6)


def test_viscosity_cap_counts_cells():
    mu, n = cap_viscosity(np.array([1.0, 1e5, np.inf, 3.0]), 1e3)
    assert n == 2 and mu.max() == 1e3


def test_unknown_model_one_line_error():
    with pytest.raises(ValueError, match=r"^friction.model = 'schaeffer': allowed"):
        frictional_stress("schaeffer", 0.5, 1.0, 0.0, 0.0, 1e-4, SolidsParameters())


# ---------------------------------------------------------------- Fig. 7 ordering
KD = SolidsParameters().stiffness_over_diameter  # k_n/d_s = 4.5 MPa


def _curves(a):
    return (johnson_jackson_1987_pressure(a), dartevelle_2004_pressure(a), berzi_2011_pressure(a, KD))


def test_fig7_below_043_johnson_jackson_smallest():
    a = np.linspace(0.401, 0.43, 300)
    jj, da, be = _curves(a)
    assert np.all(jj < da) and np.all(jj < be)
    # measured reason for the sliver 0.40 < alpha < 0.401: near alpha_min the cubic Dartevelle law
    # 1000 x^3/y^3 (x = alpha - 0.4, y = 0.63 - alpha) is below the JJ law 0.05 x^2/y^5 for
    # x < 5e-5/y^2, i.e. x < 9.53e-4, where both are below 1e-4 Pa (invisible in Fig. 7)
    x = brentq(lambda x: dartevelle_2004_pressure(0.4 + x) - johnson_jackson_1987_pressure(0.4 + x), 1e-5, 5e-3)
    assert x == pytest.approx(5e-5 / (0.23 - x) ** 2, rel=1e-6)
    assert x == pytest.approx(9.53e-4, rel=1e-3)
    assert float(johnson_jackson_1987_pressure(0.4 + x)) < 1e-4
    # "Berzi highest initially": near alpha_min the linear Berzi law is above both
    jj, da, be = _curves(np.array([0.405, 0.41]))
    assert np.all(be > da) and np.all(be > jj)


def test_fig7_043_to_047_dartevelle_far_above():
    a = np.linspace(0.43, 0.47, 200)
    jj, da, be = _curves(a)
    assert np.all(da > 2.5 * np.maximum(jj, be))
    # and its growth rate is the largest
    g = [np.gradient(c, a) for c in (jj, da, be)]
    assert np.all(g[1] > np.maximum(g[0], g[2]))


def test_fig7_047_to_050_berzi_smallest_and_slowest_growing():
    a = np.linspace(0.47, 0.50, 200)
    jj, da, be = _curves(a)
    g = [np.gradient(c, a) for c in (jj, da, be)]
    assert np.all(g[2] < np.minimum(g[0], g[1]))  # slowest growing over the whole band
    assert np.all(da > np.maximum(jj, be))
    # smallest from the Berzi/JJ crossing on, where a K x/y = Fr x^2/y^5, i.e. x = a K y^4 / Fr
    # (K = k_n/d_s): at 4.5 MPa, x = 162 y^4 -> alpha = 0.4806;
    # it moves to 0.470 at 3.0 MPa and 0.490 at 6.5 MPa (the window in which Fig. 7's ordering holds)
    def crossing(kd):
        return brentq(lambda x: berzi_2011_pressure(x, kd) - johnson_jackson_1987_pressure(x), 0.44, 0.55)

    assert crossing(KD) == pytest.approx(0.4806, abs=5e-4)
    assert crossing(3.0e6) == pytest.approx(0.470, abs=2e-3)
    assert crossing(6.5e6) == pytest.approx(0.490, abs=2e-3)
    late = a >= crossing(KD)
    assert np.all(be[late] <= np.minimum(jj[late], da[late]) + 1e-12)
