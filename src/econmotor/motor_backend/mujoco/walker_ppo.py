"""PPO for the card robots on the CPU (torch): a fine-tuning recipe that respects a warm start.

rsl_rl's PPO, which trained Holosoma's walkers, in the few lines a CPU run needs:

- **the actor** is an MLP (:func:`mlp`) started from an ONNX walker's layers exactly
  (:meth:`ActorCritic.from_actor`: before any update its mean is the ONNX's action), with a
  state-independent exploration std (``init_std``);
- **the critic** sees the observation and the env's privileged view
  (:class:`econmotor.couriers.walker_train.WalkerLearningEnv.privileged`), normalised by running statistics;
  its first ``critic_warmup_iterations`` iterations move only the critic, so the actor's first
  advantages come from a critic that knows the walker;
- **updates**: ``num_epochs`` epochs of ``num_minibatches`` shuffled minibatches (thousands of samples
  each: ``num_envs * steps_per_iteration / num_minibatches``), clipped surrogate, advantages
  standardised over the whole batch, AdamW whose learning rate follows the KL between the old and the
  new policy after every minibatch (rsl_rl's rule: above ``2 * desired_kl`` divide by 1.5, below half
  of it multiply by 1.5, within ``lr_bounds``);
- **an anchor** for a warm start (``anchor_coef > 0``): the loss adds ``anchor_coef * KL(pi_0 || pi)``,
  the KL from the actor the run started from (its mean, at the exploration std) to the current one, so
  the objective moves the walker's gait only as far as it pays (KL-regularised fine-tuning, as a
  language model is tuned against its reference).

:class:`WalkerPPOConfig` is the recipe; ``tasks/holosoma.yaml``'s ``backends.mujoco.ppo`` overrides it
per task.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np
import torch
from torch import nn

from econmotor.couriers.onnx_actor import ImportedActor
from econmotor.errors import ConfigError

_ACTIVATIONS = {"elu": nn.ELU, "tanh": nn.Tanh, "relu": nn.ReLU, "silu": nn.SiLU}


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
    init_std: float = 0.1
    anchor_coef: float = 0.0
    critic_warmup_iterations: int = 20
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
            default = getattr(cls, key)
            try:
                out[key] = tuple(type(default[0])(v) for v in raw) if isinstance(default, tuple) else type(default)(raw)
            except (TypeError, ValueError, IndexError) as exc:
                raise ConfigError(source, key, f"got {raw!r}: {exc}") from None
        cfg = cls(**out)
        if cfg.activation not in _ACTIVATIONS:
            raise ConfigError(source, "activation", f"got {cfg.activation!r}", sorted(_ACTIVATIONS))
        if (cfg.num_envs * cfg.steps_per_iteration) % cfg.num_minibatches:
            raise ConfigError(source, "num_minibatches", f"num_envs * steps_per_iteration = "
                              f"{cfg.num_envs * cfg.steps_per_iteration} must be divisible by {cfg.num_minibatches}")
        return cfg

    def to_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


def mlp(sizes: Sequence[int], activation: str) -> nn.Sequential:
    """Linear layers of ``sizes`` with ``activation`` between them (none after the last)."""
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2:
            layers.append(_ACTIVATIONS[activation]())
    return nn.Sequential(*layers)


class RunningNorm(nn.Module):
    """Running mean and variance of the critic's inputs (Chan's parallel update); ``x -> (x - m) / s``."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("var", torch.ones(dim))
        self.register_buffer("count", torch.tensor(1e-4))

    def update(self, x: torch.Tensor) -> None:
        batch_mean, batch_var, n = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta, total = batch_mean - self.mean, self.count + n
        self.mean += delta * n / total
        self.var = (self.var * self.count + batch_var * n + delta.square() * self.count * n / total) / total
        self.count = total

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.clamp((x - self.mean) / torch.sqrt(self.var + 1e-8), -10.0, 10.0)


