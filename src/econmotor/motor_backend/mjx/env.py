"""MjxCourierEnv: the mujoco couriers as batched, pure JAX functions, economics inside the step.

``reset(key, num_envs)`` and ``step(state, action)`` are pure functions of an :class:`EnvState`
pytree whose arrays lead with ``num_envs``; jit them once (shapes are fixed by ``num_envs``) and
scan them. Physics is MuJoCo's JAX port (``mujoco.mjx``) on Gymnasium's own MJCF files; the
observation, action bounds, task reward, frame skip, reset noise and fall (unhealthy
termination) are those of the Gymnasium v5 env the ``mujoco`` backend trains on, read from the
robot's record (``couriers/robots.py``: the env reads its fields and never branches on a robot's
name), so a policy's obs/action layout carries over.

Per control step, per env (every formula from :mod:`econmotor.economics.courier_formulas`, the
module the ``mujoco`` backend's metering and overlay call too, with the physics readouts of
``couriers/physics.py``):

- units: high-water mark of the root's x over ``leg_distance_m``; energy:
  ``sum |qfrc_actuator * qvel|`` over the actuated dofs / drivetrain efficiency + idle power, Wh;
  falls: Gymnasium's healthy check; risk: from the tilt; novelty: ``1 / sqrt(n)`` visits,
- the reward ``keep_task_reward * r_task + J(t) - J(t-1)``, ``J = sum_k scale_k / ref_k * m_k``
  over the running episode metrics ``m_k`` (the compiled :class:`EconomicObjectiveSpec`), so each
  term's episode sum is the episode metric of its key, exactly as in ``couriers/overlay.py``.

Auto-reset (as Brax's AutoResetWrapper, but with a fresh noisy state per episode): where an
episode ends, ``finished`` holds its raw metrics, ``done``/``truncated`` say how it ended, and
``data``/``obs``/``episode`` are already those of the next episode's first state.

Novelty: the ``mujoco`` backend counts visits per cell in an unbounded dict per env; here each
env has a fixed table of ``novelty_table_size`` counters indexed by a hash of the cell, so two
cells that hash alike share a count (with a few hundred cells visited per env and 4,096 slots,
collisions are rare but possible: novelty can read a little lower than on the CPU).

Float32 here (JAX's default) vs float64 in MuJoCo C: per-step figures agree to ~1e-5 relative
(see the parity tests for the stated tolerances).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from econmotor.couriers.overlay import TERM_METRICS, human_baseline_references, overlay_term_factors
from econmotor.couriers.physics import actuated_dof_span, has_free_root, root_tilt_rad
from econmotor.couriers.randomization import DomainRandomization, parse_randomization
from econmotor.economics import courier_formulas as cf
from econmotor.economics.termination import TerminationReason
from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx._mjx import mjx
from econmotor.motor_backend.mjx.assets import RobotSpec, load_model, robot_spec
from econmotor.motor_backend.mjx.settings import MjxTaskSettings, parse_mjx_settings
from econmotor.objectives.economic_objective import EconomicObjectiveSpec, compile_economic_overlay
from econmotor.robots import gym_couriers as robots
from econmotor.tasks import load_catalog

#: running sums of the current episode kept on the device (``EnvState.episode``).
EPISODE_KEYS = ("steps", "units", "errors", "energy_wh", "risk_sum", "novelty_sum", "task_return", "overlay_j",
                "best_x", "x0")
#: raw metrics of a finished episode kept on the device (``EnvState.finished``), before the overlay terms.
BASE_METRIC_KEYS = ("units_completed", "units_attempted", "errors", "episode_length_s", "length_steps", "energy_wh",
                    "risk_score", "novelty_score", "return", "forward_distance_m", "fell", "overlay_return")
#: the datapack domain-randomization keys this backend honours (the others raise a ConfigError).
SUPPORTED_DR_KEYS = ("friction_range", "mass_scale_range", "action_noise_std", "obs_noise_std")
_HASH_PRIMES = (73856093, 19349663, 83492791, 2654435761, 40503, 2246822519, 3266489917, 668265263)
#: the meter's running sums kept in ``EnvState.episode`` (the mjx env has no pose tracking: pose_sum stays 0).
_METER_KEYS = tuple(f.name for f in dataclasses.fields(cf.MeterSums) if f.name != "pose_sum")
#: overlay keys the mjx env can weight.
MJX_TERMS = tuple(k for k in TERM_METRICS if k != "pose_tracking")

#: how each observation part of a robot record (``couriers.robots.OBS_PARTS``) reads MJX data.
_OBS_READERS = {
    "qpos": lambda d, spec: d.qpos[spec.robot.obs_qpos_start:],
    "qvel": lambda d, spec: d.qvel,
    "qvel_clipped": lambda d, spec: jnp.clip(d.qvel, -10.0, 10.0),
    "cinert": lambda d, spec: d._impl.cinert[1:].ravel(),
    "cvel": lambda d, spec: d.cvel[1:].ravel(),
    "qfrc_actuator": lambda d, spec: d.qfrc_actuator[6:],  # past the free root's 6 dofs
    "cfrc_ext": lambda d, spec: d._impl.cfrc_ext[1:].ravel(),
    "cfrc_ext_clipped": lambda d, spec: jnp.clip(d._impl.cfrc_ext[1:], *spec["contact_force_range"]).ravel(),
}


class EnvState(NamedTuple):
    """The batched state (every array leads with ``num_envs``)."""

    data: Any
    obs: jax.Array
    reward: jax.Array
    done: jax.Array
    truncated: jax.Array
    episode: dict[str, jax.Array]
    finished: dict[str, jax.Array]
    key: jax.Array
    novelty_counts: jax.Array  # [N, novelty_table_size] int32 visit counts, kept across episodes
    randomization: dict[str, jax.Array]  # per-env friction / mass multipliers drawn at reset (may be empty)


def _merge_datapacks(datapacks: Sequence[Any]) -> tuple[dict[str, Any], dict[str, Any], list[str], str]:
    dr: dict[str, Any] = {}
    cur: dict[str, Any] = {}
    clips: list[str] = []
    sources = []
    for pack in datapacks:
        dr.update(getattr(pack, "domain_randomization", {}) or {})
        cur.update(getattr(pack, "curriculum", {}) or {})
        clips += [str(getattr(c, "path", c)) for c in getattr(pack, "motion_clips", ()) or ()]
        src = getattr(pack, "source", None) or ", ".join(getattr(pack, "sources", {}).values())
        sources.append(f"{src} (datapack '{getattr(pack, 'id', getattr(pack, 'task_id', '?'))}')")
    return dr, cur, clips, ", ".join(sources) or "<datapacks>"


def parse_mjx_randomization(datapacks: Sequence[Any]) -> DomainRandomization:
    """The datapacks' domain randomization the mjx backend honours; anything else is a ConfigError."""
    dr, cur, clips, source = _merge_datapacks(datapacks)
    randomization, _ = parse_randomization(dr, cur, source)
    for key in dr:
        if key not in SUPPORTED_DR_KEYS and not (key == "terrain" and dr[key] == "flat"):
            raise ConfigError(source, f"domain_randomization.{key}", "the mjx backend cannot honour this option",
                              SUPPORTED_DR_KEYS)
    if cur:
        raise ConfigError(source, "curriculum", "the mjx backend has no curriculum (ranges apply as written)")
    if clips:
        raise ConfigError(source, "motion_clips", "the mjx backend has no pose tracking; use the mujoco backend")
    return randomization


