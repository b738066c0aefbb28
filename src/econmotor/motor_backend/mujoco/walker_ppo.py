"""PPO for the card robots on the CPU (torch): a fine-tuning recipe that respects a warm start.

rsl_rl's PPO, which trained Holosoma's walkers, in the few lines a CPU run needs, made robust to the rare
fall (a reward thousands of times a step's) and to a warm start:

- **the actor** is an MLP (:func:`mlp`) or an ONNX walker's network exactly (:meth:`ActorCritic.from_actor`,
  :mod:`.walker_actor`: Holosoma's PPO walkers' MLP, or its FastSAC walkers' normaliser, layer norms and
  tanh-squashed head; before any update its mean is the ONNX's deterministic action), with a
  state-independent exploration std around that mean: a learned ``log_std`` (starting at ``init_std``) that the actor's
  optimiser moves with the actor's layers (the entropy bonus ``entropy_coef`` optional), clamped after
  every step to at least ``min_std`` so that exploration cannot collapse;
- **the critic** sees the observation and the env's privileged view
  (:class:`econmotor.locomotion.learning.WalkerLearningEnv.privileged`), normalised by running statistics;
  with ``value_norm`` it predicts returns standardised by their running mean and std (PopArt: when the
  statistics move, its last layer is rescaled so that its values in reward units stay put; the value loss
  is taken in the standardised units, so a fall's return is a few std, not thousands squared);
  :meth:`ActorCritic.value` is always in reward units. Its first ``critic_warmup_iterations`` iterations
  move only the critic, so the actor's first advantages come from a critic that knows the walker;
- **updates**: ``num_epochs`` epochs of ``num_minibatches`` shuffled minibatches (thousands of samples
  each: ``num_envs * steps_per_iteration / num_minibatches``), clipped surrogate, GAE advantages
  standardised within each minibatch (``advantage_norm: minibatch``, rsl_rl's option; ``batch``: over the
  whole batch, so that one fall's advantage shrinks every other sample's), the actor's (with ``log_std``)
  and the critic's gradients each clipped to norm ``max_grad_norm`` apart (``grad_clip: separate``;
  ``joint``: one clip over both, so that the critic's gradient after a fall shrinks the actor's step),
  AdamW (one parameter group for the actor, one for the critic) whose learning rate follows the KL between
  the old and the new policy after every minibatch (rsl_rl's rule: above ``2 * desired_kl`` divide by 1.5,
  below half of it multiply by 1.5, within ``lr_bounds``);
- **an anchor** for a warm start (``anchor_coef > 0``): the loss adds ``coef * KL(pi_0 || pi)``, the KL
  from the actor the run started from to the current one, both at the starting std ``init_std`` (the
  distance of the mean gait, ``sum((mu - mu_0)**2) / (2 init_std**2)``; the learned std is left to the
  surrogate and the entropy bonus). ``coef`` starts at ``anchor_coef`` and follows a KL target (PPO's
  adaptive KL penalty): after every iteration the anchor KL is measured over the iteration's batch and
  ``coef`` is doubled above ``1.5 * anchor_kl_target`` and halved below ``anchor_kl_target / 1.5``, within
  ``anchor_coef_bounds``; the objective moves the gait as far as the target, not a fixed leash's balance
  point (``anchor_kl_target: 0`` keeps ``coef`` fixed at ``anchor_coef``). The default target, 10 nats, is
  every joint's mean moved by about 0.83 of the starting std (``29 * 0.83**2 / 2``): on the G1 (29 joints,
  action scale 0.25, std 0.1) about 0.021 rad. A target of 1 nat (a quarter of the std, 0.0066 rad) was
  reached within 250k env steps and held the G1's held-out J flat after; a fixed ``0.2`` held runs at 0.1 nat.

:class:`~econmotor.motor_backend.mujoco.walker_recipe.WalkerPPOConfig` is the recipe;
``tasks/holosoma.yaml``'s ``backends.mujoco.walker.ppo`` overrides it per task. A checkpoint
(:meth:`WalkerPPO.state_dict`) keeps the networks (``log_std`` and the value normaliser's statistics with
them), the optimiser, the learning rate and the anchor's coefficient.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch
from torch import nn

from econmotor.couriers.onnx_actor import ImportedActor
from econmotor.motor_backend.mujoco.walker_actor import actor_module, load_layers, load_network, mlp, network_of
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig


class RunningNorm(nn.Module):
    """Running mean and variance of the critic's inputs (Chan's parallel update); ``x -> (x - m) / s``."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("var", torch.ones(dim))
        self.register_buffer("count", torch.tensor(1e-4))

    @property
    def std(self) -> torch.Tensor:
        return torch.sqrt(self.var + 1e-8)

    def update(self, x: torch.Tensor) -> None:
        batch_mean, batch_var, n = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta, total = batch_mean - self.mean, self.count + n
        self.mean += delta * n / total
        self.var = (self.var * self.count + batch_var * n + delta.square() * self.count * n / total) / total
        self.count = total

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.clamp((x - self.mean) / self.std, -10.0, 10.0)


