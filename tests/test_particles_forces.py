"""Force and torque correlations (particles.forces) against the published formulas, docs/physics.md

Every expected value is written out here from the paper's formula (seed eqs. 5–11, docs/physics.md);
nothing below calls one forces.py function to check another, except where a test says so.
"""

import math

import numpy as np
import pytest

from particles import forces as pf

RHO_F, MU = 1.18, 1.8e-5  # air [kg m-3], [Pa s]
RHO_P = 2500.0  # glass [kg m-3]
D = 100e-6  # [m]
SAFFMAN_EXACT = 2.0 * 6.46 / math.pi  # Saffman's 6.46 in Mei's coefficient form (4.11256...)
RE_GRID = [0.1, 1.0, 10.0, 100.0, 999.0, 1001.0, 5000.0]


def sn_cd(re):  # Schiller & Naumann (1933), seed eq. 5
    return 24.0 / re * (1.0 + 0.15 * re**0.687) if re <= 1000.0 else 0.44


def mei_f(re_p, re_s):  # Mei (1992), seed eq. 7, β = 0.5 Re_S/Re_p
    beta = 0.5 * re_s / re_p
    if re_p <= 40.0:
        return (1.0 - 0.3314 * beta**0.5) * math.exp(-re_p / 10.0) + 0.3314 * beta**0.5
    return 0.0524 * (beta * re_p) ** 0.5


def lun_liu(re_p, re_r):  # Lun & Liu (1997), seed eq. 9
    return re_r / re_p if re_p <= 1.0 else re_r / re_p * (0.178 + 0.822 * re_p**-0.522)


# ---------------------------------------------------------------- drag
@pytest.mark.parametrize("re", RE_GRID)
def test_drag_coefficient_vs_schiller_naumann_1933(re):
    assert pf.schiller_naumann_drag_coefficient(re) == pytest.approx(sn_cd(re), rel=1e-12)


def test_drag_coefficient_published_numbers():
    assert pf.schiller_naumann_drag_coefficient(1.0) == pytest.approx(27.6, rel=1e-12)  # 24·1.15
    assert pf.schiller_naumann_drag_coefficient(5000.0) == 0.44


def test_drag_branches_match_within_0p4_percent_at_1000():
    low, high = pf.schiller_naumann_drag_coefficient(1000.0), pf.schiller_naumann_drag_coefficient(1000.0 + 1e-9)
    assert low == pytest.approx(0.4383, abs=5e-5)  # docs/physics.md, 4 digits
    assert high == 0.44
    assert abs(high - low) / high < 0.004


@pytest.mark.parametrize("re", RE_GRID)
def test_drag_factor_is_cd_re_over_24(re):
    assert pf.schiller_naumann_drag_factor(re) == pytest.approx(sn_cd(re) * re / 24.0, rel=1e-12)


def test_drag_factor_tends_to_stokes_as_re_to_zero():
    assert pf.schiller_naumann_drag_factor(0.0) == 1.0
    for re in (1e-3, 1e-6, 1e-9):
        assert pf.schiller_naumann_drag_factor(re) == pytest.approx(1.0, abs=0.15 * re**0.687 * 1.000001)
        assert pf.schiller_naumann_drag_factor(re) > 1.0


@pytest.mark.parametrize("slip", [1e-4, 0.05, 1.0, 30.0])
def test_response_time_vs_drag_force_of_seed_eq3(slip):
    """m_p |u_rel|/τ_p equals (3/4)(ρ_F m_p/(ρ_p D)) C_D |u_rel|² and τ_p = ρ_p D²/(18 μ f_D)."""
    re = RHO_F * D * slip / MU
    m_p = RHO_P * math.pi * D**3 / 6.0
    tau = pf.response_time(RHO_P, D, MU, sn_cd(re) * re / 24.0)
    assert m_p * slip / tau == pytest.approx(0.75 * RHO_F * m_p / (RHO_P * D) * sn_cd(re) * slip**2, rel=1e-12)
    assert pf.response_time(RHO_P, D, MU, 1.0) == pytest.approx(RHO_P * D**2 / (18.0 * MU), rel=1e-14)


