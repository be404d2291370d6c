"""Case files -> validated Case objects: wrong files are refused with one line naming the key."""

import dataclasses
import textwrap
from pathlib import Path

import pytest

from eulag.config import (Case, CaseError, GasConfig, NumericsConfig, PhysicsConfig, PipeConfig,
                          WallConfig)

CASES = Path(__file__).resolve().parent.parent / "cases"

GOOD = """\
name = "t"

[pipe]
diameter = 0.0305
length = 4.0
sections = [3.56]

[gas]
density = 1.205
viscosity = 1.81e-5
bulk_velocity = 10.0
inlet_k = 1.0
"""

PARTICLES = """
[particles]
diameter = 200e-6
density = 1020.0
mass_loading = 2.2
"""


def write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def with_line(section, line, base=GOOD + PARTICLES):
    """The base case with ``line`` inserted as the first line of ``[section]``."""
    if section is None:
        return line + "\n" + base
    if f"[{section}]" not in base:
        return base + f"\n[{section}]\n{line}\n"
    return base.replace(f"[{section}]\n", f"[{section}]\n{line}\n", 1)


def without(key_line, base=GOOD):
    lines = [ln for ln in base.splitlines() if not ln.startswith(key_line)]
    return "\n".join(lines) + "\n"


# (case text, dotted key the message must name, a fragment of the value as shown)
WRONG = {
    "negative diameter": (GOOD.replace("diameter = 0.0305", "diameter = -0.0305"),
                          "pipe.diameter", "-0.0305"),
    "diameter in mm": (GOOD.replace("diameter = 0.0305", "diameter = 30.5"), "pipe.diameter", "30.5"),
    "zero velocity": (GOOD.replace("bulk_velocity = 10.0", "bulk_velocity = 0"),
                      "gas.bulk_velocity", "= 0"),
    "unknown key": (with_line("pipe", "diamter = 0.03"), "pipe.diamter", "0.03"),
    "unknown top-level key": (with_line(None, "colour = 'red'"), "colour", "red"),
    "unknown section": (GOOD + "\n[solver]\ncfl = 0.5\n", "solver", "cfl"),
    "missing required key": (without("viscosity"), "gas.viscosity", ""),
    "missing section": (GOOD.split("[gas]")[0], "gas", ""),
    "string for a number": (GOOD.replace("length = 4.0", 'length = "4 m"'), "pipe.length", "4 m"),
    "bool is not an int": (with_line("numerics", "radial_cells = true"), "numerics.radial_cells",
                           "true"),
    "float for an int": (with_line("numerics", "parcels = 1e5"), "numerics.parcels", "100000.0"),
    "odd azimuthal cells": (with_line("numerics", "azimuthal_cells = 41"),
                            "numerics.azimuthal_cells", "41"),
    "too few radial cells": (with_line("numerics", "radial_cells = 3"), "numerics.radial_cells", "3"),
    "y+ in the viscous sublayer": (with_line("numerics", "first_cell_yplus = 5"),
                                   "numerics.first_cell_yplus", "5"),
    "relaxation above 1": (with_line("numerics", "relaxation = 1.5"), "numerics.relaxation", "1.5"),
    "relaxation zero": (with_line("numerics", "relaxation = 0"), "numerics.relaxation", "0"),
    "parcels_start above parcels": (with_line("numerics", "parcels = 1000\nparcels_start = 2000"),
                                    "numerics.parcels_start", "2000"),
    "no parcels": (with_line("numerics", "parcels = 0"), "numerics.parcels", "0"),
    "section beyond the outlet": (GOOD.replace("sections = [3.56]", "sections = [5.0]"),
                                  "pipe.sections", "5.0"),
    "negative section": (GOOD.replace("sections = [3.56]", "sections = [-1.0]"),
                         "pipe.sections", "-1.0"),
    "unknown mode": (with_line("pipe", 'mode = "periodical"'), "pipe.mode", "periodical"),
    "unknown coupling": (with_line("physics", 'coupling = "3-way"'), "physics.coupling", "3-way"),
    "unknown partner correlation": (with_line("physics", 'partner_correlation = "pair"'),
                                    "physics.partner_correlation", "pair"),
    "collisions without four-way": (with_line("physics", 'coupling = "two-way"\n'
                                                         "inter_particle_collisions = true"),
                                    "physics.inter_particle_collisions", "true"),
    "magnus lift without rotation": (with_line("physics", "rotation = false\nmagnus_lift = true"),
                                     "physics.magnus_lift", "true"),
    "negative mass loading": (PARTICLES.replace("2.2", "-1.0"), "particles.mass_loading", "-1.0"),
    "particle as large as the pipe": (PARTICLES.replace("200e-6", "200.0"),
                                      "particles.diameter", "200.0"),
    "particle lighter than the gas": (PARTICLES.replace("1020.0", "1.02"), "particles.density", "1.02"),
    "roughness angle above 45": (with_line("walls", "roughness_angle_std_deg = 60"),
                                 "walls.roughness_angle_std_deg", "60"),
    "unknown impact angle": (with_line("walls", 'impact_angle = "grazing"'), "walls.impact_angle",
                             "grazing"),
    "negative viscosity": (GOOD.replace("viscosity = 1.81e-5", "viscosity = -1.81e-5"),
                           "gas.viscosity", "-1.81e-05"),
    "nan density": (GOOD.replace("density = 1.205", "density = nan"), "gas.density", "nan"),
    "inlet k above U0^2": (GOOD.replace("inlet_k = 1.0", "inlet_k = 500.0"), "gas.inlet_k", "500.0"),
    "negative inlet epsilon": (with_line("gas", "inlet_epsilon = -3.0"), "gas.inlet_epsilon", "-3.0"),
    "section is not a table": (with_line(None, "walls = 3", GOOD), "walls", "3"),
    "average over more passes than run": (with_line("numerics", "max_passes = 2\naverage_passes = 3"),
                                          "numerics.average_passes", "3"),
    "unknown drag law": (with_line("physics", 'drag = "stokes"'), "physics.drag", "stokes"),
    "bad name": (GOOD.replace('name = "t"', 'name = "../evil"'), "name", "../evil"),
    "missing reference data": (with_line("pipe", 'reference_data = "no_such_file.csv"'),
                               "pipe.reference_data", "no_such_file.csv"),
    "zero gas iterations": (with_line("numerics", "gas_max_iterations = 0"),
                            "numerics.gas_max_iterations", "0"),
}