class ActorCritic(nn.Module):
    """The Gaussian actor (its mean an MLP, a learned log std) and the privileged critic."""

    def __init__(self, obs_dim: int, privileged_dim: int, action_dim: int, cfg: WalkerPPOConfig) -> None:
        super().__init__()
        self.actor = mlp([obs_dim, *cfg.hidden_sizes, action_dim], cfg.activation)
        self.critic = mlp([obs_dim + privileged_dim, *cfg.critic_hidden_sizes, 1], "elu")
        self.critic_norm = RunningNorm(obs_dim + privileged_dim)
        self.log_std = nn.Parameter(torch.full((action_dim,), math.log(cfg.init_std)))
        self.activation = cfg.activation

    @classmethod
    def from_actor(cls, actor: ImportedActor, privileged_dim: int, cfg: WalkerPPOConfig) -> ActorCritic:
        """An actor-critic whose actor is ``actor``'s layers exactly (a fresh critic)."""
        if actor.obs_mean is not None:
            raise ConfigError(actor.source, "normaliser", "the walker trainer starts from actors without an "
                              "in-graph normaliser (Holosoma's PPO walkers have none)")
        shaped = WalkerPPOConfig(**{**asdict(cfg), "hidden_sizes": actor.hidden_sizes,
                                    "activation": actor.activation})
        net = cls(actor.obs_dim, privileged_dim, actor.action_dim, shaped)
        net.load_actor(actor.layers)
        return net

    def load_actor(self, layers: Sequence[Mapping[str, np.ndarray]]) -> None:
        """Set the actor's layers to ``layers`` (``[{"w": [in, out], "b": [out]}]``, :meth:`layers`'s form)."""
        linears = [m for m in self.actor if isinstance(m, nn.Linear)]
        with torch.no_grad():
            for lin, layer in zip(linears, layers, strict=True):
                lin.weight.copy_(torch.from_numpy(np.asarray(layer["w"], np.float32).T))
                lin.bias.copy_(torch.from_numpy(np.asarray(layer["b"], np.float32)))

    def layers(self) -> list[dict[str, np.ndarray]]:
        """The actor's layers as ``[{"w": [in, out], "b": [out]}]`` (what the ONNX export writes)."""
        return [{"w": m.weight.detach().numpy().T.copy(), "b": m.bias.detach().numpy().copy()}
                for m in self.actor if isinstance(m, nn.Linear)]

    def value(self, obs: torch.Tensor, privileged: torch.Tensor) -> torch.Tensor:
        return self.critic(self.critic_norm(torch.cat([obs, privileged], dim=-1))).squeeze(-1)


@dataclass
class Rollout:
    """One iteration's samples, ``[T, N, ...]``."""

    obs: torch.Tensor
    privileged: torch.Tensor
    actions: torch.Tensor
    log_probs: torch.Tensor
    means: torch.Tensor
    values: torch.Tensor
    rewards: torch.Tensor
    dones: torch.Tensor  # terminated (a fall): no bootstrap


def gae(r: Rollout, last_value: torch.Tensor, gamma: float, lam: float) -> tuple[torch.Tensor, torch.Tensor]:
    """``(advantages, returns)`` by generalised advantage estimation (truncations are bootstrapped in the
    rewards already: ``r += gamma * V(terminal)``; a step that ended any episode does not look past it)."""
    adv = torch.zeros_like(r.rewards)
    running = torch.zeros_like(last_value)
    next_value = last_value
    for t in reversed(range(r.rewards.shape[0])):
        not_done = 1.0 - r.dones[t]
        delta = r.rewards[t] + gamma * next_value * not_done - r.values[t]
        running = delta + gamma * lam * not_done * running
        adv[t] = running
        next_value = r.values[t]
    return adv, adv + r.values


