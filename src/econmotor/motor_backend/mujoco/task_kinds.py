"""The two kinds of task the mujoco backend trains, declared in one place (:func:`task_kind`).

A Gymnasium courier (``tasks/mujoco.yaml``) trains with SB3 from scratch (:mod:`.courier_tasks`); a card
robot's walker task (the G1, T1: a task with a ``locomotion`` block) trains with the torch
walker PPO on the env that prices it, from scratch or from a policy trained elsewhere, and is priced
there (:mod:`.walker_backend`). What differs between them is a :class:`TaskKind`; the backend asks a
task's kind and never tests which it is.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from econmotor.locomotion.task import is_walker_task, walker_settings
from econmotor.motor_backend.mujoco.courier_tasks import evaluate_courier, train_courier
from econmotor.motor_backend.mujoco.run import HELD_OUT_BATCH
from econmotor.motor_backend.mujoco.settings import parse_mujoco_settings
from econmotor.motor_backend.mujoco.walker_backend import (
    evaluate_walker_task,
    train_walker_task,
    walker_train_settings,
)
from econmotor.motor_backend.results import MotorEvalResult, MotorTrainingResult
from econmotor.robots.gym_couriers import robot_name
from econmotor.tasks.catalog import TaskSpec


@dataclass(frozen=True)
class TaskKind:
    """What differs between the two kinds of task this backend trains, declared once (:func:`task_kind`):
    how a run trains and is evaluated, the evaluation's batch, the robot's id, the catalog entry's check,
    whether a run may start from a policy trained elsewhere (``--init-policy``, ``--max-minutes``), the file
    a finished run holds, and whether its ONNX is exported on demand (an SB3 run) or only by training."""

    name: str
    train: Callable[..., MotorTrainingResult]  # (backend, spec, **train_policy's arguments)
    evaluate: Callable[..., MotorEvalResult]  # (backend, policy_id, spec, **evaluate_policy's arguments)
    evaluation_batch: Callable[[Any], int]
    robot_id: Callable[[TaskSpec], str]
    check_entry: Callable[[TaskSpec], Any]
    starts_from_policies: bool
    final_policy_file: str
    exports_on_demand: bool


#: a Gymnasium courier (``tasks/mujoco.yaml``): SB3 PPO or SAC on its metered env, from scratch
COURIER = TaskKind("courier", train_courier, evaluate_courier,
                   lambda backend: HELD_OUT_BATCH, lambda spec: robot_name(parse_mujoco_settings(spec).env_id),
                   parse_mujoco_settings, starts_from_policies=False, final_policy_file="policy.zip",
                   exports_on_demand=True)
#: a card robot's walker task (the G1, T1): the torch walker PPO on the env that prices it, priced there
WALKER = TaskKind("walker", train_walker_task, evaluate_walker_task,
                  lambda backend: 10 * backend.eval_workers, lambda spec: str(walker_settings(spec)["robot"]),
                  lambda spec: (walker_train_settings(spec), walker_settings(spec)), starts_from_policies=True,
                  final_policy_file="policy.onnx", exports_on_demand=False)


def task_kind(spec: TaskSpec) -> TaskKind:
    """The one place a task's kind is declared: a task with a ``locomotion`` block is a card robot's walker
    task (``mujoco/walker_backend.py``; :func:`econmotor.locomotion.task.is_walker_task`), any other a
    Gymnasium courier."""
    return WALKER if is_walker_task(spec) else COURIER


def run_kind(config: Mapping[str, Any]) -> TaskKind:
    """The kind of task a run directory's recorded config (``run_config.json``) was trained for: its
    ``trainer`` (a walker run records ``"walker"``)."""
    return WALKER if config.get("trainer") == WALKER.name else COURIER