def auto_reset(done: jax.Array, reset_one: Any, reset_keys: jax.Array, carry: Any) -> Any:
    """``carry`` (a pytree of per-env arrays) with the envs where ``done`` replaced by
    ``vmap(reset_one)(reset_keys)``, which is computed only when some episode ended."""
    def reset_done(c: Any) -> Any:
        fresh = jax.vmap(reset_one)(reset_keys)

        def pick(new: jax.Array, old: jax.Array) -> jax.Array:
            return jnp.where(done.reshape(done.shape + (1,) * (old.ndim - 1)), new, old)

        return jax.tree_util.tree_map(pick, fresh, c)

    return jax.lax.cond(jnp.any(done), reset_done, lambda c: c, carry)


def with_overlay_columns(row: dict[str, Any], cols: Mapping[str, np.ndarray], i: int,
                         factors: Mapping[str, float]) -> dict[str, Any]:
    """A finished episode's row with ``total_return`` and each overlay term's ``overlay_<key>_raw``
    (episode ``i`` of ``cols``) and ``overlay_<key>_weighted`` (times its factor)."""
    row["total_return"] = row["return"] + row["overlay_return"]
    for k, factor in factors.items():
        raw = float(cols[f"overlay_{k}_raw"][i])
        row[f"overlay_{k}_raw"] = raw
        row[f"overlay_{k}_weighted"] = factor * raw
    return row


