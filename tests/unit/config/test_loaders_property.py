"""Arbitrary YAML into every loader: a valid result or a ConfigError, nothing else."""

import tempfile
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from econmotor.config.datapacks import load_datapack_configs
from econmotor.errors import ConfigError
from econmotor.objectives import load_objective_spec
from econmotor.tasks.catalog import load_catalog
from econmotor.valuation import load_constraint_set, load_constraint_sets

KEYS = st.sampled_from([
    "mpl_weight", "energy_weight", "error_weight", "novelty_weight", "risk_weight", "extra_weights",
    "objective_vector", "objective_preset", "name", "id", "motion_clips", "domain_randomization", "curriculum",
    "tags", "task_tags", "objective_hint", "min_wage_parity", "max_error_rate", "max_energy_Wh", "energy_basis",
    "constraint_sets", "tasks", "economics", "backends", "unit", "value", "source", "path", "weight",
    "initial_difficulty", "max_difficulty", "wage_human_usd_per_hour", "safety", "throughput", "x",
])
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(-10, 10), st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8), st.sampled_from(["safety", "throughput", "per_unit", "flat", "USD/h"]),
)
VALUES = st.recursive(
    SCALARS,
    lambda children: st.one_of(st.lists(children, max_size=6), st.dictionaries(KEYS, children, max_size=6)),
    max_leaves=25,
)
DOCS = st.one_of(st.dictionaries(KEYS, VALUES, max_size=8), VALUES)
LOADERS = [
    load_objective_spec,
    load_constraint_set,
    load_constraint_sets,
    lambda p: load_datapack_configs([p]),
    lambda p: load_catalog([p]),
]


def _check_all(text: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "config.yaml"
        path.write_text(text, encoding="utf-8")
        for loader in LOADERS:
            try:
                loader(path)
            except ConfigError as exc:
                assert str(path) in str(exc)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(DOCS)
def test_structured_yaml(doc):
    _check_all(yaml.safe_dump(doc, allow_unicode=True))


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=200))
def test_arbitrary_text(text):
    _check_all(text)
