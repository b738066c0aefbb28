"""The walker PPO's fine-tuning recipe (mujoco/walker_ppo.py), each change against its undone setting:

- advantages standardised per minibatch: a fall in one minibatch does not drown the others' signal;
- value normalisation (PopArt): a fall's return does not blow up the value loss, the critic reaches
  returns of hundreds, and rescaling the statistics leaves the values in reward units where they were;
- the actor's and the critic's gradients clipped apart: the critic's gradient after a fall does not
  shrink the actor's;
- the anchor's coefficient follows a KL target (doubled above 1.5x, halved below 1/1.5x), so the actor
  moves to the target where a fixed coefficient pins it;
- the exploration std is learned by the actor's optimiser and floored at ``min_std``;
- a checkpoint keeps all of it; the new settings are validated by name.

Synthetic rollouts on small networks (real torch, a few seconds in all); every draw is seeded.
"""

from __future__ import annotations

import io
import itertools
from collections.abc import Callable

import pytest
import torch

from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.walker_ppo import ActorCritic, Rollout, WalkerPPO
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig

OBS, PRIV, ACT = 6, 4, 3
#: a fall's reward on the G1 (issue 54: about -2,333 against steps of order 1)
FALL = -2333.0
Reward = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


def _learner(seed: int = 0, **settings) -> WalkerPPO:
    """A small learner: 256 samples an iteration, the learning rate fixed, one-step returns (gamma 0)."""
    base = {"num_envs": 16, "steps_per_iteration": 16, "num_minibatches": 2, "num_epochs": 5,
            "critic_warmup_iterations": 0, "hidden_sizes": [16], "critic_hidden_sizes": [32], "gamma": 0.0,
            "lam": 0.0, "learning_rate": 1e-3, "lr_bounds": [1e-3, 1e-3]}
    cfg = WalkerPPOConfig.from_mapping({**base, **settings})
    torch.manual_seed(seed)
    return WalkerPPO(ActorCritic(OBS, PRIV, ACT, cfg), cfg)


def _rollout(learner: WalkerPPO, seed: int, reward: Reward, fall: bool = True) -> tuple[Rollout, torch.Tensor]:
    """One iteration acted by ``learner``'s actor: ``reward(noise, privileged)`` per sample (``noise``: the
    action's exploration draw in std units); with ``fall`` the first sample falls (reward FALL, its action
    the mean, a privileged marker the critic can see)."""
    cfg, net = learner.cfg, learner.net
    g = torch.Generator().manual_seed(seed)
    t, n = cfg.steps_per_iteration, cfg.num_envs
    obs, priv = torch.randn(t, n, OBS, generator=g), torch.randn(t, n, PRIV, generator=g)
    noise = torch.randn(t, n, ACT, generator=g)
    rewards, dones = reward(noise, priv), torch.zeros(t, n)
    if fall:
        noise[0, 0], rewards[0, 0], dones[0, 0], priv[0, 0, 1] = 0.0, FALL, 1.0, 4.0
    with torch.no_grad():
        mean, std = net.actor(obs), net.log_std.exp()
        actions = mean + std * noise
        logp = torch.distributions.Normal(mean, std).log_prob(actions).sum(-1)
        values = net.value(obs, priv)
    return Rollout(obs=obs, privileged=priv, actions=actions, log_probs=logp, means=mean, values=values,
                   rewards=rewards, dones=dones), torch.zeros(n)


def _toward_first_joint(noise: torch.Tensor, priv: torch.Tensor) -> torch.Tensor:
    """Pays an action for its exploration along the first joint: the better policy's mean is higher there."""
    return noise[..., 0].clone()


def _clipped_actor_grad(learner: WalkerPPO) -> float:
    """The norm of the actor's gradient the optimiser last stepped with (after clipping)."""
    return torch.linalg.vector_norm(torch.stack([p.grad.norm() for p in learner.net.actor_parameters()])).item()


