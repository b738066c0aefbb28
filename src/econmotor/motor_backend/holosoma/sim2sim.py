"""Sim-to-sim: an imported (or Holosoma-trained) locomotion policy walking a delivery course in plain MuJoCo.

Runs in .venv-holosoma (mujoco, onnxruntime and the Holosoma packages the contract is read
from, :mod:`.policy_import`); the main interpreter reaches it through a ``sim2sim`` job.

Per episode (seeded: ``seed + episode index``):

- **the robot** is its card's (:mod:`econmotor.robots`, the contract's ``card``): the model of
  :func:`econmotor.robots.model.model_spec` (the maker's MJCF, a plane named ``floor``, the physics
  step, and collisions as Holosoma's MuJoCo simulator models them: with ``self_collisions`` False,
  the G1's and T1's, the robot's colliders touch the floor only, not each other); it starts at the
  card's initial base position in its default pose (plus the initial joint perturbation).
- **control**: the policy runs at its control rate (``decimation`` physics steps per
  action); a PD loop at the physics rate drives the actuators:
  ``tau = kp (default + action_scale * action - q) - kd qd``, clipped to the effort limits.
- **observation**: :class:`ObservationBuilder`, the card's convention built by
  :mod:`econmotor.robots.observation` (the function the JAX trainer calls too); equal to
  holosoma_inference's own code (tests/integration/test_holosoma_sim2sim.py).
- **the course** (:class:`CourseController`): a corridor along +x of ``legs`` legs of
  ``leg_m`` metres (the episode ends after the last leg's dwell, or at its time limit); on each leg
  the controller commands the course speed and a yaw rate that
  steers back to the corridor's centre line (``yaw_rate = yaw_gain * heading error`` towards a
  point ``lookahead_m`` ahead on the line); at each leg end the robot stands for ``dwell_s``
  (the pick-and-place the human's leg includes, so a unit is counted alike for both).
- **stress** (:class:`Stress`, from the datapack): floor friction drawn per episode, a payload
  on the torso, pushes (a base velocity kick every few seconds, Holosoma's push randomizer),
  initial joint perturbation.
- **metering**: each physics step goes through the couriers' shared formula
  :func:`econmotor.economics.courier_formulas.meter_step` (units on the forward high-water mark
  of x along the course, electrical energy ``sum |qfrc_actuator qvel| / efficiency + idle``,
  tilt risk, falls). A fall, the card's rule (tilt past ``fall_tilt_rad`` or the base below
  ``min_base_z_m``), ends the episode with one error.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from econmotor.economics import courier_formulas as cf
from econmotor.motor_backend.couriers.physics import root_tilt_rad
from econmotor.motor_backend.holosoma import econ_formulas
from econmotor.motor_backend.holosoma.policy_import import PolicyContract
from econmotor.robots import RobotCard
from econmotor.robots import observation as robot_obs
from econmotor.robots.model import FLOOR, joint_indices, model_spec


@dataclass(frozen=True)
class CourseSettings:
    """The delivery course: legs of ``leg_m`` along +x, ``dwell_s`` standing at each leg end.

    ``speed_m_per_s``: the commanded walking speed; ``legs``: the episode ends when the last leg's
    dwell does (0: at the time limit only), so every unit an episode counts carries its dwell, as
    the human's does; ``lookahead_m`` / ``yaw_gain``: the heading controller (yaw rate in rad/s per
    rad of heading error towards the point ``lookahead_m`` ahead on the centre line).
    """

    leg_m: float
    dwell_s: float
    speed_m_per_s: float
    legs: int = 0
    lookahead_m: float = 1.0
    yaw_gain: float = 2.0


@dataclass(frozen=True)
class MeterSettings:
    """The courier meter's constants (:func:`.plan.meter_settings`, the ones the training terms read: the task
    catalog's, with unit and source there, and the robot card's fall tilt)."""

    leg_distance_m: float
    drivetrain_efficiency: float
    idle_power_w: float
    tilt_margin_rad: float
    fall_tilt_rad: float


@dataclass(frozen=True)
class Stress:
    """Datapack conditions applied to the evaluation (None: nominal)."""

    friction_range: tuple[float, float] | None = None
    payload_kg_range: tuple[float, float] | None = None
    push_interval_s: tuple[float, float] | None = None
    max_push_vel_m_per_s: tuple[float, float] | None = None
    initial_joint_noise_rad: float = 0.0
    ignored: tuple[str, ...] = ()

    @classmethod
    def from_overrides(cls, randomization: Mapping[str, Mapping[str, Any]], evaluation: Mapping[str, Any],
                       preset_terms: Mapping[str, Any], start_joint_noise_rad: float = 0.0) -> Stress:
        """From a datapack's Holosoma overrides (:mod:`.datapack_mapping`) merged onto the preset's terms.

        Only the terms a datapack sets apply (a datapack without randomization is nominal);
        ``preset_terms``: randomization term -> its preset parameters (Holosoma's values for what a
        datapack leaves out, e.g. the push interval when it only says ``pushes: true``);
        ``start_joint_noise_rad``: the catalog's per-seed start-pose noise, used unless the datapack's
        ``evaluation.initial_joint_noise_rad`` sets its own.
        """
        def params(term: str) -> dict[str, Any] | None:
            if term not in randomization:
                return None
            merged = {**dict(preset_terms.get(term, {})), **dict(randomization[term])}
            return merged if merged.get("enabled", True) else None

        friction, mass, push = params("randomize_friction_startup"), params("mass_randomizer"), \
            params("push_randomizer_state")
        ignored = tuple(f"{term} ({', '.join(sorted(p))})" for term, p in randomization.items()
                        if term not in ("randomize_friction_startup", "mass_randomizer", "push_randomizer_state"))
        if mass and "link_mass_range" in randomization.get("mass_randomizer", {}):
            ignored += ("mass_randomizer (link_mass_range)",)
        pair = (lambda v: (float(v[0]), float(v[1])) if v is not None else None)
        return cls(
            friction_range=pair(friction["friction_range"]) if friction else None,
            payload_kg_range=pair(mass.get("added_mass_range")) if mass and "added_mass_range" in
            randomization.get("mass_randomizer", {}) else None,
            push_interval_s=pair(push["push_interval_s"]) if push else None,
            max_push_vel_m_per_s=pair(push["max_push_vel"]) if push else None,
            initial_joint_noise_rad=float(evaluation.get("initial_joint_noise_rad", start_joint_noise_rad)),
            ignored=ignored)


class ObservationBuilder:
    """The policy's observation, one control step at a time: the card's convention
    (:func:`econmotor.robots.observation.build_observation`: holosoma_inference's terms, scales, sorted
    order and gait phase) over the episode's state (the gait clock, the last clipped action)."""

    def __init__(self, card: RobotCard) -> None:
        self.card = card
        self.reset()

    def reset(self) -> None:
        """Episode start: phases (0, pi) for the two feet, no previous action."""
        self.phase = robot_obs.initial_phase(np)
        self.standing = False
        self.last_action = np.zeros(self.card.num_dofs, dtype=np.float32)

    def advance_phase(self, lin_vel: np.ndarray, ang_vel: float) -> None:
        """One control step of the gait clock (:func:`econmotor.robots.observation.advance_phase`)."""
        phase, standing = robot_obs.advance_phase(self.phase, self.standing, lin_vel, ang_vel, self.card, np)
        self.phase, self.standing = phase, bool(standing)

    def build(self, **state: Any) -> np.ndarray:
        """The observation row ``[1, obs_dim]`` (float32) of a state (``quat_wxyz``, ``ang_vel_body``, ``q``,
        ``qd`` in the card's joint order, ``lin_vel_cmd``, ``ang_vel_cmd``)."""
        return robot_obs.build_observation(self.card, np, last_action=self.last_action, phase=self.phase,
                                           **state)[None, :]


