"""The walker trainer's exploration noise (motor_backend/mujoco/walker_collect.py: Noise; the recipe's
``noise_corr_s``): white by default, the stream torch's ``randn`` gives; correlated, an AR(1) process per robot
and joint whose marginal stays standard normal (the Gaussian's log-probabilities stay the policy's), started
afresh for a robot whose episode ended."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.walker_collect import Noise
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig

SHAPE = torch.Size((512, 29))


def _stream(noise: Noise, steps: int) -> np.ndarray:
    return np.stack([noise.draw(SHAPE).numpy() for _ in range(steps)])


def _lag1(x: np.ndarray) -> float:
    return float(np.corrcoef(x[1:].ravel(), x[:-1].ravel())[0, 1])


def test_white_noise_is_the_generators_randn_stream() -> None:
    drawn = _stream(Noise(0.0, torch.Generator().manual_seed(7)), 5)
    gen = torch.Generator().manual_seed(7)
    np.testing.assert_array_equal(drawn, np.stack([torch.randn(SHAPE, generator=gen).numpy() for _ in range(5)]))
    assert abs(_lag1(drawn)) < 0.02


@pytest.mark.parametrize("corr", [0.5, 0.9])
def test_correlated_noise_is_an_ar1_with_a_standard_normal_marginal(corr: float) -> None:
    x = _stream(Noise(corr, torch.Generator().manual_seed(1)), 200)
    assert _lag1(x) == pytest.approx(corr, abs=0.01)
    assert float(x.std()) == pytest.approx(1.0, abs=0.03)  # every step, the first included
    assert float(x[0].std()) == pytest.approx(1.0, abs=0.05)
    assert abs(float(x.mean())) < 0.03


def test_a_robot_whose_episode_ended_draws_afresh() -> None:
    noise = Noise(0.95, torch.Generator().manual_seed(2))
    before = _stream(noise, 50)[-1]
    rows = np.arange(0, SHAPE[0], 2)
    ended = np.zeros(SHAPE[0], bool)
    ended[rows] = True
    noise.restart(ended)
    after = noise.draw(SHAPE).numpy()
    kept = np.setdiff1d(np.arange(SHAPE[0]), rows)
    assert abs(float(np.corrcoef(before[rows].ravel(), after[rows].ravel())[0, 1])) < 0.05
    assert float(np.corrcoef(before[kept].ravel(), after[kept].ravel())[0, 1]) > 0.9
    assert float(after[rows].std()) == pytest.approx(1.0, abs=0.05)


def test_the_recipe_takes_a_correlation_time_and_rejects_a_negative_one() -> None:
    assert WalkerPPOConfig().noise_corr_s == 0.0  # white noise unless asked
    assert WalkerPPOConfig.from_mapping({"noise_corr_s": 0.5}).noise_corr_s == 0.5
    with pytest.raises(ConfigError, match="noise_corr_s"):
        WalkerPPOConfig.from_mapping({"noise_corr_s": -0.1}, "run.yaml")
    with pytest.raises(ValueError, match="correlation"):
        Noise(1.0)
