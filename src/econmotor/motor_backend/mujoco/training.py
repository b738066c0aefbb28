"""SB3 training for the mujoco backend: models, callbacks, checkpoints and resume.

Run directory (``policy_id``)::

    run_config.json                     # task, objective, datapacks, algorithm, hyperparameters, seed
    checkpoints/ckpt_<N>_steps.zip      # every checkpoint_every_steps (+ ckpt_vecnormalize_<N>_steps.pkl)
    tb/                                 # TensorBoard: SB3 scalars + overlay/<key>_raw|_weighted + econ/<key>
    policy.zip, vecnormalize.pkl        # the run's policy and its observation statistics: the kept
                                        #   checkpoint of evaluation-driven training (selection.py)
    best/policy.zip, best/vecnormalize.pkl   # the best held-out policy so far (while training)
    policy.onnx                         # the deployed actor (export.py)

Every checkpoint file is written to a temporary name and renamed into place, the
companions (VecNormalize statistics, SAC's replay buffer) before the policy zip, so a
``ckpt_<N>_steps.zip`` implies complete companions. On resume each candidate is verified
(zip CRCs, the statistics unpickle) newest first; damaged ones (a file truncated by a
crash or a full disk) are skipped and reported, and training resumes from the newest
intact checkpoint.
"""

from __future__ import annotations

import logging
import os
import pickle
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from econmotor.errors import BackendError, ConfigError
from econmotor.motor_backend.mujoco.randomization import Curriculum

ALGORITHM_CLASSES: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC}
CHECKPOINT_PREFIX = "ckpt"
POLICY_FILE = "policy.zip"
VECNORM_FILE = "vecnormalize.pkl"
_CKPT_RE = re.compile(rf"{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
log = logging.getLogger("econmotor")


def algorithm_class(name: str) -> type[BaseAlgorithm]:
    if name not in ALGORITHM_CLASSES:
        raise ConfigError("<train>", "algorithm", f"unknown algorithm '{name}'", list(ALGORITHM_CLASSES))
    return ALGORITHM_CLASSES[name]


def policy_kwargs_from(hp: Mapping[str, Any]) -> dict[str, Any]:
    """Turn YAML-friendly ``policy_kwargs`` (``activation_fn: relu|tanh``) into SB3's."""
    from torch import nn

    hp = dict(hp)
    pk = dict(hp.get("policy_kwargs") or {})
    if isinstance(pk.get("activation_fn"), str):
        acts = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}
        if pk["activation_fn"] not in acts:
            raise ConfigError("<hyperparameters>", "policy_kwargs.activation_fn", "unknown activation", list(acts))
        pk["activation_fn"] = acts[pk["activation_fn"]]
    if pk:
        hp["policy_kwargs"] = pk
    return hp


def build_model(algorithm: str, venv: VecEnv, hyperparameters: Mapping[str, Any], seed: int,
                tensorboard_dir: str | None) -> BaseAlgorithm:
    """A fresh SB3 model on ``venv`` (CPU, MlpPolicy) with the given constructor kwargs."""
    cls = algorithm_class(algorithm)
    try:
        return cls("MlpPolicy", venv, seed=seed, device="cpu", verbose=0, tensorboard_log=tensorboard_dir,
                   **policy_kwargs_from(hyperparameters))
    except TypeError as exc:
        raise ConfigError("<hyperparameters>", algorithm, f"bad SB3 {cls.__name__} argument: {exc}") from exc


def wrap_normalize(venv: VecEnv, normalize_obs: bool, stats_path: Path | None = None) -> VecEnv:
    """VecNormalize on observations only (rewards stay in task units), optionally with saved stats."""
    if not normalize_obs:
        return venv
    if stats_path is not None:
        normed = VecNormalize.load(str(stats_path), venv)
        normed.training = True
        return normed
    return VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0)


def checkpoint_problem(path: Path, steps: int, need_vecnormalize: bool = False) -> str | None:
    """Why checkpoint ``path`` cannot be resumed from (a truncated or missing file), or None if intact."""
    try:
        with zipfile.ZipFile(path) as zf:
            bad = zf.testzip()
            if bad is not None:
                return f"{path.name}: entry {bad} is corrupt"
            if "data" not in zf.namelist():
                return f"{path.name}: not an SB3 model (no 'data' entry)"
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        return f"{path.name}: {exc}"
    stats = checkpoint_vecnormalize(path, steps)
    if need_vecnormalize and not stats.is_file():
        return f"{path.name}: its VecNormalize statistics {stats.name} are missing"
    if stats.is_file():
        try:
            with stats.open("rb") as fh:
                pickle.load(fh)  # our own file, written by VecNormalize.save
        except Exception as exc:
            return f"{stats.name}: cannot be read ({type(exc).__name__}: {exc})"
    return None


def find_checkpoint(run_dir: str | Path, need_vecnormalize: bool = False) -> tuple[tuple[Path, int] | None, list[str]]:
    """``((path, N) of the newest intact checkpoint or None, [why each newer one was skipped])``."""
    found = []
    for path in (Path(run_dir) / "checkpoints").glob(f"{CHECKPOINT_PREFIX}_*_steps.zip"):
        m = _CKPT_RE.search(path.name)
        if m:
            found.append((int(m.group(1)), path))
    skipped: list[str] = []
    for steps, path in sorted(found, reverse=True):
        problem = checkpoint_problem(path, steps, need_vecnormalize)
        if problem is None:
            return (path, steps), skipped
        skipped.append(problem)
    return None, skipped


