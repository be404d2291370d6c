"""The reference paper's model as a profile: every departure of eulag from the paper is a case
key (config.DEVIATIONS), and ``profile = "paper"`` takes the paper's form for those a case file
does not set."""

import pytest

from eulag.config import DEVIATIONS, PAPER_MODEL, Case, CaseError, _public_fields, _SECTIONS

BASE = {"pipe": {"diameter": 0.0305, "length": 1.0}, "gas": {"density": 1.2, "viscosity": 1.8e-5,
        "bulk_velocity": 10.0, "inlet_k": 1.0},
        "particles": {"diameter": 200e-6, "density": 1020.0, "mass_loading": 2.2},
        "walls": {"roughness_angle_std_deg": 5.0}}


def _get(case, dotted):
    section, key = dotted.split(".")
    return getattr(getattr(case, section), key)


def test_every_deviation_is_a_case_key_with_its_default():
    for dotted, (ours, paper, what) in DEVIATIONS.items():
        section, key = dotted.split(".")
        assert key in [f.name for f in _public_fields(_SECTIONS[section])], dotted
        assert _get(Case.from_dict({**BASE, "name": "x"}), dotted) == ours, dotted
        assert what


def test_paper_profile_sets_the_papers_form_where_the_file_is_silent():
    case = Case.from_dict({**BASE, "name": "x", "profile": "paper"})
    for dotted, (ours, paper, _) in DEVIATIONS.items():
        assert _get(case, dotted) == paper, dotted
    # an explicit key wins over the profile
    explicit = Case.from_dict({**BASE, "name": "x", "profile": "paper",
                               "walls": {"roughness_angle_std_deg": 5.0, "shadow_effect": "weighted"}})
    assert explicit.walls.shadow_effect == "weighted" and explicit.walls.impact_angle == "nominal"
    # the same values written out are the same case
    assert Case.from_dict({**BASE, "name": "x"}).replace(**PAPER_MODEL) == case


def test_unknown_profile_is_one_clear_error():
    with pytest.raises(CaseError, match=r'^profile = "lain": unknown profile; allowed: "eulag", "paper"'):
        Case.from_dict({**BASE, "name": "x", "profile": "lain"})
