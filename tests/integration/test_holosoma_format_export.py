"""A policy exported here in Holosoma's format runs on Holosoma's own inference stack.

Holosoma's shipped G1 PPO walker goes ONNX -> the mjx JAX actor (``mjx/onnx_import.py``) -> an
econmotor export in Holosoma's format (``couriers/onnx_export.py``, the G1 card's metadata); in
``.venv-holosoma``, holosoma_inference's policy loader (``BasePolicy.setup_policy``) loads it, reads
its PD gains, and acts exactly as the shipped file on the same observations; the sim-to-sim
evaluator's importer (``policy_import.resolve_contract``) resolves it to the G1 preset.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import jax
import numpy as np
import pytest

from econmotor.couriers.onnx_actor import read_actor
from econmotor.couriers.onnx_export import export_onnx
from econmotor.couriers.policy_import import find_holosoma_python, holosoma_export_metadata, shipped_policy_path
from econmotor.motor_backend.holosoma.host.jobs import job_environment
from econmotor.motor_backend.mjx import ppo
from econmotor.robots import G1_29DOF

pytestmark = [pytest.mark.holosoma]
REPO = Path(__file__).resolve().parents[2]

# Runs in .venv-holosoma with this checkout's econmotor: holosoma_inference's own loader on our file.
LOAD = r"""
import json, sys
import numpy as np
from holosoma_inference.policies.locomotion import LocomotionPolicy
from econmotor.couriers.policy_import import resolve_contract

out = {}
for name, path in (("ours", sys.argv[1]), ("shipped", sys.argv[2])):
    policy = LocomotionPolicy.__new__(LocomotionPolicy)  # its loader, without robot SDK or input devices
    policy.setup_policy(path)
    obs = np.load(sys.argv[3])
    actions = np.concatenate([policy.policy({"actor_obs": row[None]}) for row in obs])
    c = resolve_contract(path)
    out[name] = {"inputs": policy.onnx_input_names, "outputs": policy.onnx_output_names,
                 "kp": policy.onnx_kp.tolist(), "kd": policy.onnx_kd.tolist(), "actions": actions.tolist(),
                 "contract": {"obs_dim": c.obs_dim, "preset": c.inference_preset, "action_scale": c.card.action_scale,
                              "dof_names": list(c.dof_names), "command_ranges": c.command_ranges}}
print("@@loaded " + json.dumps(out))
"""


def in_holosoma(script: str, *args: str) -> dict:
    """Run ``script`` in .venv-holosoma on this checkout's source; its ``@@loaded`` line, decoded."""
    python = find_holosoma_python(REPO / ".venv-holosoma")
    env = {**job_environment(), "PYTHONPATH": str(REPO / "src")}
    proc = subprocess.run([str(python), "-c", script, *args], capture_output=True, text=True, env=env, timeout=300,
                          cwd=os.getcwd())
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("@@loaded ")), None)
    assert line is not None, proc.stdout[-2000:] + proc.stderr[-4000:]
    return json.loads(line[len("@@loaded "):])


def test_export_of_the_imported_g1_walker_loads_and_acts_in_holosoma_inference(tmp_path: Path) -> None:
    shipped = shipped_policy_path("holosoma:g1_29dof/ppo", find_holosoma_python(REPO / ".venv-holosoma"))
    actor = read_actor(shipped, "holosoma:g1_29dof/ppo")
    cfg = ppo.PPOConfig(hidden_sizes=actor.hidden_sizes, activation=actor.activation, normalize_obs=False)
    learner = ppo.init_learner(jax.random.PRNGKey(0), actor.obs_dim, actor.action_dim, cfg)
    params = {**jax.device_get(learner.params), "policy": actor.layers}
    bound = np.full(actor.action_dim, G1_29DOF.action_clip, np.float32)
    ours = export_onnx(params, None, cfg.clip_obs, -bound, bound, tmp_path / "policy.onnx",
                       {"task_id": "g1_courier", "objective": {"name": "energy_saver"}}, activation=cfg.activation,
                       holosoma=holosoma_export_metadata(G1_29DOF))
    obs = np.random.default_rng(0).normal(0.0, 0.5, size=(16, actor.obs_dim)).astype(np.float32)
    np.save(tmp_path / "obs.npy", obs)
    got = in_holosoma(LOAD, str(ours), str(shipped), str(tmp_path / "obs.npy"))
    mine, theirs = got["ours"], got["shipped"]
    assert (mine["inputs"], mine["outputs"]) == (["actor_obs"], ["action"]) == (theirs["inputs"], theirs["outputs"])
    assert mine["kp"] == list(G1_29DOF.kp) and mine["kd"] == list(G1_29DOF.kd)
    np.testing.assert_allclose(mine["kp"], theirs["kp"], rtol=1e-9)  # the card's gains are the walker's
    np.testing.assert_allclose(np.asarray(mine["actions"]), np.asarray(theirs["actions"]), rtol=1e-5, atol=1e-5)
    assert np.std(theirs["actions"]) > 0.1
    assert mine["contract"]["obs_dim"] == 100 and mine["contract"]["preset"] == "g1-29dof-loco"
    assert mine["contract"]["dof_names"] == theirs["contract"]["dof_names"] == list(G1_29DOF.dof_names)
    assert mine["contract"]["action_scale"] == G1_29DOF.action_scale


