"""An ONNX actor's weights as the mjx JAX actor's (motor_backend/mjx/onnx_import.py).

Holosoma's shipped PPO walkers, converted, act as onnxruntime runs them; an econmotor export
(either format) reads back into the same parameters; an architecture the mjx actor lacks (the
FastSAC walkers' layer normalisation and tanh head, which ``read_actor`` reads for the mujoco
trainer) and a shipped name that does not exist are clear errors.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.couriers.onnx_actor import read_actor
from econmotor.couriers.onnx_export import export_onnx
from econmotor.couriers.policy_import import find_holosoma_python, shipped_policy_path
from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx import networks as nets
from econmotor.motor_backend.mjx import ppo
from econmotor.motor_backend.mjx.onnx_import import check_architecture, warm_start

REPO = Path(__file__).resolve().parents[4]
BOUND = np.float32(1e4)  # wide action bounds: the comparison is of the network, not of a clip


def onnxruntime_actions(path: Path, obs: np.ndarray) -> np.ndarray:
    """The file's actions, one row at a time (Holosoma's files take a batch of one)."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name
    return np.concatenate([session.run(None, {name: row[None]})[0] for row in obs])


def jax_actions(actor, obs: np.ndarray) -> np.ndarray:
    cfg = ppo.PPOConfig(hidden_sizes=actor.hidden_sizes, activation=actor.activation,
                        normalize_obs=actor.obs_mean is not None)
    params = {"policy": [{"w": jnp.asarray(layer["w"]), "b": jnp.asarray(layer["b"])} for layer in actor.layers]}
    stats = nets.init_stats(actor.obs_dim)
    if actor.obs_mean is not None:
        stats = nets.RunningStats(stats.count, jnp.asarray(actor.obs_mean),
                                  jnp.asarray(np.square(actor.obs_std) - nets.NORM_EPS))
        cfg = ppo.PPOConfig(**{**cfg.to_dict(), "hidden_sizes": actor.hidden_sizes, "clip_obs": actor.clip_obs or 1e30})
    low, high = jnp.full((actor.action_dim,), -BOUND), jnp.full((actor.action_dim,), BOUND)
    return np.asarray(ppo.deterministic_action(params, stats, jnp.asarray(obs), cfg, low, high))


@pytest.fixture(scope="module")
def holosoma_python() -> Path:
    return find_holosoma_python(REPO / ".venv-holosoma")


@pytest.mark.holosoma
@pytest.mark.parametrize("name", ["holosoma:g1_29dof/ppo", "holosoma:t1_29dof/ppo"])
def test_shipped_ppo_walker_converted_acts_as_onnxruntime_runs_it(name: str, holosoma_python: Path) -> None:
    path = shipped_policy_path(name, holosoma_python)
    actor = read_actor(path, name)
    assert (actor.input_name, actor.obs_dim, actor.action_dim) == ("actor_obs", 100, 29)
    assert actor.hidden_sizes == (512, 256, 128) and actor.activation == "elu" and actor.obs_mean is None
    assert actor.metadata["dof_names"][0] in ("left_hip_pitch_joint", "AAHead_yaw") and len(actor.metadata["kp"]) == 29
    obs = np.random.default_rng(0).normal(0.0, 1.0, size=(64, 100)).astype(np.float32)
    expected = onnxruntime_actions(path, obs)
    assert np.std(expected) > 0.1  # a policy that acts, not a near-zero output compared
    np.testing.assert_allclose(jax_actions(actor, obs), expected, rtol=1e-4, atol=1e-4)


@pytest.mark.holosoma
def test_fastsac_walker_is_refused_by_the_mjx_actor(holosoma_python: Path) -> None:
    path = shipped_policy_path("holosoma:g1_29dof/fastsac", holosoma_python)
    actor = read_actor(path, "holosoma:g1_29dof/fastsac")  # the mujoco walker trainer starts from it
    assert actor.architecture == "fastsac"
    with pytest.raises(ConfigError, match="FastSAC") as info:
        check_architecture(actor)
    assert "holosoma:g1_29dof/fastsac" in str(info.value) and "--motor-backend mujoco" in str(info.value)
    with pytest.raises(ConfigError, match="FastSAC"):  # before it looks at the env
        warm_start(actor, None, ppo.PPOConfig(), None, 0)


@pytest.mark.holosoma
def test_unknown_shipped_name_lists_the_shipped_ones(holosoma_python: Path) -> None:
    with pytest.raises(ConfigError) as info:
        shipped_policy_path("holosoma:h1_19dof/ppo", holosoma_python, flag="--init-policy")
    text = str(info.value)
    assert "--init-policy" in text and "ppo_h1_19dof.onnx" in text and "holosoma:g1_29dof/ppo" in text


@pytest.mark.parametrize(("activation", "normalised", "holosoma"), [("elu", False, True), ("silu", True, True),
                                                                   ("tanh", True, False)])
def test_econmotor_export_reads_back_into_the_same_actor(tmp_path: Path, activation: str, normalised: bool,
                                                         holosoma: bool) -> None:
    cfg = ppo.PPOConfig(hidden_sizes=(16, 8), activation=activation, normalize_obs=normalised)
    learner = ppo.init_learner(jax.random.PRNGKey(1), 7, 3, cfg)
    params = jax.tree_util.tree_map(lambda a: a + 0.3 * jax.random.normal(jax.random.PRNGKey(a.size), a.shape),
                                    learner.params)
    stats = nets.update_stats(learner.stats, 2.0 + 3.0 * jax.random.normal(jax.random.PRNGKey(5), (32, 7)))
    meta = {"dof_names": ["a", "b", "c"], "kp": [1.0, 2.0, 3.0], "kd": [0.1, 0.2, 0.3]} if holosoma else None
    path = export_onnx(jax.device_get(params), (np.asarray(stats.mean), np.asarray(stats.var)) if normalised else None,
                       cfg.clip_obs, np.full(3, -BOUND), np.full(3, BOUND), tmp_path / "policy.onnx",
                       {"task_id": "t"}, activation=activation, holosoma=meta)
    actor = read_actor(path)
    assert actor.input_name == ("actor_obs" if holosoma else "obs")
    assert (actor.hidden_sizes, actor.activation) == ((16, 8), activation)
    for got, want in zip(actor.layers, params["policy"], strict=True):
        np.testing.assert_array_equal(got["w"], np.asarray(want["w"]))
        np.testing.assert_array_equal(got["b"], np.asarray(want["b"]))
    assert (actor.obs_mean is not None) == normalised
    if normalised:
        np.testing.assert_allclose(actor.obs_mean, np.asarray(stats.mean), rtol=1e-6)
        np.testing.assert_allclose(actor.obs_std, np.sqrt(np.asarray(stats.var) + nets.NORM_EPS), rtol=1e-6)
        assert actor.clip_obs == cfg.clip_obs
    obs = np.random.default_rng(3).normal(2.0, 4.0, size=(20, 7)).astype(np.float32)
    np.testing.assert_allclose(jax_actions(actor, obs), onnxruntime_actions(path, obs), rtol=1e-5, atol=1e-5)
    if holosoma:
        assert actor.metadata["kp"] == [1.0, 2.0, 3.0] and actor.metadata["econmotor_task_id"] == "t"
