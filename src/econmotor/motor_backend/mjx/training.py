"""MjxTrainingRun: one JAX PPO run in a run directory, fresh or resumed; and batched evaluation.

Run directory (``policy_id``), as the mujoco backend's::

    run_config.json                     # task, objective, datapacks, hyperparameters, seed, device, num_envs
    checkpoints/ckpt_<N>_steps.npz      # every checkpoint_every_steps and at the end (checkpoint.py)
    tb/                                 # TensorBoard: rollout/, train/, overlay/<key>_raw|_weighted, econ/<key>
    policy.npz                          # the run's learner (params, optimizer state, normaliser): the kept
                                        #   held-out checkpoint of evaluation-driven training (selection.py)
    best/policy.npz                     # the best held-out learner so far (while training)
    policy.onnx                         # the deployed actor (export.py)

The host loop calls the one jitted iteration (``ppo.make_train_iteration``) until ``max_steps``
env steps (rounded up to whole iterations of ``num_envs * unroll_length``), reporting progress,
writing TensorBoard scalars of the episodes that ended, the training curve and checkpoints.

A run may start from a given learner (``initial``: an actor imported from a walker that exists,
``onnx_import.py``) instead of a fresh one. Its first ``cfg.critic_warmup_iterations`` iterations
train the critic only (``actor_weight`` 0); after the last of them Adam's state is started afresh,
so the actor's first updates have Adam's usual bias correction, not moments stale from zeros.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import numpy as np

from econmotor.errors import BackendError
from econmotor.motor_backend import run_dir as run_dirs
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.mjx import checkpoint as ckpt
from econmotor.motor_backend.mjx import ppo
from econmotor.motor_backend.mjx.compile import CacheWatch
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE, check_resume_request
from econmotor.motor_backend.selection import Selection

POLICY_FILE = "policy.npz"
BEST_DIR = "best"


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

    def _consider(self, learner: ppo.Learner, key: Any, steps: int, writer: Any) -> None:
        """One held-out evaluation of ``learner``; saved to ``best/`` when the best so far; TensorBoard."""
        result, better = self.selection.consider(
            steps, lambda n, seed, stop: self.held_out(learner, n, seed, stop))
        if better:
            ckpt.save_tree(self.run_dir / BEST_DIR / POLICY_FILE, learner, key, steps)
        self.config = {**self.config, "selection": self.selection.record()}
        run_dirs.write_run_config(self.run_dir, self.config, "mjx")
        for name, value in result.scalars().items():
            writer.add_scalar(name, value, steps)

    def _check_resume_request(self, previous: dict[str, Any]) -> None:
        """As the mujoco backend: a resumed run keeps its recorded hyperparameters; asking for others fails."""
        check_resume_request(self.run_dir, previous, self.described["task_id"], self.requested_hyperparameters)

    def _start(self, resume: bool) -> tuple[ppo.Learner | None, Any, int]:
        """The run's starting point (``(learner, key, env steps)``: a resumed run's newest checkpoint, else the
        initial learner) and its ``run_config.json``."""
        self.run_dir.mkdir(parents=True, exist_ok=True)
        found = None
        if resume:
            previous = read_run_config(self.run_dir)
            self._check_resume_request(previous)
            self.cfg = ppo.PPOConfig.from_mapping(previous["hyperparameters"], str(self.run_dir / RUN_CONFIG_FILE))
            found = ckpt.latest_checkpoint(self.run_dir)
            if self.selection is not None and (self.run_dir / BEST_DIR / POLICY_FILE).is_file():
                self.selection.restore(previous.get("selection"))
        env, cfg = self.env, self.cfg
        template = ppo.init_learner(jax.random.PRNGKey(self.seed), env.observation_size, env.action_size, cfg)
        learner, key, steps = self.initial, None, 0
        if found:
            learner, key, steps, _ = ckpt.load_tree(found[0], template)
        obs_layout, action_layout = env_layout(env, cfg.normalize_obs)
        self.config = {
            **self.described, "backend": "mjx", "algorithm": "ppo", "hyperparameters": cfg.to_dict(),
            "num_envs": self.num_envs, "max_steps": self.max_steps, "seed": self.seed,
            "checkpoint_every_steps": self.checkpoint_every_steps, "obs_layout": obs_layout,
            "action_layout": action_layout, "resumed_from_steps": steps, **self.extra_config,
        }
        if self.selection is not None and self.selection.history:
            self.config["selection"] = self.selection.record()  # a resumed run's selection so far
        run_dirs.write_run_config(self.run_dir, self.config, "mjx")

        return learner, key, steps

    def _finish(self, state: Any, steps: int, started: float, watch: CacheWatch, first_done: float | None,
                t_loop: float, per_iteration: int) -> tuple[ppo.Learner, dict[str, Any]]:
        """The last checkpoint, the selection's record, ``policy.npz`` (the kept learner) and the run's timing."""
        if first_done is not None:
            ckpt.save_tree(ckpt.checkpoint_path(self.run_dir, steps), state.learner, state.key, steps)
        learner = state.learner
        if self.selection is not None:  # the record first: policy.npz marks a complete run
            self.config = {**self.config, "trained_steps": steps, "selection": self.selection.record()}
            run_dirs.write_run_config(self.run_dir, self.config, "mjx")
        if self.selection is not None and self.selection.best is not None:
            best = self.run_dir / BEST_DIR / POLICY_FILE
            learner, _, _, _ = ckpt.load_tree(best, state.learner)
            ckpt.save_tree(self.run_dir / POLICY_FILE, learner, state.key, steps)
        else:
            ckpt.save_tree(self.run_dir / POLICY_FILE, state.learner, state.key, steps)
        trained = steps - int(self.config["resumed_from_steps"])
        loop_s = time.perf_counter() - t_loop
        timing = {"total_steps": steps, "first_iteration_s": first_done or 0.0, "train_wall_s":
                  time.perf_counter() - started, "compile_cache_hits": watch.hits,
                  "compile_s_saved": round(watch.saved_s, 3),
                  "env_steps_per_s_after_compile": (trained - per_iteration) / loop_s
                  if trained > per_iteration and loop_s > 0 else None}
        return learner, timing

    def train(self, resume: bool = False, progress: ProgressFn = no_progress
              ) -> tuple[ppo.Learner, list[dict[str, float]], dict[str, Any]]:
        """Train to ``max_steps``; returns (learner, training curve, timing)."""
        started = time.perf_counter()
        watch = CacheWatch()
        learner, key, steps = self._start(resume)
        env, cfg = self.env, self.cfg
        state = ppo.init_train_state(env, cfg, self.num_envs, self.seed, learner=learner, key=key)
        iteration = ppo.make_train_iteration(env, cfg, self.num_envs)
        per_iteration = self.num_envs * cfg.unroll_length
        writer, curve = ScalarWriter(self.run_dir / "tb" / "run"), []
        every_curve = max(per_iteration, self.max_steps // 50)
        next_curve = (steps // every_curve + 1) * every_curve
        next_ckpt = (steps // self.checkpoint_every_steps + 1) * self.checkpoint_every_steps
        window: list[tuple[float, float, float]] = []  # (return sum, length sum, count) of recent iterations
        report = lambda done: progress(f"train · {self.selection.status()}" if self.selection is not None
                                       and self.selection.status() else "train", min(done, self.max_steps),
                                       self.max_steps)
        report(steps)
        if self.selection is not None:
            self.selection.started = started
        last_held_out = steps
        first_done, t_loop = None, time.perf_counter()
        warmup_steps = cfg.critic_warmup_iterations * per_iteration
        try:
            while steps < self.max_steps and not (self.selection is not None and self.selection.should_stop):
                warming = steps < warmup_steps
                state, metrics = iteration(state, 0.0 if warming else 1.0)
                metrics = jax.device_get(metrics)
                steps += per_iteration
                if warming and steps >= warmup_steps:  # the actor moves from now on, with a fresh Adam
                    state = with_fresh_optimizer(state, cfg)
                if first_done is None:  # the first iteration includes XLA compilation
                    first_done, t_loop = time.perf_counter() - started, time.perf_counter()
                    if watch.hits:
                        progress(f"mjx: compilation cache warm: {watch.hits} compiled program(s) loaded from "
                                 f"{self.cache_dir or 'the cache'} (about {watch.saved_s:.0f} s of XLA compilation "
                                 f"saved); first iteration {first_done:.1f} s", 1.0, 1.0)
                log_scalars(writer, metrics, env.factors, steps)
                window = [*window[-9:], (float(metrics["sum/return"]), float(metrics["sum/length_steps"]),
                                         float(metrics["episodes"]))]
                if steps >= next_curve or steps >= self.max_steps:
                    next_curve = (steps // every_curve + 1) * every_curve
                    count = sum(w[2] for w in window)
                    if count > 0:
                        curve.append({"timesteps": float(steps), "mean_return": sum(w[0] for w in window) / count,
                                      "mean_length": sum(w[1] for w in window) / count})
                if steps >= next_ckpt:
                    next_ckpt = (steps // self.checkpoint_every_steps + 1) * self.checkpoint_every_steps
                    ckpt.save_tree(ckpt.checkpoint_path(self.run_dir, steps), state.learner, state.key, steps)
                if self.selection is not None and self.selection.due(steps, last_held_out):
                    last_held_out = steps
                    self._consider(state.learner, state.key, steps, writer)
                report(steps)
            if self.selection is not None and first_done is not None and self.selection.final_due(steps, last_held_out):
                self._consider(state.learner, state.key, steps, writer)  # the last weights are a candidate too
        finally:
            writer.close()
        learner, timing = self._finish(state, steps, started, watch, first_done, t_loop, per_iteration)
        return learner, curve, timing