class CourseController:
    """Closed-loop heading on the course (:class:`CourseSettings`): ``command(x, y, yaw)`` once per control step."""

    def __init__(self, course: CourseSettings, control_dt_s: float, command_ranges: Mapping[str, list[float]]) -> None:
        self.course, self.dt = course, control_dt_s
        self.vx_max = float(command_ranges.get("lin_vel_x", [-1.0, 1.0])[1])
        lo, hi = command_ranges.get("ang_vel_yaw", [-1.0, 1.0])
        self.yaw_range = (float(lo), float(hi))
        self.leg = 0
        self.dwell_left_s = 0.0
        self.legs_done = 0

    @property
    def dwelling(self) -> bool:
        return self.dwell_left_s > 0.0

    @property
    def finished(self) -> bool:
        """Every leg of the course walked and its dwell stood."""
        return 0 < self.course.legs <= self.legs_done and not self.dwelling

    def command(self, x: float, y: float, yaw: float) -> tuple[float, float]:
        """``(vx m/s, yaw rate rad/s)`` for the robot at ``(x, y)`` with heading ``yaw`` (rad)."""
        c = self.course
        if self.dwelling:
            self.dwell_left_s -= self.dt
            if not self.dwelling:
                self.leg += 1
            return 0.0, 0.0
        if x >= (self.leg + 1) * c.leg_m:
            self.legs_done += 1
            if c.dwell_s > 0.0:
                self.dwell_left_s = c.dwell_s
                return 0.0, 0.0
            self.leg += 1
        error = math.atan2(-y, c.lookahead_m) - yaw
        error = math.atan2(math.sin(error), math.cos(error))
        yaw_rate = min(max(c.yaw_gain * error, self.yaw_range[0]), self.yaw_range[1])
        return min(c.speed_m_per_s, self.vx_max), yaw_rate


