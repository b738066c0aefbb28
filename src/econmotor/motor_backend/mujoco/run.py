"""TrainingRun: one SB3 training run in a run directory, fresh or resumed from a checkpoint.

``train()`` writes ``run_config.json`` first (so an interrupted run can be resumed and
its policy read by any process), trains with progress, curve, checkpoint, curriculum and
TensorBoard callbacks, and saves the final policy atomically. With a :class:`Selection`
(evaluation-driven training, ``motor_backend/selection.py``) the held-out evaluations run in
:class:`HeldOutSelectionCallback`; the best policy so far is saved to ``best/`` and becomes the
run's ``policy.zip`` at the end, and ``run_config.json`` records the selection.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco

from econmotor.errors import ConfigError
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.mujoco.env_factory import EnvRecipe, make_env, make_vec_env
from econmotor.motor_backend.mujoco.evaluation import rollout_batched, torch_act_fn
from econmotor.motor_backend.mujoco.settings import merge_hyperparameters
from econmotor.motor_backend.mujoco.training import (
    CurriculumCallback,
    EconEpisodeLogCallback,
    algorithm_class,
    build_model,
    checkpoint_callback,
    checkpoint_vecnormalize,
    find_checkpoint,
    install_policy,
    load_checkpoint,
    log,
    save_final,
    wrap_normalize,
)
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE, check_resume_request, read_run_config, write_run_config
from econmotor.motor_backend.sb3_callbacks import HeldOutSelectionCallback, ProgressFnCallback, TrainingCurveCallback
from econmotor.motor_backend.selection import Selection

#: envs stepped together in a held-out evaluation (one batched forward pass per step)
HELD_OUT_BATCH = 16
BEST_DIR = "best"


def current_normalizer(model: Any) -> tuple[Any, Any, float, float] | None:
    """``(mean, var, epsilon, clip)`` of the model's VecNormalize now (copies), or None."""
    normed = model.get_vec_normalize_env()
    if normed is None:
        return None
    return normed.obs_rms.mean.copy(), normed.obs_rms.var.copy(), float(normed.epsilon), float(normed.clip_obs)


def env_layout(venv: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """Observation and action layout of the (first) env, for the ONNX metadata."""
    base = venv.envs[0].unwrapped if hasattr(venv, "envs") else None
    obs_dim, act = int(venv.observation_space.shape[0]), venv.action_space
    obs = {"obs_dim": obs_dim, "dtype": "float32", "normalized_in_graph": True}
    action = {"action_dim": int(act.shape[0]), "low": act.low.tolist(), "high": act.high.tolist()}
    if base is not None:
        model = base.model
        obs["joints"] = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
        obs["note"] = "Gymnasium observation of the env id: qpos without the root's horizontal position, then qvel"
        action["actuators"] = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(model.nu)]
    return obs, action


