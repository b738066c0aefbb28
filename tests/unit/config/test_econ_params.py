import pytest

from econmotor.config.econ_params import EconParams
from econmotor.errors import ConfigError, UnknownNameError


def test_toy_preset_values():
    p = EconParams.preset("toy")
    assert (p.price_per_unit, p.damage_cost, p.energy_Wh_per_attempt, p.time_step_s, p.base_rate, p.p_min,
            p.k_err, p.q_speed, p.q_care, p.care_cost, p.max_steps, p.max_catastrophic_errors,
            p.max_error_rate_sla, p.min_steps_for_sla, p.zero_throughput_patience) == (
        0.30, 1.0, 0.05, 60, 2.0, 0.02, 0.12, 1.2, 1.5, 0.25, 240, 3, 0.12, 5, 10)


def test_realistic_differs_from_toy_only_where_documented():
    toy, real = EconParams.preset("toy").to_dict(), EconParams.preset("realistic").to_dict()
    changed = {k: real[k] for k in toy if toy[k] != real[k]}
    assert changed == {"price_per_unit": 0.25, "damage_cost": 1.5, "base_rate": 1.6,
                       "max_error_rate_sla": 0.08, "energy_Wh_per_attempt": 0.08}


def test_unknown_preset_and_override():
    with pytest.raises(UnknownNameError, match="realistic"):
        EconParams.preset("nope")
    with pytest.raises(ConfigError, match="base_rat"):
        EconParams().with_overrides({"base_rat": 1.0})
    assert EconParams().with_overrides({"base_rate": 3.0}).base_rate == 3.0