def test_the_cpu_trainers_export_loads_and_acts_in_holosoma_inference(tmp_path: Path) -> None:
    """The mujoco walker trainer's export (``walker_training.export_walker``) of the shipped actor acts as the shipped
    file in holosoma_inference's loader; the fine-tuned G1 walkers committed under benchmarks/results load there
    and act as onnxruntime runs them here."""
    from econmotor.couriers.policy_import import batched_onnx_policy, resolve_contract
    from econmotor.motor_backend.mujoco.walker_ppo import ActorCritic
    from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
    from econmotor.motor_backend.mujoco.walker_training import export_walker

    shipped = shipped_policy_path("holosoma:g1_29dof/ppo", find_holosoma_python(REPO / ".venv-holosoma"))
    actor = read_actor(shipped, "holosoma:g1_29dof/ppo")
    layers = ActorCritic.from_actor(actor, 9, WalkerPPOConfig()).layers()
    contract = resolve_contract(str(shipped))
    ours = export_walker(layers, G1_29DOF, np.asarray(contract.kp), np.asarray(contract.kd), contract.command_ranges,
                         actor.activation, tmp_path / "policy.onnx", {"task_id": "humanoid_locomotion_g1"})
    obs = np.random.default_rng(1).normal(0.0, 0.5, size=(16, actor.obs_dim)).astype(np.float32)
    np.save(tmp_path / "obs.npy", obs)
    got = in_holosoma(LOAD, str(ours), str(shipped), str(tmp_path / "obs.npy"))
    np.testing.assert_allclose(np.asarray(got["ours"]["actions"]), np.asarray(got["shipped"]["actions"]),
                               rtol=1e-5, atol=1e-5)
    assert got["ours"]["kp"] == got["shipped"]["kp"] and got["ours"]["contract"]["preset"] == "g1-29dof-loco"
    committed = sorted((REPO / "benchmarks" / "results").glob("g1_*/*.onnx"))
    for path in committed:
        got = in_holosoma(LOAD, str(path), str(shipped), str(tmp_path / "obs.npy"))["ours"]
        here = batched_onnx_policy(resolve_contract(str(path)))(obs)
        np.testing.assert_allclose(np.asarray(got["actions"]), here, rtol=1e-5, atol=1e-5)
        assert got["contract"]["dof_names"] == list(G1_29DOF.dof_names)


def test_a_fine_tune_started_from_fastsac_exports_what_holosoma_inference_loads(tmp_path: Path) -> None:
    """The mujoco walker trainer's export of an actor started from the shipped G1 FastSAC walker (its normaliser,
    layer norms and tanh head) loads in holosoma_inference's loader: before any update it acts as the shipped
    file there; moved as updates move it, it acts as the torch actor."""
    import torch

    from econmotor.couriers.policy_import import resolve_contract
    from econmotor.motor_backend.mujoco.walker_ppo import ActorCritic
    from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
    from econmotor.motor_backend.mujoco.walker_training import export_walker

    name = "holosoma:g1_29dof/fastsac"
    shipped = shipped_policy_path(name, find_holosoma_python(REPO / ".venv-holosoma"))
    actor = read_actor(shipped, name)
    contract = resolve_contract(str(shipped))
    net = ActorCritic.from_actor(actor, 9, WalkerPPOConfig())
    export = lambda path: export_walker(net.network(), G1_29DOF, np.asarray(contract.kp), np.asarray(contract.kd),
                                        contract.command_ranges, actor.activation, path,
                                        {"task_id": "humanoid_locomotion_g1", "init_policy": {"policy": name}})
    start = export(tmp_path / "start.onnx")
    with torch.no_grad():
        g = torch.Generator().manual_seed(0)
        for p in net.actor.parameters():
            p.add_(0.02 * torch.randn(p.shape, generator=g))
    moved = export(tmp_path / "moved.onnx")
    obs = np.random.default_rng(2).normal(0.0, 0.5, size=(16, actor.obs_dim)).astype(np.float32)
    np.save(tmp_path / "obs.npy", obs)
    got = in_holosoma(LOAD, str(start), str(shipped), str(tmp_path / "obs.npy"))
    mine, theirs = got["ours"], got["shipped"]
    assert (mine["inputs"], mine["outputs"]) == (["actor_obs"], ["action"]) == (theirs["inputs"], theirs["outputs"])
    assert np.abs(np.asarray(mine["actions"]) - np.asarray(theirs["actions"])).max() < 1e-4
    assert np.std(theirs["actions"]) > 0.1
    assert mine["kp"] == theirs["kp"] and mine["kd"] == theirs["kd"]
    assert mine["contract"]["preset"] == "g1-29dof-loco" and mine["contract"]["obs_dim"] == 100
    assert mine["contract"]["dof_names"] == theirs["contract"]["dof_names"]
    assert mine["contract"]["command_ranges"] == theirs["contract"]["command_ranges"]
    got = in_holosoma(LOAD, str(moved), str(shipped), str(tmp_path / "obs.npy"))["ours"]
    with torch.no_grad():
        torch_actions = net.actor(torch.from_numpy(obs)).numpy()
    assert np.abs(np.asarray(got["actions"]) - torch_actions).max() < 1e-4
    assert np.abs(np.asarray(got["actions"]) - np.asarray(theirs["actions"])).max() > 1e-3  # it did move
