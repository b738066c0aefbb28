"""MjxTrainingRun: one JAX PPO run in a run directory, fresh or resumed; and batched evaluation.

Run directory (``policy_id``), as the mujoco backend's::

    run_config.json                     # task, objective, datapacks, hyperparameters, seed, device, num_envs
    checkpoints/ckpt_<N>_steps.npz      # every checkpoint_every_steps and at the end (checkpoint.py)
    tb/                                 # TensorBoard: rollout/, train/, overlay/<key>_raw|_weighted, econ/<key>
    policy.npz                          # the run's learner (params, optimizer state, normaliser): the kept
                                        #   held-out checkpoint of evaluation-driven training (selection.py)
    best/policy.npz                     # the best held-out learner so far (while training)
    policy.onnx                         # the deployed actor (export.py)

The run around the learner is the shared :class:`~econmotor.motor_backend.training_loop.TrainingLoop`
(``run_config.json``, ``curve.jsonl``, checkpoints, held-out selection, the kept policy, timing);
:class:`MjxLearner` supplies its chunks: the one jitted iteration (``ppo.make_train_iteration``) of
``num_envs * unroll_length`` env steps, with TensorBoard scalars of the episodes that ended. Its held-out
evaluations run beside training (:meth:`MjxLearner.snapshot`): a jitted iteration keeps about one core
busy, and the evaluation's compiled rollout takes the other, so on two cores they cost training little.

A run may start from a given learner (``initial``: an actor imported from a walker that exists,
``onnx_import.py``) instead of a fresh one. Its first ``cfg.critic_warmup_iterations`` iterations
train the critic only (``actor_weight`` 0); after the last of them Adam's state is started afresh,
so the actor's first updates have Adam's usual bias correction, not moments stale from zeros.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from econmotor.errors import BackendError
from econmotor.motor_backend import run_dir as run_dirs
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.beside_training import PolicySnapshot
from econmotor.motor_backend.mjx import checkpoint as ckpt
from econmotor.motor_backend.mjx import ppo
from econmotor.motor_backend.mjx.compile import CacheWatch, CompiledAhead
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE
from econmotor.motor_backend.selection import Selection
from econmotor.motor_backend.training_loop import Learner as LoopLearner
from econmotor.motor_backend.training_loop import StopFn, TrainingLoop

POLICY_FILE = "policy.npz"


def read_run_config(run_dir: str | Path, task_id: str | None = None) -> dict[str, Any]:
    """The ``run_config.json`` of an mjx run directory (the recorded backend must be ``mjx``)."""
    return run_dirs.read_run_config(run_dir, "mjx", task_id)


def load_learner(run_dir: str | Path, config: dict[str, Any], cfg: ppo.PPOConfig) -> ppo.Learner:
    """The final learner of a run (``policy.npz``; sizes from the run config's layouts)."""
    path = Path(run_dir) / POLICY_FILE
    if not path.is_file():
        raise BackendError(f"no trained policy in {run_dir} (no {POLICY_FILE}): training did not finish; "
                           "continue it with `econmotor train --motor-backend mjx --resume --output-dir <run dir>`")
    template = ppo.init_learner(jax.random.PRNGKey(0), int(config["obs_layout"]["obs_dim"]),
                                int(config["action_layout"]["action_dim"]), cfg)
    learner, _, _, _ = ckpt.load_tree(path, template)
    return learner


def env_layout(env: Any, normalized: bool) -> tuple[dict[str, Any], dict[str, Any]]:
    """Observation and action layout of the env, for the ONNX metadata (as the mujoco backend's)."""
    import mujoco

    model = env.mj_model
    obs = {"obs_dim": int(env.observation_size), "dtype": "float32", "normalized_in_graph": bool(normalized),
           "joints": [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)],
           "note": getattr(env, "obs_layout_note",
                           "Gymnasium v5 observation of the env id (the mujoco backend's layout)")}
    action = {"action_dim": int(env.action_size), "low": np.asarray(env.action_low).tolist(),
              "high": np.asarray(env.action_high).tolist(),
              "actuators": [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(model.nu)]}
    return obs, action


