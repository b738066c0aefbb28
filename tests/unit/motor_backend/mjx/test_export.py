"""mjx ONNX export and checkpoints: the graph equals the JAX deterministic policy; checkpoints round-trip."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.couriers.onnx_export import export_onnx
from econmotor.errors import BackendError
from econmotor.motor_backend.mjx import checkpoint as ckpt
from econmotor.motor_backend.mjx import networks as nets
from econmotor.motor_backend.mjx import ppo
from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle

OBS, ACT = 11, 3
LOW, HIGH = np.full(ACT, -0.4, np.float32), np.full(ACT, 0.7, np.float32)


def trained_looking_learner(normalize: bool = True) -> tuple[ppo.PPOConfig, ppo.Learner]:
    cfg = ppo.PPOConfig(hidden_sizes=(16, 8), normalize_obs=normalize)
    learner = ppo.init_learner(jax.random.PRNGKey(3), OBS, ACT, cfg)
    # a non-trivial policy head and normaliser (fresh ones output ~0 and normalise nothing)
    params = jax.tree_util.tree_map(lambda a: a + 0.3 * jax.random.normal(jax.random.PRNGKey(a.size), a.shape),
                                    learner.params)
    stats = nets.update_stats(learner.stats, 3.0 + 2.0 * jax.random.normal(jax.random.PRNGKey(9), (64, OBS)))
    return cfg, learner._replace(params=params, stats=stats)


@pytest.mark.parametrize("normalize", [True, False])
def test_onnx_handle_equals_the_jax_deterministic_policy(tmp_path: Path, normalize: bool) -> None:
    cfg, learner = trained_looking_learner(normalize)
    meta = {"task_id": "hopper_courier", "economics": {"wage_human_usd_per_hour": 18.0}}
    stats = (np.asarray(learner.stats.mean), np.asarray(learner.stats.var)) if normalize else None
    path = export_onnx(jax.device_get(learner.params), stats, cfg.clip_obs, LOW, HIGH, tmp_path / "policy.onnx", meta)
    handle = OnnxPolicyHandle(path)
    obs = np.random.default_rng(0).normal(3.0, 4.0, size=(257, OBS)).astype(np.float32)
    expected = np.asarray(ppo.deterministic_action(learner.params, learner.stats, jnp.asarray(obs), cfg,
                                                   jnp.asarray(LOW), jnp.asarray(HIGH)))
    got = handle.act(obs)
    np.testing.assert_allclose(got, expected, atol=1e-5)
    assert np.any((got > LOW) & (got < HIGH)) and np.any(got == HIGH)  # both regimes exercised
    np.testing.assert_allclose(handle.step(obs[0]), expected[0], atol=1e-5)
    assert handle.metadata == meta


def test_checkpoint_round_trips_and_refuses_other_networks(tmp_path: Path) -> None:
    cfg, learner = trained_looking_learner()
    key = jax.random.PRNGKey(42)
    path = ckpt.save_tree(ckpt.checkpoint_path(tmp_path, 1024), learner, key, 1024)
    template = ppo.init_learner(jax.random.PRNGKey(0), OBS, ACT, cfg)
    loaded, loaded_key, steps, _ = ckpt.load_tree(path, template)
    assert steps == 1024 and np.array_equal(loaded_key, key)
    for a, b in zip(jax.tree_util.tree_leaves(loaded), jax.tree_util.tree_leaves(learner), strict=True):
        np.testing.assert_array_equal(a, b)
    assert ckpt.latest_checkpoint(tmp_path) == (path, 1024)
    other = ppo.init_learner(jax.random.PRNGKey(0), OBS, ACT, ppo.PPOConfig(hidden_sizes=(4,)))
    with pytest.raises(BackendError, match="does not match"):
        ckpt.load_tree(path, other)


def test_latest_checkpoint_skips_a_truncated_newer_file(tmp_path: Path) -> None:
    _, learner = trained_looking_learner()
    good = ckpt.save_tree(ckpt.checkpoint_path(tmp_path, 100), learner, jax.random.PRNGKey(0), 100)
    bad = ckpt.checkpoint_path(tmp_path, 200)
    bad.write_bytes(good.read_bytes()[:300])  # a run killed mid-copy (save_tree itself writes atomically)
    assert ckpt.latest_checkpoint(tmp_path) == (good, 100)
    assert not list(tmp_path.rglob("*.tmp"))
