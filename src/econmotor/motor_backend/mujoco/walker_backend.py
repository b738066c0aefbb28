"""The mujoco backend's walker tasks: the card robots (G1, T1) trained and priced on the CPU.

A task with a ``locomotion`` block (``tasks/holosoma.yaml``) is a walker task: its robot, course, meter and
locomotion reward terms are that block (the one place per robot task,
:func:`econmotor.locomotion.task.walker_settings`), and its ``backends.mujoco.walker`` mapping holds the
trainer's recipe (each key optional):

- ``econ_gain``: the objective's J against the locomotion terms (reward units per unit of J: the learner
  is paid ``econ_gain`` times each step's increment of the J selection and the report score,
  :func:`econmotor.objectives.loader.running_objective_j`);
- ``ppo``: the recipe (:class:`~econmotor.motor_backend.mujoco.walker_ppo.WalkerPPOConfig`), under the
  run's ``--hyperparameters``;
- ``checkpoint_every_s``: wall seconds between checkpoints.

:func:`train_walker` runs :class:`~econmotor.motor_backend.mujoco.walker_training.WalkerTrainingRun`;
evaluation is :func:`econmotor.motor_backend.walker_pricing.price_walker` on the run's ``policy.onnx``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.config.datapacks import DatapackConfig, DatapackProvider
from econmotor.config.loading import as_float
from econmotor.couriers.onnx_actor import policy_file, read_actor
from econmotor.errors import ConfigError
from econmotor.locomotion.conditions import walker_setup
from econmotor.locomotion.task import reward_terms, walker_settings
from econmotor.motor_backend.base import ProgressFn, StopFn
from econmotor.motor_backend.capabilities import HeldOutCadence
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
from econmotor.motor_backend.mujoco.walker_training import ONNX_FILE, TRAIN_SEED_BASE, WalkerTrainingRun
from econmotor.motor_backend.results import MotorEvalResult, MotorTrainingResult
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE, read_run_config
from econmotor.motor_backend.selection import (
    DEFAULT_SELECT_EPISODES,
    SELECTION_SEED_OFFSET,
    Selection,
    selection_for,
)
from econmotor.motor_backend.training_loop import CURVE_FILE
from econmotor.motor_backend.walker_pricing import WalkerPricing, price_walker
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.objectives.loader import objective_weights_vector
from econmotor.tasks.catalog import TaskSpec

WALKER_KEYS = ("econ_gain", "ppo", "checkpoint_every_s")


@dataclass(frozen=True)
class WalkerTrainSettings:
    """A walker task's trainer settings (module docstring)."""

    econ_gain: float
    weights: dict[str, float]
    params: dict[str, dict[str, Any]]
    ppo: dict[str, Any]
    checkpoint_every_s: float = 300.0


def walker_train_settings(spec: Any) -> WalkerTrainSettings:
    """The task's ``backends.mujoco.walker`` settings; a ConfigError names the file and key."""
    where = f"tasks.{spec.task_id}.backends.mujoco.walker"
    entry = dict(spec.backends.get("mujoco") or {}).get("walker") or {}
    if not isinstance(entry, Mapping):
        raise ConfigError(spec.source, where, "must be a mapping", WALKER_KEYS)
    unknown = [k for k in entry if k not in WALKER_KEYS]
    if unknown:
        raise ConfigError(spec.source, f"{where}.{unknown[0]}", "unknown key", WALKER_KEYS)
    gain = as_float(entry.get("econ_gain", 1.0), spec.source, f"{where}.econ_gain")
    if not gain >= 0:
        raise ConfigError(spec.source, f"{where}.econ_gain", f"must be >= 0, got {gain}")
    weights, params = reward_terms(spec)  # the task's one set (its locomotion block), as the mjx couriers'
    ppo = dict(entry.get("ppo") or {})
    WalkerPPOConfig.from_mapping(ppo, f"{spec.source}: {where}.ppo")
    every = as_float(entry.get("checkpoint_every_s", 300.0), spec.source, f"{where}.checkpoint_every_s")
    return WalkerTrainSettings(gain, weights, params, ppo, every)


