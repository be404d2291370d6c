"""eulag.check: the case report's saltation velocities against the fluids correlations called
here with the documented inputs, the saltation warning, the wall-cell y+ against a hand
computation, the total pressure drop of a dataset and the single-phase report."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from fluids import saltation
from fluids.drag import v_terminal
from fluids.friction import Colebrook

from eulag.check import (SALTATION_MARGIN, check_report, runtime_estimate, saltation_line,
                         saltation_velocities, total_pressure_drop_line)
from eulag.config import Case

CASES = Path(__file__).resolve().parent.parent / "cases"


@pytest.fixture(scope="module")
def base():
    return Case.from_toml(CASES / "tsuji_morikawa_200um.toml")


def test_saltation_velocities_of_the_base_case(base):
    # the documented inputs: m_p = eta rho U0 pi D^2 / 4, v_t of fluids.drag.v_terminal
    d, rho, mu, u0 = 0.0305, 1.205, 1.81e-5, 10.0
    dp, rhop, eta = 200e-6, 1020.0, 2.2
    mp = eta * rho * u0 * math.pi * d ** 2 / 4
    vt = v_terminal(dp, rhop, rho, mu)
    expected = {
        "Rizk": saltation.Rizk(mp, dp, rho, d),
        "Matsumoto 1977": saltation.Matsumoto_1977(mp, rhop, dp, rho, d, vt),
        "Weber": saltation.Weber_saltation(mp, rhop, dp, rho, d, vt),
        "Geldart-Ling": saltation.Geldart_Ling(mp, rho, d, mu),
    }
    got = saltation_velocities(base)
    assert got.keys() == expected.keys()
    for name, v in expected.items():
        assert got[name] == pytest.approx(v, rel=1e-12), name
    # the values quoted for the base case: Rizk 5.9, Matsumoto 1977 5.4, Weber 4.4, Geldart-Ling 3.6
    for name, v in {"Rizk": 5.9, "Matsumoto 1977": 5.4, "Weber": 4.4, "Geldart-Ling": 3.6}.items():
        assert got[name] == pytest.approx(v, abs=0.05), name
    line = saltation_line(base)
    assert "Rizk 5.94" in line and "Matsumoto 1977 5.42" in line and "Weber 4.38" in line
    assert "Geldart-Ling 3.62" in line and "WARNING" not in line and "\n" not in line
    report = check_report(base)
    assert line in report.splitlines() and "WARNING" not in report


def test_slow_case_gets_a_saltation_warning(base):
    slow = base.replace(gas={"bulk_velocity": 5.0})
    top = max(saltation_velocities(slow).values())
    assert 5.0 < SALTATION_MARGIN * top
    line = saltation_line(slow)
    assert line.count("\n") == 1 and line.splitlines()[1].startswith("  WARNING: U0 = 5 m/s")
    assert any(s.startswith("  WARNING: U0 = 5 m/s") for s in check_report(slow).splitlines())


def test_wall_cell_yplus_against_a_hand_computation(base):
    case = base.replace(gas={"bulk_velocity": 15.0}, numerics={"first_cell_yplus": 50.0})
    report = check_report(case)
    line = next(s for s in report.splitlines() if s.startswith("  wall cell"))
    nums = [float(v) for v in re.findall(r"(\d+\.?\d*(?:e[-+]?\d+)?) \[(?:mm|1)\]", line)]
    thickness_mm, centroid_mm, yplus_c, yplus_b = nums[:4]

    rho, mu, d, u0 = 1.205, 1.81e-5, 0.0305, 15.0
    nu, re_b, radius = mu / rho, rho * u0 * d / mu, d / 2
    u_tau_c = u0 * math.sqrt(Colebrook(re_b, 0.0) / 8)  # the mesh's design friction velocity
    u_tau_b = u0 * math.sqrt(0.3164 * re_b ** -0.25 / 8)  # Blasius
    y_c = 50.0 * nu / u_tau_c  # the wall ring's centroid at the target y+
    # ring [R - t, R]: its centroid (2/3)(R^3 - r0^3)/(R^2 - r0^2) lies y_c from the wall; solve for t
    lo, hi = y_c, 4 * y_c
    for _ in range(100):
        t = 0.5 * (lo + hi)
        r0 = radius - t
        dist = radius - (2 / 3) * (radius ** 3 - r0 ** 3) / (radius ** 2 - r0 ** 2)
        lo, hi = (t, hi) if dist < y_c else (lo, t)
    assert thickness_mm == pytest.approx(t * 1e3, rel=1e-3)
    assert centroid_mm == pytest.approx(y_c * 1e3, rel=1e-3)
    assert yplus_c == pytest.approx(50.0, abs=0.05)
    assert yplus_b == pytest.approx(y_c * u_tau_b / nu, abs=0.05)


def test_ring_growth_against_a_hand_computation(base):
    # a 0.3 m pipe at Re = 1e6 on 6 rings: the 5 inner rings grow geometrically from the wall cell
    case = base.replace(pipe={"diameter": 0.3, "length": 40.0, "sections": [35.0]}, gas={"bulk_velocity": 50.0},
                        numerics={"radial_cells": 6, "axial_cells": 10})
    report = check_report(case)
    wall = next(s for s in report.splitlines() if s.startswith("  wall cell"))
    t = float(re.search(r"ring thickness (\S+) \[mm\]", wall).group(1)) * 1e-3
    ratio = float(re.search(r"outward (\S+) \[1\]", next(s for s in report.splitlines() if s.startswith("  rings"))).group(1))
    lo, hi = 1.0 + 1e-9, 100.0  # t (1 + q + ... + q^4) = R - t: the rest of the radius
    for _ in range(200):
        q = 0.5 * (lo + hi)
        lo, hi = (q, hi) if t * (q ** 5 - 1) / (q - 1) < 0.15 - t else (lo, q)
    assert ratio == pytest.approx(q, rel=2e-3)
    assert 3.5 < ratio < 4.0  # near the limit of rans.mesh.MAX_RING_GROWTH


def test_report_lists_every_key_with_units_and_the_particle_numbers(base):
    report = check_report(base)
    for key in base.to_attrs():
        if not key.startswith("case."):
            assert f"\n  {key} = " in report, key
    assert "  pipe.diameter = 0.0305 [m]\n" in report
    assert "  numerics.max_passes = 40 [1]  (default)\n" in report
    tau_st = 1020.0 * (200e-6) ** 2 / (18 * 1.81e-5)
    assert f"{tau_st:.4g} [s] (Stokes)" in report
    assert f"St = tau_p U0 / D = {tau_st / (0.0305 / 10.0):.3g} [1]" in report
    assert "cells        200 x 10 x 20 = 40000 [1]" in report
    assert "30000 [1] per early pass, 30000 [1] per final pass" in report


def test_single_phase_report_has_the_gas_numbers_only():
    case = Case.from_toml(CASES / "single_phase_pipe.toml")
    assert saltation_line(case) == ""
    report = check_report(case)
    assert "Reynolds     Re = rho U0 D / mu = 2.031e+04 [1]" in report
    assert "wall cell" in report and "cells        400 x 20 x 40 = 320000 [1]" in report
    for absent in ("Particles", "saltation", "tau_p", "physics.", "walls.", "numerics.parcels"):
        assert absent not in report, absent


def test_runtime_estimate_of_the_base_case_is_near_the_measured_run():
    case = Case.from_toml(CASES / "tsuji_morikawa_200um.toml")
    typical, worst, basis = runtime_estimate(case)
    # results/speed/bench_base.log: this case converged in 36 passes, 206 s on the idle 2-core
    # machine; the paper's grid (200 x 20 x 40, 240,000 final parcels, bench_paper.log) in 401 s
    assert 206 / 1.5 < typical < 206 * 1.5
    paper = case.replace(numerics={"radial_cells": 20, "azimuthal_cells": 40, "parcels": 240000})
    assert 401 / 1.5 < runtime_estimate(paper)[0] < 401 * 1.5
    assert worst > typical and "passes" in basis
    more = case.replace(numerics={"parcels": 240000})
    assert runtime_estimate(more)[0] > typical
    # a periodic pipe's parcels take about the developing pipe's steps (1,375 against 1,382 with
    # 3,000 parcels): its single axial cell does not shorten the estimate to a tenth
    periodic = case.replace(pipe={"mode": "periodic"})
    assert "~1380 steps per parcel" in runtime_estimate(periodic)[2] and runtime_estimate(periodic)[0] > 0.5 * typical


def test_total_pressure_drop_line():
    x_edge = np.array([0.0, 1.0, 3.0, 4.0])
    ds = xr.Dataset({"pressure_gradient": ("x", [80.0, 60.0, 50.0]),
                     "pressure_gradient_single_phase": ("x", [40.0, 30.0, 25.0])},
                    coords={"x": ("x", [0.5, 2.0, 3.5]), "x_edge": ("x_edge", x_edge)})
    line = total_pressure_drop_line(ds)
    assert line == "  pressure     Delta p = 250 Pa over L = 4 m (single-phase 125 Pa; ratio 2.000)"
    assert total_pressure_drop_line(ds.drop_vars("pressure_gradient")) == ""