@dataclass
class Robot:
    """A compiled MuJoCo model of the contract's robot and its joint / actuator indices (policy order)."""

    model: Any
    data: Any
    qpos_adr: np.ndarray | slice
    dof_adr: np.ndarray | slice
    actuators: np.ndarray | slice
    torso: int
    nominal_torso_mass: float
    floor_geom: int
    nominal_pair_friction: np.ndarray = field(repr=False)
    nominal_floor_friction: np.ndarray = field(repr=False)


def build_robot(contract: PolicyContract) -> Robot:
    """The card's model (:func:`econmotor.robots.model.model_spec`); joints and actuators matched by name."""
    import mujoco

    card = contract.card
    model = model_spec(card).compile()
    qpos_adr, dof_adr, actuators = joint_indices(model, card)
    torso = model.body(card.torso_body).id
    floor = model.geom(FLOOR).id
    return Robot(model, mujoco.MjData(model), _index(qpos_adr), _index(dof_adr), _index(actuators), torso,
                 float(model.body_mass[torso]), floor, model.pair_friction.copy(), model.geom_friction[floor].copy())


def _index(indices: np.ndarray) -> np.ndarray | slice:
    """A slice where the indices are consecutive (a view, no gather per physics step), else the indices."""
    first = int(indices[0])
    return slice(first, first + len(indices)) if np.array_equal(indices, np.arange(first, first + len(indices))) \
        else indices.copy()


def robot_state(robot: Robot) -> dict[str, np.ndarray]:
    """The state an observation is built from: base quaternion (w, x, y, z), body-frame angular
    velocity, joint positions and velocities in the policy's order."""
    d = robot.data
    return {"quat_wxyz": d.qpos[3:7].copy(), "ang_vel_body": d.qvel[3:6].copy(),
            "q": d.qpos[robot.qpos_adr].copy(), "qd": d.qvel[robot.dof_adr].copy()}


def holosoma_state_vector(robot: Robot) -> np.ndarray:
    """The same state as holosoma_inference's ``robot_state_data`` row: base pos, quat (wxyz), joint q,
    base linear velocity, body angular velocity, joint qd (``[1, 13 + 2 n]``)."""
    d = robot.data
    return np.concatenate([d.qpos[0:3], d.qpos[3:7], d.qpos[robot.qpos_adr], d.qvel[0:3], d.qvel[3:6],
                           d.qvel[robot.dof_adr]])[None, :]