def evaluate_episodes(evaluate: Any, batch: int, env: Any, learner: ppo.Learner, num_episodes: int, seed: int,
                      progress: ProgressFn = no_progress, label: str = "evaluate",
                      stop: Callable[[list[dict[str, Any]]], bool] | None = None) -> list[dict[str, Any]]:
    """``num_episodes`` deterministic episodes, ``batch`` at a time (batch j keyed by ``seed`` and j).

    ``evaluate`` is ``ppo.make_evaluate(env, cfg, batch)``; one raw-metrics dict per episode.
    ``stop(rows so far)`` after each batch may end the evaluation early (held-out evaluations).
    """
    rows: list[dict[str, Any]] = []
    progress(label, 0, num_episodes)
    for j in range(math.ceil(num_episodes / batch) if num_episodes > 0 else 0):
        key = jax.random.fold_in(jax.random.PRNGKey(seed), j)
        first, seen = jax.device_get(evaluate(learner.params, learner.stats, key))
        keep = np.asarray(seen, bool)
        rows += env.finished_to_dicts({k: np.asarray(v)[keep] for k, v in first.items()})
        progress(label, min(len(rows), num_episodes), num_episodes)
        if stop is not None and len(rows) < num_episodes and stop(rows[:num_episodes]):
            break
    return rows[:num_episodes]


def episode_scalars(metrics: dict[str, Any], factors: dict[str, float]) -> dict[str, float]:
    """TensorBoard scalars of the episodes that ended in one iteration (means over them)."""
    count = float(metrics["episodes"])
    if count <= 0:
        return {}
    out: dict[str, float] = {}
    for name, total in metrics.items():
        if not name.startswith("sum/"):
            continue
        key, mean = name[4:], float(total) / count
        if key == "return":
            out["rollout/ep_rew_mean"] = mean
        elif key == "length_steps":
            out["rollout/ep_len_mean"] = mean
        elif key == "overlay_return":
            out["overlay/return"] = mean
        elif key.startswith("overlay_") and key.endswith("_raw"):
            term = key[len("overlay_"):-len("_raw")]
            out[f"overlay/{term}_raw"] = mean
            out[f"overlay/{term}_weighted"] = factors.get(term, 0.0) * mean
        else:
            out[f"econ/{key}"] = mean
    return out


def with_fresh_optimizer(state: ppo.TrainState, cfg: ppo.PPOConfig) -> ppo.TrainState:
    """``state`` with Adam started afresh on its parameters (the end of a critic warm-up)."""
    return state._replace(learner=state.learner._replace(opt_state=ppo.make_optimizer(cfg).init(state.learner.params)))


def log_scalars(writer: Any, metrics: dict[str, Any], factors: dict[str, float], steps: int) -> None:
    """An iteration's TensorBoard scalars: the ended episodes' economics and the losses."""
    for name, value in episode_scalars(metrics, factors).items():
        writer.add_scalar(name, value, steps)
    for name in ("policy_loss", "value_loss", "entropy", "clip_fraction", "reward_mean"):
        writer.add_scalar(f"train/{name}", float(metrics[name]), steps)


class ScalarWriter:
    """TensorBoard scalars through tensorboard's own event writer (no torch: the JAX backend imports none).

    Args:
        logdir: the folder the ``events.out.tfevents.*`` file goes to (created if missing).
    """

    def __init__(self, logdir: str | Path) -> None:
        from tensorboard.summary.writer.event_file_writer import EventFileWriter

        Path(logdir).mkdir(parents=True, exist_ok=True)
        self._writer = EventFileWriter(str(logdir))

    def add_scalar(self, tag: str, value: float, step: int) -> None:
        """Record ``value`` under ``tag`` at env step ``step``."""
        from tensorboard.compat.proto.event_pb2 import Event
        from tensorboard.compat.proto.summary_pb2 import Summary

        self._writer.add_event(Event(wall_time=time.time(), step=int(step),
                                     summary=Summary(value=[Summary.Value(tag=tag, simple_value=float(value))])))

    def close(self) -> None:
        self._writer.close()


