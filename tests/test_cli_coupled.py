"""`eulag run` on gas-particle cases: SIGKILL + --resume equality, and bad case files."""

import os
import random
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from .test_cli import run_cli

CASE = """
name = "killme"
[pipe]
diameter = 0.0305
length = 0.5
mode = "periodic"
[gas]
density = 1.205
viscosity = 1.81e-5
bulk_velocity = 10.0
inlet_k = 1.0
[particles]
diameter = 100e-6
density = 1020.0
mass_loading = 0.2
[walls]
roughness_angle_std_deg = 3.0
[numerics]
radial_cells = 8
azimuthal_cells = 16
parcels = 3000
parcels_start = 2000
max_passes = 8
average_passes = 2
batch_size = 250
seed = 5
"""


def eulag(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "eulag", *map(str, args)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, **kw)


def same_data(a_path, b_path):
    xr = pytest.importorskip("xarray")
    with xr.open_dataset(a_path) as a, xr.open_dataset(b_path) as b:
        assert set(a.data_vars) == set(b.data_vars)
        for name in a.data_vars:
            if name.startswith("time_"):
                continue  # wall-clock times differ
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def test_sigkill_at_a_random_pass_then_resume_equals_uninterrupted(tmp_path):
    case = tmp_path / "killme.toml"
    case.write_text(CASE)
    ref = eulag("run", case, "-o", tmp_path / "ref.nc", "--quiet")
    ref.wait(timeout=600)
    assert (tmp_path / "ref.nc").exists()
    out = tmp_path / "out.nc"
    ckpt = tmp_path / "out.nc.checkpoint"
    proc = eulag("run", case, "-o", out, "--quiet")
    rng = random.Random()
    deadline = time.time() + 300
    while not ckpt.exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(rng.uniform(0.0, 0.3))  # somewhere in a later pass (or while writing a checkpoint)
    assert proc.poll() is None, "the run ended before it could be killed; the test would prove nothing"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL
    res = eulag("run", case, "-o", out, "--resume", "--quiet")
    res.wait(timeout=600)
    same_data(tmp_path / "ref.nc", out)
    # a finished run resumes without recomputing
    again = eulag("run", case, "-o", out, "--resume", "--quiet")
    again.wait(timeout=600)
    assert again.returncode in (0, 1)
    same_data(tmp_path / "ref.nc", out)


BAD = {
    "negative particle diameter": ("diameter = 100e-6", "diameter = -1e-4"),
    "particle diameter in mm": ("diameter = 100e-6", "diameter = 100"),
    "particle lighter than the gas": ("density = 1020.0", "density = 1.0"),
    "loading as a string": ("mass_loading = 0.2", 'mass_loading = "0.2"'),
    "negative loading": ("mass_loading = 0.2", "mass_loading = -2.2"),
    "zero loading (no particle mass flow; a single-phase case leaves out [particles])":
        ("mass_loading = 0.2", "mass_loading = 0.0"),
    "unknown particle key": ("mass_loading = 0.2", "mass_loading = 0.2\nshape = \"sphere\""),
    "roughness beyond 45 deg": ("roughness_angle_std_deg = 3.0", "roughness_angle_std_deg = 60.0"),
    "relaxation zero": ("seed = 5", "seed = 5\nrelaxation = 0.0"),
    "parcels_start above parcels": ("parcels_start = 2000", "parcels_start = 20000"),
    "odd azimuthal cells": ("azimuthal_cells = 16", "azimuthal_cells = 15"),
    "unknown coupling": ("[walls]", "[physics]\ncoupling = \"five-way\"\n[walls]"),
    "collisions without four-way": ("[walls]", "[physics]\ncoupling = \"two-way\"\ninter_particle_collisions = true\n[walls]"),
    "magnus without rotation": ("[walls]", "[physics]\nrotation = false\nmagnus_lift = true\n[walls]"),
    "unknown step rule": ("seed = 5", "seed = 5\nstep_rule = \"tiny\""),
}


@pytest.mark.parametrize("label", sorted(BAD))
def test_bad_particle_case_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, label):
    old, new = BAD[label]
    assert old in CASE
    case = tmp_path / "bad.toml"
    case.write_text(CASE.replace(old, new, 1))
    status, out, err = run_cli(capsys, "run", case, "-o", tmp_path / "out.nc")
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]
