"""The mujoco walker trainer started from Holosoma's FastSAC walker (mujoco/walker_actor.py, walker_ppo.py,
walker_collect.py, walker_training.export_walker):

- ``ActorCritic.from_actor`` builds the FastSAC network (normaliser, layer norms, SiLU, tanh head) whose
  mean is the shipped file's deterministic action, PPO's Gaussian around it with the learned ``log_std``,
  and a fresh MLP critic; a PPO update moves the layers and layer norms, not the normaliser or the head's
  scale;
- what the collect workers are sent carries the architecture: the actor a worker builds from it, and
  reloads every iteration, acts as the trainer's;
- the export of a moved actor is Holosoma's format with the metadata the exporter writes, acts as the torch
  actor under onnxruntime, and reads back into the same network;
- an MLP with an in-graph normaliser (an mjx export) starts too, the normaliser kept in its export.
"""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from econmotor.couriers.onnx_actor import read_actor
from econmotor.couriers.policy_import import find_holosoma_python, shipped_policy_path
from econmotor.motor_backend.mujoco.walker_actor import actor_module, load_network
from econmotor.motor_backend.mujoco.walker_collect import actor_weights
from econmotor.motor_backend.mujoco.walker_ppo import ActorCritic, Rollout, WalkerPPO
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
from econmotor.motor_backend.mujoco.walker_training import export_walker
from econmotor.robots import G1_29DOF

pytestmark = [pytest.mark.holosoma]  # the shipped file resolves in .venv-holosoma's holosoma_inference
REPO = Path(__file__).resolve().parents[4]
NAME = "holosoma:g1_29dof/fastsac"
PRIV = 9


