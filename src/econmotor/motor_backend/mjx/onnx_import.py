"""Start the mjx actor from a walker that exists: an ONNX policy's weights (:mod:`econmotor.couriers.onnx_actor`
reads them) as the JAX actor's, in the layout of ``networks.init_params``. The JAX actor is an MLP: an actor of
another architecture (Holosoma's FastSAC walkers: layer normalisation, a tanh-squashed head) or one that reads
a selection of the observation is a ConfigError (:func:`check_architecture`; the mujoco backend's walker
trainer starts from those).

:func:`warm_start` makes the run's PPO configuration match the ONNX (hidden sizes, activation,
observation normalisation), checks the ONNX's observation and action against the env's (width,
joint order, PD gains: a mismatch names both sides), and returns the learner to start from: the
actor's weights converted (so before any update its deterministic actions are the ONNX's), a
fresh critic of the same shape, and, unless the run's hyperparameters set them, the exploration
noise ``exp(log_std)`` of :data:`WARM_START_LOG_STD`, :data:`WARM_START_CRITIC_ITERATIONS`
value-only iterations first (``ppo.py``), a learning rate :data:`WARM_START_LR_FACTOR` times the
catalog's and no entropy bonus.

A shipped name resolves to its file with the holosoma backend's rules
(``policy_import.parse_policy_name``; :func:`policy_file`): in this interpreter's
holosoma_inference if it has one, else in the Holosoma interpreter's (``.venv-holosoma``,
``find_holosoma_python``), found without importing either.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from econmotor.couriers.onnx_actor import ImportedActor
from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx import networks as nets
from econmotor.motor_backend.mjx import ppo

#: exploration noise of a warm-started actor: std 0.1 on an action scaled by 0.25 is ~0.025 rad at a joint
#: (a fresh actor's std 1 would throw a walker that exists off its feet before the critic knows it)
WARM_START_LOG_STD = float(np.log(0.1))
#: value-only iterations before the actor moves
WARM_START_CRITIC_ITERATIONS = 30
#: fine-tuning's learning rate is the catalog's times this, and it adds no entropy bonus. Measured on the
#: G1 (CPU, 16 envs): at the catalog's 3e-4 with entropy 0.01, std 0.2 and 10 warm-up iterations the
#: shipped walker's episodes fell from 7.1 s to 0.27 s within 13,000 actor steps (PPO without a KL
#: target takes 128 Adam steps an iteration; rsl_rl, which trained it, shrinks its rate on KL)
WARM_START_LR_FACTOR = 0.1
#: an imported normaliser counts as this many observations, so fine-tuning's observations move it slowly
IMPORTED_STATS_COUNT = 1e6


def _check_side(actor: ImportedActor, key: str, theirs: Any, ours: Any, what: str) -> None:
    """The ONNX's ``key`` metadata (when it has it) equals the env's; else a ConfigError naming both."""
    if theirs is None or ours is None:
        return
    same = (list(theirs) == list(ours)) if key == "dof_names" else np.allclose(
        np.asarray(theirs, float), np.asarray(ours, float), rtol=1e-6, atol=1e-9)
    if not same:
        raise ConfigError(actor.source, key, f"the policy's {what} differ from the env's (policy: {list(theirs)}; "
                          f"env: {list(ours)}): it was trained for another robot or convention")


def check_architecture(actor: ImportedActor) -> None:
    """``actor`` is an MLP of the whole observation (the JAX actor's architecture); else a ConfigError."""
    if actor.architecture != "mlp":
        raise ConfigError(actor.source, "architecture", f"a {actor.architecture} actor (Holosoma's FastSAC layout: "
                          "layer normalisation, tanh-squashed head) is not an architecture the mjx trainer's "
                          "actor has (an MLP); the mujoco backend's walker trainer (--motor-backend mujoco) "
                          "starts from it")
    if actor.obs_index is not None:
        raise ConfigError(actor.source, "input selection", "an actor reading a selection of the observation "
                          "(Slice/Gather) is not an architecture the mjx trainer's actor has (an MLP of all of it)")


def check_fits(actor: ImportedActor, env: Any) -> None:
    """The ONNX takes the env's observation and gives its action (widths; joints and gains where both say)."""
    for name, theirs, ours in (("observation", actor.obs_dim, env.observation_size),
                               ("action", actor.action_dim, env.action_size)):
        if theirs != ours:
            raise ConfigError(actor.source, f"input '{actor.input_name}'" if name == "observation" else "action",
                              f"the policy's {name} has {theirs} values, the env's {ours}")
    card = getattr(env, "card", None)
    for key, what in (("dof_names", "joints (in order)"), ("kp", "PD stiffness"), ("kd", "PD damping")):
        _check_side(actor, key, actor.metadata.get(key), getattr(card, key, None), what)


def warm_start(actor: ImportedActor, env: Any, cfg: ppo.PPOConfig, requested: Mapping[str, Any] | None,
               seed: int) -> tuple[ppo.PPOConfig, ppo.Learner, list[str]]:
    """``(cfg, learner, notes)``: the configuration matching ``actor``, the learner to start from, and what
    changed in words (module docstring). ``requested``: the run's explicit hyperparameters."""
    import jax
    import jax.numpy as jnp

    check_architecture(actor)
    check_fits(actor, env)
    requested = dict(requested or {})
    normalised = actor.obs_mean is not None
    changes = {"hidden_sizes": actor.hidden_sizes, "activation": actor.activation, "normalize_obs": normalised}
    for key, value in changes.items():
        if key in requested and requested[key] != value and not (key == "hidden_sizes"
                                                                 and tuple(requested[key]) == value):
            raise ConfigError("<hyperparameters>", key, f"{requested[key]!r} does not fit --init-policy "
                              f"{actor.source}, whose actor has {key} {value!r}")
    changed = [f"{key} {getattr(cfg, key)!r} -> {value!r}" for key, value in changes.items()
               if getattr(cfg, key) != value]
    notes = [f"the network is shaped as {actor.source}'s: {', '.join(changed)}"] if changed else []
    defaults = {"init_log_std": WARM_START_LOG_STD, "critic_warmup_iterations": WARM_START_CRITIC_ITERATIONS,
                "learning_rate": cfg.learning_rate * WARM_START_LR_FACTOR, "entropy_cost": 0.0}
    changes.update({k: v for k, v in defaults.items() if k not in requested})
    if normalised and actor.clip_obs is not None:
        changes["clip_obs"] = actor.clip_obs
    elif normalised:
        changes["clip_obs"] = float(np.finfo(np.float32).max)  # Holosoma's normaliser does not clip
    cfg = replace(cfg, **changes)
    learner = ppo.init_learner(jax.random.PRNGKey(seed), actor.obs_dim, actor.action_dim, cfg)
    params = {**learner.params, "policy": [{"w": jnp.asarray(layer["w"]), "b": jnp.asarray(layer["b"])}
                                           for layer in actor.layers]}
    stats = learner.stats
    if normalised:  # (obs - mean) / std == (obs - mean) / sqrt(var + eps)
        var = np.maximum(np.square(actor.obs_std.astype(np.float64)) - nets.NORM_EPS, 0.0)
        stats = nets.RunningStats(jnp.asarray(IMPORTED_STATS_COUNT, jnp.float32), jnp.asarray(actor.obs_mean),
                                  jnp.asarray(var, jnp.float32))
    optimizer_state = ppo.make_optimizer(cfg).init(params)
    notes.append(f"started from {actor.source}: actor {actor.obs_dim} -> {' -> '.join(map(str, actor.hidden_sizes))}"
                 f" -> {actor.action_dim} ({actor.activation}); exploration std {np.exp(cfg.init_log_std):.2g}; "
                 f"{cfg.critic_warmup_iterations} critic-only iterations first; learning rate {cfg.learning_rate:g}")
    return cfg, ppo.Learner(params, optimizer_state, stats), notes