@pytest.mark.parametrize("label", sorted(WRONG))
def test_wrong_case_file_names_the_key(tmp_path, label):
    text, key, shown = WRONG[label]
    if label.startswith(("negative mass", "particle ")):
        text = GOOD + text
    path = write(tmp_path, text)
    with pytest.raises(CaseError) as info:
        Case.from_toml(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(key + " ") or msg.startswith(key + ":"), msg
    assert shown in msg, msg
    if "unknown key" in msg or "missing" in msg or "out of range" in msg:
        assert "allowed" in msg, msg


def test_invalid_toml_and_missing_file(tmp_path):
    with pytest.raises(CaseError, match="not valid TOML"):
        Case.from_toml(write(tmp_path, "[pipe\ndiameter = 1"))
    with pytest.raises(CaseError, match="no such case file"):
        Case.from_toml(tmp_path / "absent.toml")


def test_defaults_of_a_minimal_single_phase_case(tmp_path):
    case = Case.from_toml(write(tmp_path, without("sections", without("name", GOOD)),
                                name="my pipe.toml"))
    assert case.name == "my_pipe"  # from the file name
    assert case.particles is None and case.single_phase
    assert case.pipe.mode == "developing"
    assert case.pipe.sections == (4.0,)  # the outlet
    assert case.gas.inlet_epsilon is None
    assert case.walls == WallConfig(roughness_angle_std_deg=0.0, impact_angle="effective",
                                    lateral_roughness=True, shadow_effect="weighted")
    ph = case.physics
    assert ph.coupling == "four-way" and ph.inter_particle_collisions is True
    assert all([ph.saffman_mei_lift, ph.magnus_lift, ph.rotation, ph.langevin, ph.gravity,
                ph.langevin_drift_correction])
    assert ph.drag == "schiller-naumann" and ph.magnus_model == "lun-liu"
    n = case.numerics
    assert (n.axial_cells, n.radial_cells, n.azimuthal_cells) == (400, 20, 40)
    assert n.first_cell_yplus == 30.0 and isinstance(n.first_cell_yplus, float)
    assert (n.parcels, n.parcels_start, n.average_passes, n.max_passes) == (240000, 30000, 3, 40)
    assert n.step_rule == "default" and n.relaxation == 0.3 and n.seed == 1
    assert n.gas_tolerance == 1e-6 and n.gas_max_iterations == 3000


def test_particle_defaults_and_automatic_switches(tmp_path):
    case = Case.from_toml(write(tmp_path, GOOD + PARTICLES + "\n[physics]\ncoupling = \"two-way\"\n"
                                "rotation = false\n"))
    assert case.particles.injection_rms == 0.5
    assert case.particles.restitution == 0.9 and case.particles.friction == 0.4
    assert case.physics.inter_particle_collisions is False  # only four-way collides
    assert case.physics.magnus_lift is False  # no rotation, no Magnus lift
    small = Case.from_toml(write(tmp_path, with_line("numerics", "parcels = 500")))
    assert small.numerics.parcels_start == 500


def test_int_accepted_for_float_and_stored_as_float(tmp_path):
    case = Case.from_toml(write(tmp_path, GOOD.replace("length = 4.0", "length = 4")))
    assert case.pipe.length == 4.0 and isinstance(case.pipe.length, float)


def test_round_trip_through_attrs(tmp_path):
    text = with_line("physics", 'coupling = "two-way"', GOOD + PARTICLES) + "\n[walls]\n" \
        "roughness_angle_std_deg = 1.5\nshadow_effect = \"rejection\"\n"
    case = Case.from_toml(write(tmp_path, with_line("gas", "inlet_epsilon = 3.5", text)))
    attrs = case.to_attrs()
    for key, value in attrs.items():
        assert key == "case.name" or key == "case.description" or "." in key
        assert isinstance(value, (str, int, float)) or value.dtype.kind == "f", (key, value)
        assert not isinstance(value, bool), key
    assert attrs["physics.gravity"] == "true"
    assert attrs["physics.inter_particle_collisions"] == "false"
    assert attrs["numerics.parcels"] == 240000
    assert Case.from_attrs(attrs) == case
    single = Case.from_toml(write(tmp_path, GOOD))
    assert not any(k.startswith("particles.") for k in single.to_attrs())
    assert isinstance(single.to_attrs()["gas.inlet_epsilon"], str)  # "auto: ..." when absent
    assert Case.from_attrs(single.to_attrs()) == single


def test_round_trip_through_netcdf(tmp_path):
    xr = pytest.importorskip("xarray")
    case = Case.from_toml(write(tmp_path, GOOD + PARTICLES))
    path = tmp_path / "a.nc"
    xr.Dataset(attrs=case.to_attrs()).to_netcdf(path)
    with xr.open_dataset(path) as ds:
        assert Case.from_attrs(ds.attrs) == case


def test_shipped_cases_are_valid():
    for path in sorted(CASES.glob("*.toml")):
        Case.from_toml(path)
    case = Case.from_toml(CASES / "single_phase_pipe.toml")
    assert (case.pipe.diameter, case.pipe.length, case.gas.bulk_velocity) == (0.0305, 4.0, 10.0)
    assert case.particles is None


def test_replace_revalidates_and_follows_automatic_defaults(tmp_path):
    case = Case.from_toml(write(tmp_path, GOOD + PARTICLES))
    light = case.replace(numerics={"parcels": 2000})
    assert light.numerics.parcels == 2000 and light.numerics.parcels_start == 2000
    assert case.numerics.parcels == 240000  # frozen original untouched
    two = case.replace(physics={"coupling": "two-way"})
    assert two.physics.inter_particle_collisions is False
    assert case.replace(particles=None).single_phase
    with pytest.raises(CaseError, match=r"^numerics\.parcels = 0"):
        case.replace(numerics={"parcels": 0})
    with pytest.raises(dataclasses.FrozenInstanceError):
        case.pipe.diameter = 1.0


def test_sections_construct_and_validate_directly():
    assert PipeConfig(diameter=0.1, length=2).sections == (2.0,)
    with pytest.raises(CaseError, match=r"^gas\.bulk_velocity = 0"):
        GasConfig(density=1.2, viscosity=1.8e-5, bulk_velocity=0, inlet_k=1.0)
    with pytest.raises(CaseError, match=r"^numerics\.azimuthal_cells = 10\.0: wrong type"):
        NumericsConfig(azimuthal_cells=10.0)
    assert PhysicsConfig(coupling="one-way").inter_particle_collisions is False


def test_a_dataset_from_before_a_later_key_is_the_case_with_its_earlier_value():
    """A result written before physics.partner_momentum, numerics.mirror_symmetry and
    physics.langevin_drift_form existed ran with the partners' impulse discarded, without
    symmetry and with the drift term's factor (1 - R_P) T_L: rebuilt from its attributes
    it is that case, not today's default (config.LATER_KEYS), so --resume does not take it
    for a run of today's case."""
    from eulag.config import CASES_DIR, LATER_KEYS, Case
    from eulag.runs import same_case

    today = Case.from_toml(CASES_DIR / "tsuji_morikawa_200um.toml")
    assert today.physics.partner_momentum == "returned" and today.numerics.mirror_symmetry
    old = {k: v for k, v in today.to_attrs().items() if k not in LATER_KEYS}
    rebuilt = Case.from_attrs(old)
    assert rebuilt.physics.partner_momentum == "discarded"
    assert rebuilt.numerics.mirror_symmetry is False
    assert not same_case(old, today)
    assert rebuilt.physics.langevin_drift_form == "particle"
    earlier = today.replace(physics={"partner_momentum": "discarded", "partner_correlation": "particle",
                                     "langevin_drift_form": "particle"},
                            numerics={"mirror_symmetry": False})
    assert same_case(old, earlier)
    assert same_case(today.to_attrs(), today)  # a dataset of today keeps every key


def test_a_dense_phase_case_without_its_model_key_says_so():
    """A slug or two-fluid case file that leaves out ``model`` is read as an Euler-Lagrange case; its
    first table says which model it belongs to instead of "unknown key"."""
    for table, model in (("tube", "dem-darcy"), ("solids", "two-fluid")):
        with pytest.raises(CaseError, match=rf'^\[{table}\]: a table of the {model} model, in a case without '
                                            rf'model = "{model}"'):
            Case.from_dict({"name": "x", table: {"a": 1}})


def test_case_differences_compare_values_as_netcdf_stores_them():
    """A one-element list is stored as a scalar attribute: not a difference; real ones are named."""
    import numpy as np

    from eulag.config import case_differences

    assert case_differences({"pipe.sections": 3.56}, {"pipe.sections": np.array([3.56])}) == ""
    assert case_differences({"numerics.seed": np.int64(1), "pipe.sections": np.float64(3.56)},
                            {"numerics.seed": 3, "pipe.sections": [3.56]}) == "numerics.seed = 1 stored, 3 in this case"
