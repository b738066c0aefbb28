"""The mujoco backend's Gymnasium couriers (``tasks/mujoco.yaml``): an SB3 run and its evaluation.

A courier trains with Stable-Baselines3 PPO or SAC on its metered Gymnasium env (``mujoco/run.py``:
:class:`~econmotor.motor_backend.mujoco.run.TrainingRun`), from scratch, and is evaluated on deterministic
episodes of the same env at the datapacks' full difficulty. ``backend`` is the
:class:`~econmotor.motor_backend.mujoco.backend.MujocoBackend` asked (its recipe, run directories and
evaluation after training); :mod:`.task_kinds` declares which tasks these are.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import torch

from econmotor.config.datapacks import DatapackConfig
from econmotor.errors import ConfigError
from econmotor.motor_backend.base import ProgressFn, StopFn
from econmotor.motor_backend.mujoco.env_factory import make_env
from econmotor.motor_backend.mujoco.evaluation import load_policy, rollout_episodes
from econmotor.motor_backend.mujoco.run import TrainingRun
from econmotor.motor_backend.results import (
    EvalProvenance,
    MotorEvalResult,
    MotorTrainingResult,
    aggregate_raw,
    evaluation_result,
    mean_power_w,
)
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE
from econmotor.motor_backend.selection import selection_for
from econmotor.motor_backend.training_loop import CURVE_FILE
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.tasks.catalog import TaskSpec


def train_courier(backend: Any, spec: TaskSpec, *, objective: EconomicObjectiveSpec, datapack_ids: Sequence[str],
                   datapack_configs: list[DatapackConfig], num_envs: int, max_steps: int, seed: int,
                   output_dir: str | Path | None, eval_episodes: int, progress: ProgressFn, resume: bool,
                   algorithm: str | None, hyperparameters: dict[str, Any] | None,
                   checkpoint_every_steps: int | None, select_every_steps: int | None,
                   select_episodes: int | None, until_deployable: bool, **_: Any) -> MotorTrainingResult:
    """A Gymnasium courier's SB3 run, its evaluation after training and its result."""
    task_id = spec.task_id
    recipe, described = backend.recipe(task_id, objective, datapack_ids, datapack_configs)
    settings = recipe.settings
    if output_dir is None and resume:
        raise ConfigError("<train>", "output_dir", "resume needs the run directory to continue")
    run = TrainingRun(
        run_dir=backend.run_dir(output_dir, task_id, seed), recipe=recipe,
        described={"backend": backend.name, **described},
        algorithm=algorithm or settings.algorithm, hyperparameters=hyperparameters,
        num_envs=num_envs if num_envs > 0 else settings.num_envs, max_steps=int(max_steps), seed=int(seed),
        vec_env=backend.vec_env, checkpoint_every_steps=checkpoint_every_steps or settings.checkpoint_every_steps,
        requested_algorithm=algorithm, eval_recipe=backend.eval_recipe(recipe), onnx_metadata=backend.onnx_metadata,
        selection=selection_for(spec, objective, select_every_steps, select_episodes,
                                until_deployable, seed, backend.held_out_cadence, backend.evaluation_batch(task_id)),
    )
    curve = run.train(resume=resume, progress=progress)
    artifacts = {"policy": str(run.run_dir / "policy.zip"), "tensorboard": str(run.run_dir / "tb"),
                 "run_config": str(run.run_dir / RUN_CONFIG_FILE), "onnx": str(run.onnx),
                 "curve": str(run.run_dir / CURVE_FILE)}
    evaluation = backend.evaluate_after_training(run.run_dir, task_id, objective, eval_episodes, seed,
                                                 datapack_configs=datapack_configs, progress=progress,
                                                 datapack_ids=datapack_ids)
    return backend.training_result(run.run_dir, task_id, evaluation, curve, run.config, artifacts)


def evaluate_courier(backend: Any, policy_id: str, spec: TaskSpec, *, objective: EconomicObjectiveSpec,
                     num_episodes: int, seed: int, config: Mapping[str, Any],
                     datapack_configs: list[DatapackConfig], output_dir: str | Path | None,
                     progress: ProgressFn, datapack_ids: Sequence[str], stop: StopFn | None) -> MotorEvalResult:
    """A courier's SB3 policy on deterministic episodes of its metered Gymnasium env."""
    task_id = spec.task_id
    torch.set_num_threads(backend.torch_threads)
    recipe, described = backend.recipe(task_id, objective, datapack_ids, datapack_configs)
    _, act = load_policy(policy_id, config["algorithm"])
    env = make_env(backend.eval_recipe(recipe), seed=seed)
    raw_eps = rollout_episodes(env, act, num_episodes, seed, progress, stop=stop,
                               batch=backend.evaluation_batch(task_id))
    env.close()
    eval_config = {**described, "policy_id": str(policy_id), "num_episodes": num_episodes, "seed": seed,
                   "algorithm": config["algorithm"], "deterministic": True}
    provenance = EvalProvenance(
        evaluator="mujoco", figures_from=f"Gymnasium MuJoCo {recipe.settings.env_id} (the run's "
        f"{config['algorithm']} policy, deterministic, metered as in training)",
        mean_power_w=mean_power_w(aggregate_raw(raw_eps)))
    return evaluation_result(backend.name, policy_id, task_id, raw_eps, spec.economics,
                             eval_config, output_dir, provenance)