# ---------------------------------------------------------------- slip-shear lift
# (Re_p, Re_S): β = 0.005 … 0.4 (Mei's range), both branches, the switch Re_p = 40 on the first one
MEI_CASES = [(0.1, 0.001), (0.5, 0.1), (1.0, 0.8), (10.0, 4.0), (40.0, 8.0), (40.0001, 8.0), (60.0, 12.0),
             (100.0, 80.0)]


@pytest.mark.parametrize("re_p,re_s", MEI_CASES)
def test_mei_correction_vs_mei_1992(re_p, re_s):
    assert pf.mei_1992_correction(re_p, re_s) == pytest.approx(mei_f(re_p, re_s), rel=1e-12)


def test_mei_correction_hand_values():
    # β = 0.1, Re_p = 40: (1 − 0.3314√0.1) e^−4 + 0.3314√0.1 = 0.12119…; above 40: 0.0524·√4 = 0.1048
    assert pf.mei_1992_correction(40.0, 8.0) == pytest.approx(0.12119, abs=1e-5)
    assert pf.mei_1992_correction(40.0 + 1e-12, 8.0) == pytest.approx(0.1048, rel=1e-9)


@pytest.mark.parametrize("beta", [0.005, 0.1, 0.4])
def test_mei_correction_tends_to_saffman_as_rep_to_zero(beta):
    """At fixed β, f = 1 − (1 − 0.3314√β)(1 − e^(−Re_p/10)) → 1 (Saffman's result)."""
    for re_p in (1e-3, 1e-6, 1e-9):
        f = pf.mei_1992_correction(re_p, 2.0 * beta * re_p)
        assert f == pytest.approx(1.0, abs=0.1 * re_p)
        assert f < 1.0


@pytest.mark.parametrize("re_p,re_s", MEI_CASES)
def test_saffman_mei_coefficient_vs_mei_form(re_p, re_s):
    c = pf.saffman_mei_lift_coefficient(re_p, re_s)
    assert c == pytest.approx(4.1126 / math.sqrt(re_s) * mei_f(re_p, re_s), rel=1e-12)
    assert c == pytest.approx(SAFFMAN_EXACT / math.sqrt(re_s) * mei_f(re_p, re_s), rel=2e-5)  # 4.1126 rounded


@pytest.mark.parametrize("slip,shear", [(1e-7, 1e-4), (0.01, 50.0), (0.3, 2000.0)])
def test_saffman_force_vs_saffman_1965_closed_form(slip, shear):
    """(ρ/2)(π/4)D³ C_LS |u_rel||ω| = 1.615 μ D |u_rel| Re_S^0.5 f (seed eq. 6; f → 1 in the first case)."""
    re_p, re_s = RHO_F * D * slip / MU, RHO_F * D**2 * shear / MU
    force = 0.5 * RHO_F * math.pi / 4.0 * D**3 * pf.saffman_mei_lift_coefficient(re_p, re_s) * slip * shear
    saffman = 1.615 * MU * D * slip * math.sqrt(re_s)
    assert force == pytest.approx(saffman * mei_f(re_p, re_s), rel=2e-5)  # 4.1126 vs 2·6.46/π: 8.8e-6
    if re_p < 1e-6:
        assert force == pytest.approx(saffman, rel=2e-5)


