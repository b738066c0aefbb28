"""GymCourierEnv: a Gymnasium v5 body (hopper, walker2d, ant, humanoid) on the courier task, one env in MJX.

A thin env of :mod:`econmotor.motor_backend.mjx.base_env` (``reset(key)`` / ``step(state, action)`` of one
env); :func:`~econmotor.motor_backend.mjx.wrappers.make_env` wraps it into the batched, auto-resetting,
economically metered env the mjx backend trains on (``wrappers.py``: the meter, the overlay reward and the
raw episode metrics). Physics is MuJoCo's JAX port (``mujoco.mjx``) on Gymnasium's own MJCF files; the
observation, action bounds, task reward, frame skip, reset noise and fall (unhealthy termination) are
those of the Gymnasium v5 env the ``mujoco`` backend trains on, read from the robot's record
(``robots/gym_couriers.py``: the env reads its fields and never branches on a robot's name), so a policy's
obs/action layout carries over.

What the meter reads (``State.readings``, one row per control step, with the physics readouts of
``couriers/physics.py``): the root's x, ``sum |qfrc_actuator * qvel|`` over the actuated dofs, the root's
tilt, Gymnasium's healthy check as the fall; the meter counts novelty on the observation's first
``novelty_dims``. Domain randomization (:data:`SUPPORTED_DR_KEYS`): friction and mass multipliers drawn
per episode, action and observation noise per step.

Float32 here (JAX's default) vs float64 in MuJoCo C: per-step figures agree to ~1e-5 relative
(see the parity tests for the stated tolerances).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from econmotor.couriers.overlay import TERM_METRICS
from econmotor.couriers.physics import actuated_dof_span, has_free_root, root_tilt_rad
from econmotor.couriers.randomization import DomainRandomization, parse_randomization
from econmotor.economics import courier_formulas as cf
from econmotor.errors import ConfigError
from econmotor.motor_backend.mjx._mjx import mjx
from econmotor.motor_backend.mjx.assets import RobotSpec, load_model, robot_spec
from econmotor.motor_backend.mjx.base_env import Env, State, reading
from econmotor.motor_backend.mjx.host_physics import HOST_OBS_PARTS, HostPhysics
from econmotor.motor_backend.mjx.settings import PHYSICS
from econmotor.robots import gym_couriers as robots

#: the datapack domain-randomization keys this env honours (the others raise a ConfigError).
SUPPORTED_DR_KEYS = ("friction_range", "mass_scale_range", "action_noise_std", "obs_noise_std")
#: overlay keys the mjx couriers can weight (no pose tracking).
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


class GymCourierEnv(Env):
    """One Gymnasium v5 body on a courier task (module docstring); batched by ``wrappers.make_env``.

    Args:
        task_id: a catalog task whose mjx entry names a Gymnasium ``env_id``.
        datapacks: datapack configs or bundles (domain randomization: :data:`SUPPORTED_DR_KEYS`).
        seed, catalog, readings: as :class:`~econmotor.motor_backend.mjx.base_env.Env`.
        physics: ``"mjx"`` or ``"mujoco"`` (MuJoCo C on the host, ``mjx/host_physics.py``); default: the
            task's ``cpu_physics`` on a CPU, MJX on an accelerator.
    """

    terms = MJX_TERMS
    counts_novelty = True

    def __init__(self, task_id: str, *, datapacks: Sequence[Any] = (), seed: int = 0, catalog: Any = None,
                 readings: bool = True, physics: str | None = None) -> None:
        super().__init__(task_id, seed=seed, catalog=catalog, readings=readings)
        s = self.settings
        self.robot: RobotSpec = robot_spec(s.env_id, s.env_kwargs, self.where)
        self._use_model(load_model(self.robot, s.model_options, self.where))
        self.randomization = parse_mjx_randomization(datapacks)
        p = self.robot.params
        self.frame_skip = int(p["frame_skip"])
        self.control_dt_s = self.meter_dt_s = float(self.mj_model.opt.timestep) * self.frame_skip
        self.max_episode_steps = int(self.robot.max_episode_steps)
        self.episode_s = self.max_episode_steps * self.control_dt_s
        self.healthy = self.robot.robot.healthy_rule(p)
        ctrl = np.asarray(self.mj_model.actuator_ctrlrange, dtype=np.float32)
        self.action_low, self.action_high = ctrl[:, 0].copy(), ctrl[:, 1].copy()
        self.action_size = int(self.mj_model.nu)
        self._dof_lo, self._dof_hi = actuated_dof_span(self.mj_model)
        self._free_root = has_free_root(self.mj_model)
        self._needs_cfrc = self.robot.robot.reads_contact_forces
        self._init_qpos = jnp.asarray(self.mj_model.qpos0, dtype=jnp.float32)
        self.physics = physics or (s.cpu_physics if jax.default_backend() == "cpu" else "mjx")
        self.host: HostPhysics | None = None
        if self.physics == "mujoco":
            self._check_host_physics()
            self.host = HostPhysics(self.mj_model, self.frame_skip)
            self._template = self.host.template()
            self.physics_label = f"MuJoCo {mujoco.__version__} (C), called from JAX"
        elif self.physics != "mjx":
            raise ConfigError(self.where, "cpu_physics", f"unknown physics {self.physics!r}", PHYSICS)
        self.observation_size = int(jax.eval_shape(lambda d: self._obs(d, self.model), self._template).shape[0])

    def _check_host_physics(self) -> None:
        """MuJoCo C on the host returns qpos, qvel and qfrc_actuator: a body whose observation, reward or
        forward x reads more (contact forces, body kinematics) needs MJX."""
        robot = self.robot.robot
        needs = [p for p in robot.obs_parts if p not in HOST_OBS_PARTS]
        needs += ["contact forces"] if robot.reads_contact_forces else []
        needs += [robot.forward_x] if robot.forward_x != "root_x" else []
        if needs:
            raise ConfigError(self.where, "cpu_physics", f"{self.robot.robot.env_id} reads {', '.join(needs)}, "
                              "which MuJoCo C on the host does not return; use mjx", ["mjx"])

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

    # ------------------------------------------------------------------ domain randomization
    def randomized_model(self, draws: Mapping[str, jax.Array]) -> Any:
        """The body's model with the episode's friction and mass multipliers."""
        m = self.model
        if "friction_scale" in draws:
            m = m.replace(geom_friction=m.geom_friction.at[:, 0].multiply(draws["friction_scale"]))
        if "mass_scale" in draws:
            scale = draws["mass_scale"]
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

    def _noisy_obs(self, obs: jax.Array, key: jax.Array) -> jax.Array:
        std = self.randomization.obs_noise_std
        return obs + std * jax.random.normal(key, obs.shape) if std > 0 else obs

    # ------------------------------------------------------------------ one env
    def reset(self, key: jax.Array) -> State:
        """Gymnasium's noisy start (the episode's randomization drawn first)."""
        k_pos, k_vel, k_dr, k_obs = jax.random.split(key, 4)
        dr = self._draw_randomization(k_dr)
        m = self.randomized_model(dr)
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
        return self.first_state(data, self._noisy_obs(self._obs(data, m), k_obs), key, randomization=dr)

    def step(self, state: State, action: jax.Array) -> State:
        """``frame_skip`` physics steps of the (noisy, clipped) action; Gymnasium's reward and fall."""
        p = self.robot.params
        m = self.randomized_model(state.randomization) if self.host is None else self.model
        k_act, k_obs = jax.random.split(state.key)
        if self.randomization.action_noise_std > 0:
            action = action + self.randomization.action_noise_std * jax.random.normal(k_act, action.shape)
        action = jnp.clip(action, self.action_low, self.action_high)
        x_before = self._forward_x(state.data, m)
        if self.host is not None:
            data = self.host.step(state.data, action, state.randomization)
        else:
            data = state.data.replace(ctrl=action)
            data = jax.lax.fori_loop(0, self.frame_skip, lambda _, d: mjx.step(m, d), data)
            if self._needs_cfrc:
                data = mjx.rne_postconstraint(m, data)
        qpos, qvel = data.qpos, data.qvel
        healthy = robots.is_healthy(self.healthy, qpos, qvel, jnp)
        fell = jnp.logical_not(healthy) if p["terminate_when_unhealthy"] else jnp.zeros((), bool)
        task_r = self._task_reward(x_before, data, m, action, healthy.astype(jnp.float32))
        readings = state.readings
        if self.readings:
            lo, hi = self._dof_lo, self._dof_hi
            now = reading(qpos[0], cf.mechanical_power_w(data.qfrc_actuator[lo:hi], qvel[lo:hi], jnp),
                          root_tilt_rad(qpos, self._free_root, jnp), fell)
            readings = {k: v[None] for k, v in now.items()}
        return state._replace(data=data, obs=self._noisy_obs(self._obs(data, m), k_obs),
                              reward=jnp.asarray(task_r, jnp.float32), done=fell.astype(jnp.float32),
                              truncated=jnp.zeros((), jnp.float32), readings=readings)
