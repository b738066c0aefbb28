import pytest

from econmotor.errors import ConfigError, UnknownNameError
from econmotor.objectives import compile_economic_overlay, load_objective_spec

SPEC_EXAMPLE = """\
mpl_weight: 1.0
energy_weight: 0.2
error_weight: 0.5
novelty_weight: 0.0
risk_weight: 0.3
extra_weights:
  stability_margin: -0.1
"""


def write(tmp_path, text, name="objective.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_flat_form_is_the_spec_example(tmp_path):
    spec = load_objective_spec(write(tmp_path, SPEC_EXAMPLE))
    assert compile_economic_overlay(spec).to_dict() == {
        "mpl_per_hour": 1.0, "energy_kwh": -0.2, "error_rate": -0.5, "risk_score": -0.3, "stability_margin": -0.1,
    }
    assert spec.name == "objective"


def test_vector_form_maps_terms_onto_weights(tmp_path):
    spec = load_objective_spec(write(tmp_path, "objective_vector: [2, 1, 0.5, 3, 0.25]\nname: v\n"))
    assert (spec.mpl_weight, spec.error_weight, spec.energy_weight, spec.risk_weight, spec.novelty_weight) == (
        2.0, 1.0, 0.5, 3.0, 0.25)
    assert spec.name == "v"


def test_preset_form(tmp_path):
    spec = load_objective_spec(write(tmp_path, "objective_preset: safety\n"))
    assert (spec.mpl_weight, spec.error_weight, spec.energy_weight, spec.risk_weight) == (0.5, 2.0, 1.0, 3.0)
    assert spec.name == "safety"


@pytest.mark.parametrize(
    "text, key",
    [
        ("mpl_weigth: 1.0\n", "mpl_weigth"),
        ("mpl_weight: .nan\n", "mpl_weight"),
        ("mpl_weight: .inf\n", "mpl_weight"),
        ("mpl_weight: fast\n", "mpl_weight"),
        ("objective_vector: [1, 2]\n", "objective_vector"),
        ("objective_vector: [1, 2, 3, -4, 0]\n", "objective_vector[3]"),
        ("objective_preset: 3\n", "objective_preset"),
        ("mpl_weight: 1\nobjective_preset: safety\n", None),
        ("extra_weights: [1, 2]\n", "extra_weights"),
        ("extra_weights: {energy_kwh: 1.0}\n", "extra_weights.energy_kwh"),
        ("name: x\n", None),
    ],
)
def test_bad_input_names_file_and_key(tmp_path, text, key):
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_objective_spec(path)
    assert str(path) in str(info.value)
    assert info.value.key == key


def test_unknown_key_suggests_the_close_one(tmp_path):
    with pytest.raises(ConfigError, match="did you mean 'mpl_weight'"):
        load_objective_spec(write(tmp_path, "mpl_weigth: 1.0\n"))


def test_unknown_preset_lists_presets(tmp_path):
    with pytest.raises(ConfigError, match="throughput_focused"):
        load_objective_spec(write(tmp_path, "objective_preset: fastest\n"))


@pytest.mark.parametrize("text", ["", "# nothing\n", "- 1\n- 2\n", "just a string\n", "{a: [\n"])
def test_empty_non_mapping_or_broken_files(tmp_path, text):
    with pytest.raises(ConfigError):
        load_objective_spec(write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_objective_spec(tmp_path / "nope.yaml")


def test_unknown_preset_name_in_vector_api():
    from econmotor.config.objective_profile import ObjectiveVector

    with pytest.raises(UnknownNameError, match="balanced"):
        ObjectiveVector.from_preset("nope")


@pytest.mark.parametrize("form", ["objective_preset: energy_saver", "objective_vector: [1, 1, 3, 1, 0]",
                                  "mpl_weight: 1.0\nenergy_weight: 3.0"])
def test_an_objective_states_its_energy_term_in_every_form(tmp_path, form):
    path = tmp_path / "priced.yaml"
    path.write_text(f"{form}\nenergy_term: usd\n")
    assert load_objective_spec(path).energy_term == "usd"
    path.write_text(f"{form}\n")
    assert load_objective_spec(path).energy_term == "wh"  # the default: r_energy = -Wh
    path.write_text(f"{form}\nenergy_term: kwh\n")
    with pytest.raises(ConfigError) as info:
        load_objective_spec(path)
    assert info.value.key == "energy_term" and str(path) in str(info.value)
