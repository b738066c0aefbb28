import math

import pytest

from econmotor.errors import ConfigError
from econmotor.valuation import (
    ConstraintSet,
    apply_constraint_penalties,
    load_constraint_set,
    load_constraint_sets,
)

SUMMARY = {"wage_parity": 0.8, "error_rate_episode": 0.08, "energy_Wh": 30.0, "energy_Wh_per_unit": 0.5}


def test_spec_section5_penalty():
    # (0.9 - 0.8)*10 + (0.08 - 0.05)*10 = 1.0 + 0.3
    constraints = {"min_wage_parity": 0.9, "max_error_rate": 0.05}
    assert apply_constraint_penalties(5.0, SUMMARY, constraints) == pytest.approx(5.0 - 1.3)


def test_energy_per_unit_and_per_episode():
    per_unit = ConstraintSet(max_energy_Wh=0.4)
    per_episode = ConstraintSet(max_energy_Wh=20.0, energy_basis="per_episode")
    assert per_unit.violations(SUMMARY) == {"max_energy_Wh": pytest.approx(0.1)}
    assert per_episode.violations(SUMMARY) == {"max_energy_Wh": pytest.approx(10.0)}
    assert apply_constraint_penalties(0.0, SUMMARY, per_episode) == pytest.approx(-100.0)


def test_met_constraints_cost_nothing():
    met = ConstraintSet(min_wage_parity=0.5, max_error_rate=0.1, max_energy_Wh=1.0)
    assert met.satisfied(SUMMARY)
    assert apply_constraint_penalties(3.0, SUMMARY, met) == 3.0


def test_load_single_and_named_sets(tmp_path):
    one = tmp_path / "c.yaml"
    one.write_text("min_wage_parity: 0.9\nmax_error_rate: 0.05\nmax_energy_Wh: 20\nenergy_basis: per_episode\n")
    cs = load_constraint_set(one)
    assert (cs.min_wage_parity, cs.max_error_rate, cs.max_energy_Wh, cs.energy_basis, cs.name) == (
        0.9, 0.05, 20.0, "per_episode", "c")
    many = tmp_path / "sets.yaml"
    many.write_text("constraint_sets:\n  strict: {max_error_rate: 0.01}\n  loose: {max_error_rate: 0.2}\n")
    assert [s.name for s in load_constraint_sets(many)] == ["strict", "loose"]


@pytest.mark.parametrize("text, key", [
    ("max_error_rat: 0.1\n", "max_error_rat"),
    ("max_error_rate: 2\n", "max_error_rate"),
    ("max_energy_Wh: -1\n", "max_energy_Wh"),
    ("energy_basis: per_hour\n", "energy_basis"),
    ("min_wage_parity: .nan\n", "min_wage_parity"),
])
def test_bad_constraint_files(tmp_path, text, key):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_constraint_set(path)
    assert info.value.key == key and str(path) in str(info.value)


# ---------------------------------------------------------------- what mutation testing found unchecked
def test_violations_by_hand_on_both_energy_bases():
    summary = {"wage_parity": 0.7, "error_rate": 0.08, "energy_wh_per_unit": 3.0, "energy_wh": 40.0}
    per_unit = ConstraintSet(min_wage_parity=1.0, max_error_rate=0.05, max_energy_Wh=2.5)
    assert per_unit.active() == ["min_wage_parity", "max_error_rate", "max_energy_Wh"]
    assert per_unit.violations(summary) == pytest.approx({"min_wage_parity": 0.3, "max_error_rate": 0.03,
                                                         "max_energy_Wh": 0.5})
    per_episode = ConstraintSet(max_energy_Wh=30.0, energy_basis="per_episode")
    assert per_episode.active() == ["max_energy_Wh"] and per_episode.violations(summary) == {"max_energy_Wh": 10.0}
    met = ConstraintSet(min_wage_parity=0.7, max_error_rate=0.08, max_energy_Wh=3.0)  # exactly at every limit
    assert met.violations(summary) == {"min_wage_parity": 0.0, "max_error_rate": 0.0, "max_energy_Wh": 0.0}
    assert met.satisfied(summary) and not per_unit.satisfied(summary)
    assert ConstraintSet().active() == [] and ConstraintSet().violations(summary) == {}


def test_energy_per_unit_reads_either_spelling_and_is_infinite_without_one():
    rule = ConstraintSet(max_energy_Wh=1.0)
    assert rule.energy_value({"energy_Wh_per_unit": 2.5}) == 2.5
    assert rule.energy_value({"energy_wh_per_unit": 1.5}) == 1.5
    assert rule.energy_value({"energy_Wh_per_unit": None, "energy_wh_per_unit": 4}) == 4.0
    assert rule.energy_value({}) == math.inf and rule.violations({"error_rate": 0.0}) == {"max_energy_Wh": math.inf}

    class Summary:  # an object with attributes, as the step summaries are
        energy_Wh_per_unit = 0.25

    assert rule.energy_value(Summary()) == 0.25
    assert rule.violations({"energy_wh_per_unit": 1.5}) == {"max_energy_Wh": 0.5}