def test_lift_directions_in_simple_shear_vs_hand_cross_products():
    """U = G y e_x, lagging particle (u_rel = +Δu e_x): ω_F = −G e_z, Saffman lift toward the faster fluid (+y);
    a non-spinning particle (ω_p = 0, Ω = ½ω_F) gets a Magnus lift toward the slower fluid (−y).
    The directions follow from the cross products written here and positive coefficients; the
    kernel's lifted step is checked against an ODE solution in test_particles_motion.py."""
    g, du, h = 200.0, 0.1, 1e-3
    velocity = lambda x: np.array([g * x[1], 0.0, 0.0])  # noqa: E731
    grad = np.array([[(velocity(h * e)[i] - velocity(-h * e)[i]) / (2 * h) for e in np.eye(3)] for i in range(3)])
    omega_f = np.array([grad[2, 1] - grad[1, 2], grad[0, 2] - grad[2, 0], grad[1, 0] - grad[0, 1]])
    assert omega_f == pytest.approx([0.0, 0.0, -g], abs=1e-9)
    u_rel = np.array([du, 0.0, 0.0])
    assert np.cross(u_rel, omega_f) == pytest.approx([0.0, du * g, 0.0])  # y: u_z ω_x − u_x ω_z = +Δu G
    re_p, re_s = RHO_F * D * du / MU, RHO_F * D**2 * g / MU
    f_ls = 0.5 * RHO_F * math.pi / 4 * D**3 * pf.saffman_mei_lift_coefficient(re_p, re_s) * np.cross(u_rel, omega_f)
    assert f_ls[1] > 0.0 and f_ls[0] == 0.0 and f_ls[2] == 0.0
    big_omega = 0.5 * omega_f - np.zeros(3)  # Ω = ½∇×U − ω_p
    assert np.cross(big_omega, u_rel) == pytest.approx([0.0, -0.5 * g * du, 0.0])
    re_r = RHO_F * D**2 * np.linalg.norm(big_omega) / MU
    c_lr = pf.lun_liu_1997_lift_coefficient(re_p, re_r)
    f_lr = 0.5 * RHO_F * math.pi / 4 * D**2 * c_lr * du * np.cross(big_omega, u_rel) / np.linalg.norm(big_omega)
    assert f_lr[1] < 0.0


# ---------------------------------------------------------------- slip-rotation lift
@pytest.mark.parametrize("re_p", [1e-3, 0.5, 1.0, 1.5, 10.0, 100.0, 999.0])
@pytest.mark.parametrize("re_r", [1e-3, 0.7, 20.0])
def test_rotational_lift_coefficient_vs_lun_liu_1997(re_p, re_r):
    assert pf.lun_liu_1997_lift_coefficient(re_p, re_r) == pytest.approx(lun_liu(re_p, re_r), rel=1e-12)


def test_lun_liu_continuous_at_rep_1():
    assert 0.178 + 0.822 == 1.0
    below, above = pf.lun_liu_1997_lift_coefficient(1.0, 0.3), pf.lun_liu_1997_lift_coefficient(1.0 + 1e-12, 0.3)
    assert above == pytest.approx(below, rel=1e-10)
    assert pf.lun_liu_1997_lift_coefficient(1.0, 0.3) == pytest.approx(0.3, rel=1e-15)


@pytest.mark.parametrize("slip,spin", [(1e-3, 10.0), (0.1, 500.0), (2.0, 3000.0)])
def test_rotational_lift_force_vs_seed_eq8_and_rubinow_keller_1961(slip, spin):
    """(ρ/2)(π/4)D² C_LR|u_rel| Ω×u_rel/|Ω| = (π/8)ρD³(Re_p/Re_r) C_LR Ω×u_rel (seed eq. 8);
    for Re_p ≤ 1 this is Rubinow & Keller's (π/8)ρD³ Ω×u_rel."""
    u_rel, big_omega = np.array([slip, 0.2 * slip, 0.0]), np.array([0.0, spin, -0.5 * spin])
    re_p = RHO_F * D * np.linalg.norm(u_rel) / MU
    re_r = RHO_F * D**2 * np.linalg.norm(big_omega) / MU
    c_lr = pf.lun_liu_1997_lift_coefficient(re_p, re_r)
    cross = np.cross(big_omega, u_rel)
    force = 0.5 * RHO_F * math.pi / 4 * D**2 * c_lr * np.linalg.norm(u_rel) * cross / np.linalg.norm(big_omega)
    # the seed's eq. 8 rearranged (algebra: Re_p/Re_r = |u_rel|/(D|Ω|)); the code is tested below,
    # where Lun & Liu's C_LR = Re_r/Re_p must give Rubinow & Keller's force
    assert force == pytest.approx(math.pi / 8 * RHO_F * D**3 * re_p / re_r * c_lr * cross, rel=1e-12)
    if re_p <= 1.0:
        assert force == pytest.approx(math.pi / 8 * RHO_F * D**3 * cross, rel=1e-12)