class MjxLearner(LoopLearner):
    """JAX PPO's jitted iterations as the loop's learner (module docstring)."""

    policy_file = POLICY_FILE

    def __init__(self, run: MjxTrainingRun, progress: ProgressFn) -> None:
        self.run, self.progress = run, progress
        self.chunk_steps = run.num_envs * run.cfg.unroll_length
        self.env_steps, self.learner, self.key = 0, run.initial, None
        self.resumed_from = 0
        self.state: Any = None
        self.iteration: Any = None
        self.watch, self.started = CacheWatch(), time.perf_counter()
        self.first_done: float | None = None
        self.t_loop = self.started
        self.window: list[tuple[float, float, float]] = []  # (return sum, length sum, count) of recent iterations
        self.writer = ScalarWriter(run.run_dir / "tb" / "run")

    def _template(self) -> ppo.Learner:
        env, cfg = self.run.env, self.run.cfg
        return ppo.init_learner(jax.random.PRNGKey(self.run.seed), env.observation_size, env.action_size, cfg)

    def _ready(self) -> Any:
        """The train state (built at the first chunk, from the start or the restored checkpoint) and the compiled
        iteration."""
        if self.state is None:
            run = self.run

            def build() -> ppo.TrainState:
                return ppo.init_train_state(run.env, run.cfg, run.num_envs, run.seed, learner=self.learner,
                                            key=self.key)

            # XLA compiles the iteration in a thread while this one resets the envs (a compilation of its own)
            self.iteration = CompiledAhead(ppo.make_train_iteration(run.env, run.cfg, run.num_envs),
                                           jax.eval_shape(build), 1.0, name="econmotor-mjx-iteration")
            self.state = build()
        return self.state

    def learn(self, until_steps: int) -> dict[str, float] | None:
        cfg, warmup_steps = self.run.cfg, self.run.cfg.critic_warmup_iterations * self.chunk_steps
        state = self._ready()
        while True:
            warming = self.env_steps < warmup_steps
            state, metrics = self.iteration(state, 0.0 if warming else 1.0)
            metrics = jax.device_get(metrics)
            self.env_steps += self.chunk_steps
            if warming and self.env_steps >= warmup_steps:  # the actor moves from now on, with a fresh Adam
                state = with_fresh_optimizer(state, cfg)
            if self.first_done is None:
                self._first_iteration_done()
            log_scalars(self.writer, metrics, self.run.env.factors, self.env_steps)
            self.window = [*self.window[-9:], (float(metrics["sum/return"]), float(metrics["sum/length_steps"]),
                                               float(metrics["episodes"]))]
            if self.env_steps >= until_steps:
                break
        self.state = state
        count = sum(w[2] for w in self.window)
        if count <= 0:
            return None
        return {"mean_return": sum(w[0] for w in self.window) / count,
                "mean_length": sum(w[1] for w in self.window) / count}

    def _first_iteration_done(self) -> None:
        """The first iteration includes XLA compilation: timed apart, and a warm cache said."""
        self.first_done, self.t_loop = time.perf_counter() - self.started, time.perf_counter()
        if self.run.after_first_iteration is not None:
            self.run.after_first_iteration()
        watch = self.watch
        if watch.hits:
            self.progress(f"mjx: compilation cache warm: {watch.hits} compiled program(s) loaded from "
                          f"{self.run.cache_dir or 'the cache'} (about {watch.saved_s:.0f} s of XLA compilation "
                          f"saved); first iteration {self.first_done:.1f} s", 1.0, 1.0)

    def evaluate(self, num_episodes: int, first_seed: int, stop: StopFn) -> list[dict[str, Any]]:
        return self.run.held_out(self._ready().learner, num_episodes, first_seed, stop)

    def snapshot(self) -> PolicySnapshot:
        """The current learner copied (the next iteration donates the train state's buffers): its held-out
        evaluation runs in a thread, on the core the jitted iterations leave idle on a CPU."""
        state = self._ready()
        frozen = jax.block_until_ready(jax.tree_util.tree_map(jnp.copy, (state.learner, state.key)))
        return MjxSnapshot(self.run, *frozen, self.env_steps)

    def save_checkpoint(self, run_dir: Path) -> None:
        if self.state is not None:
            ckpt.save_tree(ckpt.checkpoint_path(run_dir, self.env_steps), self.state.learner, self.state.key,
                           self.env_steps)

    def load_checkpoint(self, run_dir: Path) -> int:
        found = ckpt.latest_checkpoint(run_dir)
        if found:
            self.learner, self.key, self.env_steps, _ = ckpt.load_tree(found[0], self._template())
        self.resumed_from = self.env_steps
        return self.env_steps

    def save_policy(self, directory: Path) -> None:
        state = self._ready()
        ckpt.save_tree(directory / POLICY_FILE, state.learner, state.key, self.env_steps)

    def load_policy(self, directory: Path) -> None:
        state = self._ready()
        learner, _, _, _ = ckpt.load_tree(directory / POLICY_FILE, state.learner)
        self.state = state._replace(learner=learner)

    def export(self, run_dir: Path) -> Path | None:
        return self.run.export(run_dir, self._ready().learner) if self.run.export is not None else None

    def log_scalars(self, scalars: Mapping[str, float], env_steps: int) -> None:
        for name, value in scalars.items():
            self.writer.add_scalar(name, value, env_steps)

    def timing(self) -> dict[str, Any]:
        trained = self.env_steps - self.resumed_from
        loop_s = time.perf_counter() - self.t_loop
        return {"first_iteration_s": self.first_done or 0.0, "compile_cache_hits": self.watch.hits,
                "compile_s_saved": round(self.watch.saved_s, 3),
                # False: a state unlike the shapes it was compiled for, so the iteration compiled a second time
                "iteration_compiled_ahead": None if self.iteration is None else not self.iteration.fell_back,
                "env_steps_per_s_after_compile": (trained - self.chunk_steps) / loop_s
                if trained > self.chunk_steps and loop_s > 0 else None}

    def close(self) -> None:
        self.writer.close()