def train_walker(spec: Any, objective: EconomicObjectiveSpec, packs: Sequence[Any], run_dir: Path, *,
                 num_envs: int, max_steps: int, seed: int, init_policy: str | None,
                 hyperparameters: Mapping[str, Any] | None, selection: Selection | None, resume: bool,
                 max_wall_s: float | None, progress: Any, described: Mapping[str, Any]
                 ) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Train a walker (module docstring) into ``run_dir``; the run's config (``run_config.json``'s content)
    and its training curve."""
    run, config = walker_run(spec, objective, packs, run_dir, num_envs=num_envs, max_steps=max_steps, seed=seed,
                             init_policy=init_policy, hyperparameters=hyperparameters, selection=selection,
                             resume=resume, max_wall_s=max_wall_s, described=described)
    outcome = run.train(resume=resume, progress=progress, config=config, requested_hyperparameters=hyperparameters)
    return outcome.config, outcome.curve


def walker_run(spec: Any, objective: EconomicObjectiveSpec, packs: Sequence[Any], run_dir: Path, *,
               num_envs: int, max_steps: int, seed: int, init_policy: str | None,
               hyperparameters: Mapping[str, Any] | None, selection: Selection | None, resume: bool,
               max_wall_s: float | None, described: Mapping[str, Any]) -> tuple[WalkerTrainingRun, dict[str, Any]]:
    """The training run :func:`train_walker` runs, and its description for ``run_config.json``: held-out
    episodes alternate the nominal conditions a report prices by default and, under datapacks, the training's
    stress (``select_stresses``, recorded as ``selection_conditions``)."""
    trainer = walker_train_settings(spec)
    settings = walker_settings(spec)
    bundle = DatapackProvider().resolve(spec.task_id, [p.id for p in packs], list(packs))
    init = read_actor(policy_file(init_policy), init_policy) if init_policy else None
    setup = walker_setup(spec, settings, bundle, list(packs), str(init.path) if init else None,
                         init_policy, refuse_unapplied=True)
    ppo = {**trainer.ppo, **dict(hyperparameters or {})}
    if num_envs > 0:
        ppo["num_envs"] = num_envs
    workers = None  # one collecting process per usable core (walker_training.WalkerTrainingRun)
    if resume:  # a resumed run keeps its recorded recipe (the loop refuses a request for another) and workers
        recorded = read_run_config(run_dir, "mujoco")
        ppo, workers = dict(recorded["hyperparameters"]), recorded.get("collect_workers")
    cfg = WalkerPPOConfig.from_mapping(ppo, "--hyperparameters")
    c = setup.contract
    config = {
        **described, "backend": "mujoco", "trainer": "walker", "task_id": spec.task_id, "robot": setup.card.name,
        "algorithm": "ppo", "seed": int(seed), "max_steps": int(max_steps), "max_wall_s": max_wall_s,
        "hyperparameters": cfg.to_dict(), "objective": objective.to_dict(),
        "objective_weights": objective_weights_vector(objective), "econ_gain": trainer.econ_gain,
        "locomotion_rewards": {k: {"weight": w, **trainer.params.get(k, {})} for k, w in trainer.weights.items()},
        "course": asdict(setup.course), "meter": asdict(setup.meter), "episode_s": setup.episode_s,
        "stress": asdict(setup.stress),
        # the conditions held-out episode i runs under, [i % len] (select_stresses below): the datapacks act as one
        "selection_conditions": ["nominal", "+".join(setup.datapack_ids)] if packs else ["nominal"],
        "datapack_ids": list(setup.datapack_ids), "notes": list(setup.notes),
        "init_policy": {**init.describe(), "critic_warmup_iterations": cfg.critic_warmup_iterations}
        if init else None,
        "economics": {r["name"]: r["value"] for r in spec.economics.parameters()},
        "seeds": {"training_from": TRAIN_SEED_BASE + int(seed) * 1_000_000,
                  "selection_from": int(seed) + SELECTION_SEED_OFFSET},
        "onnx": str(run_dir / ONNX_FILE)}
    run = WalkerTrainingRun(
        run_dir=run_dir, setup=setup, cfg=cfg, objective=objective, economics=spec.economics,
        gain=trainer.econ_gain, weights=trainer.weights,
        params=trainer.params, seed=int(seed), max_steps=int(max_steps), init=init,
        max_wall_s=float(max_wall_s) if max_wall_s else math.inf, checkpoint_every_s=trainer.checkpoint_every_s,
        selection=selection, metadata=_onnx_metadata(config),
        kp=np.asarray(c.kp) if c else None, kd=np.asarray(c.kd) if c else None,
        command_ranges=c.command_ranges if c else None,
        select_stresses=(setup.nominal_stress, setup.stress) if packs else (setup.nominal_stress,),
        collect_workers=workers)
    config["collect_workers"] = run.collect_workers  # a seed's rollouts depend on how the robots are split
    return run, config


def _onnx_metadata(config: Mapping[str, Any]) -> dict[str, Any]:
    keys = ("task_id", "objective", "objective_weights", "econ_gain", "datapack_ids", "economics", "algorithm",
            "seed", "robot", "trainer")
    out = {k: config.get(k) for k in keys}
    if config.get("init_policy"):
        out["init_policy"] = {k: config["init_policy"][k] for k in ("policy", "sha256")}
    return out


#: held-out selection of a walker run: every 500k env steps, whatever the wall time (a run's looks, and so the
#: checkpoint it keeps, depend on its seed only)
WALKER_CADENCE = HeldOutCadence(every_steps=500_000, max_share=None)
#: a held-out evaluation must be able to see falls, which the acceptance rule judges per leg (falls / (legs +
#: falls)): its first look (and each look after it) runs at least this many legs, before the sequential plan is asked
MIN_SELECT_LEGS = 100
#: a held-out evaluation's first look, and the episodes between looks: ceil(MIN_SELECT_LEGS / 3) = 34 episodes of
#: the G1's and T1's nominal 3-leg course (tasks/holosoma.yaml: sim2sim_legs; 34 x 3 = 102 legs, about 200k env
#: steps of the G1's course); tests/integration/test_walker_one_pricer.py holds it to every walker task's course
WALKER_SELECT_BATCH = 34
#: a walker's held-out evaluation, at most this many episodes by default (``--select-episodes`` overrides; at
#: least one look): the shared cap, 160 episodes (480 legs: 0 falls in them pass the G1's 1% fall limit at the
#: plan's look confidence)
WALKER_SELECT_EPISODES = DEFAULT_SELECT_EPISODES


def train_walker_task(backend: Any, spec: TaskSpec, *, objective: EconomicObjectiveSpec,
                      datapack_configs: list[DatapackConfig], num_envs: int, max_steps: int, seed: int,
                      output_dir: str | Path | None, eval_episodes: int, progress: ProgressFn, resume: bool,
                      hyperparameters: dict[str, Any] | None, select_every_steps: int | None,
                      select_episodes: int | None, until_deployable: bool, init_policy: str | None,
                      max_wall_s: float | None, **_: Any) -> MotorTrainingResult:
    """A walker task's run (``mujoco/walker_backend.py``), its post-training evaluation and result."""
    packs = datapack_configs
    if output_dir is None and resume:
        raise ConfigError("<train>", "output_dir", "resume needs the run directory to continue")
    run_dir = backend.run_dir(output_dir, spec.task_id, seed)
    if resume:
        init_policy = (read_run_config(run_dir).get("init_policy") or {}).get("policy")
    selection = selection_for(spec, objective, select_every_steps, select_episodes or WALKER_SELECT_EPISODES,
                              until_deployable, seed, WALKER_CADENCE, WALKER_SELECT_BATCH)
    config, curve = train_walker(spec, objective, packs, run_dir, num_envs=num_envs, max_steps=max_steps,
                                 seed=seed, init_policy=init_policy, hyperparameters=hyperparameters,
                                 selection=selection, resume=resume, max_wall_s=max_wall_s, progress=progress,
                                 described={"datapacks": [p.to_dict() for p in packs]})
    evaluation = backend.evaluate_after_training(run_dir, spec.task_id, objective, eval_episodes, seed,
                                                 datapack_configs=packs, progress=progress)
    artifacts = {"policy": str(run_dir), "onnx": str(run_dir / ONNX_FILE), "run_config": str(run_dir /
                                                                                          RUN_CONFIG_FILE),
                 "curve": str(run_dir / CURVE_FILE), "checkpoint": str(run_dir / "checkpoints" / "latest.pt")}
    return backend.training_result(run_dir, spec.task_id, evaluation, curve, config, artifacts)


def evaluate_walker_task(backend: Any, policy_id: str, spec: TaskSpec, *, num_episodes: int, seed: int,
                         datapack_configs: list[DatapackConfig], output_dir: str | Path | None,
                         progress: ProgressFn, stop: StopFn | None, **_: Any) -> MotorEvalResult:
    """A walker run's ``policy.onnx`` priced sim-to-sim on the env it learned on (the one pricer)."""
    return price_walker(WalkerPricing(
        backend=backend.name, spec=spec, settings=walker_settings(spec), packs=datapack_configs,
        policy=str(Path(policy_id).resolve() / ONNX_FILE), policy_id=str(policy_id), imported=False,
        workers=backend.eval_workers, batch=backend.evaluation_batch(spec.task_id), label="mujoco"),
        num_episodes, seed, backend.run_dir(output_dir, spec.task_id, seed).resolve(), progress, stop)