@pytest.mark.parametrize("re_p,re_r", [(0.1, 0.05), (1.0, 2.0), (10.0, 5.0), (100.0, 400.0), (139.0, 10.0)])
def test_rotational_lift_vs_oesterle_bui_dinh_1998(re_p, re_r):
    c = pf.oesterle_bui_dinh_1998_lift_coefficient(re_p, re_r)
    assert c == pytest.approx(0.45 + (re_r / re_p - 0.45) * math.exp(-0.05684 * re_r**0.4 * re_p**0.3), rel=1e-12)
    assert 0.05684 * 4**0.4 == pytest.approx(0.09896, abs=5e-6)  # radius-based form, docs/physics.md
    re_rad = re_r / 4.0
    rad = 0.45 + (4 * re_rad / re_p - 0.45) * math.exp(-0.05684 * 4**0.4 * re_rad**0.4 * re_p**0.3)
    assert c == pytest.approx(rad, rel=1e-12)


@pytest.mark.parametrize("ratio", [0.2, 2.0, 20.0])
def test_oesterle_bui_dinh_tends_to_rubinow_keller_as_rep_to_zero(ratio):
    for re_p in (1e-4, 1e-8, 1e-12):  # relative error (1 − 0.45/ratio)·0.05684 ratio^0.4 Re_p^0.7 to first order
        c = pf.oesterle_bui_dinh_1998_lift_coefficient(re_p, ratio * re_p)
        assert c == pytest.approx(ratio, rel=1.3 * 0.05684 * ratio**0.4 * re_p**0.7 + 1e-15)
    assert pf.oesterle_bui_dinh_1998_lift_coefficient(1e4, 1e6) == pytest.approx(0.45, rel=1e-6)


# ---------------------------------------------------------------- torque
@pytest.mark.parametrize("re_r", [1e-3, 0.5, 10.0, 32.0])
def test_torque_stokes_limit_vs_rubinow_keller_1961(re_r):
    """(ρ/2)(D/2)^5 C_R |Ω| Ω = 8π μ r³ Ω = π μ D³ Ω for Re_r ≤ 32 (seed eqs. 10–11)."""
    spin = re_r * MU / (RHO_F * D**2)
    torque = 0.5 * RHO_F * (D / 2) ** 5 * pf.dennis_1980_torque_coefficient(re_r) * spin * spin
    assert torque == pytest.approx(8.0 * math.pi * MU * (D / 2) ** 3 * spin, rel=1e-12)
    assert torque == pytest.approx(math.pi * MU * D**3 * spin, rel=1e-12)


def test_torque_coefficient_continuous_at_32():
    low, high = pf.dennis_1980_torque_coefficient(32.0), pf.dennis_1980_torque_coefficient(32.0 + 1e-9)
    assert low == pytest.approx(6.283, abs=5e-4) and high == pytest.approx(6.293, abs=5e-4)  # docs/physics.md
    assert abs(high - low) / low < 0.002


