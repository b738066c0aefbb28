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