def task_settings(task_id: str, catalog: Any = None) -> tuple[Any, MjxTaskSettings, str]:
    """``(task spec, its validated mjx settings, "<file>: backend_entries.mjx.<task>")`` (the shipped
    catalog unless ``catalog`` is given): what every mjx env starts from."""
    spec = (catalog if catalog is not None else load_catalog()).get(task_id)
    settings = parse_mjx_settings(spec)
    return spec, settings, f"{settings.source}: backend_entries.mjx.{task_id}"


class MjxCourierEnv:
    """A courier task as batched pure functions (module docstring); API in ``MJX_INTERFACE.md``.

    Args:
        task_id: a catalog task with a ``backends.mjx`` entry.
        objective: the economic objective compiled into the reward overlay (None: no overlay).
        datapacks: datapack configs or bundles (domain randomization: :data:`SUPPORTED_DR_KEYS`).
        seed: kept for the caller's records; randomness comes from the keys given to ``reset``.
        catalog: a :class:`~econmotor.tasks.TaskCatalog` (default: the shipped one).
        keep_task_reward: add the overlay to the task reward (True) or use it alone.
        economics: False strips the metering, novelty table and overlay from the step (the
            reward is the task's, ``finished`` holds only the return and the length): the
            baseline ``benchmarks/mjx_throughput.py`` times the economics against.
    """

    def __init__(self, task_id: str, *, objective: EconomicObjectiveSpec | None = None,
                 datapacks: Sequence[Any] = (), seed: int = 0, catalog: Any = None,
                 keep_task_reward: bool = True, economics: bool = True) -> None:
        spec, self.settings, where = task_settings(task_id, catalog)
        s = self.settings
        self.task_id, self.seed = task_id, int(seed)
        self.robot: RobotSpec = robot_spec(s.env_id, s.env_kwargs, where)
        self.mj_model: mujoco.MjModel = load_model(self.robot, s.model_options, where)
        self.model = mjx.put_model(self.mj_model)
        self.randomization = parse_mjx_randomization(datapacks)
        p = self.robot.params
        self.frame_skip = int(p["frame_skip"])
        self.control_dt_s = float(self.mj_model.opt.timestep) * self.frame_skip
        self.max_episode_steps = int(self.robot.max_episode_steps)
        self.keep_task_reward = bool(keep_task_reward)
        self.economics = bool(economics)
        self.healthy = self.robot.robot.healthy_rule(p)
        ctrl = np.asarray(self.mj_model.actuator_ctrlrange, dtype=np.float32)
        self.action_low, self.action_high = ctrl[:, 0].copy(), ctrl[:, 1].copy()
        self.action_size = int(self.mj_model.nu)
        self._dof_lo, self._dof_hi = actuated_dof_span(self.mj_model)
        self._free_root = has_free_root(self.mj_model)
        self._needs_cfrc = self.robot.robot.reads_contact_forces
        # the overlay: scales and human-baseline references as the mujoco backend compiles them
        scales = dict(compile_economic_overlay(objective)) if objective is not None and economics else {}
        econ = spec.economics
        refs = human_baseline_references(econ.mp_human_units_per_hour, econ.error_rate_human, s.idle_power_w,
                                         self.max_episode_steps * self.control_dt_s) \
            if s.overlay_normalization == "human_baseline" else {}
        self.scales = scales
        self.references = {k: v for k, v in refs.items() if k in scales}
        # scale_k / ref_k; a term the mjx env cannot weight is a ConfigError
        self.factors = overlay_term_factors(self.scales, self.references, terms=MJX_TERMS, backend="mjx")
        self._constants = cf.MeterConstants(s.leg_distance_m, s.drivetrain_efficiency, s.idle_power_w,
                                            self.control_dt_s, s.tilt_margin_rad, s.fall_tilt_rad)
        self._coefficients = cf.overlay_coefficients(self.factors, self.control_dt_s)
        self.metric_keys: tuple[str, ...] = BASE_METRIC_KEYS + tuple(f"overlay_{k}_raw" for k in self.scales) \
            if economics else ("length_steps", "return", "fell")
        self._init_qpos = jnp.asarray(self.mj_model.qpos0, dtype=jnp.float32)
        self._template = mjx.make_data(self.model)
        self.observation_size = int(jax.eval_shape(lambda d: self._obs(d, self.model), self._template).shape[0])

    # ------------------------------------------------------------------ per-robot physics readouts
    def _obs(self, d: Any, m: Any) -> jax.Array:
        """Gymnasium v5's ``_get_obs`` of this robot: the parts its record lists, in order."""
        return jnp.concatenate([_OBS_READERS[part](d, self.robot) for part in self.robot.robot.obs_parts])

    def _forward_x(self, d: Any, m: Any) -> jax.Array:
        """The x the task reward differentiates (the record's ``forward_x``): the root's, the main
        body's, or the mass centre's."""
        kind = self.robot.robot.forward_x
        if kind == "main_body_x":
            return d.xpos[1, 0]
        if kind == "mass_centre_x":
            mass = m.body_mass
            return jnp.sum(mass * d.xipos[:, 0]) / jnp.sum(mass)
        return d.qpos[0]

    def _task_reward(self, x_before: jax.Array, d: Any, m: Any, action: jax.Array, healthy: jax.Array) -> jax.Array:
        p, contact_cost = self.robot.params, self.robot.robot.contact_cost
        velocity = (self._forward_x(d, m) - x_before) / self.control_dt_s
        reward = p["forward_reward_weight"] * velocity + p["healthy_reward"] * healthy
        reward = reward - p["ctrl_cost_weight"] * jnp.sum(jnp.square(action))
        if contact_cost == "clipped_forces":
            lo, hi = p["contact_force_range"]
            reward = reward - p["contact_cost_weight"] * jnp.sum(jnp.square(jnp.clip(d._impl.cfrc_ext, lo, hi)))
        elif contact_cost == "clipped_total":
            lo, hi = p["contact_cost_range"]
            cost = jnp.clip(p["contact_cost_weight"] * jnp.sum(jnp.square(d._impl.cfrc_ext)), lo, hi)
            reward = reward - cost
        return reward

    def _randomized_model(self, dr: Mapping[str, jax.Array]) -> Any:
        m = self.model
        if "friction_scale" in dr:
            m = m.replace(geom_friction=m.geom_friction.at[:, 0].multiply(dr["friction_scale"]))
        if "mass_scale" in dr:
            scale = dr["mass_scale"]
            m = m.replace(body_mass=m.body_mass * scale, body_inertia=m.body_inertia * scale[:, None])
        return m

    def _draw_randomization(self, key: jax.Array) -> dict[str, jax.Array]:
        r, out = self.randomization, {}
        k1, k2 = jax.random.split(key)
        if r.friction_range is not None:
            out["friction_scale"] = jax.random.uniform(k1, (), minval=r.friction_range[0], maxval=r.friction_range[1])
        if r.mass_scale_range is not None:
            lo, hi = r.mass_scale_range
            scale = jax.random.uniform(k2, (self.mj_model.nbody,), minval=lo, maxval=hi)
            out["mass_scale"] = scale.at[0].set(1.0)  # the world body
        return out

    # ------------------------------------------------------------------ one env
    def _reset_one(self, key: jax.Array) -> tuple[Any, jax.Array, dict[str, jax.Array], dict[str, jax.Array]]:
        k_pos, k_vel, k_dr, k_obs = jax.random.split(key, 4)
        dr = self._draw_randomization(k_dr)
        m = self._randomized_model(dr)
        scale = float(self.robot["reset_noise_scale"])
        nq, nv = self.mj_model.nq, self.mj_model.nv
        qpos = self._init_qpos + jax.random.uniform(k_pos, (nq,), minval=-scale, maxval=scale)
        if self.robot.robot.reset_qvel_noise == "normal":  # Ant-v5: Gaussian velocity noise
            qvel = scale * jax.random.normal(k_vel, (nv,))
        else:
            qvel = jax.random.uniform(k_vel, (nv,), minval=-scale, maxval=scale)
        data = self._template.replace(qpos=qpos, qvel=qvel)
        if self.robot.robot.obs_reads_body_kinematics:
            # Humanoid-v5's reset obs holds cinert and cvel (after Gymnasium's mj_forward); qfrc_actuator
            # (ctrl = 0) and cfrc_ext (not computed by mj_forward) read 0 there as in the template. The
            # kinematics alone give them, far cheaper to compile and run than a whole mjx.forward; the
            # next mjx.step recomputes everything else from qpos and qvel.
            data = mjx.com_vel(m, mjx.com_pos(m, mjx.kinematics(m, data)))
        obs = self._noisy_obs(self._obs(data, m), k_obs)
        zero = jnp.zeros((), jnp.float32)
        episode = {k: zero for k in EPISODE_KEYS}
        episode["best_x"] = episode["x0"] = qpos[0]
        return data, obs, episode, dr

    def _noisy_obs(self, obs: jax.Array, key: jax.Array) -> jax.Array:
        std = self.randomization.obs_noise_std
        return obs + std * jax.random.normal(key, obs.shape) if std > 0 else obs

    def _novelty_visit(self, counts: jax.Array, point: jax.Array) -> tuple[jax.Array, jax.Array]:
        cell = cf.novelty_cell(point, self.settings.novelty_bin, jnp).astype(jnp.int32).astype(jnp.uint32)
        primes = jnp.asarray(np.array(_HASH_PRIMES[: cell.shape[0]] + (1,) * max(0, cell.shape[0] - 8),
                                      dtype=np.uint32))
        h = jnp.bitwise_xor.reduce(cell * primes) % jnp.uint32(counts.shape[0])
        counts = counts.at[h].add(1)
        return counts, cf.novelty_bonus(counts[h].astype(jnp.float32))

    def _step_one(self, data: Any, action: jax.Array, ep: dict[str, jax.Array], counts: jax.Array,
                  dr: dict[str, jax.Array], key: jax.Array):
        s, p = self.settings, self.robot.params
        m = self._randomized_model(dr)
        k_act, k_obs = jax.random.split(key)
        if self.randomization.action_noise_std > 0:
            action = action + self.randomization.action_noise_std * jax.random.normal(k_act, action.shape)
        action = jnp.clip(action, self.action_low, self.action_high)
        x_before = self._forward_x(data, m)
        data = data.replace(ctrl=action)
        data = jax.lax.fori_loop(0, self.frame_skip, lambda _, d: mjx.step(m, d), data)
        if self._needs_cfrc:
            data = mjx.rne_postconstraint(m, data)
        qpos, qvel = data.qpos, data.qvel
        healthy = robots.is_healthy(self.healthy, qpos, qvel, jnp)
        fell = jnp.logical_not(healthy) if p["terminate_when_unhealthy"] else jnp.zeros((), bool)
        task_r = self._task_reward(x_before, data, m, action, healthy.astype(jnp.float32))
        obs = self._noisy_obs(self._obs(data, m), k_obs)
        if not self.economics:
            new = {**ep, "steps": ep["steps"] + 1.0, "task_return": ep["task_return"] + task_r}
            finished = {"length_steps": new["steps"], "return": new["task_return"], "fell": fell.astype(jnp.float32)}
            return data, obs, task_r, fell, new, counts, finished
        # metering and the overlay potential: the mujoco backend's meter_step, on traced arrays
        lo, hi = self._dof_lo, self._dof_hi
        counts, bonus = self._novelty_visit(counts, obs[: s.novelty_dims])
        reading = cf.StepReading(x_m=qpos[0],
                                 mechanical_w=cf.mechanical_power_w(data.qfrc_actuator[lo:hi], qvel[lo:hi], jnp),
                                 tilt_rad=root_tilt_rad(qpos, self._free_root, jnp), fell=fell, novelty_bonus=bonus)
        sums = self._meter_sums(ep)
        cf.meter_step(sums, reading, self._constants, jnp)
        j = jnp.asarray(cf.overlay_potential(sums, self._coefficients, jnp), jnp.float32)
        new = {**ep, **{k: getattr(sums, k) for k in _METER_KEYS}, "task_return": ep["task_return"] + task_r,
               "overlay_j": j}
        overlay_r = j - ep["overlay_j"]
        reward = (task_r if self.keep_task_reward else 0.0) + overlay_r
        finished = self._episode_metrics(new, fell)
        return data, obs, reward, fell, new, counts, finished

    @staticmethod
    def _meter_sums(ep: dict[str, jax.Array]) -> cf.MeterSums:
        """The meter's running sums of an episode dict (``EnvState.episode`` of one env)."""
        return cf.MeterSums(**{k: ep[k] for k in _METER_KEYS})

    def _episode_metrics(self, ep: dict[str, jax.Array], fell: jax.Array) -> dict[str, jax.Array]:
        metrics = cf.running_metrics(self._meter_sums(ep), self.control_dt_s, jnp)
        out = {
            "units_completed": ep["units"],
            "units_attempted": ep["units"] + ep["errors"],
            "errors": ep["errors"],
            "episode_length_s": ep["steps"] * self.control_dt_s,
            "length_steps": ep["steps"],
            "energy_wh": ep["energy_wh"],
            "risk_score": metrics.risk_score,
            "novelty_score": metrics.novelty_score,
            "return": ep["task_return"],
            "forward_distance_m": ep["best_x"] - ep["x0"],
            "fell": fell.astype(jnp.float32),
            "overlay_return": ep["overlay_j"],
        }
        for k in self.scales:
            out[f"overlay_{k}_raw"] = jnp.asarray(getattr(metrics, k), jnp.float32)
        return out

    # ------------------------------------------------------------------ the batched API
    def reset(self, key: jax.Array, num_envs: int) -> EnvState:
        """``num_envs`` fresh episodes (pure; jit with ``num_envs`` static)."""
        keys = jax.random.split(key, 2 * num_envs)
        env_keys, reset_keys = keys[:num_envs], keys[num_envs:]
        data, obs, episode, dr = jax.vmap(self._reset_one)(reset_keys)
        zeros = jnp.zeros((num_envs,), jnp.float32)
        finished = {k: zeros for k in self.metric_keys}
        counts = jnp.zeros((num_envs, self.settings.novelty_table_size if self.economics else 1), jnp.int32)
        return EnvState(data, obs, zeros, zeros, zeros, episode, finished, env_keys, counts, dr)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        """One control step of every env, auto-resetting the ones whose episode ended (pure)."""
        keys = jax.vmap(lambda k: jax.random.split(k, 3))(state.key)
        env_keys, step_keys, reset_keys = keys[:, 0], keys[:, 1], keys[:, 2]
        data, obs, reward, fell, episode, counts, finished = jax.vmap(self._step_one)(
            state.data, action, state.episode, state.novelty_counts, state.randomization, step_keys)
        truncated = jnp.logical_and(episode["steps"] >= self.max_episode_steps, jnp.logical_not(fell))
        done = jnp.logical_or(fell, truncated)

        data, obs, episode, dr = auto_reset(done, self._reset_one, reset_keys,
                                            (data, obs, episode, state.randomization))
        return EnvState(data, obs, reward.astype(jnp.float32), done.astype(jnp.float32),
                        truncated.astype(jnp.float32), episode, finished, env_keys, counts, dr)

    # ------------------------------------------------------------------ host side
    def finished_to_dicts(self, finished: Mapping[str, Any]) -> list[dict[str, Any]]:
        """Rows of finished episodes (arrays of one length) -> the mujoco backend's raw-episode dicts.

        Keys and types as ``mujoco/evaluation.py``'s ``flatten_episode``: the meter's raw metrics,
        ``overlay_return``, ``total_return`` and ``overlay_<key>_raw`` / ``overlay_<key>_weighted``.
        """
        if not self.economics:
            raise ValueError("an env built with economics=False has no raw economic metrics")
        cols = {k: np.asarray(v, dtype=np.float64).reshape(-1) for k, v in finished.items()}
        n = len(next(iter(cols.values()))) if cols else 0
        rows = []
        for i in range(n):
            row = {k: float(cols[k][i]) for k in BASE_METRIC_KEYS if k != "fell"}
            row["control_dt_s"] = self.control_dt_s
            row["termination_reason"] = TerminationReason.FALL if cols["fell"][i] > 0.5 else TerminationReason.MAX_STEPS
            rows.append(with_overlay_columns(row, cols, i, self.factors))
        return rows