def test_penalty_is_ten_per_unit_of_violation_from_a_mapping_too():
    from econmotor.valuation.constraints import PENALTY_SCALE, apply_constraint_penalties

    assert PENALTY_SCALE == 10.0
    summary = {"wage_parity": 0.5, "error_rate": 0.2}
    assert apply_constraint_penalties(1.0, summary, {"min_wage_parity": 1.0, "max_error_rate": 0.1}) == \
        pytest.approx(1.0 - 10.0 * (0.5 + 0.1))


def test_parse_errors_name_the_source_and_the_full_key(tmp_path):
    from econmotor.valuation.constraints import load_constraint_sets, parse_constraint_set

    with pytest.raises(ConfigError) as info:
        parse_constraint_set({"max_error_rate": 1.5}, "c.yaml", "constraint_sets.a")
    assert info.value.source == "c.yaml" and info.value.key == "constraint_sets.a.max_error_rate"
    with pytest.raises(ConfigError) as info:
        parse_constraint_set({"max_energy_Wh": -1.0}, "c.yaml")
    assert info.value.key == "max_energy_Wh"
    with pytest.raises(ConfigError) as info:
        parse_constraint_set({"energy_basis": "per_hour"}, "c.yaml")
    assert info.value.key == "energy_basis" and "per_episode" in str(info.value)
    with pytest.raises(ConfigError) as info:
        parse_constraint_set({"min_wage_parity": "x"}, "c.yaml")
    assert info.value.key == "min_wage_parity"
    parsed = parse_constraint_set({"max_error_rate": 0.0, "min_wage_parity": 0.5, "max_energy_Wh": 0.0,
                                   "energy_basis": "per_episode"}, "c.yaml", name="n")
    assert (parsed.max_error_rate, parsed.min_wage_parity, parsed.max_energy_Wh, parsed.energy_basis, parsed.name) \
        == (0.0, 0.5, 0.0, "per_episode", "n")
    assert parse_constraint_set({"max_error_rate": None}).max_error_rate is None
    path = tmp_path / "sets.yaml"
    path.write_text("constraint_sets:\n  open:\n  strict: {max_error_rate: 0.01}\n")
    sets = load_constraint_sets(path)
    assert [(s.name, s.max_error_rate) for s in sets] == [("open", None), ("strict", 0.01)]
    path.write_text("constraint_sets: {a: {}}\nextra: 1\n")
    with pytest.raises(ConfigError) as info:
        load_constraint_sets(path)
    assert str(path) in str(info.value) and "extra" in str(info.value)


def test_a_missing_wage_parity_counts_as_none_and_the_defaults_are_named():
    from econmotor.valuation.constraints import parse_constraint_set

    assert ConstraintSet(min_wage_parity=0.75).violations({}) == {"min_wage_parity": 0.75}
    assert parse_constraint_set({}).name == "constraints" and ConstraintSet().name == "constraints"
    for bad in ({"max_error_rate": -0.1}, {"name": 3}):
        with pytest.raises(ConfigError) as info:
            parse_constraint_set(bad, "c.yaml", "sets.x")
        assert info.value.source == "c.yaml" and info.value.key == f"sets.x.{next(iter(bad))}"
    with pytest.raises(ConfigError) as info:
        parse_constraint_set({"colour": 1}, "c.yaml", "sets.x")
    assert info.value.source == "c.yaml" and "sets.x" in str(info.value) and "colour" in str(info.value)
    with pytest.raises(ConfigError) as info:
        parse_constraint_set([1], "c.yaml", "sets.x")
    assert info.value.source == "c.yaml" and info.value.key == "sets.x"


def test_constraint_files_name_a_bare_set_by_its_file_and_errors_by_file_and_key(tmp_path):
    bare = tmp_path / "tight.yaml"
    bare.write_text("max_error_rate: 0.02\n")
    (only,) = load_constraint_sets(bare)
    assert (only.name, only.max_error_rate) == ("tight", 0.02)
    nested = tmp_path / "sets.yaml"
    nested.write_text("constraint_sets:\n  a: {max_error_rate: 2.0}\n")
    with pytest.raises(ConfigError) as info:
        load_constraint_sets(nested)
    assert (info.value.source, info.value.key) == (str(nested), "constraint_sets.a.max_error_rate")
    bare.write_text("max_error_rate: 2.0\n")
    with pytest.raises(ConfigError) as info:
        load_constraint_sets(bare)
    assert (info.value.source, info.value.key) == (str(bare), "max_error_rate")
    nested.write_text("constraint_sets: [1, 2]\n")
    with pytest.raises(ConfigError) as info:
        load_constraint_sets(nested)
    assert (info.value.source, info.value.key) == (str(nested), "constraint_sets")


def test_an_object_summary_without_a_per_unit_energy_is_infinitely_far_from_the_limit():
    class Summary:
        wage_parity = 1.0

    assert ConstraintSet(max_energy_Wh=5.0).energy_value(Summary()) == math.inf


def test_a_bad_constraint_set_names_its_source_or_constraints_by_default():
    from econmotor.valuation.constraints import parse_constraint_set

    with pytest.raises(ConfigError, match=r"^<constraints>: key 'max_error_rate'"):
        parse_constraint_set({"max_error_rate": 2.0})
    with pytest.raises(ConfigError, match=r"^sets\.yaml: key 'strict\.max_error_rate'"):
        parse_constraint_set({"max_error_rate": -0.1}, "sets.yaml", prefix="strict")