@dataclass
class TrainingRun:
    """One training run (fields are the run's configuration)."""

    run_dir: Path
    recipe: EnvRecipe
    described: dict[str, Any]
    algorithm: str
    hyperparameters: dict[str, Any] | None
    num_envs: int
    max_steps: int
    seed: int
    vec_env: str = "dummy"
    checkpoint_every_steps: int = 20_000
    requested_algorithm: str | None = None
    selection: Selection | None = None
    eval_recipe: EnvRecipe | None = None
    config: dict[str, Any] = field(default_factory=dict)

    def _held_out(self, model: Any, num_episodes: int, first_seed: int, stop: Any) -> list[dict[str, Any]]:
        """Deterministic held-out episodes of the model as it is now (selection.EvaluateFn)."""
        recipe = self.eval_recipe or self.recipe
        envs = [make_env(recipe, seed=first_seed + i) for i in range(min(HELD_OUT_BATCH, num_episodes))]
        try:
            return rollout_batched(envs, torch_act_fn(model, current_normalizer(model)), num_episodes, first_seed,
                                   stop)
        finally:
            for env in envs:
                env.close()

    def _save_best(self, model: Any) -> None:
        save_final(model, self.run_dir / BEST_DIR)

    def _record_selection(self) -> None:
        self.config = {**self.config, "selection": self.selection.record()}
        write_run_config(self.run_dir, self.config, "mujoco")

    def _hyperparameters(self) -> dict[str, Any]:
        hp = merge_hyperparameters(self.recipe.settings.algo_hyperparameters(self.algorithm), self.hyperparameters)
        if self.algorithm == "sac":  # a replay buffer larger than the run only costs memory and checkpoints
            hp["buffer_size"] = int(min(hp.get("buffer_size", 1_000_000), max(self.max_steps, 1000)))
        return hp

    def _check_resume_request(self, previous: dict[str, Any]) -> None:
        """A resumed run continues with its recorded task, algorithm and hyperparameters; an explicit
        request for different ones is an error (start a new run directory to change them)."""
        check_resume_request(self.run_dir, previous, self.described["task_id"], self.hyperparameters)
        if self.requested_algorithm and self.requested_algorithm != previous.get("algorithm"):
            raise ConfigError(str(self.run_dir / RUN_CONFIG_FILE), "algorithm",
                              f"the run was trained with {previous.get('algorithm')!r}; resume cannot switch to "
                              f"{self.requested_algorithm!r} (use a new --output-dir)")

    def train(self, resume: bool = False, progress: ProgressFn = no_progress) -> tuple[Any, list[dict[str, float]]]:
        """Train to ``max_steps`` total environment steps; returns (model, training curve)."""
        self.run_dir.mkdir(parents=True, exist_ok=True)
        if self.selection is not None:
            self.selection.started = time.perf_counter()  # "deployable after N wall seconds" counts from here
        ckpt, skipped = find_checkpoint(self.run_dir, self.recipe.settings.normalize_obs) if resume else (None, [])
        for problem in skipped:
            log.warning("skipped a damaged checkpoint: %s; resuming from %s", problem,
                        f"{ckpt[0].name}" if ckpt else "the start (no intact checkpoint)")
        if resume:
            previous = read_run_config(self.run_dir, "mujoco")
            self._check_resume_request(previous)
            self.algorithm = previous["algorithm"]
            if self.selection is not None and (self.run_dir / BEST_DIR / "policy.zip").is_file():
                self.selection.restore(previous.get("selection"))
        hp = previous["hyperparameters"] if resume else self._hyperparameters()
        venv = make_vec_env(self.recipe, self.num_envs, self.seed, self.vec_env)
        stats = checkpoint_vecnormalize(*ckpt) if ckpt else None
        venv = wrap_normalize(venv, self.recipe.settings.normalize_obs, stats if stats and stats.is_file() else None)
        obs_layout, action_layout = env_layout(venv.venv if hasattr(venv, "venv") else venv)
        self.config = {
            **self.described, "algorithm": self.algorithm, "hyperparameters": hp, "num_envs": self.num_envs,
            "max_steps": self.max_steps, "seed": self.seed, "vec_env": self.vec_env,
            "checkpoint_every_steps": self.checkpoint_every_steps, "obs_layout": obs_layout,
            "action_layout": action_layout, "resumed_from_steps": ckpt[1] if ckpt else 0,
            "skipped_checkpoints": skipped,
        }
        if self.selection is not None and self.selection.history:
            self.config["selection"] = self.selection.record()  # a resumed run's selection so far
        write_run_config(self.run_dir, self.config, "mujoco")
        tb_dir = str(self.run_dir / "tb")
        if ckpt:
            model = load_checkpoint(self.algorithm, ckpt[0], ckpt[1], venv)
            model.tensorboard_log = tb_dir
        else:
            model = build_model(self.algorithm, venv, hp, self.seed, tb_dir)
        curve = TrainingCurveCallback(every_steps=max(1000, self.max_steps // 50))
        callbacks = [ProgressFnCallback(progress, self.max_steps), curve, EconEpisodeLogCallback(),
                     checkpoint_callback(self.run_dir, self.checkpoint_every_steps, self.num_envs,
                                         save_replay_buffer=self.algorithm == "sac")]
        if self.recipe.curriculum.ramp_steps > 0:
            callbacks.append(CurriculumCallback(self.recipe.curriculum))
        if self.selection is not None:
            callbacks[0].status = self.selection.status
            callbacks.append(HeldOutSelectionCallback(self.selection, self._held_out, self._save_best,
                                                      self._record_selection))
        remaining = self.max_steps - model.num_timesteps
        if remaining > 0:
            model.learn(remaining, callback=callbacks, reset_num_timesteps=ckpt is None, tb_log_name="run")
        if self.selection is not None:  # the record first: policy.zip marks a complete run
            self.config = {**self.config, "trained_steps": int(model.num_timesteps),
                           "selection": self.selection.record()}
            write_run_config(self.run_dir, self.config, "mujoco")
        if self.selection is not None and self.selection.best is not None:
            install_policy(self.run_dir / BEST_DIR, self.run_dir)
            model = algorithm_class(self.algorithm).load(str(self.run_dir / "policy.zip"), device="cpu")
        else:
            save_final(model, self.run_dir)
        venv.close()
        return model, curve.curve