def _yaw(quat_wxyz: np.ndarray) -> float:
    w, x, y, z = quat_wxyz
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def reset_robot(robot: Robot, contract: PolicyContract, stress: Stress, rng: np.random.Generator) -> dict[str, float]:
    """Initial state and this episode's stress draws (friction, payload, first push time)."""
    import mujoco

    m, d = robot.model, robot.data
    mujoco.mj_resetData(m, d)
    card = contract.card
    d.qpos[0:3] = card.init_pos
    d.qpos[3:7] = (1.0, 0.0, 0.0, 0.0)
    noise = stress.initial_joint_noise_rad
    d.qpos[robot.qpos_adr] = card.array("default_dof_angles") + (
        rng.uniform(-noise, noise, card.num_dofs) if noise > 0 else 0.0)
    draws: dict[str, float] = {}
    m.pair_friction[:] = robot.nominal_pair_friction
    m.geom_friction[robot.floor_geom] = robot.nominal_floor_friction
    if stress.friction_range is not None:
        mu = float(rng.uniform(*stress.friction_range))
        m.geom_friction[robot.floor_geom, 0] = mu
        m.pair_friction[:, 0:2] = mu
        draws["friction"] = mu
    payload = float(rng.uniform(*stress.payload_kg_range)) if stress.payload_kg_range is not None else 0.0
    m.body_mass[robot.torso] = robot.nominal_torso_mass + payload
    draws["payload_kg"] = payload
    mujoco.mj_forward(m, d)
    return draws


def meter_constants(meter: MeterSettings, physics_dt_s: float) -> cf.MeterConstants:
    """The shared meter's constants, metering every physics step (``dt_s`` = the physics step)."""
    return econ_formulas.meter_constants(asdict(meter), physics_dt_s)


def step_reading(qpos: np.ndarray, qfrc: np.ndarray, qvel: np.ndarray, fall_tilt_rad: float,
                 min_base_z_m: float) -> cf.StepReading:
    """What the shared meter reads from one physics step: the base's x (the course runs along +x),
    ``sum |qfrc_actuator qvel|`` over the policy's joints, the torso tilt, and whether the robot fell
    (tilt past ``fall_tilt_rad``, base below ``min_base_z_m`` or a non-finite state)."""
    tilt = root_tilt_rad(qpos[:7].tolist(), True, cf.PY)
    z = float(qpos[2])
    fell = tilt > fall_tilt_rad or z < min_base_z_m or not math.isfinite(z)
    return cf.StepReading(x_m=float(qpos[0]), mechanical_w=cf.mechanical_power_w(qfrc.tolist(), qvel.tolist(), cf.PY),
                          tilt_rad=tilt, fell=fell)