@pytest.mark.parametrize("re_r", [32.5, 100.0, 500.0, 999.0])
def test_torque_coefficient_vs_dennis_1980(re_r):
    c = pf.dennis_1980_torque_coefficient(re_r)
    assert c == pytest.approx(12.9 / re_r**0.5 + 128.4 / re_r, rel=1e-12)
    re_rad = re_r / 4.0  # Sommerfeld's 6.45/√Re_R + 32.1/Re_R with the radius-based Re_R: identical
    assert c == pytest.approx(6.45 / re_rad**0.5 + 32.1 / re_rad, rel=1e-12)


@pytest.mark.parametrize("re_r", [1e-6, 1.0, 32.0, 32.5, 100.0, 999.0])
def test_torque_factor_is_cr_re_over_64pi(re_r):
    expected = 1.0 if re_r <= 32.0 else (12.9 / re_r**0.5 + 128.4 / re_r) * re_r / (64 * math.pi)
    assert pf.torque_factor(re_r) == pytest.approx(expected, rel=1e-12)
    c_r = pf.dennis_1980_torque_coefficient(re_r)  # the two functions agree
    assert pf.torque_factor(re_r) == pytest.approx(c_r * re_r / (64 * math.pi), rel=1e-12)
    assert pf.torque_factor(0.0) == 1.0


@pytest.mark.parametrize("f_r", [1.0, 1.37])
def test_rotational_response_time_vs_moment_of_inertia(f_r):
    m_p = RHO_P * math.pi * D**3 / 6.0
    i_p = m_p * D**2 / 10.0  # seed, below eq. 4
    tau_r = pf.rotational_response_time(RHO_P, D, MU, f_r)
    assert tau_r == pytest.approx(i_p / (math.pi * MU * D**3 * f_r), rel=1e-12)


# ---------------------------------------------------------------- compiled vs Python
ARGS = {
    "schiller_naumann_drag_coefficient": [(r,) for r in RE_GRID],
    "schiller_naumann_drag_factor": [(r,) for r in [0.0] + RE_GRID],
    "response_time": [(RHO_P, D, MU, 1.3)],
    "mei_1992_correction": MEI_CASES,
    "saffman_mei_lift_coefficient": MEI_CASES,
    "lun_liu_1997_lift_coefficient": [(0.5, 0.2), (1.0, 0.2), (30.0, 7.0)],
    "schiller_naumann_drag_factor_ln": [(r, math.log(r)) for r in RE_GRID] + [(0.0, -math.inf)],
    "lun_liu_1997_lift_coefficient_ln": [(r, 0.2, math.log(r)) for r in (0.5, 1.0, 30.0)],
    "oesterle_bui_dinh_1998_lift_coefficient": [(0.1, 0.05), (10.0, 5.0)],
    "dennis_1980_torque_coefficient": [(1.0,), (32.0,), (100.0,)],
    "torque_factor": [(0.0,), (32.0,), (100.0,)],
    "rotational_response_time": [(RHO_P, D, MU, 1.3)],
}


@pytest.mark.parametrize("name", pf.__all__)
def test_compiled_matches_py_func(name):
    fn = getattr(pf, name)
    for args in ARGS[name]:
        assert fn(*args) == pytest.approx(fn.py_func(*args), rel=1e-14), (name, args)


def test_ln_forms_equal_the_plain_correlations_bitwise():
    """The step's ``*_ln`` forms (one shared ln Re_p) are the same numbers as the plain functions."""
    for r in [0.0] + RE_GRID:
        assert pf.schiller_naumann_drag_factor_ln(r, pf._log0(r)) == pf.schiller_naumann_drag_factor(r)
    for r in RE_GRID:
        assert pf.lun_liu_1997_lift_coefficient_ln(r, 3.0, pf._log0(r)) == pf.lun_liu_1997_lift_coefficient(r, 3.0)
        # Re^0.687 through exp(0.687 ln Re) is the power to round-off
        assert pf.schiller_naumann_drag_factor(r) == pytest.approx(1.0 + 0.15 * r**0.687 if r <= 1000 else 0.44 * r / 24,
                                                                   rel=1e-14)
