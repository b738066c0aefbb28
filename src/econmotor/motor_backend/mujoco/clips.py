"""Motion clips: npz reference trajectories, a pose-tracking reward and reference-state init.

A clip file is an ``.npz`` with ``qpos`` ``[T, nq]`` (the model's generalised positions,
T >= 2) and ``fps`` (frames per second). :func:`record_clip` writes one from any
``act(obs) -> action`` rollout.

Pose tracking (DeepMimic's pose reward, Peng et al. 2018, eq. 7) at step t::

    pose_tracking_t = exp(-2 * sum_j (q_j - q_ref_j(t))^2)     in (0, 1]

over the joint coordinates excluding the root's horizontal position (``qpos[1:]`` for
planar robots, ``qpos[2:]`` for free-floating ones), where ``q_ref(t)`` is the clip frame
at time ``t0 + t * dt`` (clips loop). Reference-state initialisation: each reset picks a
clip by weight and a start frame uniformly, and starts the robot in that frame's pose and
velocity (finite differences of the clip), shifted so the root starts at the env's origin.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from econmotor.config.datapacks import DatapackBundle
from econmotor.errors import ConfigError


@dataclass(frozen=True, eq=False)
class MotionClip:
    """One reference trajectory: ``qpos`` [T, nq] sampled at ``fps``."""

    qpos: np.ndarray
    fps: float
    weight: float = 1.0
    path: str = "<clip>"

    def qvel(self, frame: int, nv: int) -> np.ndarray:
        """Finite-difference velocity at ``frame`` (hinge/slide coordinates; nq == nv models only)."""
        nxt = min(frame + 1, len(self.qpos) - 1)
        prev = nxt - 1
        vel = (self.qpos[nxt] - self.qpos[prev]) * self.fps
        return vel[:nv] if len(vel) >= nv else np.zeros(nv)


def check_clip_file(path: str | Path, origin: str = "<datapack>", key: str = "motion_clips") -> Path:
    """``path`` if a clip file is there; else a ConfigError naming the datapack ``origin`` and ``key``."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(origin, f"{key}.path", f"motion clip file not found: {path} (a relative path is read "
                          "from the current folder, else from the datapack's)")
    return path


def load_clip(path: str | Path, nq: int, origin: str = "<datapack>", key: str = "motion_clips",
              weight: float = 1.0) -> MotionClip:
    """Read and check one clip file; errors name the datapack ``origin`` and ``key``."""
    path = check_clip_file(path, origin, key)
    try:
        with np.load(path) as data:
            qpos = np.asarray(data["qpos"], dtype=np.float64)
            fps = float(np.asarray(data["fps"]))
    except (KeyError, ValueError, OSError) as exc:
        raise ConfigError(origin, f"{key}.path", f"{path} is not a clip npz with 'qpos' and 'fps': {exc}") from exc
    if qpos.ndim != 2 or qpos.shape[1] != nq or len(qpos) < 2:
        raise ConfigError(origin, f"{key}.path", f"{path}: qpos must be [T >= 2, nq = {nq}], got {qpos.shape}")
    if not np.all(np.isfinite(qpos)) or not fps > 0:
        raise ConfigError(origin, f"{key}.path", f"{path}: qpos must be finite and fps > 0")
    return MotionClip(qpos, fps, weight, str(path))


def load_bundle_clips(bundle: DatapackBundle, nq: int) -> list[MotionClip]:
    """Every clip of a resolved datapack bundle, checked against a model with ``nq`` positions."""
    clips = []
    for i, ref in enumerate(bundle.motion_clips):
        origin = bundle.clip_origins.get(ref.path, "<datapacks>")
        source = bundle.sources.get(origin, origin)
        clips.append(load_clip(ref.path, nq, f"datapack '{origin}' ({source})", f"motion_clips[{i}]", ref.weight))
    return clips


def save_clip(path: str | Path, qpos: np.ndarray, fps: float) -> Path:
    """Write a clip npz (atomically)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.npz")
    np.savez(tmp, qpos=np.asarray(qpos, dtype=np.float64), fps=np.float64(fps))
    tmp.replace(path)
    return path


def record_clip(env: gym.Env, act: Callable[[np.ndarray], np.ndarray], num_steps: int, seed: int,
                path: str | Path) -> Path:
    """Roll ``act`` out in ``env`` for up to ``num_steps`` steps and save the visited ``qpos`` as a clip."""
    obs, _ = env.reset(seed=seed)
    data = env.unwrapped.data
    frames = [data.qpos.copy()]
    for _ in range(num_steps):
        obs, _, terminated, truncated, _ = env.step(act(obs))
        frames.append(data.qpos.copy())
        if terminated or truncated:
            break
    return save_clip(path, np.stack(frames), 1.0 / float(env.unwrapped.dt))


class PoseTrackingWrapper(gym.Wrapper):
    """Reference-state initialisation and ``info["pose_tracking"]`` per step (see module doc).

    Args:
        env: a Gymnasium MuJoCo env (``set_state`` and ``_get_obs`` are used).
        clips: reference clips (sampled by weight).
        reference_init: start each episode in a clip frame (RSI) instead of the env's default pose.
        seed: seed of the clip / frame sampler.
    """

    #: the metering wrapper outside reads ``info["pose_tracking"]`` each step when this is in its chain
    reports_pose_tracking = True

    def __init__(self, env: gym.Env, clips: Sequence[MotionClip], reference_init: bool = True,
                 seed: int | None = None) -> None:
        super().__init__(env)
        if not clips:
            raise ConfigError("PoseTrackingWrapper", "clips", "needs at least one motion clip")
        base = env.unwrapped
        self._base, self._data = base, base.data
        free = int(base.model.jnt_type[0]) == int(mujoco.mjtJoint.mjJNT_FREE)
        self._first = 2 if free else 1
        self._nroot = 2 if free else 1
        self.clips = list(clips)
        weights = np.array([c.weight for c in self.clips], dtype=float)
        self._p = weights / weights.sum()
        self.reference_init = reference_init
        self._rng = np.random.default_rng(seed)
        self._clip, self._t0, self._steps, self._dt = self.clips[0], 0.0, 0, float(base.dt)

    def reset(self, **kwargs: Any):
        if kwargs.get("seed") is not None:
            self._rng = np.random.default_rng(kwargs["seed"] + 104729)
        obs, info = self.env.reset(**kwargs)
        self._clip = self.clips[int(self._rng.choice(len(self.clips), p=self._p))]
        frame = int(self._rng.integers(0, len(self._clip.qpos) - 1)) if self.reference_init else 0
        self._t0, self._steps = frame / self._clip.fps, 0
        if self.reference_init:
            qpos = self._clip.qpos[frame].copy()
            qpos[: self._nroot] = self._data.qpos[: self._nroot]
            nv = self._base.model.nv
            qvel = self._clip.qvel(frame, nv) if self._base.model.nq == nv else self._data.qvel.copy()
            self._base.set_state(qpos, qvel)
            obs = self._base._get_obs()
        return obs, info

    @property
    def current_clip(self) -> MotionClip:
        """The clip this episode tracks (drawn by weight at reset)."""
        return self._clip

    def reference_frame(self) -> np.ndarray:
        """The clip's qpos at the current time (looping)."""
        t = self._t0 + self._steps * self._dt
        return self._clip.qpos[round(t * self._clip.fps) % len(self._clip.qpos)]

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        diff = self._data.qpos[self._first:] - self.reference_frame()[self._first:]
        info["pose_tracking"] = float(np.exp(-2.0 * float(diff @ diff)))
        return obs, reward, terminated, truncated, info