def run_episode(robot: Robot, contract: PolicyContract, policy: Callable[[np.ndarray], np.ndarray],
                course: CourseSettings, meter: MeterSettings, stress: Stress, episode_s: float, seed: int,
                record: list[dict[str, Any]] | None = None,
                on_observation: Callable[[Robot, ObservationBuilder, np.ndarray, float, float], None] | None = None,
                ) -> dict[str, Any]:
    """One seeded episode: raw metrics in the standard keys plus the course's (see the module docstring).

    ``record``: when a list, each physics step's metered inputs are appended to it
    (``qpos``, ``qfrc``, ``qvel``) so a test can meter them again. ``on_observation(robot, builder,
    row, vx, yaw_rate)``: called with each observation before the policy sees it.
    """
    import mujoco

    rng = np.random.default_rng(seed)
    m, d = robot.model, robot.data
    draws = reset_robot(robot, contract, stress, rng)
    card = contract.card
    obs = ObservationBuilder(card)
    controller = CourseController(course, card.control_dt_s, contract.command_ranges)
    constants = meter_constants(meter, card.physics_dt_s)
    sums = cf.MeterSums(best_x=float(d.qpos[0]))
    kp, kd = np.asarray(contract.kp), np.asarray(contract.kd)  # the policy's own gains
    limit, default = card.array("effort_limits"), card.array("default_dof_angles")
    next_push = float(rng.uniform(*stress.push_interval_s)) if stress.push_interval_s is not None else math.inf
    control_steps = round(episode_s / card.control_dt_s)
    walk_s, walk_m, pushes, max_lateral = 0.0, 0.0, 0, 0.0
    fell, steps_done = False, 0
    for step in range(control_steps):
        if controller.finished:
            break
        t = step * card.control_dt_s
        if t >= next_push:
            lo, hi = stress.max_push_vel_m_per_s  # type: ignore[misc]
            d.qvel[0:2] += rng.uniform(-1.0, 1.0, 2) * np.array([lo, hi])
            next_push = t + float(rng.uniform(*stress.push_interval_s))  # type: ignore[misc]
            pushes += 1
        x = float(d.qpos[0])
        vx, yaw_rate = controller.command(x, float(d.qpos[1]), _yaw(d.qpos[3:7]))
        lin = np.array([vx, 0.0])
        obs.advance_phase(lin, yaw_rate)
        row = obs.build(lin_vel_cmd=lin, ang_vel_cmd=yaw_rate, **robot_state(robot))
        if on_observation is not None:
            on_observation(robot, obs, row, vx, yaw_rate)
        action = np.minimum(np.maximum(np.asarray(policy(row), dtype=np.float32).reshape(-1), -card.action_clip),
                            card.action_clip)
        obs.last_action = action
        target = default + card.action_scale * action.astype(np.float64)
        for _ in range(card.decimation):
            q, qd = d.qpos[robot.qpos_adr], d.qvel[robot.dof_adr]
            d.ctrl[robot.actuators] = np.minimum(np.maximum(kp * (target - q) - kd * qd, -limit), limit)
            mujoco.mj_step(m, d)
            qfrc, qvel = d.qfrc_actuator[robot.dof_adr], d.qvel[robot.dof_adr]
            reading = step_reading(d.qpos, qfrc, qvel, card.fall_tilt_rad, card.min_base_z_m)
            cf.meter_step(sums, reading, constants, cf.PY)
            fell = bool(reading.fell)
            if record is not None:
                record.append({"qpos": d.qpos.copy(), "qfrc": qfrc.copy(), "qvel": qvel.copy()})
            if fell:
                break
        steps_done = step + 1
        if vx > 0.0:  # a walking control step: its progress along x counts toward the achieved speed
            walk_s += card.control_dt_s
            walk_m += float(d.qpos[0]) - x
        max_lateral = max(max_lateral, abs(float(d.qpos[1])))
        if fell:
            break
    n, units, best_x, errors, energy_wh, risk_sum = (
        float(v) for v in (sums.steps, sums.units, sums.best_x, sums.errors, sums.energy_wh, sums.risk_sum))
    length_s = n * card.physics_dt_s
    power_w = energy_wh * cf.SECONDS_PER_HOUR / length_s if length_s > 0 else 0.0
    return {
        "units_completed": units, "units_attempted": units + errors, "errors": errors,
        "episode_length_s": length_s, "length_steps": float(steps_done), "energy_wh": energy_wh,
        "risk_score": risk_sum / n if n else 0.0, "novelty_score": 0.0,
        "termination_reason": "fall" if fell else "course_done" if controller.finished else "time_out",
        "distance_m": best_x - card.init_pos[0], "legs_reached": float(controller.legs_done),
        "commanded_speed_m_per_s": min(course.speed_m_per_s, controller.vx_max),
        "achieved_speed_m_per_s": walk_m / walk_s if walk_s > 0 else 0.0, "walking_s": walk_s,
        "max_lateral_m": max_lateral, "mean_power_w": power_w,
        "mean_mech_power_w": cf.mechanical_from_electrical_w(power_w, meter.drivetrain_efficiency, meter.idle_power_w),
        "pushes": float(pushes), **{f"stress_{k}": v for k, v in draws.items()},
    }


def onnx_policy(contract: PolicyContract) -> Callable[[np.ndarray], np.ndarray]:
    """The ONNX policy as ``f(obs [1, obs_dim] float32) -> action [1, n]``: the deployed handle's ``act``."""
    from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle

    return OnnxPolicyHandle(contract.onnx_path).act


def evaluate(contract: PolicyContract, course: CourseSettings, meter: MeterSettings, stress: Stress,
             num_episodes: int, episode_s: float, seed: int,
             progress: Callable[[int, int], None] = lambda done, total: None) -> tuple[list[dict[str, Any]], float]:
    """``num_episodes`` seeded episodes (seeds ``seed + i``): (raw metrics per episode, wall seconds)."""
    robot = build_robot(contract)
    policy = onnx_policy(contract)
    start = time.perf_counter()
    episodes = []
    for i in range(num_episodes):
        episodes.append(run_episode(robot, contract, policy, course, meter, stress, episode_s, seed + i))
        progress(i + 1, num_episodes)
    return episodes, time.perf_counter() - start
