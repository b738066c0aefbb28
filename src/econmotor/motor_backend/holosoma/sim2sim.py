"""Sim-to-sim: an imported (or Holosoma-trained) locomotion policy walking a delivery course in plain MuJoCo.

Runs in .venv-holosoma (mujoco, onnxruntime and the Holosoma packages the contract is read
from, :mod:`.policy_import`); the main interpreter reaches it through a ``sim2sim`` job.

Per episode (seeded: ``seed + episode index``):

- **the robot** starts at Holosoma's initial base position in its default pose (plus the
  datapack's initial joint perturbation); the floor is a plane named ``floor`` (the G1
  MJCF's foot contact pairs refer to it); the physics step is Holosoma's (``1 / fps``).
- **collisions** as Holosoma's MuJoCo simulator models the robot (:func:`apply_collision_filter`):
  with the preset's ``enable_self_collisions=False`` (the G1 and T1 walkers') the robot's colliders
  touch the floor only, not each other.
- **control**: the policy runs at its control rate (``decimation`` physics steps per
  action); a PD loop at the physics rate drives the actuators:
  ``tau = kp (default + action_scale * action - q) - kd qd``, clipped to the effort limits.
- **observation**: :class:`ObservationBuilder`, holosoma_inference's contract (terms, scales,
  sorted order, history, gait phase); equal to holosoma_inference's own code
  (tests/integration/test_holosoma_sim2sim.py).
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
  tilt risk, falls). A fall (tilt past ``fall_tilt_rad`` or the base below
  :data:`FALL_HEIGHT_FRACTION` of its initial height) ends the episode with one error.
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
from econmotor.motor_backend.holosoma.policy_import import PolicyContract, check_dof_names

#: the base below this fraction of its initial height is a fall (the robot is on the ground)
FALL_HEIGHT_FRACTION = 0.5
#: commands below this (m/s, rad/s) are "stand" for holosoma_inference's gait phase
_STAND_EPS = 0.01


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
    """The courier meter's constants (the task catalog's, with unit and source there; the same
    :func:`.plan.meter_settings` the training terms read)."""

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
    """The policy's observation, built the way holosoma_inference builds it (its contract, not its code).

    Terms (holosoma_inference's ``get_current_obs_buffer_dict``): ``base_ang_vel`` (body frame),
    ``projected_gravity`` (gravity in the body frame), ``command_lin_vel`` (vx, vy),
    ``command_ang_vel`` (yaw rate), ``dof_pos`` minus the default pose, ``dof_vel``, ``actions``
    (the last clipped policy output), ``sin_phase`` / ``cos_phase`` of the two feet's gait
    phases; each times its scale, concatenated in the contract's (sorted) order, each term's
    ``history_length`` frames oldest first (zeros before the first).
    """

    def __init__(self, contract: PolicyContract) -> None:
        self.c = contract
        self.default = np.asarray(contract.default_dof_angles, dtype=np.float64)
        self.phase_dt = 2.0 * math.pi / (contract.control_rate_hz * contract.gait_period_s)
        self.reset()

    def reset(self) -> None:
        """Episode start: zero history, phases (0, pi) for the two feet, no previous action."""
        self.history: dict[str, list[np.ndarray]] = {t: [] for t in self.c.obs_terms}
        self.phase = np.array([0.0, math.pi])
        self.standing = False
        self.last_action = np.zeros(len(self.c.dof_names), dtype=np.float32)

    def advance_phase(self, lin_vel: np.ndarray, ang_vel: float) -> None:
        """One control step of the gait clock; both feet at pi while the command is "stand"."""
        self.phase = np.fmod(self.phase + self.phase_dt + math.pi, 2.0 * math.pi) - math.pi
        if np.linalg.norm(lin_vel) < _STAND_EPS and abs(ang_vel) < _STAND_EPS:
            self.phase = np.full(2, math.pi)
            self.standing = True
        elif self.standing:
            self.phase = np.array([0.0, math.pi])
            self.standing = False

    def terms(self, quat_wxyz: np.ndarray, ang_vel_body: np.ndarray, q: np.ndarray, qd: np.ndarray,
              lin_vel_cmd: np.ndarray, ang_vel_cmd: float) -> dict[str, np.ndarray]:
        """Unscaled terms of the current state (``q``, ``qd`` in the policy's joint order)."""
        w, x, y, z = (float(v) for v in quat_wxyz)
        # third row of the body-to-world rotation matrix = world z axis in the body frame
        gravity = -np.array([2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)])
        return {"base_ang_vel": np.asarray(ang_vel_body, dtype=np.float64), "projected_gravity": gravity,
                "command_lin_vel": np.asarray(lin_vel_cmd, dtype=np.float64),
                "command_ang_vel": np.array([ang_vel_cmd]), "dof_pos": q - self.default, "dof_vel": qd,
                "actions": self.last_action.astype(np.float64), "sin_phase": np.sin(self.phase),
                "cos_phase": np.cos(self.phase), "command_stand": np.array([0.0 if self.standing else 1.0])}

    def build(self, **state: Any) -> np.ndarray:
        """The observation row ``[1, obs_dim]`` (float32) of a state (arguments of :meth:`terms`)."""
        current = self.terms(**state)
        parts = []
        n = self.c.history_length
        for term in self.c.obs_terms:
            frame = (current[term] * self.c.obs_scales[term]).astype(np.float32)
            buf = self.history[term]
            buf.append(frame)
            del buf[:-n]
            if len(buf) < n:  # before the history fills: zeros for the frames not seen yet
                parts.extend([np.zeros_like(frame)] * (n - len(buf)))
            parts.extend(buf)
        return np.concatenate(parts)[None, :]


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
    """The contract's MJCF with a floor plane and Holosoma's physics step; joints and actuators matched by name."""
    import mujoco

    spec = mujoco.MjSpec.from_file(contract.xml_path)
    spec.option.timestep = contract.physics_dt_s
    if not any(g.name == "floor" for g in spec.geoms):
        spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05])
    apply_collision_filter(spec, contract.self_collisions)
    model = spec.compile()
    joints = [model.joint(j).name for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    act_joint = {model.joint(int(model.actuator_trnid[a, 0])).name: a for a in range(model.nu)
                 if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT}
    check_dof_names(contract.dof_names, joints, list(act_joint), contract.xml_path, contract.onnx_path)
    jids = [model.joint(n).id for n in contract.dof_names]
    torso = model.body(contract.torso_body).id
    floor = model.geom("floor").id
    return Robot(model, mujoco.MjData(model), _index(model.jnt_qposadr[jids]), _index(model.jnt_dofadr[jids]),
                 _index(np.array([act_joint[n] for n in contract.dof_names])), torso, float(model.body_mass[torso]),
                 floor, model.pair_friction.copy(), model.geom_friction[floor].copy())


#: MuJoCo collision bits of Holosoma's scene manager: robot geoms are class 1, the floor and terrain class 2
ROBOT_CONTYPE, ENVIRONMENT_CONTYPE = 1, 2


def apply_collision_filter(spec: Any, self_collisions: bool) -> int:
    """Holosoma's collision classes on an ``MjSpec`` (its MuJoCo scene manager's ``_configure_robot_collisions``).

    Every geom of a named robot body that collides by MuJoCo's default (``contype = conaffinity = 1``) gets
    ``conaffinity`` 3 (robot and environment) with self-collisions, 2 (environment only) without; the floor
    gets ``contype`` 2, ``conaffinity`` 1. Two geoms touch when ``contype_a & conaffinity_b`` or
    ``contype_b & conaffinity_a``: the robot always touches the floor, and itself only with self-collisions.
    The MJCF's explicit ``<pair>`` contacts (the G1's feet on the floor) are kept. Returns the geoms set.
    """
    robot_conaffinity = ROBOT_CONTYPE | ENVIRONMENT_CONTYPE if self_collisions else ENVIRONMENT_CONTYPE
    changed = 0
    for body in spec.bodies:
        if not body.name or body.name == spec.worldbody.name:
            continue
        for geom in body.geoms:
            if geom.contype == ROBOT_CONTYPE and geom.conaffinity == ROBOT_CONTYPE:
                geom.conaffinity = robot_conaffinity
                changed += 1
    for geom in spec.worldbody.geoms:
        if geom.name == "floor":
            geom.contype, geom.conaffinity = ENVIRONMENT_CONTYPE, ROBOT_CONTYPE
    return changed


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
    d.qpos[0:3] = contract.init_pos
    d.qpos[3:7] = (1.0, 0.0, 0.0, 0.0)
    noise = stress.initial_joint_noise_rad
    d.qpos[robot.qpos_adr] = np.asarray(contract.default_dof_angles) + (
        rng.uniform(-noise, noise, len(contract.dof_names)) if noise > 0 else 0.0)
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
    obs = ObservationBuilder(contract)
    controller = CourseController(course, contract.control_dt_s, contract.command_ranges)
    constants = meter_constants(meter, contract.physics_dt_s)
    sums = cf.MeterSums(best_x=float(d.qpos[0]))
    kp, kd = np.asarray(contract.kp), np.asarray(contract.kd)
    limit = np.asarray(contract.effort_limits)
    default = np.asarray(contract.default_dof_angles)
    min_z = FALL_HEIGHT_FRACTION * contract.init_pos[2]
    next_push = float(rng.uniform(*stress.push_interval_s)) if stress.push_interval_s is not None else math.inf
    control_steps = round(episode_s / contract.control_dt_s)
    walk_s, walk_m, pushes, max_lateral = 0.0, 0.0, 0, 0.0
    fell, steps_done = False, 0
    for step in range(control_steps):
        if controller.finished:
            break
        t = step * contract.control_dt_s
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
        action = np.clip(np.asarray(policy(row), dtype=np.float32).reshape(-1), -contract.action_clip,
                         contract.action_clip)
        obs.last_action = action
        target = default + contract.action_scale * action.astype(np.float64)
        for _ in range(contract.decimation):
            q, qd = d.qpos[robot.qpos_adr], d.qvel[robot.dof_adr]
            d.ctrl[robot.actuators] = np.clip(kp * (target - q) - kd * qd, -limit, limit)
            mujoco.mj_step(m, d)
            qfrc, qvel = d.qfrc_actuator[robot.dof_adr], d.qvel[robot.dof_adr]
            reading = step_reading(d.qpos, qfrc, qvel, meter.fall_tilt_rad, min_z)
            cf.meter_step(sums, reading, constants, cf.PY)
            fell = bool(reading.fell)
            if record is not None:
                record.append({"qpos": d.qpos.copy(), "qfrc": qfrc.copy(), "qvel": qvel.copy()})
            if fell:
                break
        steps_done = step + 1
        if vx > 0.0:  # a walking control step: its progress along x counts toward the achieved speed
            walk_s += contract.control_dt_s
            walk_m += float(d.qpos[0]) - x
        max_lateral = max(max_lateral, abs(float(d.qpos[1])))
        if fell:
            break
    n, units, best_x, errors, energy_wh, risk_sum = (
        float(v) for v in (sums.steps, sums.units, sums.best_x, sums.errors, sums.energy_wh, sums.risk_sum))
    length_s = n * contract.physics_dt_s
    power_w = energy_wh * cf.SECONDS_PER_HOUR / length_s if length_s > 0 else 0.0
    return {
        "units_completed": units, "units_attempted": units + errors, "errors": errors,
        "episode_length_s": length_s, "length_steps": float(steps_done), "energy_wh": energy_wh,
        "risk_score": risk_sum / n if n else 0.0, "novelty_score": 0.0,
        "termination_reason": "fall" if fell else "course_done" if controller.finished else "time_out",
        "distance_m": best_x - contract.init_pos[0], "legs_reached": float(controller.legs_done),
        "commanded_speed_m_per_s": min(course.speed_m_per_s, controller.vx_max),
        "achieved_speed_m_per_s": walk_m / walk_s if walk_s > 0 else 0.0, "walking_s": walk_s,
        "max_lateral_m": max_lateral, "mean_power_w": power_w,
        "mean_mech_power_w": cf.mechanical_from_electrical_w(power_w, meter.drivetrain_efficiency, meter.idle_power_w),
        "pushes": float(pushes), **{f"stress_{k}": v for k, v in draws.items()},
    }


def onnx_policy(contract: PolicyContract) -> Callable[[np.ndarray], np.ndarray]:
    """The ONNX policy as ``f(obs [1, obs_dim] float32) -> action [1, n]``: the deployed handle's ``act``."""
    from econmotor.motor_backend.holosoma.backend import HolosomaPolicyHandle

    return HolosomaPolicyHandle(contract.onnx_path).act


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