def test_defaults_are_the_fine_tuning_recipe() -> None:
    cfg = WalkerPPOConfig()
    assert (cfg.advantage_norm, cfg.grad_clip, cfg.value_norm) == ("minibatch", "separate", True)
    assert (cfg.anchor_kl_target, cfg.init_std, cfg.min_std) == (10.0, 0.1, 0.02)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_per_minibatch_advantages_keep_the_signal_a_fall_would_drown(seed: int) -> None:
    """One fall among 256 samples: standardised over the batch, its advantage takes the batch's std and
    the other samples' advantages shrink to a constant; per minibatch, the three in four minibatches
    without it keep their unit-scale signal and the actor learns to raise the first joint."""
    gain = {}
    for mode in ("minibatch", "batch"):
        learner = _learner(seed, advantage_norm=mode, num_minibatches=4, num_epochs=2, hidden_sizes=[16])
        r, last = _rollout(learner, seed, _toward_first_joint)
        obs = r.obs.reshape(-1, OBS)
        before = learner.net.actor(obs).detach()
        learner.update(r, last)
        gain[mode] = ((learner.net.actor(obs).detach() - before)[:, 0].mean() / learner.cfg.init_std).item()
    assert gain["minibatch"] > 0.2, gain
    assert gain["minibatch"] > 3.0 * gain["batch"], gain


def test_value_normalisation_keeps_a_fall_from_blowing_up_the_critic() -> None:
    """Returns of 300 +- 50 a step and one fall an iteration: in standardised units the value loss stays
    of order one and the critic reaches the returns within 20 iterations; in reward units its loss is in
    the hundred thousands and its clipped steps leave it near zero."""
    returns = lambda noise, priv: 300.0 + 50.0 * priv[..., 0]
    error, loss = {}, {}
    for normalised in (True, False):
        learner = _learner(value_norm=normalised, critic_warmup_iterations=1000)
        for i in range(20):
            stats = learner.update(*_rollout(learner, 100 + i, returns))
        loss[normalised] = stats["value_loss"]
        r, _ = _rollout(learner, 999, returns, fall=False)
        error[normalised] = (learner.net.value(r.obs, r.privileged) - r.rewards).square().mean().sqrt().item()
    assert loss[True] < 10.0 and loss[False] > 1e3, loss
    assert error[True] < 80.0 and error[False] > 200.0, error  # RMS error in reward units; returns' std 50


def test_value_normalisation_keeps_the_values_in_reward_units() -> None:
    """New statistics (returns about 1000 +- 300) rescale the critic's last layer: its values stay put."""
    learner = _learner()
    obs, priv = torch.randn(64, OBS), torch.randn(64, PRIV)
    before = learner.net.value(obs, priv).detach()
    learner.net.update_value_norm(1000.0 + 300.0 * torch.randn(512, generator=torch.Generator().manual_seed(0)))
    assert learner.net.value_norm.mean.item() == pytest.approx(1000.0, rel=0.05)
    assert learner.net.value_norm.std.item() == pytest.approx(300.0, rel=0.1)
    torch.testing.assert_close(learner.net.value(obs, priv).detach(), before, rtol=1e-4, atol=1e-4)
    target = learner.net.value_target(torch.tensor([1000.0]))
    assert abs(target.item()) < 0.2  # the critic is fitted to standardised returns


def test_actor_and_critic_are_clipped_apart() -> None:
    """A critic in reward units after a fall: its gradient norm is near a hundred, the actor's below the
    limit. Clipped apart, the actor steps with its own gradient whatever the critic's loss weighs; clipped
    together, the critic's gradient shrinks it by the ratio of the two."""
    clipped, raw = {}, {}
    for mode, value_coef in (("separate", 1.0), ("separate", 100.0), ("joint", 1.0)):
        learner = _learner(grad_clip=mode, value_coef=value_coef, value_norm=False, num_minibatches=1,
                           num_epochs=1, max_grad_norm=1.0)
        stats = learner.update(*_rollout(learner, 0, _toward_first_joint))
        clipped[mode, value_coef] = _clipped_actor_grad(learner)
        raw[mode, value_coef] = (stats["grad_norm_actor"], stats["grad_norm_critic"])
    actor, critic = raw["separate", 1.0]
    assert actor < 1.0 < 10.0 < critic, raw  # the critic's far beyond the limit, the actor's within it
    assert clipped["separate", 1.0] == pytest.approx(actor, rel=1e-4)  # its own gradient, untouched
    assert clipped["separate", 100.0] == pytest.approx(actor, rel=1e-4)
    assert clipped["joint", 1.0] == pytest.approx(actor / (actor**2 + critic**2) ** 0.5, rel=1e-3)
    assert clipped["joint", 1.0] < 0.05 * clipped["separate", 1.0], clipped


