"""What a backend declares beyond the three operations: capabilities, run size, held-out cadence."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple


@dataclass(frozen=True)
class BackendCapabilities:
    """What a backend can do beyond the three operations.

    Attributes:
        resume: ``train_policy(..., resume=True)`` continues an interrupted run from its checkpoints.
        algorithms: learners ``train_policy(..., algorithm=...)`` accepts (empty: the backend's own only).
        vec_env_kinds: vector-env kinds the constructor's ``vec_env`` accepts (empty: not selectable).
        imported_policies: ``evaluate_policy`` also takes policies trained elsewhere (a file or a
            shipped name), not only this backend's run directories.
        records_clips: ``record_clip(policy_id, path, num_steps, seed)`` saves a motion clip.
        evaluation_driven: held-out evaluations choose the checkpoint a run keeps, and training can
            stop once deployable (``motor_backend/selection.py``; ``--until-deployable``).
        init_policies: ``train_policy(..., init_policy=...)`` starts a new run's actor from a policy
            trained elsewhere (an ONNX file in Holosoma's format or a shipped name such as
            ``holosoma:g1_29dof/ppo``; ``--init-policy``) and fine-tunes it for the objective.
        shadow_env: :meth:`MotorBackendBase.shadow_env` builds one Gymnasium env of a task whose
            ``info["step_summary"]`` carries each step's economics (shadow mode, ``rl/``).
        course_speed: the evaluation walks a course at a commanded speed, and the constructor's
            ``course_speed_m_per_s`` (m/s; default: the task catalog's ``course_speed_m_per_s``) sets it
            (``compare --command-speed``).
        time_budget: ``train_policy(..., max_wall_s=...)`` stops training at a wall-time budget
            (``train --max-minutes``).
        hyperparameters: ``train_policy(..., hyperparameters={...})`` overrides the learner's recipe for one
            run, each key checked by the learner (``train --hyperparameters KEY=VALUE``).
    """

    resume: bool = False
    algorithms: tuple[str, ...] = ()
    vec_env_kinds: tuple[str, ...] = ()
    imported_policies: bool = False
    records_clips: bool = False
    evaluation_driven: bool = False
    init_policies: bool = False
    shadow_env: bool = False
    course_speed: bool = False
    time_budget: bool = False
    hyperparameters: bool = False


class ShadowEnv(NamedTuple):
    """One Gymnasium env of a task for shadow mode: ``info["step_summary"]`` every step, the
    episode's raw metrics at its end; ``dt_s`` seconds per step; ``max_episode_steps`` its limit."""

    env: Any
    dt_s: float
    max_episode_steps: int


@dataclass(frozen=True)
class HeldOutCadence:
    """When evaluation-driven training evaluates by default (``--select-every`` not given).

    Attributes:
        every_steps: env steps between held-out evaluations, at least (1: after any training iteration).
        max_share: and only once the training since the last one took at least ``(1 - max_share) /
            max_share`` times its cost (so by default they cost at most ~10% of a run, whatever the device);
            None: at every ``every_steps`` env steps alone, so two runs of one seed look at the same steps
            and keep the same checkpoint whatever the machine's speed.
    """

    every_steps: int = 25_000
    max_share: float | None = 0.10


@dataclass(frozen=True)
class RunSize:
    """A training request's size: ``num_envs`` (0: the task's catalog default) and ``max_steps``
    (environment steps); ``task_id`` where the size is meant for one task."""

    num_envs: int
    max_steps: int
    task_id: str | None = None

    def filled(self, num_envs: int | None, max_steps: int | None) -> RunSize:
        """A request's size: what it gives, this size for what it leaves out (None; ``num_envs`` 0 is
        the task's catalog default and stays 0). The one run-size rule of every command."""
        return RunSize(self.num_envs if num_envs is None else int(num_envs),
                       self.max_steps if max_steps is None else int(max_steps), self.task_id)