def latest_checkpoint(run_dir: str | Path, need_vecnormalize: bool = False) -> tuple[Path, int] | None:
    """The newest intact ``checkpoints/ckpt_<N>_steps.zip`` and its N, or None (see :func:`find_checkpoint`)."""
    return find_checkpoint(run_dir, need_vecnormalize)[0]


def checkpoint_vecnormalize(ckpt: Path, steps: int) -> Path:
    return ckpt.parent / f"{CHECKPOINT_PREFIX}_vecnormalize_{steps}_steps.pkl"


def checkpoint_replay_buffer(ckpt: Path, steps: int) -> Path:
    return ckpt.parent / f"{CHECKPOINT_PREFIX}_replay_buffer_{steps}_steps.pkl"


def load_checkpoint(algorithm: str, ckpt: Path, steps: int, venv: VecEnv) -> BaseAlgorithm:
    """Load a checkpoint (and SAC's replay buffer when saved) onto ``venv``."""
    try:
        model = algorithm_class(algorithm).load(str(ckpt), env=venv, device="cpu")
    except (ValueError, OSError) as exc:
        raise BackendError(f"cannot resume from {ckpt}: {exc}; delete it to start over") from exc
    buffer = checkpoint_replay_buffer(ckpt, steps)
    if hasattr(model, "load_replay_buffer") and buffer.is_file():
        model.load_replay_buffer(str(buffer))
    return model


def save_checkpoint(model: BaseAlgorithm, run_dir: Path, save_replay_buffer: bool) -> Path:
    """``checkpoints/ckpt_<N>_steps.zip`` of ``model`` at its ``num_timesteps`` N, SB3's CheckpointCallback's
    names, every file written atomically, companions first and the policy zip last (module docstring)."""
    folder = Path(run_dir) / "checkpoints"
    folder.mkdir(parents=True, exist_ok=True)
    steps = int(model.num_timesteps)
    zip_path = folder / f"{CHECKPOINT_PREFIX}_{steps}_steps.zip"
    buffer = getattr(model, "replay_buffer", None)
    if save_replay_buffer and buffer is not None:
        _atomic(str(checkpoint_replay_buffer(zip_path, steps)), model.save_replay_buffer)
    normalizer = model.get_vec_normalize_env()
    if normalizer is not None:
        _atomic(str(checkpoint_vecnormalize(zip_path, steps)), normalizer.save)
    _atomic(str(zip_path), model.save)
    return zip_path


def _atomic(final: str, save: Any) -> None:
    """``save(tmp)`` then rename ``tmp`` to ``final`` (same directory, so the rename is atomic)."""
    stem, dot, ext = final.rpartition(".")
    tmp = f"{stem}.tmp{os.getpid()}{dot}{ext}"  # keeps the extension SB3 insists on
    try:
        save(tmp)
        os.replace(tmp, final)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


class CurriculumCallback(BaseCallback):
    """Set every env's difficulty to ``curriculum.difficulty(num_timesteps)`` every ``every`` calls."""

    def __init__(self, curriculum: Curriculum, every: int = 16) -> None:
        super().__init__()
        self.curriculum, self.every = curriculum, max(1, every)
        self.history: list[tuple[int, float]] = []

    def _apply(self) -> None:
        d = self.curriculum.difficulty(self.num_timesteps)
        self.training_env.env_method("set_difficulty", d)
        self.history.append((self.num_timesteps, d))
        self.logger.record("curriculum/difficulty", d)

    def _on_training_start(self) -> None:
        self._apply()

    def _on_step(self) -> bool:
        if self.n_calls % self.every == 0:
            self._apply()
        return True


class EconEpisodeLogCallback(BaseCallback):
    """Log each finished episode's overlay terms (raw and weighted) and econ raw metrics to TensorBoard."""

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", ()):
            terms = info.get("overlay_terms")
            if terms is None:
                continue
            for key, sums in terms.items():
                self.logger.record_mean(f"overlay/{key}_raw", sums["raw"])
                self.logger.record_mean(f"overlay/{key}_weighted", sums["weighted"])
            self.logger.record_mean("overlay/return", info.get("overlay_return", 0.0))
            for key, value in (info.get("econ_episode") or {}).items():
                if isinstance(value, (int, float)):
                    self.logger.record_mean(f"econ/{key}", float(value))
        return True


def save_final(model: BaseAlgorithm, run_dir: Path) -> None:
    """Write ``vecnormalize.pkl`` (when normalised), then ``policy.zip``, each atomically, into ``run_dir``.

    The policy last, as for checkpoints: ``policy.zip`` marks a complete run, so a crash before
    it leaves a run that resumes, never one that looks complete without its normalisation.
    """
    run_dir.mkdir(parents=True, exist_ok=True)
    venv = model.get_env()
    if isinstance(venv, VecNormalize):
        _atomic(str(run_dir / VECNORM_FILE), venv.save)
    _atomic(str(run_dir / POLICY_FILE), model.save)


def obs_normalizer(run_dir: str | Path) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """``(mean, var, epsilon, clip)`` of the run's saved VecNormalize, or None when not normalised."""
    path = Path(run_dir) / VECNORM_FILE
    if not path.is_file():
        return None
    import pickle

    with open(path, "rb") as fh:
        stats = pickle.load(fh)
    return stats.obs_rms.mean.copy(), stats.obs_rms.var.copy(), float(stats.epsilon), float(stats.clip_obs)