def test_the_anchor_coefficient_follows_the_kl_target() -> None:
    """Started at 50 (a leash the actor cannot move against), the coefficient halves while the anchor KL
    is under target / 1.5 and the actor moves to the target; a fixed 50 pins it at a hundredth of it.
    Started at the bounds' floor against a tiny target, it doubles."""
    target = 0.05
    trace: dict[float, list[tuple[float, float]]] = {}
    for kl_target in (target, 0.0):
        learner = _learner(anchor_coef=50.0, anchor_kl_target=kl_target)
        trace[kl_target] = []
        for i in range(12):
            stats = learner.update(*_rollout(learner, i, _toward_first_joint, fall=False))
            trace[kl_target].append((stats["anchor_kl"], stats["anchor_coef"]))
    steered, fixed = trace[target], trace[0.0]
    assert steered[0][1] == 25.0 and steered[1][1] == 12.5  # under target / 1.5: halved each iteration
    assert target / 1.5 < steered[-1][0] < 1.5 * target, steered
    assert all(coef == 50.0 for _, coef in fixed) and max(kl for kl, _ in fixed) < target / 10, fixed
    rising = _learner(anchor_coef=1e-3, anchor_kl_target=1e-5)
    coefs = [rising.update(*_rollout(rising, i, _toward_first_joint, fall=False))["anchor_coef"] for i in range(3)]
    assert coefs == [2e-3, 4e-3, 8e-3]


def test_the_default_anchor_lets_the_objective_move_the_gait() -> None:
    """Under the default target (10 nats), an objective that pays one joint moves its mean several stds from
    the start before the anchor holds it; the old target of 1 nat held it within about 1.4 std (the G1's
    fine-tune stopped learning once the anchor reached it)."""
    moved = {}
    for settings in ({}, {"anchor_kl_target": 1.0}):
        learner = _learner(anchor_coef=0.2, **settings)
        start = learner.net.actor(torch.zeros(1, OBS)).detach()
        for i in range(40):
            learner.update(*_rollout(learner, i, _toward_first_joint, fall=False))
        shift = (learner.net.actor(torch.zeros(1, OBS)).detach() - start)[0, 0].item()
        moved[settings.get("anchor_kl_target", "default")] = shift / learner.cfg.init_std
    assert moved["default"] > 3.0 and moved[1.0] < 2.0, moved


def test_the_starting_actor_is_evaluated_once_an_update_and_pulls_as_it_did_per_minibatch() -> None:
    """The anchor's reference does not move: its means over the batch are taken once per update (not once per
    minibatch and epoch), and the anchor's gradient on a minibatch is the one its own pass would give."""
    learner = _learner(anchor_coef=1.0)
    rollout, last = _rollout(learner, 0, _toward_first_joint)
    calls: list[int] = []
    learner.reference.register_forward_hook(lambda module, args, out: calls.append(args[0].shape[0]))
    learner.update(rollout, last)
    assert calls == [learner.cfg.num_envs * learner.cfg.steps_per_iteration]  # one pass over the whole batch
    obs = rollout.obs.reshape(-1, OBS)[:40]
    learner.optimizer.zero_grad()
    own = learner._anchor_kl(learner.reference(obs), learner.net.actor(obs))
    torch.autograd.backward(own, inputs=list(learner.net.actor.parameters()))
    per_minibatch = [p.grad.clone() for p in learner.net.actor.parameters()]
    learner.optimizer.zero_grad()
    batch_mean = learner._reference_mean(rollout.obs.reshape(-1, OBS))[:40]
    torch.autograd.backward(learner._anchor_kl(batch_mean, learner.net.actor(obs)),
                            inputs=list(learner.net.actor.parameters()))
    for a, p in zip(per_minibatch, learner.net.actor.parameters(), strict=True):
        torch.testing.assert_close(p.grad, a)


def test_the_anchor_coefficient_waits_for_the_critic() -> None:
    learner = _learner(anchor_coef=1.0, critic_warmup_iterations=2)
    for i in range(2):
        stats = learner.update(*_rollout(learner, i, _toward_first_joint, fall=False))
        assert stats["critic_warmup"] == 1.0 and stats["anchor_coef"] == 1.0 and stats["anchor_kl"] == 0.0


