"""TrainingRun: one SB3 training run in a run directory, fresh or resumed from a checkpoint.

The run around the model is the shared :class:`~econmotor.motor_backend.training_loop.TrainingLoop`
(``run_config.json``, the curve, checkpoints, held-out selection, the kept policy, timing); this module
supplies the SB3 model as its :class:`MujocoLearner`: chunks of ``model.learn`` with the curriculum and
the economics' TensorBoard callbacks, SB3-format checkpoints (``mujoco/training.py``), ``policy.zip`` with
its ``vecnormalize.pkl``, the held-out evaluation (``HELD_OUT_BATCH`` envs stepped together) and the ONNX
export.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco

from econmotor.errors import ConfigError
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.mujoco.env_factory import EnvRecipe, make_env, make_vec_env
from econmotor.motor_backend.mujoco.evaluation import rollout_batched, torch_act_fn
from econmotor.motor_backend.mujoco.export import export_onnx
from econmotor.motor_backend.mujoco.settings import merge_hyperparameters
from econmotor.motor_backend.mujoco.training import (
    POLICY_FILE,
    CurriculumCallback,
    EconEpisodeLogCallback,
    algorithm_class,
    build_model,
    checkpoint_vecnormalize,
    find_checkpoint,
    load_checkpoint,
    log,
    obs_normalizer,
    save_checkpoint,
    save_final,
    wrap_normalize,
)
from econmotor.motor_backend.run_dir import RUN_CONFIG_FILE
from econmotor.motor_backend.sb3_learner import SB3Learner
from econmotor.motor_backend.selection import Selection
from econmotor.motor_backend.training_loop import StopFn, TrainingLoop

ONNX_FILE = "policy.onnx"

#: envs stepped together in a held-out evaluation (one batched forward pass per step)
HELD_OUT_BATCH = 16


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


class MujocoLearner(SB3Learner):
    """An SB3 model on the mujoco backend's envs as the loop's learner (module docstring)."""

    policy_file = POLICY_FILE

    def __init__(self, model: Any, run: TrainingRun, resumed_at: int, callbacks: list[Any],
                 metadata: Mapping[str, Any]) -> None:
        super().__init__(model, callbacks, str(run.run_dir / "tb"), resumed=resumed_at > 0)
        self.run, self.resumed_at, self.metadata = run, resumed_at, metadata

    def evaluate(self, num_episodes: int, first_seed: int, stop: StopFn) -> list[dict[str, Any]]:
        return self.run._held_out(self.model, num_episodes, first_seed, stop)

    def save_checkpoint(self, run_dir: Path) -> None:
        save_checkpoint(self.model, run_dir, save_replay_buffer=self.run.algorithm == "sac")

    def load_checkpoint(self, run_dir: Path) -> int:
        return self.resumed_at  # loaded with its VecNormalize statistics when the env was built (TrainingRun)

    def save_policy(self, directory: Path) -> None:
        save_final(self.model, directory)

    def load_policy(self, directory: Path) -> None:
        self.model = algorithm_class(self.run.algorithm).load(str(directory / POLICY_FILE), device="cpu")

    def export(self, run_dir: Path) -> Path:
        return export_onnx(self.model, obs_normalizer(run_dir), run_dir / ONNX_FILE, dict(self.metadata))

    def close(self) -> None:
        self.run.venv.close()


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
    #: the ONNX export's metadata from the run config (None: the config's own keys are not described)
    onnx_metadata: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    config: dict[str, Any] = field(default_factory=dict)
    venv: Any = None

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

    def _hyperparameters(self) -> dict[str, Any]:
        hp = merge_hyperparameters(self.recipe.settings.algo_hyperparameters(self.algorithm), self.hyperparameters)
        if self.algorithm == "sac":  # a replay buffer larger than the run only costs memory and checkpoints
            hp["buffer_size"] = int(min(hp.get("buffer_size", 1_000_000), max(self.max_steps, 1000)))
        return hp

    def _check_algorithm(self, previous: dict[str, Any]) -> None:
        """A resumed run continues with its recorded algorithm (start a new run directory to change it)."""
        if self.requested_algorithm and self.requested_algorithm != previous.get("algorithm"):
            raise ConfigError(str(self.run_dir / RUN_CONFIG_FILE), "algorithm",
                              f"the run was trained with {previous.get('algorithm')!r}; resume cannot switch to "
                              f"{self.requested_algorithm!r} (use a new --output-dir)")

    def _model(self, hp: dict[str, Any], ckpt: tuple[Path, int] | None) -> Any:
        """The model on a fresh vector env: from the checkpoint (with its VecNormalize statistics) or new."""
        self.venv = make_vec_env(self.recipe, self.num_envs, self.seed, self.vec_env)
        stats = checkpoint_vecnormalize(*ckpt) if ckpt else None
        self.venv = wrap_normalize(self.venv, self.recipe.settings.normalize_obs,
                                   stats if stats and stats.is_file() else None)
        if ckpt:
            return load_checkpoint(self.algorithm, ckpt[0], ckpt[1], self.venv)
        return build_model(self.algorithm, self.venv, hp, self.seed, None)

    def train(self, resume: bool = False, progress: ProgressFn = no_progress) -> list[dict[str, float]]:
        """Train to ``max_steps`` total environment steps (the kept policy is ``policy.zip``); the training
        curve."""
        loop = TrainingLoop(self.run_dir, "mujoco", {**self.described}, self.max_steps,
                            checkpoint_every_steps=self.checkpoint_every_steps, selection=self.selection,
                            curve_every_steps=max(1000, self.max_steps // 50),
                            requested_hyperparameters=self.hyperparameters, progress=progress)
        ckpt, skipped = None, []
        if resume:
            previous = loop.previous()
            self._check_algorithm(previous)
            self.algorithm = previous["algorithm"]
            ckpt, skipped = find_checkpoint(self.run_dir, self.recipe.settings.normalize_obs)
            for problem in skipped:
                log.warning("skipped a damaged checkpoint: %s; resuming from %s", problem,
                            f"{ckpt[0].name}" if ckpt else "the start (no intact checkpoint)")
        hp = previous["hyperparameters"] if resume else self._hyperparameters()
        model = self._model(hp, ckpt)
        obs_layout, action_layout = env_layout(self.venv.venv if hasattr(self.venv, "venv") else self.venv)
        loop.config = {
            **self.described, "algorithm": self.algorithm, "hyperparameters": hp, "num_envs": self.num_envs,
            "seed": self.seed, "vec_env": self.vec_env, "checkpoint_every_steps": self.checkpoint_every_steps,
            "obs_layout": obs_layout, "action_layout": action_layout, "skipped_checkpoints": skipped,
        }
        callbacks = [EconEpisodeLogCallback()]
        if self.recipe.curriculum.ramp_steps > 0:
            callbacks.append(CurriculumCallback(self.recipe.curriculum))
        metadata = self.onnx_metadata(loop.config) if self.onnx_metadata else {}
        outcome = loop.run(MujocoLearner(model, self, ckpt[1] if ckpt else 0, callbacks, metadata), resume)
        self.config, self.onnx = outcome.config, outcome.export
        return outcome.curve
