"""Stable-Baselines3 callbacks shared by the SB3-based backends.

Small and composable, as SB3's own ``callbacks.py``: one reports progress to a
:data:`~econmotor.motor_backend.base.ProgressFn`, one records the training curve, one runs
the held-out evaluations of evaluation-driven training (``selection.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger

from econmotor.motor_backend.base import ProgressFn
from econmotor.motor_backend.selection import Selection


def quiet_logger() -> Logger:
    """An SB3 logger that writes nothing, for a model trained without TensorBoard. SB3's default
    (``verbose=0``, no ``tensorboard_log``) makes an empty ``$TMPDIR/SB3-<time>`` folder at every
    ``learn``; ``model.set_logger(quiet_logger())`` keeps the records in memory only."""
    return Logger(folder=None, output_formats=[])


class ProgressFnCallback(BaseCallback):
    """Report ``num_timesteps`` to ``progress(label, done, total)`` every ``every`` calls.

    With ``status`` (e.g. :meth:`Selection.status`, the latest held-out verdict) the label is
    ``"<label> · <status>"``: one bar, keyed by the part before ``" · "``, whose text follows it.
    """

    def __init__(self, progress: ProgressFn, total_timesteps: int, label: str = "train", every: int = 64,
                 status: Callable[[], str] | None = None) -> None:
        super().__init__()
        self.progress, self.total, self.label, self.every = progress, int(total_timesteps), label, max(1, every)
        self.status = status

    def _report(self, done: int) -> None:
        said = self.status() if self.status is not None else ""
        self.progress(f"{self.label} · {said}" if said else self.label, min(done, self.total), self.total)

    def _on_training_start(self) -> None:
        self._report(0)

    def _on_step(self) -> bool:
        if self.n_calls % self.every == 0:
            self._report(self.num_timesteps)
        return True

    def _on_training_end(self) -> None:
        self._report(self.num_timesteps)


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


#: ``evaluate(model, num_episodes, first_seed, stop) -> raw episodes`` (see selection.EvaluateFn).
ModelEvaluateFn = Callable[[BaseAlgorithm, int, int, Callable[[list[dict[str, Any]]], bool]], list[dict[str, Any]]]


class HeldOutSelectionCallback(BaseCallback):
    """Evaluation-driven training (``selection.py``): every ``every_steps`` env steps, and at the end
    of training, evaluate the current policy on the held-out episodes; ``save_best(model)`` when it is
    the best so far; log ``held_out/*`` to TensorBoard; stop training once deployable when asked to."""

    def __init__(self, selection: Selection, evaluate: ModelEvaluateFn,
                 save_best: Callable[[BaseAlgorithm], None], after: Callable[[], None] | None = None) -> None:
        super().__init__()
        self.selection, self.evaluate, self.save_best, self.after = selection, evaluate, save_best, after
        self._last = -1

    def _on_training_start(self) -> None:
        self._last = self.num_timesteps

    def _held_out(self) -> None:
        self._last = self.num_timesteps
        result, better = self.selection.consider(
            self.num_timesteps, lambda n, seed, stop: self.evaluate(self.model, n, seed, stop))
        if better:
            self.save_best(self.model)
        if self.after is not None:
            self.after()  # e.g. record the selection so far in run_config.json
        for name, value in result.scalars().items():
            self.logger.record(name, value)
        self.logger.dump(self.num_timesteps)

    def _on_step(self) -> bool:
        if self.selection.due(self.num_timesteps, self._last):
            self._held_out()
        return not self.selection.should_stop

    def _on_training_end(self) -> None:
        if self.selection.final_due(self.num_timesteps, self._last):
            self._held_out()  # the last weights are a candidate too
