"""A Stable-Baselines3 model as a :class:`~econmotor.motor_backend.training_loop.Learner`.

The loop calls ``model.learn(n, reset_num_timesteps=False)`` chunk by chunk, as SB3's documentation
continues a model's training: the env is not reset between chunks, ``num_timesteps`` and the episode
buffer carry on, and one logger (TensorBoard or none) serves the whole run. (SB3 would count a
learning-rate schedule's progress within each chunk; econmotor's hyperparameters come from YAML and are
constants.) Per-step callbacks (a curriculum, the economics' TensorBoard scalars) stay SB3 callbacks;
what happens between chunks is the loop's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.utils import configure_logger

from econmotor.motor_backend.sb3_callbacks import quiet_logger
from econmotor.motor_backend.training_loop import Learner

#: an off-policy model (SAC) learns in chunks of about this many env steps between the loop's reports
OFF_POLICY_CHUNK = 1_000


class SB3Learner(Learner):
    """Chunks of ``model.learn``; a subclass adds checkpoints, policy files, export and evaluation.

    Args:
        model: the SB3 model (fresh or loaded from a checkpoint, with its env).
        callbacks: per-step SB3 callbacks of every chunk.
        tensorboard_dir: TensorBoard's folder (``<dir>/run_<N>``, continued by a resumed run), or None.
        resumed: the model comes from a checkpoint (its TensorBoard run is continued, not a new one).
    """

    def __init__(self, model: BaseAlgorithm, callbacks: Sequence[BaseCallback] = (),
                 tensorboard_dir: str | None = None, resumed: bool = False) -> None:
        self.model, self.callbacks = model, list(callbacks)
        model.set_logger(configure_logger(0, tensorboard_dir, "run", not resumed) if tensorboard_dir
                         else quiet_logger())

    @property
    def env_steps(self) -> int:  # type: ignore[override]
        return int(self.model.num_timesteps)

    @property
    def chunk_steps(self) -> int:  # type: ignore[override]
        n_envs = self.model.n_envs
        n_steps = getattr(self.model, "n_steps", None)  # on-policy: one rollout
        return int(n_steps * n_envs) if n_steps else max(n_envs, OFF_POLICY_CHUNK // n_envs * n_envs)

    def learn(self, until_steps: int) -> Mapping[str, Any] | None:
        self.model.learn(max(1, until_steps - self.env_steps), callback=list(self.callbacks),
                         reset_num_timesteps=False, tb_log_name="run")
        buffer = self.model.ep_info_buffer
        if not buffer:
            return None
        return {"mean_return": float(np.mean([ep["r"] for ep in buffer])),
                "mean_length": float(np.mean([ep["l"] for ep in buffer]))}

    def log_scalars(self, scalars: Mapping[str, float], env_steps: int) -> None:
        for name, value in scalars.items():
            self.model.logger.record(name, value)
        self.model.logger.dump(env_steps)

    def close(self) -> None:
        env = self.model.get_env()
        if env is not None:
            env.close()
