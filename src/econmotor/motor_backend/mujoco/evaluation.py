"""Deterministic rollouts of a trained policy and the raw metrics of each episode."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from econmotor.errors import BackendError
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.mujoco.training import POLICY_FILE, algorithm_class, obs_normalizer

ActFn = Callable[[np.ndarray], np.ndarray]


def torch_act_fn(model: Any, normalizer: tuple[np.ndarray, np.ndarray, float, float] | None) -> ActFn:
    """``obs -> model.predict(normalise(obs), deterministic=True)`` (VecNormalize's formula): the policy's
    deterministic action clipped to the action space, as ``predict`` computes it, without ``predict``'s
    per-call checks (a third of its cost for one observation)."""
    import torch

    policy, space = model.policy, model.action_space
    low, high = space.low, space.high

    def act(obs: np.ndarray) -> np.ndarray:
        x = np.asarray(obs, dtype=np.float64)
        if normalizer is not None:
            mean, var, eps, clip = normalizer
            x = np.clip((x - mean) / np.sqrt(var + eps), -clip, clip)
        batch = x.ndim > 1
        with torch.no_grad():
            actions = policy._predict(torch.as_tensor(x if batch else x[None], dtype=torch.float32),
                                      deterministic=True).numpy()
        actions = policy.unscale_action(actions) if policy.squash_output else np.clip(actions, low, high)
        return actions if batch else actions[0]

    return act


def load_policy(run_dir: str | Path, algorithm: str) -> tuple[Any, ActFn]:
    """Load ``policy.zip`` (+ observation statistics) of a run: ``(model, act)``."""
    path = Path(run_dir) / POLICY_FILE
    if not path.is_file():
        raise BackendError(f"no trained policy in {run_dir} (no {POLICY_FILE}): training did not finish; "
                           "continue it with `econmotor train --resume --output-dir <run dir>`")
    model = algorithm_class(algorithm).load(str(path), device="cpu")
    return model, torch_act_fn(model, obs_normalizer(run_dir))


def flatten_episode(info: dict[str, Any]) -> dict[str, Any]:
    """An episode's raw metrics from its last step's info, overlay sums flattened in."""
    raw = dict(info["econ_episode"])
    raw["overlay_return"] = float(info.get("overlay_return", 0.0))
    raw["total_return"] = raw["return"] + raw["overlay_return"]
    for key, sums in (info.get("overlay_terms") or {}).items():
        raw[f"overlay_{key}_raw"] = sums["raw"]
        raw[f"overlay_{key}_weighted"] = sums["weighted"]
    return raw


def rollout_episodes(env: gym.Env, act: ActFn, num_episodes: int, seed: int,
                     progress: ProgressFn = no_progress, label: str = "evaluate",
                     stop: Callable[[list[dict[str, Any]]], bool] | None = None,
                     batch: int = 16) -> list[dict[str, Any]]:
    """Run ``num_episodes`` episodes (episode i reset with ``seed + i``); one raw-metrics dict each.
    After every ``batch`` episodes ``stop(episodes so far)`` may end the evaluation early."""
    episodes: list[dict[str, Any]] = []
    progress(label, 0, num_episodes)
    for i in range(num_episodes):
        if stop is not None and i and i % batch == 0 and stop(episodes):
            break
        obs, _ = env.reset(seed=seed + i)
        while True:
            obs, _, terminated, truncated, info = env.step(act(obs))
            if terminated or truncated:
                break
        episodes.append(flatten_episode(info))
        progress(label, i + 1, num_episodes)
    return episodes


def rollout_batched(envs: Sequence[gym.Env], act: ActFn, num_episodes: int, seed: int,
                    stop: Callable[[list[dict[str, Any]]], bool] | None = None) -> list[dict[str, Any]]:
    """``num_episodes`` deterministic episodes (episode i reset with ``seed + i``, as
    :func:`rollout_episodes`), ``len(envs)`` at a time with one batched ``act`` per step: the
    policy's forward pass, most of a single-env step's cost, is shared by the batch.

    After each ``len(envs)`` finished episodes ``stop(rows so far)`` may end the evaluation early
    (episodes still running are dropped); it sees the episodes finished in an unbroken run from the
    first (episode order), as a sequential evaluation's looks need. Rows are returned in episode order.
    """
    rows: dict[int, dict[str, Any]] = {}
    next_episode, running = 0, {}  # env index -> episode index
    obs = [None] * len(envs)
    for k, env in enumerate(envs):
        if next_episode < num_episodes:
            obs[k], _ = env.reset(seed=seed + next_episode)
            running[k] = next_episode
            next_episode += 1
    checked = 0
    while running:
        active = sorted(running)
        actions = act(np.stack([obs[k] for k in active]))
        for k, action in zip(active, actions, strict=True):
            obs[k], _, terminated, truncated, info = envs[k].step(action)
            if not (terminated or truncated):
                continue
            rows[running.pop(k)] = flatten_episode(info)
            if next_episode < num_episodes:
                obs[k], _ = envs[k].reset(seed=seed + next_episode)
                running[k] = next_episode
                next_episode += 1
        if stop is not None and len(rows) - checked >= len(envs) and running:
            checked = len(rows)
            prefix = []
            while len(prefix) in rows:
                prefix.append(rows[len(prefix)])
            if stop(prefix):
                break
    return [rows[i] for i in sorted(rows)]
