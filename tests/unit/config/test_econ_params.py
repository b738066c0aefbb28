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


def test_load_econ_params_from_a_preset_name_and_from_yaml(tmp_path):
    from econmotor.config.econ_params import load_econ_params

    assert load_econ_params("realistic") == EconParams.preset("realistic")
    assert load_econ_params(EconParams.preset("toy")) == EconParams()
    path = tmp_path / "econ.yaml"
    path.write_text("preset: realistic\nbase_rate: 1.8\nmax_steps: 120\nenergy_price_usd_per_kwh: 0.2\n")
    params = load_econ_params(path)
    assert params == EconParams.preset("realistic").with_overrides(
        {"base_rate": 1.8, "max_steps": 120, "energy_price_usd_per_kwh": 0.2})
    assert load_econ_params(str(path)) == params


@pytest.mark.parametrize("text, key", [("base_rat: 1.0\n", "base_rat"), ("max_steps: 1.5\n", "max_steps"),
                                       ("damage_cost: -1\n", "damage_cost"), ("preset: huge\n", "preset"),
                                       ("p_min: .nan\n", "p_min")])
def test_load_econ_params_rejects_bad_yaml_naming_file_and_key(tmp_path, text, key):
    from econmotor.config.econ_params import load_econ_params

    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=key) as err:
        load_econ_params(path)
    assert "bad.yaml" in str(err.value)


def test_load_econ_params_unknown_preset_lists_the_presets():
    from econmotor.config.econ_params import load_econ_params

    with pytest.raises(UnknownNameError, match="realistic"):
        load_econ_params("fancy")
    with pytest.raises(ConfigError, match="not found"):
        load_econ_params("missing.yaml")
