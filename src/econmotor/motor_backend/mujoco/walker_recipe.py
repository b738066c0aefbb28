"""The CPU walker PPO's recipe: :class:`WalkerPPOConfig`, every setting of a run with its default.

What each setting does is :mod:`econmotor.motor_backend.mujoco.walker_ppo`'s (the algorithm); the
catalog's ``backends.mujoco.walker.ppo`` (``tasks/holosoma.yaml``) and ``--hyperparameters`` override the
defaults here, each checked when read (an unknown key or a bad value is a ConfigError naming it).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

from econmotor.errors import ConfigError
from econmotor.locomotion.learning import PACES

#: the actor's and critic's activations (names of torch modules)
ACTIVATIONS = ("elu", "tanh", "relu", "silu")
_CHOICES = {"advantage_norm": ("minibatch", "batch"), "grad_clip": ("separate", "joint"), "j_pace": PACES,
            "policy_lag": (0, 1)}
_POSITIVE = ("learning_rate", "desired_kl", "clip", "max_grad_norm", "init_std", "min_std")
_BOOLS = {"true": True, "false": False}


@dataclass(frozen=True)
class WalkerPPOConfig:
    """The recipe (module docstring); every field may be set from the catalog or ``--hyperparameters``."""

    num_envs: int = 32
    steps_per_iteration: int = 64
    num_minibatches: int = 2
    num_epochs: int = 5
    learning_rate: float = 1e-4
    desired_kl: float = 0.01
    lr_bounds: tuple[float, float] = (1e-6, 1e-3)
    clip: float = 0.2
    gamma: float = 0.99
    lam: float = 0.95
    value_coef: float = 1.0
    entropy_coef: float = 0.0
    max_grad_norm: float = 1.0
    #: "separate": the actor's (with log_std) and the critic's gradients clipped apart; "joint": one clip
    grad_clip: str = "separate"
    #: "minibatch": advantages standardised within each minibatch; "batch": over the whole batch
    advantage_norm: str = "minibatch"
    #: the walking speed J's rates are taken at while an episode runs (econmotor.locomotion.learning): "course",
    #: the course's commanded speed; "walker", the walker's own (an average of its finished episodes')
    j_pace: str = "course"
    #: the critic predicts returns standardised by their running mean and std (PopArt)
    value_norm: bool = True
    init_std: float = 0.1
    #: the exploration std's floor (log_std clamped after every step)
    min_std: float = 0.02
    #: the exploration noise's correlation time in seconds (walker_collect.Noise: each robot's noise an
    #: Ornstein-Uhlenbeck process sampled at the control rate, correlated exp(-dt / noise_corr_s) from one step to
    #: the next, its marginal the Gaussian's); 0: white noise, a fresh draw every step
    noise_corr_s: float = 0.0
    #: the anchor's starting coefficient (0: no anchor)
    anchor_coef: float = 0.0
    #: the anchor KL the coefficient steers to (nats per sample, summed over the action's dimensions; walker_ppo's
    #: module docstring); 0: the coefficient stays anchor_coef. 10 nats: on the G1 (29 joints, std 0.1) each
    #: joint's mean about 0.83 std (0.021 rad) from the starting walker's; at 1 nat the anchor reached its target
    #: within 250k env steps and held the held-out J flat after (benchmarks/RESULTS.md, the fine-tune's trials)
    anchor_kl_target: float = 10.0
    anchor_coef_bounds: tuple[float, float] = (1e-3, 1e3)
    critic_warmup_iterations: int = 20
    #: 0: each iteration's robots step under the actor its update starts from, the update waiting for them;
    #: 1: the robots step the next iteration under the current actor while the update runs (Sample Factory's
    #: policy lag of one iteration: the update's batch was collected by the actor one update back, its stored
    #: log-probabilities that actor's), so collection and the update share the cores
    policy_lag: int = 0
    critic_hidden_sizes: tuple[int, ...] = (512, 256, 128)
    hidden_sizes: tuple[int, ...] = (512, 256, 128)
    activation: str = "elu"

    @property
    def minibatch_size(self) -> int:
        return self.num_envs * self.steps_per_iteration // self.num_minibatches

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any] | None, source: str = "<hyperparameters>") -> WalkerPPOConfig:
        """The defaults overridden by ``values``; an unknown key or a bad value is a ConfigError naming it."""
        names = {f.name: f for f in fields(cls)}
        out: dict[str, Any] = {}
        for key, raw in dict(values or {}).items():
            if key not in names:
                raise ConfigError(source, key, "not a walker PPO setting", sorted(names))
            out[key] = _parse(source, key, getattr(cls, key), raw)
        cfg = cls(**out)
        cfg._check(source)
        return cfg

    def _check(self, source: str) -> None:
        """A ConfigError naming the first key whose value the recipe cannot run with."""
        if self.activation not in ACTIVATIONS:
            raise ConfigError(source, "activation", f"got {self.activation!r}", list(ACTIVATIONS))
        for key, allowed in _CHOICES.items():
            if getattr(self, key) not in allowed:
                raise ConfigError(source, key, f"got {getattr(self, key)!r}", list(allowed))
        for key in _POSITIVE:
            if not getattr(self, key) > 0:
                raise ConfigError(source, key, f"must be > 0, got {getattr(self, key)!r}")
        if self.min_std > self.init_std:
            raise ConfigError(source, "min_std", f"must be at most init_std ({self.init_std}), got {self.min_std}")
        bounds = self.anchor_coef_bounds
        if not (len(bounds) == 2 and 0 < bounds[0] <= bounds[1]):
            raise ConfigError(source, "anchor_coef_bounds", f"must be [low, high] with 0 < low <= high, "
                              f"got {list(bounds)}")
        steered = self.anchor_coef > 0 and self.anchor_kl_target > 0
        if self.anchor_coef < 0 or (steered and not bounds[0] <= self.anchor_coef <= bounds[1]):
            raise ConfigError(source, "anchor_coef", f"must be 0 (no anchor) or, under a KL target, within "
                              f"anchor_coef_bounds {list(bounds)}, got {self.anchor_coef}")
        if self.noise_corr_s < 0:
            raise ConfigError(source, "noise_corr_s", f"must be >= 0 (0: white noise), got {self.noise_corr_s}")
        if self.anchor_kl_target < 0:
            raise ConfigError(source, "anchor_kl_target", f"must be >= 0, got {self.anchor_kl_target}")
        if (self.num_envs * self.steps_per_iteration) % self.num_minibatches:
            raise ConfigError(source, "num_minibatches", f"num_envs * steps_per_iteration = "
                              f"{self.num_envs * self.steps_per_iteration} must be divisible by {self.num_minibatches}")

    def to_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


def _parse(source: str, key: str, default: Any, raw: Any) -> Any:
    """``raw`` as ``default``'s type (a tuple's items as its first item's; a bool from a bool or
    ``"true"``/``"false"``); a ConfigError naming ``key`` when it is not one."""
    try:
        if isinstance(default, bool):
            if isinstance(raw, bool):
                return raw
            if isinstance(raw, str) and raw.lower() in _BOOLS:
                return _BOOLS[raw.lower()]
            raise ValueError("not true or false")
        if isinstance(default, tuple):
            return tuple(type(default[0])(v) for v in raw)
        return type(default)(raw)
    except (TypeError, ValueError, IndexError) as exc:
        raise ConfigError(source, key, f"got {raw!r}: {exc}") from None
