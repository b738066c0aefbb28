"""Stable-Baselines3 callbacks shared by the SB3-based backends.

Small and composable, as SB3's own ``callbacks.py``: one reports progress to a
:data:`~econmotor.motor_backend.base.ProgressFn`, one records the training curve.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from econmotor.motor_backend.base import ProgressFn


class ProgressFnCallback(BaseCallback):
    """Report ``num_timesteps`` to ``progress(label, done, total)`` every ``every`` calls."""

    def __init__(self, progress: ProgressFn, total_timesteps: int, label: str = "train", every: int = 64) -> None:
        super().__init__()
        self.progress, self.total, self.label, self.every = progress, int(total_timesteps), label, max(1, every)

    def _on_training_start(self) -> None:
        self.progress(self.label, 0, self.total)

    def _on_step(self) -> bool:
        if self.n_calls % self.every == 0:
            self.progress(self.label, min(self.num_timesteps, self.total), self.total)
        return True

    def _on_training_end(self) -> None:
        self.progress(self.label, min(self.num_timesteps, self.total), self.total)


class TrainingCurveCallback(BaseCallback):
    """Record ``{"timesteps", "mean_return", "mean_length"}`` from SB3's episode buffer.

    A point is added every ``every_steps`` environment steps once an episode has ended
    (needs the env wrapped in SB3's ``Monitor``, as ``make_vec_env`` does).
    """

    def __init__(self, every_steps: int = 1000) -> None:
        super().__init__()
        self.every_steps = max(1, int(every_steps))
        self.curve: list[dict[str, float]] = []
        self._next = self.every_steps

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            self._next += self.every_steps
            self._record()
        return True

    def _on_training_end(self) -> None:
        self._record()

    def _record(self) -> None:
        buffer = self.model.ep_info_buffer
        if not buffer:
            return
        point = {
            "timesteps": float(self.num_timesteps),
            "mean_return": float(np.mean([ep["r"] for ep in buffer])),
            "mean_length": float(np.mean([ep["l"] for ep in buffer])),
        }
        if not self.curve or self.curve[-1]["timesteps"] != point["timesteps"]:
            self.curve.append(point)