def onnxruntime_actions(path: Path, obs: np.ndarray) -> np.ndarray:
    """The file's actions, one row at a time (the shipped file takes a batch of one)."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name
    return np.concatenate([session.run(None, {name: row[None]})[0] for row in obs])


@pytest.fixture(scope="module")
def fastsac():
    return read_actor(shipped_policy_path(NAME, find_holosoma_python(REPO / ".venv-holosoma")), NAME)


def _obs(seed: int, n: int = 64) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, 1.0, size=(n, 100)).astype(np.float32)


def _moved(net: ActorCritic, seed: int) -> None:
    """Every learned parameter of the actor moved a little (as updates would)."""
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in net.actor.parameters():
            p.add_(0.02 * torch.randn(p.shape, generator=g))


def test_the_actor_critic_from_fastsac_acts_as_the_shipped_file(fastsac) -> None:
    cfg = WalkerPPOConfig()
    net = ActorCritic.from_actor(fastsac, PRIV, cfg)
    kinds = [type(m).__name__ for m in net.actor]
    assert kinds == ["Normaliser", *["Linear", "LayerNorm", "SiLU"] * 3, "Linear", "TanhHead"]
    learner = WalkerPPO(net, cfg)
    obs = _obs(0)
    expected = onnxruntime_actions(fastsac.path, obs)
    assert np.std(expected) > 0.5
    assert np.abs(learner.mean_action(obs) - expected).max() < 1e-4
    # PPO's Gaussian around that action, its std the learned log_std
    np.testing.assert_allclose(net.log_std.detach().exp().numpy(), np.full(29, cfg.init_std), rtol=1e-6)
    torch.manual_seed(0)
    actions, out = learner.act(obs, np.zeros((64, PRIV), np.float32))
    np.testing.assert_allclose(out["means"].numpy(), learner.mean_action(obs), atol=1e-6)
    assert np.std(actions - out["means"].numpy()) == pytest.approx(cfg.init_std, rel=0.05)
    # a fresh critic: an ELU MLP of the observation and the privileged view, nothing from the ONNX
    linears = [m for m in net.critic if isinstance(m, nn.Linear)]
    assert linears[0].in_features == 100 + PRIV and linears[-1].out_features == 1
    assert [m.out_features for m in linears[:-1]] == list(cfg.critic_hidden_sizes)
    assert all(isinstance(m, (nn.Linear, nn.ELU)) for m in net.critic)


def test_an_update_moves_the_layers_and_layer_norms_not_the_normaliser_or_the_head(fastsac) -> None:
    cfg = WalkerPPOConfig.from_mapping({"num_envs": 8, "steps_per_iteration": 8, "num_minibatches": 2,
                                        "num_epochs": 1, "critic_warmup_iterations": 0, "anchor_coef": 0.2})
    torch.manual_seed(0)
    learner = WalkerPPO(ActorCritic.from_actor(fastsac, PRIV, cfg), cfg)
    before = {k: v.clone() for k, v in learner.net.actor.state_dict().items()}
    g = torch.Generator().manual_seed(1)
    obs = torch.from_numpy(_obs(1, 64)).reshape(8, 8, 100)
    priv = torch.randn(8, 8, PRIV, generator=g)
    with torch.no_grad():
        mean = learner.net.actor(obs)
        actions = mean + learner.net.log_std.exp() * torch.randn(mean.shape, generator=g)
        logp = torch.distributions.Normal(mean, learner.net.log_std.exp()).log_prob(actions).sum(-1)
    rollout = Rollout(obs=obs, privileged=priv, actions=actions, log_probs=logp, means=mean,
                      values=learner.net.value(obs, priv).detach(), rewards=torch.randn(8, 8, generator=g),
                      dones=torch.zeros(8, 8))
    stats = learner.update(rollout, torch.zeros(8))
    assert math.isfinite(stats["surrogate"]) and stats["anchor_kl"] > 0.0
    after = learner.net.actor.state_dict()
    moved = {k for k in before if not torch.equal(before[k], after[k])}
    assert {"1.weight", "2.weight", "2.bias", "10.weight"} <= moved
    assert not moved & {"0.mean", "0.std", "11.scale", "11.bias"}


def test_the_collect_workers_rebuild_the_same_actor(fastsac) -> None:
    net = ActorCritic.from_actor(fastsac, PRIV, WalkerPPOConfig())
    first = pickle.loads(pickle.dumps(actor_weights(net)))  # what goes down a worker's pipe
    assert first["network"]["architecture"] == "fastsac"
    worker = actor_module(first["network"]).requires_grad_(False)  # a worker's first iteration
    obs = torch.from_numpy(_obs(2))
    with torch.no_grad():
        np.testing.assert_array_equal(worker(obs).numpy(), net.actor(obs).numpy())
        _moved(net, 3)
        load_network(worker, pickle.loads(pickle.dumps(actor_weights(net)))["network"])  # a later iteration
        np.testing.assert_array_equal(worker(obs).numpy(), net.actor(obs).numpy())
    plain = ActorCritic(100, PRIV, 29, WalkerPPOConfig())  # an MLP's network does not fit a FastSAC actor
    with pytest.raises(ValueError, match="does not fit"):
        load_network(worker, plain.network())


def test_the_export_of_a_moved_fastsac_actor_acts_as_it_and_reads_back(fastsac, tmp_path: Path) -> None:
    net = ActorCritic.from_actor(fastsac, PRIV, WalkerPPOConfig())
    _moved(net, 4)
    path = export_walker(net.network(), G1_29DOF, np.asarray(G1_29DOF.kp), np.asarray(G1_29DOF.kd),
                         G1_29DOF.command_ranges, "elu", tmp_path / "policy.onnx",
                         {"task_id": "humanoid_locomotion_g1", "init_policy": {"policy": NAME}})
    obs = _obs(5)
    with torch.no_grad():
        mine = net.actor(torch.from_numpy(obs)).numpy()
    theirs = onnxruntime_actions(path, obs)
    assert np.abs(theirs - mine).max() < 1e-4
    assert np.abs(theirs - onnxruntime_actions(fastsac.path, obs)).max() > 1e-3  # it moved: not the shipped file
    back = read_actor(path)
    assert (back.input_name, back.architecture, back.hidden_sizes, back.activation) == \
        ("actor_obs", "fastsac", (512, 256, 128), "silu")
    assert back.metadata["dof_names"] == list(G1_29DOF.dof_names) and back.metadata["kp"] == list(G1_29DOF.kp)
    assert back.metadata["econmotor_task_id"] == "humanoid_locomotion_g1" and "command_ranges" in back.metadata
    fresh = ActorCritic.from_actor(fastsac, PRIV, WalkerPPOConfig())
    fresh.load_actor(back.network())  # what the training loop does with the best held-out policy
    with torch.no_grad():
        np.testing.assert_allclose(fresh.actor(torch.from_numpy(obs)).numpy(), mine, atol=1e-6)


def test_an_mlp_with_an_in_graph_normaliser_starts_and_exports_with_it(tmp_path: Path) -> None:
    """The normaliser FastSAC needs serves an MLP's too (an mjx export's, Sub/Div/Clip): once refused, now read
    into the torch actor and written back by the export."""
    from econmotor.couriers.onnx_export import export_onnx

    rng = np.random.default_rng(6)
    layers = [{"w": rng.normal(0, 0.3, (100, 16)).astype(np.float32), "b": rng.normal(0, 0.1, 16).astype(np.float32)},
              {"w": rng.normal(0, 0.3, (16, 29)).astype(np.float32), "b": rng.normal(0, 0.1, 29).astype(np.float32)}]
    stats = (rng.normal(0, 1, 100).astype(np.float32), rng.uniform(0.5, 2.0, 100).astype(np.float32))
    bound = np.full(29, 100.0, np.float32)
    source = export_onnx({"policy": layers}, stats, 3.0, -bound, bound, tmp_path / "mjx.onnx", {"task_id": "t"},
                         activation="tanh")
    actor = read_actor(source)
    assert actor.architecture == "mlp" and actor.clip_obs == 3.0
    net = ActorCritic.from_actor(actor, PRIV, WalkerPPOConfig())
    obs = _obs(7) * 4.0  # some clipped by the normaliser's clip
    with torch.no_grad():
        mine = net.actor(torch.from_numpy(obs)).numpy()
    assert np.abs(mine - onnxruntime_actions(source, obs)).max() < 1e-5
    path = export_walker(net.network(), G1_29DOF, np.asarray(G1_29DOF.kp), np.asarray(G1_29DOF.kd),
                         G1_29DOF.command_ranges, "tanh", tmp_path / "policy.onnx", {"task_id": "t"})
    assert np.abs(onnxruntime_actions(path, obs) - mine).max() < 1e-5
