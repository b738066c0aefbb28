"""The mjx backend's networks and observation normaliser, as plain JAX functions on pytrees.

Parameters are dicts of arrays (no Flax), so checkpoints are flat ``.npz`` files and the ONNX
export (``couriers/onnx_export.py``) reads the same arrays::

    params = {"policy": [{"w": [in, h1], "b": [h1]}, ..., {"w": [h_k, act], "b": [act]}],
              "log_std": [act],
              "value":  [{"w": [in, h1], "b": [h1]}, ..., {"w": [h_k, 1], "b": [1]}]}

Policy: a Gaussian with mean ``mlp(x)`` and a state-independent ``log_std`` (SB3's
``MlpPolicy``); the action sent to the env is the sample clipped to ``[low, high]``, the
deterministic action is ``clip(mean, low, high)``. The hidden layers' activation is one of
:data:`ACTIVATIONS` (tanh by default, as SB3's; ``elu`` is rsl_rl's and Holosoma's PPO actor's, so an
actor imported from Holosoma's ONNX (``mjx/onnx_import.py``) runs here unchanged).

Observation normaliser (SB3 ``VecNormalize`` formula, statistics merged per batch with Chan's
parallel form of Welford's algorithm)::

    x = clip((obs - mean) / sqrt(var + eps), -clip_obs, clip_obs)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from econmotor.couriers.onnx_export import NORM_EPS

Params = dict[str, Any]
#: hidden-layer activations by name (the ONNX export writes the same op, ``couriers/onnx_export.py``).
ACTIVATIONS = {"tanh": jnp.tanh, "elu": jax.nn.elu, "relu": jax.nn.relu, "silu": jax.nn.silu}


def _dense_init(key: jax.Array, sizes: Sequence[int], out_scale: float) -> list[dict[str, jax.Array]]:
    """Orthogonal weights (gain sqrt(2) on hidden layers, ``out_scale`` on the last), zero biases."""
    layers = []
    keys = jax.random.split(key, len(sizes) - 1)
    for i, (k, n_in, n_out) in enumerate(zip(keys, sizes[:-1], sizes[1:], strict=True)):
        gain = out_scale if i == len(sizes) - 2 else jnp.sqrt(2.0)
        w = jax.nn.initializers.orthogonal(scale=gain)(k, (n_in, n_out), jnp.float32)
        layers.append({"w": w, "b": jnp.zeros((n_out,), jnp.float32)})
    return layers


def init_params(key: jax.Array, obs_size: int, action_size: int, hidden_sizes: Sequence[int],
                init_log_std: float = 0.0) -> Params:
    """Fresh actor-critic parameters (CleanRL's initialisation: policy head 0.01, value head 1)."""
    k_pi, k_v = jax.random.split(key)
    hidden = [int(h) for h in hidden_sizes]
    return {
        "policy": _dense_init(k_pi, [obs_size, *hidden, action_size], 0.01),
        "log_std": jnp.full((action_size,), init_log_std, jnp.float32),
        "value": _dense_init(k_v, [obs_size, *hidden, 1], 1.0),
    }


def mlp(layers: Sequence[dict[str, jax.Array]], x: jax.Array, activation: str = "tanh") -> jax.Array:
    """Hidden layers with ``activation`` (a key of :data:`ACTIVATIONS`), linear output."""
    act = ACTIVATIONS[activation]
    for layer in layers[:-1]:
        x = act(x @ layer["w"] + layer["b"])
    return x @ layers[-1]["w"] + layers[-1]["b"]


def policy_mean(params: Params, x: jax.Array, activation: str = "tanh") -> jax.Array:
    return mlp(params["policy"], x, activation)


def value(params: Params, x: jax.Array, activation: str = "tanh") -> jax.Array:
    return mlp(params["value"], x, activation)[..., 0]


def gaussian_log_prob(action: jax.Array, mean: jax.Array, log_std: jax.Array) -> jax.Array:
    """Sum over action dims of log N(action; mean, exp(log_std)^2)."""
    z = (action - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * z * z - log_std - 0.5 * jnp.log(2.0 * jnp.pi), axis=-1)


def gaussian_entropy(log_std: jax.Array) -> jax.Array:
    return jnp.sum(log_std + 0.5 * jnp.log(2.0 * jnp.pi * jnp.e))


class RunningStats(NamedTuple):
    """Observation statistics (SB3 ``RunningMeanStd``: count starts at 1e-4, mean 0, var 1)."""

    count: jax.Array  # [] float32
    mean: jax.Array  # [obs_size]
    var: jax.Array  # [obs_size]


def init_stats(obs_size: int) -> RunningStats:
    return RunningStats(jnp.asarray(1e-4, jnp.float32), jnp.zeros((obs_size,), jnp.float32),
                        jnp.ones((obs_size,), jnp.float32))


def update_stats(stats: RunningStats, batch: jax.Array) -> RunningStats:
    """Merge a batch ``[..., obs_size]`` into the statistics (Chan et al.'s parallel Welford)."""
    batch = batch.reshape(-1, batch.shape[-1])
    n = jnp.asarray(batch.shape[0], jnp.float32)
    b_mean, b_var = jnp.mean(batch, axis=0), jnp.var(batch, axis=0)
    delta = b_mean - stats.mean
    total = stats.count + n
    mean = stats.mean + delta * n / total
    m2 = stats.var * stats.count + b_var * n + delta * delta * stats.count * n / total
    return RunningStats(total, mean, m2 / total)


def normalize(stats: RunningStats, obs: jax.Array, clip_obs: float) -> jax.Array:
    return jnp.clip((obs - stats.mean) / jnp.sqrt(stats.var + NORM_EPS), -clip_obs, clip_obs)
