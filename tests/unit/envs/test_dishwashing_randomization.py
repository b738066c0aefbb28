"""Per-episode EconParams randomization and its curriculum."""

from __future__ import annotations

import numpy as np
import pytest

from econmotor.config.econ_params import EconParams
from econmotor.envs import DishwashingEnv, parse_econ_randomization
from econmotor.errors import ConfigError


def test_unknown_keys_are_errors_listing_the_supported_ones():
    with pytest.raises(ConfigError) as exc:
        parse_econ_randomization({"friction_range": [0.5, 1.0]}, source="pack.yaml")
    text = str(exc.value)
    assert "pack.yaml" in text and "domain_randomization.friction_range" in text and "base_rate_range" in text
    with pytest.raises(ConfigError, match="ramp_steps"):
        parse_econ_randomization({}, {"ramp_step": 10})
    with pytest.raises(ConfigError, match="p_min_range"):
        parse_econ_randomization({"p_min_range": [0.1, 0.9]})  # p_min above the 0.5 error cap
    with pytest.raises(ConfigError, match="low"):
        parse_econ_randomization({"base_rate_range": [3.0, 1.0]})


def test_samples_stay_in_range_and_differ_between_episodes():
    rand = parse_econ_randomization({"base_rate_range": [1.0, 3.0], "k_err_range": [0.05, 0.2]})
    env = DishwashingEnv(EconParams.preset("toy"), randomization=rand)
    drawn = []
    for seed in range(20):
        _, info = env.reset(seed=seed)
        drawn.append((info["econ_params"]["base_rate"], info["econ_params"]["k_err"]))
        assert env.params.base_rate == info["econ_params"]["base_rate"]
    rates, gains = np.array(drawn).T
    assert rates.min() >= 1.0 and rates.max() <= 3.0 and gains.min() >= 0.05 and gains.max() <= 0.2
    assert len(set(rates)) == 20
    _, again = env.reset(seed=3)
    assert (again["econ_params"]["base_rate"], again["econ_params"]["k_err"]) == drawn[3]


def test_curriculum_ramps_from_nominal_to_full_range():
    base = EconParams.preset("toy")
    rand = parse_econ_randomization({"base_rate_range": [3.0, 4.0]},
                                    {"initial_difficulty": 0.0, "max_difficulty": 1.0, "ramp_steps": 100})
    rng = np.random.default_rng(0)
    assert rand.difficulty(0) == 0.0 and rand.difficulty(50) == 0.5 and rand.difficulty(500) == 1.0
    assert rand.sample(base, rng, 0).base_rate == base.base_rate
    half = [rand.sample(base, rng, 50).base_rate for _ in range(200)]
    assert min(half) >= 2.5 and max(half) <= 3.0  # nominal 2.0 + 0.5 * ([3, 4] - 2.0)
    full = [rand.sample(base, rng, 100).base_rate for _ in range(200)]
    assert min(full) >= 3.0 and max(full) <= 4.0


def test_shipped_dishwashing_datapacks_are_valid():
    from pathlib import Path

    from econmotor.config.datapacks import load_datapack_configs

    root = Path(__file__).resolve().parents[3] / "configs" / "datapacks"
    packs = load_datapack_configs(sorted(root.glob("dishwashing_*.yaml")))
    assert {p.id for p in packs} >= {"dishwashing_nominal", "dishwashing_varied_crockery"}
    for pack in packs:
        rand = parse_econ_randomization(pack.domain_randomization, pack.curriculum, pack.source)
        for name, (low, high) in rand.ranges.items():
            assert low <= high and name in EconParams.__dataclass_fields__