class WalkerPPO:
    """The learner: :meth:`act` during a rollout, :meth:`update` after it (module docstring)."""

    def __init__(self, net: ActorCritic, cfg: WalkerPPOConfig) -> None:
        self.net, self.cfg = net, cfg
        self.learning_rate = cfg.learning_rate
        self.optimizer = torch.optim.AdamW(net.parameters(), lr=cfg.learning_rate, weight_decay=0.0)
        self.iterations = 0
        #: the actor the run started from (the anchor's reference; None without one)
        self.reference = copy.deepcopy(net.actor).requires_grad_(False) if cfg.anchor_coef > 0 else None
        self.reference_std = float(cfg.init_std)

    @torch.no_grad()
    def act(self, obs: np.ndarray, privileged: np.ndarray) -> tuple[np.ndarray, dict[str, torch.Tensor]]:
        o, p = torch.from_numpy(obs), torch.from_numpy(privileged)
        mean = self.net.actor(o)
        std = self.net.log_std.exp()
        action = mean + std * torch.randn_like(mean)
        log_prob = torch.distributions.Normal(mean, std).log_prob(action).sum(-1)
        return action.numpy(), {"obs": o, "privileged": p, "actions": action, "log_probs": log_prob,
                                "means": mean, "values": self.net.value(o, p)}

    @torch.no_grad()
    def value(self, obs: np.ndarray, privileged: np.ndarray) -> np.ndarray:
        return self.net.value(torch.from_numpy(obs), torch.from_numpy(privileged)).numpy()

    @torch.no_grad()
    def mean_action(self, obs: np.ndarray) -> np.ndarray:
        return self.net.actor(torch.from_numpy(np.asarray(obs, np.float32))).numpy()

    def update(self, r: Rollout, last_value: torch.Tensor) -> dict[str, float]:
        """One iteration's update; its statistics (losses, KL, learning rate, std)."""
        cfg, net = self.cfg, self.net
        adv, returns = gae(r, last_value, cfg.gamma, cfg.lam)
        flat = lambda x: x.reshape(-1, *x.shape[2:])
        obs, priv, actions = flat(r.obs), flat(r.privileged), flat(r.actions)
        old_logp, old_mean, adv, returns = flat(r.log_probs), flat(r.means), flat(adv), flat(returns)
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        net.critic_norm.update(torch.cat([obs, priv], dim=-1))
        warmup = self.iterations < cfg.critic_warmup_iterations
        old_std = net.log_std.detach().exp()
        stats: dict[str, float] = {"value_loss": 0.0, "surrogate": 0.0, "kl": 0.0}
        n, size, updates = obs.shape[0], cfg.minibatch_size, 0
        for _ in range(cfg.num_epochs):
            perm = torch.randperm(n)
            for start in range(0, n - size + 1, size):
                idx = perm[start:start + size]
                mean = net.actor(obs[idx])
                std = net.log_std.exp()
                logp = torch.distributions.Normal(mean, std).log_prob(actions[idx]).sum(-1)
                ratio = torch.exp(logp - old_logp[idx])
                clipped = torch.clamp(ratio, 1 - cfg.clip, 1 + cfg.clip)
                surrogate = -torch.min(ratio * adv[idx], clipped * adv[idx]).mean()
                value_loss = (net.value(obs[idx], priv[idx]) - returns[idx]).square().mean()
                entropy = net.log_std.sum() + 0.5 * math.log(2 * math.pi * math.e) * net.log_std.numel()
                loss = cfg.value_coef * value_loss
                if not warmup:
                    loss = loss + surrogate - cfg.entropy_coef * entropy
                    if self.reference is not None:
                        ref_std = torch.full_like(std, self.reference_std)
                        anchor = _gaussian_kl(self.reference(obs[idx]), ref_std, mean, std)
                        loss = loss + cfg.anchor_coef * anchor
                        stats["anchor_kl"] = stats.get("anchor_kl", 0.0) + anchor.item()
                self.optimizer.zero_grad()
                loss.backward()
                if warmup:
                    for p in [*net.actor.parameters(), net.log_std]:
                        p.grad = None
                nn.utils.clip_grad_norm_(net.parameters(), cfg.max_grad_norm)
                self.optimizer.step()
                with torch.no_grad():
                    kl = _gaussian_kl(old_mean[idx], old_std, net.actor(obs[idx]), net.log_std.exp())
                if not warmup:
                    self._adapt(float(kl))
                stats["value_loss"] += value_loss.item()
                stats["surrogate"] += surrogate.item()
                stats["kl"] += float(kl)
                updates += 1
        self.iterations += 1
        out = {k: v / max(updates, 1) for k, v in stats.items()}
        return {**out, "learning_rate": self.learning_rate, "std": net.log_std.detach().exp().mean().item(),
                "critic_warmup": float(warmup)}

    def _adapt(self, kl: float) -> None:
        lo, hi = self.cfg.lr_bounds
        if kl > 2.0 * self.cfg.desired_kl:
            self.learning_rate = max(lo, self.learning_rate / 1.5)
        elif kl < 0.5 * self.cfg.desired_kl:
            self.learning_rate = min(hi, self.learning_rate * 1.5)
        for group in self.optimizer.param_groups:
            group["lr"] = self.learning_rate

    def state_dict(self) -> dict[str, Any]:
        return {"net": self.net.state_dict(), "optimizer": self.optimizer.state_dict(),
                "learning_rate": self.learning_rate, "iterations": self.iterations,
                "reference": self.reference.state_dict() if self.reference is not None else None}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        self.net.load_state_dict(state["net"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.learning_rate, self.iterations = float(state["learning_rate"]), int(state["iterations"])
        if self.reference is not None and state.get("reference") is not None:
            self.reference.load_state_dict(state["reference"])
        self._adapt(self.cfg.desired_kl)  # the rate recorded, applied to the optimizer (within the bounds)


def _gaussian_kl(mean0: torch.Tensor, std0: torch.Tensor, mean1: torch.Tensor, std1: torch.Tensor) -> torch.Tensor:
    """Mean over rows of ``KL(N(mean0, std0) || N(mean1, std1))`` summed over the action's dimensions."""
    kl = torch.log(std1 / std0) + (std0.square() + (mean0 - mean1).square()) / (2.0 * std1.square()) - 0.5
    return kl.sum(-1).mean()
