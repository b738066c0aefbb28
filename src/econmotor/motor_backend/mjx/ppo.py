"""PPO in JAX over a batched MJX env: one jitted training iteration, one jitted evaluation.

Read top to bottom (CleanRL / PureJaxRL style). Why not Brax's trainer: brax 0.14.2 calls
``jax.device_put_replicated``, which current JAX (0.10, 0.11) has removed (AttributeError),
and under current ``pmap`` it recompiled its training and evaluation functions more than once
per run. This module jits plain functions on one device instead, so each compiles once:

``make_train_iteration(env, cfg, num_envs)`` returns ``iteration(state, actor_weight=1.0) -> (state, metrics)``:

1. rollout: ``lax.scan`` of ``cfg.unroll_length`` steps of ``env.step`` over ``num_envs``
   envs; actions sampled from the Gaussian policy on normalised observations, clipped to
   ``[env.action_low, env.action_high]`` for the env (the log-probability is of the sample);
2. observation statistics: the rollout's raw observations merged into the running mean/var
   (the rollout itself used the statistics from before it, so the stored log-probabilities and
   the normalised observations the update sees agree);
3. GAE(gamma, lambda) with Brax's treatment of auto-reset: a step that ended by falling stops
   the bootstrap (``termination = done * (1 - truncated)``); a step that ended at the time
   limit is masked out of the advantages (its next observation is already the reset one);
4. ``cfg.num_epochs`` epochs of ``cfg.num_minibatches`` shuffled minibatches of the
   clipped-surrogate loss ``a (-min(r A, clip(r, 1 +- eps) A) - entropy_cost H) + value_cost (V - R)^2``
   with Adam (optax) after global-norm gradient clipping. ``a`` is the iteration's ``actor_weight``
   (1; 0 during a critic warm-up, ``cfg.critic_warmup_iterations``: the actor's gradients are then
   exactly zero, so an actor started from a walker that exists (``--init-policy``) does not move
   while the fresh critic learns its values; the host loop then starts Adam afresh, ``training.py``).
   With ``cfg.desired_kl`` the rate follows the KL between the rollout's policy and the updated one
   after every minibatch (:func:`adapt_learning_rate`).

``metrics`` holds the losses and, over the episodes that ended during the rollout, the count
and the sums of every raw metric the env reports in ``finished`` (returns, overlay terms, ...).

``make_evaluate(env, cfg, num_envs)`` returns ``evaluate(params, stats, key) -> (finished,
seen)``: ``num_envs`` deterministic episodes (action ``clip(mean, low, high)``), stepped
until every env has finished one (at most ``env.max_episode_steps`` steps, a ``lax.while_loop``);
the first episode each env finishes is returned.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax

from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx import networks as nets


@dataclass(frozen=True)
class PPOConfig:
    """PPO hyperparameters (catalog ``backends.mjx.hyperparameters.ppo`` and per-run overrides).

    Attributes:
        learning_rate: Adam step size.
        unroll_length: env steps per env per iteration (an iteration is ``num_envs * unroll_length``
            env steps).
        num_minibatches: minibatches per epoch (the batch is ``num_envs * unroll_length``).
        num_epochs: passes over each rollout.
        gamma / gae_lambda: discount and GAE lambda.
        clip_epsilon: PPO ratio clip epsilon.
        entropy_cost / value_cost: entropy bonus and value-loss weights.
        max_grad_norm: global-norm gradient clip.
        hidden_sizes: hidden layers of the policy and the value MLPs.
        activation: the hidden layers' activation (``networks.ACTIVATIONS``: tanh, elu, relu, silu).
        init_log_std: initial log standard deviation of the Gaussian policy.
        critic_warmup_iterations: iterations at the start of a run that train the critic only
            (0: none; a run started from an imported actor sets it, ``mjx/onnx_import.py``).
        normalize_obs: running observation normalisation (exported into the ONNX graph).
        clip_obs: clip of the normalised observations.
        normalize_advantages: standardise advantages per minibatch.
        reward_scaling: rewards are multiplied by this for learning only (metrics stay in task units).
        desired_kl: > 0: the learning rate follows the KL between the rollout's policy and the updated one
            after every minibatch (rsl_rl's rule, as the mujoco walker trainer's: above twice this divide
            by 1.5, below half of it multiply by 1.5, within ``lr_bounds``); 0: a fixed rate.
        lr_bounds: the adaptive rate's range.
    """

    learning_rate: float = 3e-4
    unroll_length: int = 32
    num_minibatches: int = 4
    num_epochs: int = 4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_epsilon: float = 0.2
    entropy_cost: float = 0.0
    value_cost: float = 0.5
    max_grad_norm: float = 0.5
    hidden_sizes: tuple[int, ...] = (64, 64)
    activation: str = "tanh"
    init_log_std: float = 0.0
    critic_warmup_iterations: int = 0
    normalize_obs: bool = True
    clip_obs: float = 10.0
    normalize_advantages: bool = True
    reward_scaling: float = 1.0
    desired_kl: float = 0.0
    lr_bounds: tuple[float, float] = (1e-6, 1e-3)

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any] | None, source: str = "<hyperparameters>") -> PPOConfig:
        """Build from YAML/JSON values; unknown keys or wrong types are a ConfigError naming the key."""
        known = {f.name: f for f in fields(cls)}
        kw: dict[str, Any] = {}
        for key, raw in (values or {}).items():
            if key not in known:
                raise ConfigError(source, key, "unknown mjx PPO hyperparameter", sorted(known))
            default = getattr(cls, key)
            try:
                if isinstance(default, bool):
                    if not isinstance(raw, bool):
                        raise TypeError("expected true or false")
                    kw[key] = raw
                elif isinstance(default, str):
                    if raw not in nets.ACTIVATIONS:
                        raise ValueError(f"expected one of {', '.join(nets.ACTIVATIONS)}")
                    kw[key] = raw
                elif key == "lr_bounds":
                    kw[key] = tuple(float(v) for v in raw)
                    if len(kw[key]) != 2 or not 0 < kw[key][0] <= kw[key][1]:
                        raise ValueError("expected [low, high] with 0 < low <= high")
                elif isinstance(default, tuple):
                    kw[key] = tuple(int(v) for v in raw)
                    if not kw[key] or min(kw[key]) < 1:
                        raise ValueError("expected a non-empty list of positive layer sizes")
                elif isinstance(default, int):
                    kw[key] = int(raw)
                    least = 0 if key in ZERO_ALLOWED else 1
                    if kw[key] < least:
                        raise ValueError(f"expected an integer >= {least}")
                else:
                    kw[key] = float(raw)
            except (TypeError, ValueError) as exc:
                raise ConfigError(source, key, f"bad value {raw!r}: {exc}") from exc
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["hidden_sizes"] = list(self.hidden_sizes)
        out["lr_bounds"] = list(self.lr_bounds)
        return out


#: integer hyperparameters that may be 0
ZERO_ALLOWED = ("critic_warmup_iterations",)


class Learner(NamedTuple):
    """What training changes and a checkpoint keeps."""

    params: nets.Params
    opt_state: Any
    stats: nets.RunningStats


class TrainState(NamedTuple):
    learner: Learner
    env_state: Any
    key: jax.Array


class Transition(NamedTuple):
    x: jax.Array  # normalised observation the action was taken on
    raw_obs: jax.Array
    action: jax.Array  # the Gaussian sample (before clipping to the env's bounds)
    log_prob: jax.Array
    value: jax.Array
    reward: jax.Array
    done: jax.Array
    truncated: jax.Array


def make_optimizer(cfg: PPOConfig) -> optax.GradientTransformation:
    """Adam after a global-norm clip; with ``desired_kl`` its rate is a state the update adapts
    (:func:`adapt_learning_rate`)."""
    adam = optax.inject_hyperparams(optax.adam)(learning_rate=cfg.learning_rate, eps=1e-5) if cfg.desired_kl > 0 \
        else optax.adam(cfg.learning_rate, eps=1e-5)
    return optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm), adam)


def adapt_learning_rate(opt_state: Any, kl: jax.Array, cfg: PPOConfig) -> Any:
    """The optimizer state with its rate adapted to ``kl`` (rsl_rl's rule, :class:`PPOConfig`'s ``desired_kl``)."""
    clip_state, adam_state = opt_state
    lr = adam_state.hyperparams["learning_rate"]
    lr = jnp.where(kl > 2.0 * cfg.desired_kl, lr / 1.5, jnp.where(kl < 0.5 * cfg.desired_kl, lr * 1.5, lr))
    lr = jnp.clip(lr, cfg.lr_bounds[0], cfg.lr_bounds[1])
    return clip_state, adam_state._replace(hyperparams={**adam_state.hyperparams, "learning_rate": lr})


def gaussian_kl(mean0: jax.Array, mean1: jax.Array, log_std0: jax.Array, log_std1: jax.Array) -> jax.Array:
    """Mean over rows of ``KL(N(mean0, e^log_std0) || N(mean1, e^log_std1))``, summed over the action."""
    var0, var1 = jnp.exp(2.0 * log_std0), jnp.exp(2.0 * log_std1)
    kl = log_std1 - log_std0 + (var0 + (mean0 - mean1) ** 2) / (2.0 * var1) - 0.5
    return jnp.mean(jnp.sum(kl, axis=-1))


def init_learner(key: jax.Array, obs_size: int, action_size: int, cfg: PPOConfig) -> Learner:
    params = nets.init_params(key, obs_size, action_size, cfg.hidden_sizes, cfg.init_log_std)
    return Learner(params, make_optimizer(cfg).init(params), nets.init_stats(obs_size))


def init_train_state(env: Any, cfg: PPOConfig, num_envs: int, seed: int,
                     learner: Learner | None = None, key: jax.Array | None = None) -> TrainState:
    """A fresh learner (or the given one, e.g. from a checkpoint) and ``num_envs`` reset envs."""
    root = jax.random.PRNGKey(seed) if key is None else key
    k_params, k_env, k_run = jax.random.split(root, 3)
    if learner is None:
        learner = init_learner(k_params, env.observation_size, env.action_size, cfg)
    env_state = jax.jit(env.reset, static_argnums=1)(k_env, num_envs)
    return TrainState(learner, env_state, k_run)


def observe(stats: nets.RunningStats, obs: jax.Array, cfg: PPOConfig) -> jax.Array:
    return nets.normalize(stats, obs, cfg.clip_obs) if cfg.normalize_obs else obs


def deterministic_action(params: nets.Params, stats: nets.RunningStats, obs: jax.Array, cfg: PPOConfig,
                         low: jax.Array, high: jax.Array) -> jax.Array:
    """``clip(mean(normalise(obs)), low, high)`` (what the ONNX graph computes)."""
    return jnp.clip(nets.policy_mean(params, observe(stats, obs, cfg), cfg.activation), low, high)


def gae(tr: Transition, last_value: jax.Array, gamma: float, lam: float) -> tuple[jax.Array, jax.Array]:
    """Advantages and value targets ``[T, N]`` (auto-reset handling in the module docstring)."""
    next_values = jnp.concatenate([tr.value[1:], last_value[None]], axis=0)
    termination = tr.done * (1.0 - tr.truncated)
    keep = 1.0 - tr.truncated
    deltas = (tr.reward + gamma * (1.0 - termination) * next_values - tr.value) * keep

    def backward(acc, xs):
        delta, term, kp = xs
        acc = delta + gamma * lam * (1.0 - term) * kp * acc
        return acc, acc

    _, adv = jax.lax.scan(backward, jnp.zeros_like(last_value), (deltas, termination, keep), reverse=True)
    return adv, adv + tr.value


def ppo_loss(params: nets.Params, batch: tuple[jax.Array, ...], cfg: PPOConfig,
             actor_weight: jax.Array | float = 1.0) -> tuple[jax.Array, dict]:
    x, action, old_log_prob, advantage, target, mask = batch
    mean = nets.policy_mean(params, x, cfg.activation)
    log_prob = nets.gaussian_log_prob(action, mean, params["log_std"])
    ratio = jnp.exp(log_prob - old_log_prob)
    weight = mask / jnp.maximum(jnp.sum(mask), 1.0)
    if cfg.normalize_advantages:
        mu = jnp.sum(advantage * weight)
        sd = jnp.sqrt(jnp.sum((advantage - mu) ** 2 * weight))
        advantage = (advantage - mu) / (sd + 1e-8)
    surrogate = jnp.minimum(ratio * advantage, jnp.clip(ratio, 1 - cfg.clip_epsilon, 1 + cfg.clip_epsilon) * advantage)
    policy_loss = -jnp.sum(surrogate * weight)
    value_loss = jnp.sum((nets.value(params, x, cfg.activation) - target) ** 2 * weight)
    entropy = nets.gaussian_entropy(params["log_std"])
    loss = actor_weight * (policy_loss - cfg.entropy_cost * entropy) + cfg.value_cost * value_loss
    clip_fraction = jnp.sum((jnp.abs(ratio - 1.0) > cfg.clip_epsilon) * weight)
    return loss, {"policy_loss": policy_loss, "value_loss": value_loss, "entropy": entropy,
                  "clip_fraction": clip_fraction}


def _make_env_step(env: Any, cfg: PPOConfig):
    """``env_step(carry, _)`` of a rollout scan: the Gaussian's sample, its log-probability and value, the env's
    step, and the raw metrics of the episodes it ended (summed)."""
    low, high = jnp.asarray(env.action_low, jnp.float32), jnp.asarray(env.action_high, jnp.float32)
    metric_keys = tuple(env.metric_keys)

    def env_step(carry, _):
        learner, env_state, key = carry
        key, k_act = jax.random.split(key)
        x = observe(learner.stats, env_state.obs, cfg)
        mean = nets.policy_mean(learner.params, x, cfg.activation)
        log_std = learner.params["log_std"]
        action = mean + jnp.exp(log_std) * jax.random.normal(k_act, mean.shape)
        log_prob = nets.gaussian_log_prob(action, mean, log_std)
        v = nets.value(learner.params, x, cfg.activation)
        nxt = env.step(env_state, jnp.clip(action, low, high))
        done = nxt.done.astype(jnp.float32)
        tr = Transition(x, env_state.obs, action, log_prob, v, nxt.reward * cfg.reward_scaling, done,
                        nxt.truncated.astype(jnp.float32))
        ended = {k: jnp.sum(jnp.where(done > 0, nxt.finished[k].astype(jnp.float32), 0.0)) for k in metric_keys}
        return (learner, nxt, key), (tr, ended)

    return env_step


def _make_update_epoch(cfg: PPOConfig, batch_size: int):
    """``update_epoch(carry, key)`` of the update scan: ``cfg.num_minibatches`` shuffled minibatches, each an Adam
    step on :func:`ppo_loss` (and, with ``desired_kl``, the rate adapted to the minibatch's KL)."""
    optimizer = make_optimizer(cfg)
    minibatch = batch_size // cfg.num_minibatches

    def update_minibatch(carry, batch):
        params, opt_state, actor_weight, old_log_std = carry
        batch, old_mean = batch[:-1], batch[-1]
        (_, info), grads = jax.value_and_grad(ppo_loss, has_aux=True)(params, batch, cfg, actor_weight)
        updates, opt_state = optimizer.update(grads, opt_state, params)
        params = optax.apply_updates(params, updates)
        if cfg.desired_kl > 0:  # the KL of this minibatch's rollout policy to the updated one sets the next rate
            kl = gaussian_kl(old_mean, nets.policy_mean(params, batch[0], cfg.activation), old_log_std,
                             params["log_std"])
            opt_state = jax.lax.cond(actor_weight > 0, lambda o: adapt_learning_rate(o, kl, cfg), lambda o: o,
                                     opt_state)
            info = {**info, "kl": kl, "learning_rate": opt_state[1].hyperparams["learning_rate"]}
        return (params, opt_state, actor_weight, old_log_std), info

    def update_epoch(carry, key):
        params, opt_state, flat, actor_weight, old_log_std = carry
        perm = jax.random.permutation(key, batch_size)
        shuffled = jax.tree_util.tree_map(lambda a: a[perm].reshape(cfg.num_minibatches, minibatch, *a.shape[1:]),
                                          flat)
        (params, opt_state, _, _), info = jax.lax.scan(update_minibatch,
                                                       (params, opt_state, actor_weight, old_log_std), shuffled)
        return (params, opt_state, flat, actor_weight, old_log_std), info

    return update_epoch


def make_train_iteration(env: Any, cfg: PPOConfig, num_envs: int):
    """The jitted ``iteration(state) -> (state, metrics)`` (one rollout + the PPO update)."""
    batch_size = num_envs * cfg.unroll_length
    if batch_size % cfg.num_minibatches:
        raise ConfigError("<hyperparameters>", "num_minibatches",
                          f"num_envs * unroll_length = {batch_size} must be divisible by {cfg.num_minibatches}")
    env_step, update_epoch = _make_env_step(env, cfg), _make_update_epoch(cfg, batch_size)

    def iteration(state: TrainState, actor_weight: jax.Array | float = 1.0) -> tuple[TrainState, dict[str, jax.Array]]:
        learner = state.learner
        (_, env_state, key), (tr, ended) = jax.lax.scan(env_step, (learner, state.env_state, state.key), None,
                                                        length=cfg.unroll_length)
        last_value = nets.value(learner.params, observe(learner.stats, env_state.obs, cfg), cfg.activation)
        advantage, target = gae(tr, last_value, cfg.gamma, cfg.gae_lambda)
        stats = nets.update_stats(learner.stats, tr.raw_obs) if cfg.normalize_obs else learner.stats
        mask = 1.0 - tr.truncated
        old_mean = nets.policy_mean(learner.params, tr.x, cfg.activation)  # the rollout's policy (for the KL)
        flat = jax.tree_util.tree_map(lambda a: a.reshape(batch_size, *a.shape[2:]),
                                      (tr.x, tr.action, tr.log_prob, advantage, target, mask, old_mean))
        key, k_epochs = jax.random.split(key)
        weight = jnp.asarray(actor_weight, jnp.float32)
        carry = (learner.params, learner.opt_state, flat, weight, learner.params["log_std"])
        (params, opt_state, _, _, _), info = jax.lax.scan(update_epoch, carry,
                                                          jax.random.split(k_epochs, cfg.num_epochs))
        metrics = {k: jnp.mean(v) for k, v in info.items()}
        metrics["episodes"] = jnp.sum(tr.done)
        metrics.update({f"sum/{k}": jnp.sum(v) for k, v in ended.items()})
        metrics["reward_mean"] = jnp.mean(tr.reward) / cfg.reward_scaling
        return TrainState(Learner(params, opt_state, stats), env_state, key), metrics

    return jax.jit(iteration, donate_argnums=0)


def make_evaluate(env: Any, cfg: PPOConfig, num_envs: int):
    """The jitted ``evaluate(params, stats, key) -> (finished, seen)`` (module docstring)."""
    low, high = jnp.asarray(env.action_low, jnp.float32), jnp.asarray(env.action_high, jnp.float32)
    metric_keys = tuple(env.metric_keys)

    def evaluate(params: nets.Params, stats: nets.RunningStats, key: jax.Array):
        env_state = env.reset(key, num_envs)
        first = {k: jnp.zeros_like(env_state.finished[k]) for k in metric_keys}
        seen = jnp.zeros((num_envs,), bool)

        def running(carry):
            _, _, seen, t = carry
            return jnp.logical_and(t < env.max_episode_steps, jnp.logical_not(jnp.all(seen)))

        def step(carry):
            env_state, first, seen, t = carry
            action = deterministic_action(params, stats, env_state.obs, cfg, low, high)
            nxt = env.step(env_state, action)
            take = (nxt.done > 0) & ~seen
            first = {k: jnp.where(take, nxt.finished[k].astype(first[k].dtype), first[k]) for k in metric_keys}
            return nxt, first, seen | (nxt.done > 0), t + 1

        _, first, seen, _ = jax.lax.while_loop(running, step, (env_state, first, seen, jnp.asarray(0, jnp.int32)))
        return first, seen

    return jax.jit(evaluate)
