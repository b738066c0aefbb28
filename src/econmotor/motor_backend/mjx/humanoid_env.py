"""HumanoidWalkerEnv: a real robot (a robot card: Unitree G1, Booster T1) walking the delivery course, one env in MJX.

A thin env of :mod:`econmotor.motor_backend.mjx.base_env` (``reset(key)`` / ``step(state, action)`` of one
env), batched, auto-reset and economically metered by :func:`~econmotor.motor_backend.mjx.wrappers.make_env`
as the Gymnasium couriers are, so the mjx backend trains, evaluates and exports it unchanged. A task runs
here when its mjx entry inherits the task's locomotion block (``inherit: locomotion``, ``tasks/mjx.yaml``); everything
robot-specific is read from the card (:mod:`econmotor.robots`), never from the robot's name.

- **the robot**: the card's MJCF with its maker's collision filter and feet-only contacts, its
  actuators applying the card's PD law (:func:`econmotor.locomotion.model.pd_actuator_spec` with
  ``contacts="feet"``: the MuJoCo C walker env's law), the task's ``model_options`` (solver
  iterations) applied; the start: ``card.init_pos``, upright, the default pose plus the start-pose noise.
- **action -> torques**, Holosoma's convention: the action clipped to ``+-card.action_clip``,
  PD targets ``default + action_scale * action`` written to ``ctrl``, ``card.decimation`` physics
  steps per action in which the actuators apply ``tau = clip(kp (target - q) - kd qd, -effort_limit,
  effort_limit)`` (the episode's kp/kd scales set in the model by :meth:`HumanoidWalkerEnv.randomized_model`).
- **observation**: holosoma_inference's ``actor_obs`` (:func:`econmotor.robots.observation.build_observation`),
  the command being the course's (below); so a policy trained here runs in the sim-to-sim
  evaluator and in holosoma_inference, and theirs here.
- **the course** (:mod:`econmotor.locomotion.course`): the sim-to-sim evaluator's,
  legs of ``leg_m`` at the course speed with a dwell at each end; the episode ends at its time
  limit (the locomotion block's ``sim2sim_episode_s``), when the course is done, or at a fall.
- **metering**: every physics step is a reading (``State.readings``: x, ``sum |qfrc_actuator qvel|``,
  tilt, the card's fall rule), metered by ``wrappers.EconomicMeter`` as the evaluator meters it
  (frozen after a fall); the walker's own raw metrics (legs, speed, walking time, lateral drift,
  mean power, course done) come from :meth:`HumanoidWalkerEnv.extra_metrics`.
- **reward**: the locomotion terms of :mod:`econmotor.locomotion.rewards` with the task's locomotion block's
  weights, the set the MuJoCo C learner computes too (the meter adds the economic overlay's ``J(t) - J(t-1)``).
- **stress in the graph**, from the datapacks (``humanoid_stress.yaml``, read by
  :meth:`econmotor.locomotion.stress.Stress.from_datapacks` as for the MuJoCo C walker env):
  floor friction and torso payload per episode, base-velocity pushes at random intervals, kp/kd
  scale per joint (``kp_range`` / ``kd_range``), start-pose noise; no control delay
  (:data:`HUMANOID_LACKS`), and what no walker env applies is a ConfigError naming the datapack and key.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from econmotor.couriers.physics import has_fallen, root_tilt_rad
from econmotor.economics import courier_formulas as cf
from econmotor.errors import ConfigError
from econmotor.locomotion.course import (
    CourseSettings,
    CourseState,
    course_command,
    course_finished,
    course_start,
    heading_yaw,
)
from econmotor.locomotion.learning import course_point
from econmotor.locomotion.model import pd_actuator_spec, pd_gain_bias
from econmotor.locomotion.rewards import LocomotionReading, locomotion_reward
from econmotor.locomotion.stress import Stress
from econmotor.motor_backend.mjx._mjx import mjx
from econmotor.motor_backend.mjx.assets import apply_model_options
from econmotor.motor_backend.mjx.base_env import Env, State, like, reading
from econmotor.robots import card as robot_card
from econmotor.robots.model import joint_indices
from econmotor.robots.observation import (
    advance_phase,
    build_observation,
    initial_phase,
    projected_gravity,
    rotate_inverse,
)

#: overlay keys a walker can weight (no novelty table, no pose tracking)
HUMANOID_TERMS = ("mpl_per_hour", "error_rate", "energy_kwh", "risk_score")
#: the walker's own running sums (besides the episode's and the meter's)
WALKER_EPISODE_KEYS = ("walk_s", "walk_m", "max_lateral_m", "legs_done", "start_steps")
#: the walker's own raw metrics of a finished episode
WALKER_METRIC_KEYS = ("legs_reached", "achieved_speed_m_per_s", "walking_s", "max_lateral_m", "mean_power_w",
                      "course_done", "episode_limit_s")
#: datapack stress keys this env cannot apply besides those no walker env applies (no action delay buffer)
HUMANOID_LACKS = ("ctrl_delay_steps",)


def check_humanoid_datapack(pack: Any, source: str) -> None:
    """A datapack the humanoid couriers can apply (:meth:`Stress.from_datapacks` with :data:`HUMANOID_LACKS`),
    else its ConfigError naming ``source`` and the key."""
    Stress.from_datapacks([replace(pack, source=source)], {"push_interval_s": (1.0, 1.0), "max_push_vel": (0.0, 0.0)},
                          lacks=HUMANOID_LACKS)


class HumanoidWalkerEnv(Env):
    """A robot card walking a courier task's course (module docstring); batched by ``wrappers.make_env``.

    Args:
        task_id: a catalog task whose mjx entry names a ``robot``.
        datapacks: datapack configs or bundles (their stress: :meth:`Stress.from_datapacks`, which refuses
            what this env cannot apply, and :data:`HUMANOID_LACKS`).
        seed, catalog, readings: as :class:`~econmotor.motor_backend.mjx.base_env.Env`.
        random_start: start every episode at a random point of the course (training;
            :func:`locomotion.learning.course_point`).
    """

    obs_layout_note = "holosoma_inference actor_obs of the robot card (econmotor/robots)"
    terms = HUMANOID_TERMS
    extra_metric_keys = WALKER_METRIC_KEYS

    def __init__(self, task_id: str, *, datapacks: Sequence[Any] = (), seed: int = 0, catalog: Any = None,
                 readings: bool = True, random_start: bool = False) -> None:
        super().__init__(task_id, seed=seed, catalog=catalog, readings=readings)
        self.random_start = bool(random_start)
        s, where = self.settings, self.where
        self.card = c = robot_card(s.robot, where)
        loco = s.locomotion  # the task's locomotion block: time limit and reward terms (mjx/settings.py)
        self.episode_s, self.weights, self.reward_params = loco["episode_s"], loco["weights"], loco["params"]
        self.course = CourseSettings(**{"leg_m": s.leg_distance_m, **s.course})
        self.stress = Stress.from_datapacks(datapacks, c.push_preset, s.start_joint_noise_rad, lacks=HUMANOID_LACKS)
        m = pd_actuator_spec(c, c.array("kp"), c.array("kd"), contacts="feet").compile()
        apply_model_options(m, s.model_options, where)
        self._use_model(m)
        qadr, dadr, act = joint_indices(m, c)
        self._qadr, self._dadr, self._act = (jnp.asarray(a) for a in (qadr, dadr, act))
        self._torso = m.body(c.torso_body).id
        self._feet = jnp.asarray([m.body(b).id for b in c.foot_bodies])
        self._contact_points = jnp.asarray([m.body(b).id for b in c.foot_contact_bodies])
        self._floor = m.geom("floor").id
        self.physics_dt_s = self.meter_dt_s = float(m.opt.timestep)
        self.control_dt_s = c.control_dt_s
        if abs(self.physics_dt_s - c.physics_dt_s) > 1e-12:
            raise ConfigError(where, "model_options", "the physics step is the robot card's")
        self.max_episode_steps = round(self.episode_s / self.control_dt_s)
        self.readings_per_step = c.decimation
        self.action_size = c.num_dofs
        self.action_low = np.full(c.num_dofs, -c.action_clip, np.float32)
        self.action_high = np.full(c.num_dofs, c.action_clip, np.float32)
        self.observation_size = c.obs_dim
        ranges = c.command_ranges
        self._vx_max, self._yaw_range = float(ranges["lin_vel_x"][1]), tuple(float(v) for v in ranges["ang_vel_yaw"])
        qpos0 = np.asarray(m.qpos0, np.float64).copy()
        qpos0[0:3], qpos0[3:7] = c.init_pos, (1.0, 0.0, 0.0, 0.0)
        qpos0[qadr] = c.default_dof_angles
        self._qpos0 = jnp.asarray(qpos0, jnp.float32)
        self._default = jnp.asarray(c.default_dof_angles, jnp.float32)
        self._kp, self._kd = jnp.asarray(c.kp, jnp.float32), jnp.asarray(c.kd, jnp.float32)
        self._heat_coeff = jnp.asarray(c.heat_coeff(np.float32))  # the card's motor model (W per (N m)^2)

    # ------------------------------------------------------------------ physics readouts
    def has_fallen(self, qpos: jax.Array, qvel: jax.Array) -> jax.Array:
        """The card's fall rule with its runaway rule (:func:`econmotor.couriers.physics.has_fallen`)."""
        return has_fallen(self.card, qpos, qvel, jnp)

    def randomized_model(self, draws: Mapping[str, jax.Array]) -> Any:
        """The card's model with the episode's floor friction, torso payload and PD gains (the card's
        kp/kd scaled by the episode's draws, in the actuators' parameters)."""
        m = self.model
        if self.stress.kp_range or self.stress.kd_range:
            gain, bias = pd_gain_bias(m.actuator_gainprm, m.actuator_biasprm, self._act,
                                      self._kp * draws["kp_scale"], self._kd * draws["kd_scale"])
            m = m.replace(actuator_gainprm=gain, actuator_biasprm=bias)
        if "friction" in draws:
            mu = draws["friction"]
            m = m.replace(geom_friction=m.geom_friction.at[self._floor, 0].set(mu),
                          pair_friction=m.pair_friction.at[:, 0:2].set(mu))
        if "payload_kg" in draws:
            m = m.replace(body_mass=m.body_mass.at[self._torso].add(draws["payload_kg"]))
        return m

    def _draw(self, key: jax.Array, rng: tuple[float, float], shape: tuple[int, ...] = ()) -> jax.Array:
        return jax.random.uniform(key, shape, minval=rng[0], maxval=rng[1])

    def _observe(self, data: Any, robot: dict[str, jax.Array]) -> tuple[jax.Array, dict[str, jax.Array]]:
        """The course's command for the next step, the gait clock advanced, and the observation."""
        qpos = data.qpos
        course = CourseState(robot["leg"], robot["dwell_left_s"], robot["legs_done"])
        course, vx, yaw_rate = course_command(course, qpos[0], qpos[1], heading_yaw(qpos[3:7], jnp), self.course,
                                              self.control_dt_s, self._vx_max, self._yaw_range, jnp)
        lin = jnp.stack([vx, 0.0 * vx])
        phase, standing = advance_phase(robot["phase"], robot["standing"], lin, yaw_rate, self.card, jnp)
        obs = build_observation(self.card, jnp, quat_wxyz=qpos[3:7], ang_vel_body=data.qvel[3:6],
                                q=qpos[self._qadr], qd=data.qvel[self._dadr], lin_vel_cmd=lin, ang_vel_cmd=yaw_rate,
                                last_action=robot["last_action"], phase=phase)
        robot = {**robot, "leg": course.leg, "dwell_left_s": course.dwell_left_s, "legs_done": course.legs_done,
                 "command": jnp.stack([vx, 0.0 * vx, yaw_rate]), "phase": phase, "standing": standing}
        return obs, robot

    # ------------------------------------------------------------------ one env
    def _draw_stress(self, keys: Sequence[jax.Array]) -> dict[str, jax.Array]:
        """The episode's friction, payload and kp/kd scales (from the reset's keys 1 to 4)."""
        st, n = self.stress, self.card.num_dofs
        k_mu, k_pay, k_kp, k_kd = keys
        dr: dict[str, jax.Array] = {}
        if st.friction_range is not None:
            dr["friction"] = self._draw(k_mu, st.friction_range)
        if st.payload_kg_range is not None:
            dr["payload_kg"] = self._draw(k_pay, st.payload_kg_range)
        dr["kp_scale"] = self._draw(k_kp, st.kp_range, (n,)) if st.kp_range else jnp.ones(n)
        dr["kd_scale"] = self._draw(k_kd, st.kd_range, (n,)) if st.kd_range else jnp.ones(n)
        return dr

    def reset(self, key: jax.Array) -> State:
        """The card's start (the default pose plus start noise, at the course's start or, with
        ``random_start``, a random point of it) and the episode's stress draws."""
        st, n = self.stress, self.card.num_dofs
        keys = jax.random.split(key, 7)
        k_q, k_push, k_start = keys[0], keys[5], keys[6]
        qpos = self._qpos0
        if st.initial_joint_noise_rad > 0:
            noise = st.initial_joint_noise_rad
            qpos = qpos.at[self._qadr].add(self._draw(k_q, (-noise, noise), (n,)))
        dr = self._draw_stress(keys[1:5])
        data = self._template.replace(qpos=qpos, qvel=jnp.zeros_like(self._template.qvel))
        zero = jnp.zeros((), jnp.float32)
        start = course_start(jnp)
        robot = {"phase": jnp.asarray(initial_phase(np), jnp.float32), "standing": jnp.zeros((), bool),
                 "last_action": jnp.zeros(n, jnp.float32), "command": jnp.zeros(3, jnp.float32),
                 **{k: zero + v for k, v in start._asdict().items()}, "time_s": zero,
                 "next_push_s": self._draw(k_push, st.push_interval_s) if st.push_interval_s else jnp.full((), jnp.inf),
                 "course_done": jnp.zeros((), bool)}
        episode = dict.fromkeys(WALKER_EPISODE_KEYS, zero)
        if self.random_start:  # a random point of the course: the base there, the course's time so far spent
            x, point, steps = course_point(self.course, jax.random.uniform(k_start, (3,)), self.control_dt_s,
                                           self.max_episode_steps, jnp)
            data = data.replace(qpos=data.qpos.at[0].set(x))
            robot = {**robot, **{k: zero + v for k, v in point._asdict().items()}, "time_s": steps * self.control_dt_s,
                     "next_push_s": robot["next_push_s"] + steps * self.control_dt_s}
            episode["control_steps"] = episode["start_steps"] = zero + steps
        obs, observed = self._observe(data, robot)
        return self.first_state(data, obs, key, episode=episode, info=like(observed, robot), randomization=dr)

    def _push(self, data: Any, robot: dict[str, jax.Array], key: jax.Array) -> tuple[Any, dict[str, jax.Array]]:
        """Holosoma's push: a base velocity kick every few seconds (the next one's time drawn)."""
        st = self.stress
        k_dir, k_next = jax.random.split(key)
        push = robot["time_s"] >= robot["next_push_s"]
        kick = jax.random.uniform(k_dir, (2,), minval=-1.0, maxval=1.0) * jnp.asarray(st.max_push_vel_m_per_s)
        data = data.replace(qvel=data.qvel.at[0:2].add(jnp.where(push, kick, 0.0)))
        return data, {**robot, "next_push_s": jnp.where(push, robot["time_s"] + self._draw(k_next, st.push_interval_s),
                                                        robot["next_push_s"])}

    def _physics(self, m: Any, data: Any, target: jax.Array):
        """``card.decimation`` physics steps of the PD loop on the PD ``target`` (the actuators' ``ctrl``;
        they apply the law): ``(data, fell, readings)`` (a reading per step)."""

        def physics_step(carry, _):
            d, alive = carry
            d = mjx.step(m, d)
            fell = self.has_fallen(d.qpos, d.qvel)
            frc = d.qfrc_actuator[self._dadr]
            now = reading(d.qpos[0], cf.mechanical_power_w(frc, d.qvel[self._dadr], jnp),
                          root_tilt_rad(d.qpos, True, jnp), fell, cf.winding_heat_w(frc, self._heat_coeff, jnp)) \
                if self.readings else {}
            return (d, alive & ~fell), now

        data = data.replace(ctrl=data.ctrl.at[self._act].set(target))
        (data, alive), readings = jax.lax.scan(physics_step, (data, jnp.ones((), bool)), None,
                                               length=self.card.decimation)
        return data, ~alive, readings

    def step(self, state: State, action: jax.Array) -> State:
        """Holosoma's PD loop on the clipped action (pushes, kp/kd draws), the locomotion reward, the course."""
        c, robot, ep, data = self.card, state.info, state.episode, state.data
        m = self.randomized_model(state.randomization)
        action = jnp.clip(action, -c.action_clip, c.action_clip)
        if self.stress.push_interval_s is not None:
            data, robot = self._push(data, robot, state.key)
        x_before = data.qpos[0]
        data, fell, readings = self._physics(m, data, self._default + c.action_scale * action)
        qpos, qvel = data.qpos, data.qvel
        quat = qpos[3:7]
        loco = LocomotionReading(
            command=robot["command"], lin_vel_body=rotate_inverse(quat, qvel[0:3], jnp), ang_vel_body=qvel[3:6],
            gravity_body=projected_gravity(quat, jnp), action=action, last_action=robot["last_action"],
            q=qpos[self._qadr], default_q=self._default, phase=robot["phase"],
            foot_z=data.xpos[self._contact_points, 2], feet_xy=data.xpos[self._feet, 0:2],
            feet_gravity_xy=-data.xmat[self._feet, 2, 0:2], base_yaw=heading_yaw(quat, jnp))
        task_r, _ = locomotion_reward(loco, self.weights, self.reward_params, self.control_dt_s, jnp)
        course_done = course_finished(CourseState(robot["leg"], robot["dwell_left_s"], robot["legs_done"]),
                                      self.course, jnp)
        walking = robot["command"][0] > 0.0
        new = {**ep, "walk_s": ep["walk_s"] + jnp.where(walking, self.control_dt_s, 0.0),
               "walk_m": ep["walk_m"] + jnp.where(walking, qpos[0] - x_before, 0.0),
               "max_lateral_m": jnp.maximum(ep["max_lateral_m"], jnp.abs(qpos[1]))}
        robot = {**robot, "last_action": action, "time_s": robot["time_s"] + self.control_dt_s,
                 "course_done": course_done}
        obs, robot = self._observe(data, robot)
        new["legs_done"] = robot["legs_done"]
        return state._replace(data=data, obs=obs, reward=jnp.asarray(task_r, jnp.float32),
                              done=fell.astype(jnp.float32), truncated=course_done.astype(jnp.float32),
                              episode=like(new, ep), info=like(robot, state.info), readings=readings)

    def extra_metrics(self, state: State) -> dict[str, jax.Array]:
        """Legs reached, speed while walking, walking time, lateral drift, mean power, course done, time limit."""
        ep = state.episode
        length_s = ep["steps"] * self.physics_dt_s
        return {"legs_reached": ep["legs_done"], "achieved_speed_m_per_s": cf.safe_div(ep["walk_m"], ep["walk_s"], jnp),
                "walking_s": ep["walk_s"], "max_lateral_m": ep["max_lateral_m"],
                "mean_power_w": cf.safe_div(ep["energy_wh"] * cf.SECONDS_PER_HOUR, length_s, jnp),
                "course_done": state.info["course_done"].astype(jnp.float32),
                # the time limit from the episode's start (a fall's J rate is over it: courier_formulas.rate_length_s)
                "episode_limit_s": (self.max_episode_steps - ep["start_steps"]) * self.control_dt_s}