class ActorCritic(nn.Module):
    """The Gaussian actor (its mean an MLP or an imported network, :mod:`.walker_actor`; a learned log std)
    and the privileged critic (its output in the returns' standardised units under ``value_norm``:
    :attr:`value_norm` holds their statistics)."""

    def __init__(self, obs_dim: int, privileged_dim: int, action_dim: int, cfg: WalkerPPOConfig) -> None:
        super().__init__()
        self.actor = mlp([obs_dim, *cfg.hidden_sizes, action_dim], cfg.activation)
        self.critic = mlp([obs_dim + privileged_dim, *cfg.critic_hidden_sizes, 1], "elu")
        self.critic_norm = RunningNorm(obs_dim + privileged_dim)
        self.value_norm = RunningNorm(1)  # the returns' (kept, and unused, without cfg.value_norm)
        self.log_std = nn.Parameter(torch.full((action_dim,), math.log(cfg.init_std)))
        self.activation = cfg.activation
        self.normalises_values = cfg.value_norm

    @classmethod
    def from_actor(cls, actor: ImportedActor, privileged_dim: int, cfg: WalkerPPOConfig) -> ActorCritic:
        """An actor-critic whose actor is ``actor``'s network exactly (its architecture, any in-graph
        normaliser, layer norms and tanh head with it) and a fresh critic."""
        shaped = WalkerPPOConfig(**{**asdict(cfg), "hidden_sizes": actor.hidden_sizes,
                                    "activation": actor.activation})
        net = cls(actor.obs_dim, privileged_dim, actor.action_dim, shaped)
        net.actor = actor_module(actor.network())
        return net

    def load_actor(self, actor: Sequence[Mapping[str, np.ndarray]] | Mapping[str, Any]) -> None:
        """Set the actor to ``actor``: a network of its architecture (:meth:`network`'s form) or, for an MLP,
        its layers (``[{"w": [in, out], "b": [out]}]``, :meth:`layers`'s form)."""
        if isinstance(actor, Mapping):
            load_network(self.actor, actor)
        else:
            load_layers(self.actor, actor)

    def layers(self) -> list[dict[str, np.ndarray]]:
        """The actor's linear layers as ``[{"w": [in, out], "b": [out]}]``."""
        return [{"w": m.weight.detach().numpy().T.copy(), "b": m.bias.detach().numpy().copy()}
                for m in self.actor if isinstance(m, nn.Linear)]

    def network(self) -> dict[str, Any]:
        """The actor's network now (:func:`.walker_actor.network_of`: its architecture with its arrays), what
        the ONNX export writes and the collect workers are sent."""
        return network_of(self.actor)

    def actor_parameters(self) -> list[nn.Parameter]:
        """What the actor's optimiser group moves and its clip covers: the mean's layers and ``log_std``."""
        return [*self.actor.parameters(), self.log_std]

    def critic_output(self, obs: torch.Tensor, privileged: torch.Tensor) -> torch.Tensor:
        """The critic's raw output (standardised returns under ``value_norm``, else reward units)."""
        return self.critic(self.critic_norm(torch.cat([obs, privileged], dim=-1))).squeeze(-1)

    def value(self, obs: torch.Tensor, privileged: torch.Tensor) -> torch.Tensor:
        """The value in reward units."""
        out = self.critic_output(obs, privileged)
        return out * self.value_norm.std + self.value_norm.mean if self.normalises_values else out

    def value_target(self, returns: torch.Tensor) -> torch.Tensor:
        """``returns`` in :meth:`critic_output`'s units."""
        return (returns - self.value_norm.mean) / self.value_norm.std if self.normalises_values else returns

    @torch.no_grad()
    def update_value_norm(self, returns: torch.Tensor) -> None:
        """Fold ``returns`` into the returns' statistics and rescale the critic's last layer so that its
        values in reward units stay what they were (PopArt's "preserving outputs")."""
        if not self.normalises_values:
            return
        last = self.critic[-1]
        old_mean, old_std = self.value_norm.mean.clone(), self.value_norm.std.clone()
        self.value_norm.update(returns.reshape(-1, 1))
        new_mean, new_std = self.value_norm.mean, self.value_norm.std
        last.weight.mul_(old_std / new_std)
        last.bias.copy_((last.bias * old_std + old_mean - new_mean) / new_std)


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
        self.optimizer = torch.optim.AdamW([{"params": net.actor_parameters(), "name": "actor"},
                                            {"params": list(net.critic.parameters()), "name": "critic"}],
                                           lr=cfg.learning_rate, weight_decay=0.0)
        self.iterations = 0
        #: the actor the run started from (the anchor's reference; None without one)
        self.reference = copy.deepcopy(net.actor).requires_grad_(False) if cfg.anchor_coef > 0 else None
        self.reference_std = float(cfg.init_std)
        #: the anchor's coefficient now: ``anchor_coef`` at the start, then steered to ``anchor_kl_target``
        self.anchor_coef = float(cfg.anchor_coef)

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
        """One iteration's update; its statistics (losses, KL, learning rate, std, gradient norms before
        clipping, the anchor's KL and coefficient, the returns' std)."""
        cfg, net = self.cfg, self.net
        adv, returns = gae(r, last_value, cfg.gamma, cfg.lam)
        flat = lambda x: x.reshape(-1, *x.shape[2:])
        obs, priv, actions = flat(r.obs), flat(r.privileged), flat(r.actions)
        old_logp, old_mean, adv, returns = flat(r.log_probs), flat(r.means), flat(adv), flat(returns)
        if cfg.advantage_norm == "batch":
            adv = _standardised(adv)
        net.critic_norm.update(torch.cat([obs, priv], dim=-1))
        net.update_value_norm(returns)
        targets = net.value_target(returns)
        warmup = self.iterations < cfg.critic_warmup_iterations
        old_std = net.log_std.detach().exp()
        # the starting actor's means over the batch: one pass per update (it does not move), indexed per minibatch
        ref_mean = self._reference_mean(obs)
        totals: dict[str, float] = {}
        n, size, updates = obs.shape[0], cfg.minibatch_size, 0
        for _ in range(cfg.num_epochs):
            perm = torch.randperm(n)
            for start in range(0, n - size + 1, size):
                idx = perm[start:start + size]
                stats = self._step(obs[idx], priv[idx], actions[idx], old_logp[idx], adv[idx], targets[idx], warmup,
                                   None if ref_mean is None else ref_mean[idx])
                with torch.no_grad():
                    stats["kl"] = float(_gaussian_kl(old_mean[idx], old_std, net.actor(obs[idx]), net.log_std.exp()))
                if not warmup:
                    self._adapt(stats["kl"])
                for k, v in stats.items():
                    totals[k] = totals.get(k, 0.0) + v
                updates += 1
        out = {k: v / max(updates, 1) for k, v in totals.items()}
        if ref_mean is not None:
            out.update(self._steer_anchor(obs, ref_mean, steer=not warmup))
        if net.normalises_values:
            out["value_scale"] = float(net.value_norm.std)
        self.iterations += 1
        return {**out, "learning_rate": self.learning_rate, "std": net.log_std.detach().exp().mean().item(),
                "critic_warmup": float(warmup)}

    def _step(self, obs: torch.Tensor, priv: torch.Tensor, actions: torch.Tensor, old_logp: torch.Tensor,
              adv: torch.Tensor, target: torch.Tensor, warmup: bool, ref_mean: torch.Tensor | None = None
              ) -> dict[str, float]:
        """One minibatch's gradient step (``target``: the returns in the critic's units; ``ref_mean``: the starting
        actor's means of ``obs``, under an anchor); its losses and gradient norms."""
        cfg, net = self.cfg, self.net
        if cfg.advantage_norm == "minibatch":
            adv = _standardised(adv)
        mean, std = net.actor(obs), net.log_std.exp()
        ratio = torch.exp(torch.distributions.Normal(mean, std).log_prob(actions).sum(-1) - old_logp)
        clipped = torch.clamp(ratio, 1 - cfg.clip, 1 + cfg.clip)
        surrogate = -torch.min(ratio * adv, clipped * adv).mean()
        value_loss = (net.critic_output(obs, priv) - target).square().mean()
        entropy = net.log_std.sum() + 0.5 * math.log(2 * math.pi * math.e) * net.log_std.numel()
        loss = cfg.value_coef * value_loss
        if not warmup:
            loss = loss + surrogate - cfg.entropy_coef * entropy
            if ref_mean is not None:
                loss = loss + self.anchor_coef * self._anchor_kl(ref_mean, mean)
        self.optimizer.zero_grad()
        loss.backward()
        if warmup:
            for p in net.actor_parameters():
                p.grad = None
        norms = self._clip()
        self.optimizer.step()
        with torch.no_grad():
            net.log_std.clamp_(min=math.log(cfg.min_std))
        return {"value_loss": value_loss.item(), "surrogate": surrogate.item(), **norms}

    def _clip(self) -> dict[str, float]:
        """Clip the gradients (``grad_clip``: the actor's and the critic's apart, or together); their norms
        before clipping."""
        actor, critic = self.net.actor_parameters(), list(self.net.critic.parameters())
        limit = self.cfg.max_grad_norm
        if self.cfg.grad_clip == "separate":
            a, c = nn.utils.clip_grad_norm_(actor, limit), nn.utils.clip_grad_norm_(critic, limit)
        else:
            a, c = _grad_norm(actor), _grad_norm(critic)
            nn.utils.clip_grad_norm_(actor + critic, limit)
        return {"grad_norm_actor": float(a), "grad_norm_critic": float(c)}

    @torch.no_grad()
    def _reference_mean(self, obs: torch.Tensor) -> torch.Tensor | None:
        """The starting actor's means of ``obs`` (None without an anchor)."""
        return None if self.reference is None else self.reference(obs)

    def _anchor_kl(self, ref_mean: torch.Tensor, mean: torch.Tensor) -> torch.Tensor:
        """``KL(pi_0 || pi)`` at the starting std: the distance of ``mean`` from the reference's ``ref_mean``."""
        ref_std = torch.full_like(self.net.log_std, self.reference_std)
        return _gaussian_kl(ref_mean, ref_std, mean, ref_std)

    @torch.no_grad()
    def _steer_anchor(self, obs: torch.Tensor, ref_mean: torch.Tensor, steer: bool) -> dict[str, float]:
        """The anchor KL over the iteration's batch after its update; with ``steer`` and a KL target, the
        coefficient doubled above ``1.5 * anchor_kl_target``, halved below ``anchor_kl_target / 1.5``."""
        kl = float(self._anchor_kl(ref_mean, self.net.actor(obs)))
        target, (lo, hi) = self.cfg.anchor_kl_target, self.cfg.anchor_coef_bounds
        if steer and target > 0:
            if kl > 1.5 * target:
                self.anchor_coef = min(hi, self.anchor_coef * 2.0)
            elif kl < target / 1.5:
                self.anchor_coef = max(lo, self.anchor_coef / 2.0)
        return {"anchor_kl": kl, "anchor_coef": self.anchor_coef}

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
                "learning_rate": self.learning_rate, "iterations": self.iterations, "anchor_coef": self.anchor_coef,
                "reference": self.reference.state_dict() if self.reference is not None else None}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        self.net.load_state_dict(state["net"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.learning_rate, self.iterations = float(state["learning_rate"]), int(state["iterations"])
        self.anchor_coef = float(state.get("anchor_coef", self.cfg.anchor_coef))
        if self.reference is not None and state.get("reference") is not None:
            self.reference.load_state_dict(state["reference"])
        self._adapt(self.cfg.desired_kl)  # the rate recorded, applied to the optimizer (within the bounds)


def _standardised(x: torch.Tensor) -> torch.Tensor:
    return (x - x.mean()) / (x.std() + 1e-8)


def _grad_norm(params: Sequence[nn.Parameter]) -> torch.Tensor:
    """The 2-norm of ``params``' gradients together (0 without any)."""
    grads = [p.grad.detach().norm() for p in params if p.grad is not None]
    return torch.linalg.vector_norm(torch.stack(grads)) if grads else torch.tensor(0.0)


def _gaussian_kl(mean0: torch.Tensor, std0: torch.Tensor, mean1: torch.Tensor, std1: torch.Tensor) -> torch.Tensor:
    """Mean over rows of ``KL(N(mean0, std0) || N(mean1, std1))`` summed over the action's dimensions."""
    kl = torch.log(std1 / std0) + (std0.square() + (mean0 - mean1).square()) / (2.0 * std1.square()) - 0.5
    return kl.sum(-1).mean()
