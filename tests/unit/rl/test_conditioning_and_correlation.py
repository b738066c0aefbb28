"""The conditioned observation carries the vector; running correlations match scipy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.envs.dishwashing import DishwashingEnv
from econmotor.errors import ConfigError
from econmotor.rl.conditioning import ObjectiveConditioningWrapper
from econmotor.rl.correlation import RunningCorrelation


def test_fixed_conditioning_appends_the_normalised_vector_every_step():
    base = DishwashingEnv(reward_mode="legacy")
    env = ObjectiveConditioningWrapper(base, ObjectiveVector.from_preset("throughput"), "fixed")
    expected = np.array([2, 1, 0.5, 1, 0]) / 4.5
    assert env.observation_space.shape == (base.observation_space.shape[0] + 5,)
    obs, info = env.reset(seed=1)
    assert np.allclose(obs[-5:], expected, atol=1e-6)
    assert info["objective_vector"] == pytest.approx(expected.tolist())
    for _ in range(3):
        obs, *_ = env.step(env.action_space.sample())
        assert np.allclose(obs[-5:], expected, atol=1e-6)
        assert env.observation_space.contains(obs)


def test_dirichlet_conditioning_samples_a_new_simplex_vector_per_episode_reproducibly():
    def vectors(seed):
        env = ObjectiveConditioningWrapper(DishwashingEnv(reward_mode="legacy"), ObjectiveVector(), "dirichlet")
        out = [env.reset(seed=seed)[0][-5:]]
        out += [env.reset()[0][-5:] for _ in range(4)]
        return np.array(out)

    a, b = vectors(7), vectors(7)
    assert np.array_equal(a, b)
    assert len({tuple(np.round(v, 6)) for v in a}) == 5
    assert np.allclose(a.sum(axis=1), 1.0, atol=1e-5)
    assert np.all(a[:, 4] == 0.0)  # novelty pinned at 0 by the default concentration


def test_a_vector_can_be_pinned_for_evaluation():
    env = ObjectiveConditioningWrapper(DishwashingEnv(reward_mode="legacy"), ObjectiveVector(), "dirichlet")
    env.set_objective(ObjectiveVector.from_preset("safety"))
    for _ in range(2):
        obs, _ = env.reset()
        assert np.allclose(obs[-5:], np.array([0.5, 2, 1, 3, 0]) / 6.5, atol=1e-6)
    obs, _ = env.reset(options={"objective_vector": [0, 0, 1, 0, 0]})
    assert np.allclose(obs[-5:], [0, 0, 1, 0, 0])


def test_conditioning_rejects_unknown_modes():
    with pytest.raises(ConfigError, match="dirichlet"):
        ObjectiveConditioningWrapper(DishwashingEnv(), ObjectiveVector(), "uniform")


def test_running_correlation_matches_scipy_with_ties_and_windows():
    rng = np.random.default_rng(0)
    x = rng.normal(size=3000)
    y = 0.5 * x + rng.normal(size=3000)
    y[:300] = 1.0  # ties
    corr = RunningCorrelation(capacity=8)
    for a, b in zip(x, y, strict=True):
        corr.add(float(a), float(b))
    assert corr.pearson() == pytest.approx(stats.pearsonr(x, y)[0], abs=1e-10)
    assert corr.spearman() == pytest.approx(stats.spearmanr(x, y)[0], abs=1e-10)
    assert corr.spearman(500) == pytest.approx(stats.spearmanr(x[-500:], y[-500:])[0], abs=1e-10)
    assert corr.pearson_window(500) == pytest.approx(stats.pearsonr(x[-500:], y[-500:])[0], abs=1e-10)


def test_correlation_is_nan_without_spread():
    corr = RunningCorrelation()
    corr.add(1.0, 2.0)
    assert np.isnan(corr.pearson()) and np.isnan(corr.spearman())
    corr.add(1.0, 3.0)
    assert np.isnan(corr.pearson())
