"""Objective conditioning: the normalised objective vector is part of the observation.

:class:`ObjectiveConditioningWrapper` appends the current vector (on the simplex,
order ``[mpl, error, energy, safety, novelty]``) to a flat ``Box`` observation.
With ``sampling="fixed"`` the vector never changes; with ``"dirichlet"`` every
``reset`` draws a fresh vector from ``Dirichlet(concentration)`` using the
environment's seeded generator, so one policy learns to serve any preset.
Evaluation pins a vector with :meth:`ObjectiveConditioningWrapper.set_objective`
(or ``reset(options={"objective_vector": [...]})``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.errors import ConfigError

SAMPLING_MODES = ("fixed", "dirichlet")
#: default Dirichlet concentration; 0 pins a term at weight 0 (novelty: no env measures it by default).
DEFAULT_CONCENTRATION = (1.0, 1.0, 1.0, 1.0, 0.0)


def sample_simplex(rng: np.random.Generator, concentration: Sequence[float]) -> ObjectiveVector:
    """Draw ``w ~ Dirichlet(concentration)`` over the terms whose concentration is > 0 (others 0)."""
    conc = np.asarray(concentration, dtype=np.float64)
    active = conc > 0
    values = np.zeros(5)
    values[active] = rng.dirichlet(conc[active])
    return ObjectiveVector.from_list([float(v) for v in values])


class ObjectiveConditioningWrapper(gym.Wrapper):
    """Append the normalised objective vector to the observation; resample it per episode.

    Args:
        env: an environment with a 1-D ``Box`` observation space.
        objective: the fixed vector (``fixed``) or the first one (``dirichlet``); normalised here.
        sampling: ``"fixed"`` or ``"dirichlet"``.
        concentration: Dirichlet concentration per term (5 numbers >= 0, at least one > 0).
    """

    def __init__(self, env: gym.Env, objective: ObjectiveVector, sampling: str = "fixed",
                 concentration: Sequence[float] = DEFAULT_CONCENTRATION) -> None:
        super().__init__(env)
        if sampling not in SAMPLING_MODES:
            raise ConfigError("--objective-sampling", None, f"unknown mode {sampling!r}", SAMPLING_MODES)
        space = env.observation_space
        if not isinstance(space, gym.spaces.Box) or len(space.shape) != 1:
            raise ConfigError("<env>", "observation_space", f"needs a 1-D Box to append the vector, got {space}")
        conc = [float(c) for c in concentration]
        if len(conc) != 5 or min(conc) < 0 or max(conc) <= 0:
            raise ConfigError("<conditioning>", "concentration", f"need 5 numbers >= 0, one > 0; got {conc}")
        self.sampling, self.concentration = sampling, tuple(conc)
        self.objective_vector = objective.normalize()
        low = np.concatenate([space.low, np.zeros(5)]).astype(space.dtype)
        high = np.concatenate([space.high, np.ones(5)]).astype(space.dtype)
        self.observation_space = gym.spaces.Box(low, high, dtype=space.dtype)
        self._pinned = sampling == "fixed"
        self._rng = np.random.default_rng()

    def set_objective(self, objective: ObjectiveVector | None) -> None:
        """Pin a vector for every following episode (evaluation); ``None`` resumes sampling."""
        if objective is None:
            self._pinned = self.sampling == "fixed"
            return
        self.objective_vector, self._pinned = objective.normalize(), True

    def _conditioned(self, obs: np.ndarray) -> np.ndarray:
        vec = np.asarray(self.objective_vector.to_list(), dtype=self.observation_space.dtype)
        return np.concatenate([np.asarray(obs, dtype=self.observation_space.dtype), vec])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        options = dict(options or {})
        if "objective_vector" in options:
            self.objective_vector = ObjectiveVector.from_list(options.pop("objective_vector")).normalize()
        elif not self._pinned:
            self.objective_vector = sample_simplex(self._rng, self.concentration)
        obs, info = self.env.reset(seed=seed, options=options or None)
        info["objective_vector"] = self.objective_vector.to_list()
        return self._conditioned(obs), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._conditioned(obs), reward, terminated, truncated, info
