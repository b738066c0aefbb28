"""Stable-Baselines3 callbacks shared by the SB3-based backends.

Small and composable, as SB3's own ``callbacks.py``: one reports progress to a
:data:`~econmotor.motor_backend.base.ProgressFn` (shadow mode's SAC). What happens between chunks of a
backend's training (the curve, checkpoints, held-out selection) is the shared loop's
(``training_loop.py``, ``sb3_learner.py``).
"""

from __future__ import annotations

from collections.abc import Callable

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger

from econmotor.motor_backend.base import ProgressFn


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