@dataclass(frozen=True)
class MjxSnapshot(PolicySnapshot):
    """A learner at ``env_steps``, evaluated and saved as :class:`MjxLearner` would."""

    run: MjxTrainingRun
    learner: ppo.Learner
    key: jax.Array
    env_steps: int

    def evaluate(self, num_episodes: int, first_seed: int, stop: StopFn) -> list[dict[str, Any]]:
        return self.run.held_out(self.learner, num_episodes, first_seed, stop)

    def save_policy(self, directory: Path) -> None:
        ckpt.save_tree(directory / POLICY_FILE, self.learner, self.key, self.env_steps)


@dataclass
class MjxTrainingRun:
    """One training run (fields are the run's configuration; ``config`` is filled by ``train``)."""

    run_dir: Path
    env: Any
    described: dict[str, Any]
    cfg: ppo.PPOConfig
    requested_hyperparameters: dict[str, Any] | None
    num_envs: int
    max_steps: int
    seed: int
    checkpoint_every_steps: int
    extra_config: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    #: evaluation-driven training (motor_backend/selection.py) and its held-out evaluation:
    #: ``held_out(learner, num_episodes, first_seed, stop) -> raw episodes``
    selection: Selection | None = None
    held_out: Callable[..., list[dict[str, Any]]] | None = None
    #: the learner a fresh run starts from (None: ``ppo.init_learner``); a resumed run starts from its checkpoint
    initial: ppo.Learner | None = None
    #: JAX's persistent compilation cache (said when a run starts warm from it)
    cache_dir: str | None = None
    #: ``export(run_dir, learner) -> policy.onnx`` of the kept learner (None: no export)
    export: Callable[[Path, ppo.Learner], Path] | None = None
    onnx: Path | None = None
    #: called once the first iteration has run (the backend compiles its evaluator then: beside training,
    #: not beside the iteration's own compilation, which uses both cores of a small CPU)
    after_first_iteration: Callable[[], Any] | None = None

    def train(self, resume: bool = False, progress: ProgressFn = no_progress) -> list[dict[str, float]]:
        """Train to ``max_steps`` (the shared loop; the kept learner is ``policy.npz``); the training curve."""
        loop = TrainingLoop(self.run_dir, "mjx", {**self.described}, self.max_steps,
                            checkpoint_every_steps=self.checkpoint_every_steps, selection=self.selection,
                            requested_hyperparameters=self.requested_hyperparameters, progress=progress)
        if resume:
            previous = loop.previous()
            self.cfg = ppo.PPOConfig.from_mapping(previous["hyperparameters"], str(self.run_dir / RUN_CONFIG_FILE))
        obs_layout, action_layout = env_layout(self.env, self.cfg.normalize_obs)
        self.config = loop.config = {
            **self.described, "algorithm": "ppo", "hyperparameters": self.cfg.to_dict(), "num_envs": self.num_envs,
            "seed": self.seed, "checkpoint_every_steps": self.checkpoint_every_steps, "obs_layout": obs_layout,
            "action_layout": action_layout, **self.extra_config}
        outcome = loop.run(MjxLearner(self, progress), resume)
        self.config, self.onnx = outcome.config, outcome.export
        return outcome.curve