def test_the_exploration_std_is_learned_and_floored() -> None:
    """Rewards that punish exploration shrink the std: the actor's optimiser moves log_std, down to
    min_std and no further (without the floor it reaches 0.014 within these 10 iterations)."""
    learner = _learner(init_std=0.03, min_std=0.02, learning_rate=3e-2, lr_bounds=[3e-2, 3e-2],
                       critic_hidden_sizes=[16])
    actor_group = next(g for g in learner.optimizer.param_groups if g["name"] == "actor")
    assert any(p is learner.net.log_std for p in actor_group["params"])
    punished = lambda noise, priv: -noise.square().sum(-1)
    stds = []
    for i in range(10):
        learner.update(*_rollout(learner, i, punished, fall=False))
        stds.append(learner.net.log_std.exp().min().item())
    assert stds[0] < 0.03 and all(b <= a + 1e-7 for a, b in itertools.pairwise(stds)), stds
    assert min(stds) >= 0.02 * (1 - 1e-6) and stds[-1] == pytest.approx(0.02, rel=1e-6), stds


def test_the_exploration_std_waits_for_the_critic() -> None:
    learner = _learner(critic_warmup_iterations=1)
    start = learner.net.log_std.detach().clone()
    learner.update(*_rollout(learner, 0, _toward_first_joint))
    assert torch.equal(learner.net.log_std.detach(), start)
    learner.update(*_rollout(learner, 1, _toward_first_joint))
    assert not torch.equal(learner.net.log_std.detach(), start)


def test_a_checkpoint_keeps_the_recipes_state() -> None:
    """After three updates (the std, the returns' statistics and the anchor's coefficient all moved), a
    fresh learner loaded from the saved state acts, values and updates exactly as the original."""
    settings = {"anchor_coef": 1.0, "anchor_kl_target": 0.01}
    learner = _learner(seed=0, **settings)
    for i in range(3):
        learner.update(*_rollout(learner, i, _toward_first_joint))
    assert learner.anchor_coef != 1.0 and not torch.allclose(learner.net.log_std, torch.full((ACT,), -2.302585))
    buffer = io.BytesIO()
    torch.save(learner.state_dict(), buffer)
    buffer.seek(0)
    restored = _learner(seed=1, **settings)
    restored.load_state_dict(torch.load(buffer, weights_only=False))
    assert restored.anchor_coef == learner.anchor_coef
    assert torch.equal(restored.net.log_std, learner.net.log_std)
    for name in ("mean", "var", "count"):
        assert torch.equal(getattr(restored.net.value_norm, name), getattr(learner.net.value_norm, name))
    r, last = _rollout(learner, 7, _toward_first_joint)
    torch.testing.assert_close(restored.net.value(r.obs, r.privileged), learner.net.value(r.obs, r.privileged))
    stats = []
    for one in (learner, restored):
        torch.manual_seed(5)
        stats.append(one.update(r, last))
    assert stats[0] == stats[1]
    for a, b in zip(learner.net.parameters(), restored.net.parameters(), strict=True):
        assert torch.equal(a, b)


@pytest.mark.parametrize(("key", "value"), [
    ("advantage_norm", "whole"), ("grad_clip", "both"), ("value_norm", "maybe"), ("min_std", 0.0),
    ("min_std", 0.5), ("anchor_kl_target", -0.1), ("anchor_coef_bounds", [0.0, 1.0]),
    ("anchor_coef_bounds", [1.0]), ("anchor_coef", -1.0), ("anchor_coef", 1e4), ("max_grad_norm", 0.0),
    ("j_pace", "fast"), ("policy_lag", 2), ("policy_lag", "one"),
])
def test_a_bad_recipe_setting_is_named(key: str, value: object) -> None:
    with pytest.raises(ConfigError) as caught:
        WalkerPPOConfig.from_mapping({key: value})
    assert caught.value.key == key


def test_recipe_settings_read_from_text() -> None:
    cfg = WalkerPPOConfig.from_mapping({"value_norm": "false", "advantage_norm": "batch", "grad_clip": "joint",
                                        "anchor_coef": 1e4, "anchor_kl_target": 0})  # a fixed coefficient: any
    assert (cfg.value_norm, cfg.advantage_norm, cfg.grad_clip, cfg.anchor_coef) == (False, "batch", "joint", 1e4)
    assert WalkerPPOConfig.from_mapping(cfg.to_dict()) == cfg
