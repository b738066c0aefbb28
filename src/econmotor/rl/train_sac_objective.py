"""Objective-conditioned SAC with shadow mode (spec: RewardBuilder integration, phases 3-4).

The whole training loop, top to bottom (SB3 SAC; wrappers and callbacks, no fork)::

    base  = make_task_env(task)                       # step_summary in info every step
    env   = ObjectiveConditioningWrapper(base, w)     # obs + normalised w; fixed | dirichlet per episode
    env   = ShadowRewardWrapper(env, ...)             # legacy and objective reward from the same summary;
                                                      # the learner sees legacy unless flipped; constraints
    env   = Monitor(env)
    model = SAC("MlpPolicy", env, **hyperparameters)  # lagrangian: LagrangeRelabelReplayBuffer, replayed
                                                      # rewards re-shaped with the current multipliers
    model.learn(total_steps, callback=[ShadowCallback, ProgressFnCallback])
    recorder.finish()                                  # JSONL + summary JSON + plot
    evaluate(model, every requested preset / vector)   # deterministic episodes, J per vector

``reward_weights`` picks the scales the objective reward applies to the RewardBuilder
terms: ``identity`` (``combine_reward(w, terms)``, the spec's form), ``analytic``
(dollar-consistent, :mod:`econmotor.networks.econ_objective_net`) or ``net``
(EconObjectiveNet, which starts equal to ``analytic`` or to a saved net, is fitted after
training and evaluation on the run's episodes and saved with the run). The objective vector is always normalised
onto the simplex, for the observation and for the reward alike. ``energy_term`` is the objective option of
:mod:`econmotor.config.objective_profile`: ``"wh"`` (default, spec §7: ``r_energy = -Wh``) or ``"usd"``
(priced with the catalog's electricity price), for every episode J, step reward and evaluation of the run.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.monitor import Monitor

from econmotor.config.objective_profile import OBJECTIVE_PRESETS, ObjectiveVector, check_energy_term
from econmotor.errors import ConfigError
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.sb3_callbacks import ProgressFnCallback, quiet_logger
from econmotor.networks.econ_objective_net import (
    EconFeatures,
    EconObjectiveNet,
    EnergyResponse,
    analytic_reward_weights,
    identity_reward_weights,
)
from econmotor.rl.conditioning import ObjectiveConditioningWrapper
from econmotor.rl.constraint_shaping import ConstraintShaper
from econmotor.rl.relabel_buffer import LagrangeRelabelReplayBuffer
from econmotor.rl.shadow import ShadowRewardWrapper
from econmotor.rl.shadow_log import ShadowRecorder, json_safe
from econmotor.rl.task_env import TaskEnv, make_task_env
from econmotor.valuation import ConstraintSet
from econmotor.valuation.reward_builder import WEIGHTED_TERM_NAMES

REWARD_WEIGHT_MODES = ("identity", "analytic", "net")
NET_FILE = "econ_objective_net.pt"


@dataclass(frozen=True)
class ShadowConfig:
    """Everything a shadow run needs (recorded as ``config.json`` in the run directory)."""

    env: str = "dishwashing"
    objective: tuple[float, ...] = (1.0, 0.2, 0.1, 0.05, 0.0)
    objective_label: str = "default"
    energy_term: str = "wh"  # the objective option: "wh" (spec §7) or "usd" (priced; off by default)
    total_steps: int = 20_000
    use_objective_reward: bool = False
    constraints: ConstraintSet | None = None
    constraint_mode: str = "penalty"
    objective_sampling: str = "fixed"
    reward_weights: str = "identity"
    reward_net_path: str | None = None  # ``net``: start from a saved EconObjectiveNet (else the analytic init)
    seed: int = 0
    save_dir: str | None = None
    shadow: bool = True  # False: the same SAC on the env's own legacy reward (benchmarks)
    max_episode_steps: int | None = None
    econ_overrides: Mapping[str, Any] = field(default_factory=dict)
    lagrange_lr: float = 1.0
    lagrange_init: float = 0.0
    lagrange_update_every: int = 1
    lagrange_relabel: bool = True  # lagrangian: replayed rewards re-shaped with the current multipliers
    eval_episodes: int = 5
    eval_objectives: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    learning_rate: float = 3e-4
    buffer_size: int = 100_000
    batch_size: int = 256
    learning_starts: int = 1000
    gamma: float = 0.99
    train_freq: int = 1
    gradient_steps: int = 1
    ent_coef: str | float = "auto"  # SB3 SAC entropy coefficient ("auto_0.01": auto-tuned from 0.01)
    net_arch: tuple[int, ...] = (256, 256)

    def __post_init__(self) -> None:
        if self.reward_weights not in REWARD_WEIGHT_MODES:
            raise ConfigError("--reward-weights", None, f"unknown mode {self.reward_weights!r}", REWARD_WEIGHT_MODES)
        if self.total_steps < 1:
            raise ConfigError("--total-steps", None, f"must be >= 1, got {self.total_steps}")
        ObjectiveVector.from_list(list(self.objective), source="--objective-vector").normalize()
        check_energy_term(self.energy_term, "--energy-term")
        if not self.shadow and (self.use_objective_reward or self.constraints is not None):
            raise ConfigError("<ShadowConfig>", "shadow", "the flip and constraints need the shadow wrapper; "
                              "set shadow=True")

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["constraints"] = self.constraints.to_dict() if self.constraints else None
        return json_safe(out)


@dataclass(frozen=True)
class ShadowRunResult:
    """What :func:`train_sac_objective` returns.

    Attributes:
        save_dir: the run directory (``None`` when nothing was saved).
        summary: the shadow summary (correlations, mean sums) — empty with ``shadow=False``.
        evaluation: objective label -> mean metrics of the deterministic evaluation episodes.
        multipliers: Lagrange multiplier history (``lagrangian`` mode).
        steps_per_s: environment steps per second of ``model.learn``.
        model: the trained SB3 model.
    """

    save_dir: str | None
    summary: dict[str, Any]
    evaluation: dict[str, dict[str, float]]
    multipliers: list[dict[str, float]]
    steps_per_s: float
    model: Any = field(repr=False, compare=False)


class ShadowCallback(BaseCallback):
    """Put each finished episode's shadow statistics into SB3's logger (TensorBoard / stdout)."""

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", ()):
            record = info.get("shadow_episode")
            if record is None:
                continue
            for key in ("legacy_sum", "objective_sum", "episode_J"):
                self.logger.record_mean(f"shadow/{key}", record[key])
            for key, value in record["correlation"].items():
                if value is not None:
                    self.logger.record(f"shadow/{key}", value)
            for name, value in record.get("constraints", {}).get("multipliers", {}).items():
                self.logger.record(f"lagrange/{name}", value)
        return True


def make_weights_fn(mode: str, task: TaskEnv, net: EconObjectiveNet | None, energy_term: str = "wh"):
    """Objective vector -> RewardWeights for the step terms of ``task`` (identity / analytic / net).

    The shadow wrapper's step terms are increments whose episode sums are the episode's
    terms, so the summary they cover is an episode: the analytic mapping's ``h`` is the
    episode length limit in hours (``max_episode_steps * dt_s / 3600``), as in
    :func:`fit_net_on_records`.
    """
    econ = EconFeatures.from_economics(task.economics)
    energy = EnergyResponse(task.max_episode_steps * task.dt_s / 3600.0, energy_term == "usd")
    if mode == "identity":
        return identity_reward_weights
    if mode == "analytic":
        return lambda vector: analytic_reward_weights(vector, econ, energy)
    return lambda vector: net.reward_weights(vector, econ, energy)


def build_env(config: ShadowConfig, recorder: ShadowRecorder | None, net: EconObjectiveNet | None = None,
              constraints: bool = True):
    """The wrapped env of a run (see the module docstring); returns (env, task, shaper)."""
    task = make_task_env(config.env, config.max_episode_steps, config.econ_overrides)
    objective = ObjectiveVector.from_list(list(config.objective), energy_term=config.energy_term)
    env = ObjectiveConditioningWrapper(task.env, objective, config.objective_sampling)
    shaper = None
    if config.shadow:
        if constraints and config.constraints is not None:
            shaper = ConstraintShaper(config.constraints, config.constraint_mode, lagrange_lr=config.lagrange_lr,
                                      lagrange_init=config.lagrange_init,
                                      update_every_episodes=config.lagrange_update_every)
        env = ShadowRewardWrapper(env, economics=task.economics,
                                  weights_for=make_weights_fn(config.reward_weights, task, net, config.energy_term),
                                  objective=objective, use_objective_reward=config.use_objective_reward,
                                  constraints=shaper, recorder=recorder, task_id=task.task_id)
    return Monitor(env), task, shaper


def train_sac_objective(config: ShadowConfig, progress: ProgressFn = no_progress) -> ShadowRunResult:
    """Train SAC with shadow mode; save, evaluate and return the run (see module docstring)."""
    import torch

    torch.manual_seed(config.seed)
    save_dir = Path(config.save_dir) if config.save_dir else None
    net = None
    if config.reward_weights == "net":
        net = EconObjectiveNet.load(config.reward_net_path) if config.reward_net_path else EconObjectiveNet()
    recorder = ShadowRecorder(save_dir) if config.shadow else None
    env, task, shaper = build_env(config, recorder, net)
    env.reset(seed=config.seed)
    env.action_space.seed(config.seed)
    buffer: dict[str, Any] = {}
    if shaper is not None and shaper.mode == "lagrangian" and config.lagrange_relabel:
        buffer = {"replay_buffer_class": LagrangeRelabelReplayBuffer,
                  "replay_buffer_kwargs": {"multipliers": shaper.multipliers}}
    model = SAC("MlpPolicy", env, learning_rate=config.learning_rate, buffer_size=config.buffer_size,
                batch_size=config.batch_size, learning_starts=config.learning_starts, gamma=config.gamma,
                train_freq=config.train_freq, gradient_steps=config.gradient_steps, ent_coef=config.ent_coef,
                policy_kwargs={"net_arch": list(config.net_arch)}, seed=config.seed, verbose=0, device="cpu",
                **buffer)
    model.set_logger(quiet_logger())
    callbacks = [ProgressFnCallback(progress, config.total_steps, label="shadow SAC")]
    if config.shadow:
        callbacks.insert(0, ShadowCallback())
    start = time.perf_counter()
    model.learn(config.total_steps, callback=callbacks)
    steps_per_s = config.total_steps / max(1e-9, time.perf_counter() - start)
    summary = recorder.finish() if recorder is not None else {}
    evaluation = evaluate(model, config, net, progress)  # with the weights the policy trained on
    if net is not None and recorder is not None and recorder.records:
        fit_net_on_records(net, recorder.records, task)
    multipliers = list(shaper.multipliers.history) if shaper is not None and shaper.mode == "lagrangian" else []
    if save_dir is not None:
        save_run(save_dir, model, config, summary, evaluation, multipliers, net, steps_per_s)
    return ShadowRunResult(str(save_dir) if save_dir else None, summary, evaluation, multipliers,
                           steps_per_s, model)


def eval_objectives(config: ShadowConfig) -> dict[str, tuple[float, ...]]:
    """The vectors to evaluate: the configured ones, else the training vector (and, for a
    dirichlet run, the throughput, energy_saver and safety presets too)."""
    if config.eval_objectives:
        return dict(config.eval_objectives)
    out = {config.objective_label: tuple(config.objective)}
    if config.objective_sampling == "dirichlet":
        out.update({name: OBJECTIVE_PRESETS[name] for name in ("throughput", "energy_saver", "safety")})
    return out


def evaluate(model: Any, config: ShadowConfig, net: EconObjectiveNet | None = None,
             progress: ProgressFn = no_progress, episodes: int | None = None) -> dict[str, dict[str, float]]:
    """Deterministic episodes per objective vector: mean J, MPL, error rate, Wh/unit, wage parity."""
    episodes = config.eval_episodes if episodes is None else episodes
    out: dict[str, dict[str, float]] = {}
    if episodes <= 0:
        return out
    targets = eval_objectives(config)
    eval_config = ShadowConfig(**{**asdict(config), "constraints": config.constraints, "shadow": True,
                                  "objective_sampling": "fixed", "use_objective_reward": False})
    env, _, _ = build_env(eval_config, ShadowRecorder(), net, constraints=False)
    conditioning = env.get_wrapper_attr("set_objective")
    for i, (label, vector) in enumerate(targets.items()):
        conditioning(ObjectiveVector.from_list(list(vector)))
        rows = []
        for ep in range(episodes):
            obs, _ = env.reset(seed=config.seed + 10_000 + ep)
            done = False
            while not done:
                action, _ = model.predict(obs, deterministic=True)
                obs, _, terminated, truncated, info = env.step(action)
                done = terminated or truncated
            rows.append(info["shadow_episode"])
        out[label] = {
            "J": float(np.mean([r["episode_J"] for r in rows])),
            "mpl_units_per_hour": _mean_econ(rows, "mpl_episode"),
            "error_rate": _mean_econ(rows, "error_rate_episode"),
            "energy_Wh_per_unit": _mean_econ(rows, "energy_Wh_per_unit"),
            "wage_parity": _mean_econ(rows, "wage_parity"),
            "legacy_sum": float(np.mean([r["legacy_sum"] for r in rows])),
            "objective_sum": float(np.mean([r["objective_sum"] for r in rows])),
            "episode_steps": float(np.mean([r["steps"] for r in rows])),
        }
        if config.constraints is not None:
            out[label]["constraints_met_share"] = float(np.mean(
                [config.constraints.satisfied(_as_summary(r)) for r in rows]))
        progress("evaluate", i + 1, len(targets))
    return out


def _mean_econ(rows: Sequence[Mapping[str, Any]], key: str) -> float:
    return float(np.mean([r["econ"].get(key) or 0.0 for r in rows]))


def _as_summary(record: Mapping[str, Any]) -> dict[str, Any]:
    econ = dict(record["econ"])
    if econ.get("energy_Wh_per_unit") is None:
        econ["energy_Wh_per_unit"] = float("inf")
    return econ


def fit_net_on_records(net: EconObjectiveNet, records: Sequence[Mapping[str, Any]], task: TaskEnv) -> list[float]:
    """Fit EconObjectiveNet on a run's episodes: outcome = wage parity - energy USD/h / w_h.

    Each row: the episode's objective vector, the task's econ features, the episode's
    hours, its RewardBuilder terms and the realised net dollar rate over the human wage.
    """
    econ = EconFeatures.from_economics(task.economics)
    rows = [r for r in records if (r["econ"].get("episode_length_s") or 0) > 0]
    if not rows:
        return []
    w_h = task.economics.wage_human_usd_per_hour
    hours = [r["econ"]["episode_length_s"] / 3600.0 for r in rows]
    energy_usd_per_h = [(r["econ"].get("energy_Wh") or 0.0) / 1000.0 * task.economics.energy_price_usd_per_kwh / h
                        for r, h in zip(rows, hours, strict=True)]
    outcomes = [(r["econ"].get("wage_parity") or 0.0) - e / w_h for r, e in zip(rows, energy_usd_per_h, strict=True)]
    return net.fit([r["objective_vector"] for r in rows], [econ] * len(rows),
                   [EnergyResponse(h, r.get("energy_term") == "usd") for r, h in zip(rows, hours, strict=True)],
                   [[r["episode_terms"][k] for k in WEIGHTED_TERM_NAMES] for r in rows], outcomes)


def save_run(save_dir: Path, model: Any, config: ShadowConfig, summary: Mapping[str, Any],
             evaluation: Mapping[str, Any], multipliers: list, net: EconObjectiveNet | None,
             steps_per_s: float) -> None:
    """Write the model, config, evaluation, multipliers and (``net`` mode) the EconObjectiveNet."""
    save_dir.mkdir(parents=True, exist_ok=True)
    model.save(save_dir / "sac_model.zip")
    if net is not None:
        net.save(save_dir / NET_FILE)
    result = {"config": config.to_dict(), "summary": summary, "evaluation": evaluation,
              "multipliers": multipliers, "steps_per_s": steps_per_s}
    tmp = save_dir / "run.json.tmp"
    tmp.write_text(json.dumps(json_safe(result), indent=2), encoding="utf-8")
    tmp.replace(save_dir / "run.json")


__all__ = ["REWARD_WEIGHT_MODES", "ShadowConfig", "ShadowRunResult", "build_env", "evaluate",
           "train_sac_objective"]
