"""A walker task's one place: the catalog's ``locomotion`` block of a card robot's task.

Every backend that trains or prices the G1 or T1 reads the same block (the ``holosoma`` backend's
training terms and sim-to-sim evaluation, the mujoco backend's CPU trainer, the ``mjx`` humanoid
couriers): its robot card, its meter, its course and its locomotion reward terms. The block, and
what :func:`walker_settings` turns it into (``tasks/holosoma.yaml`` holds the values, each with its
unit and source)::

    tasks:
      humanoid_locomotion_g1:
        locomotion:
          robot: g1_29dof                   # the robot card (econmotor/robots): model, joints, PD, fall rule
          unit_length_m: 10.0               # the meter: one unit of work, a carry leg, m
          drivetrain_efficiency: 0.8        #   electrical W = mechanical W / efficiency + heat + idle
          idle_power_w: 50.0                #   drawn whenever the robot is on, W
          tilt_margin_rad: 0.2              #   tilt risk grows beyond it, up to 1 at the card's fall tilt
          dwell_s: 20.0                     # the course: the pick-and-place stood at each leg end, s
          course_speed_m_per_s: 1.0         #   the commanded walking speed, m/s
          sim2sim_legs: 3                   #   legs per episode
          sim2sim_episode_s: 240.0          #   an episode's time limit, s
          sim2sim_start_joint_noise_rad: 0.05  # each joint's start within +- this of the default pose
          rewards: {tracking_lin_vel: {weight: 2.0, tracking_sigma: 0.25}, ...}  # locomotion/rewards.py

Backends keep only what is theirs (Holosoma's experiment names and overlay gain, a trainer's
recipe, MJX's physics options). :func:`task_settings` is the holosoma backend's view (its entry over
:data:`OVERLAY_DEFAULTS`, with the locomotion block where the task has one: a whole-body tracking task
keeps its robot and meter in its holosoma entry); :func:`meter_settings` the meter's constants;
:func:`course_settings` the delivery course; :func:`reward_terms` the reward's weights and parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

from econmotor.config.loading import as_float, require_mapping
from econmotor.economics import courier_formulas as cf
from econmotor.errors import ConfigError
from econmotor.locomotion.course import CourseSettings
from econmotor.locomotion.rewards import TERMS
from econmotor.robots import CARDS
from econmotor.robots import card as robot_card


@dataclass(frozen=True)
class MeterSettings:
    """The courier meter's constants (:func:`meter_settings`: the task catalog's, with unit and source
    there, and the robot card's fall tilt)."""

    leg_distance_m: float
    drivetrain_efficiency: float
    idle_power_w: float
    tilt_margin_rad: float
    fall_tilt_rad: float

    def constants(self, dt_s: float) -> cf.MeterConstants:
        """The shared meter's constants, metering steps of ``dt_s``."""
        return meter_constants(asdict(self), dt_s)


#: the econ overlay's physical parameters where a task's ``backends.holosoma`` catalog entry leaves them out
#: (the entry names Holosoma's experiment presets; the catalog is their one place)
OVERLAY_DEFAULTS: dict[str, Any] = {
    "progress_mode": "velocity",   # progress = base velocity along the command / unit_length_m
    "unit_length_m": 10.0,         # metres of commanded travel per unit of work
    "unit_duration_s": 10.0,       # seconds per unit in "time" mode (tracking a clip)
    "drivetrain_efficiency": 0.8,  # electrical -> joint mechanical power
    "novelty_rate": 0.01,          # running-statistics rate of the joint-space novelty
    "overlay_gain": 0.05,          # reward units per metric unit (keeps the overlay near the task terms)
    "uses_motion_clip": False,
}
#: the courier meter's settings (idle power and the tilt margin have no default: each is sourced in the task
#: catalog; the fall tilt is the robot card's)
METER_KEYS = ("robot", "unit_length_m", "drivetrain_efficiency", "idle_power_w", "tilt_margin_rad")
#: the delivery course's settings (no defaults: each is sourced in the task catalog, see holosoma.yaml)
SIM2SIM_KEYS = ("dwell_s", "course_speed_m_per_s", "sim2sim_legs", "sim2sim_episode_s",
                "sim2sim_start_joint_noise_rad")
#: a walker task's ``locomotion`` block: the robot, the meter, the course, the reward terms
LOCOMOTION_KEYS = (*METER_KEYS, *SIM2SIM_KEYS, "rewards")
#: Holosoma's own keys of a ``backends.holosoma`` entry (a task without a locomotion block adds the meter's)
HOLOSOMA_KEYS = ("experiment", "progress_mode", "unit_duration_s", "novelty_rate", "overlay_gain",
                 "uses_motion_clip", "algo")


def is_walker_task(spec: Any) -> bool:
    """Whether ``spec`` is a card robot's walker task: it has a ``locomotion`` block."""
    return getattr(spec, "locomotion", None) is not None


def locomotion_where(spec: Any) -> str:
    """Where a task's robot and meter are written: its ``locomotion`` block, or (a task without one, such as
    whole-body tracking) its ``backends.holosoma`` entry."""
    return f"tasks.{spec.task_id}." + ("locomotion" if is_walker_task(spec) else "backends.holosoma")


def walker_settings(spec: Any) -> dict[str, Any]:
    """A walker task's ``locomotion`` block, checked (:data:`LOCOMOTION_KEYS`, the robot card, the meter's
    ranges, the reward terms); a ConfigError names the catalog file and key."""
    where = f"tasks.{spec.task_id}.locomotion"
    if not is_walker_task(spec):
        raise ConfigError(spec.source, where, f"task '{spec.task_id}' has no locomotion block: it is not a card "
                          "robot's walker task")
    block = dict(require_mapping(spec.locomotion, spec.source, where))
    unknown = [k for k in block if k not in LOCOMOTION_KEYS]
    if unknown:
        raise ConfigError(spec.source, f"{where}.{unknown[0]}", "unknown key", LOCOMOTION_KEYS)
    missing = [k for k in LOCOMOTION_KEYS if k not in block]
    if missing:
        raise ConfigError(spec.source, f"{where}.{missing[0]}", "missing: the walker task needs it (with its unit "
                          "and source)", LOCOMOTION_KEYS)
    for key in SIM2SIM_KEYS:
        as_float(block[key], spec.source, f"{where}.{key}")
    meter_settings(spec.task_id, block, spec.source, where)
    reward_terms(spec)
    return block


def reward_terms(spec: Any) -> tuple[dict[str, float], dict[str, dict[str, Any]]]:
    """``(weights, params)`` of a walker task's locomotion reward (``locomotion.rewards``: ``{term: {weight,
    ...params}}``, terms of :data:`econmotor.locomotion.rewards.TERMS`), the one set every engine's learner uses."""
    where = f"tasks.{spec.task_id}.locomotion.rewards"
    rewards = require_mapping((spec.locomotion or {}).get("rewards"), spec.source, where)
    weights: dict[str, float] = {}
    params: dict[str, dict[str, Any]] = {}
    for name, term in rewards.items():
        if name not in TERMS or not isinstance(term, Mapping) or "weight" not in term:
            raise ConfigError(spec.source, f"{where}.{name}", "a locomotion reward term {weight: w, ...params}",
                              sorted(TERMS))
        weights[name] = as_float(term["weight"], spec.source, f"{where}.{name}.weight", allow_negative=True)
        params[name] = {k: v for k, v in term.items() if k != "weight"}
    return weights, params


def task_settings(spec: Any) -> dict[str, Any]:
    """The holosoma backend's settings of a task: its ``backends.holosoma`` entry over :data:`OVERLAY_DEFAULTS`
    and, for a walker task, the ``locomotion`` block (robot, meter, course), written once there."""
    entry = spec.backend_entry("holosoma")
    where = f"tasks.{spec.task_id}.backends.holosoma"
    walker = is_walker_task(spec)
    allowed = HOLOSOMA_KEYS if walker else (*HOLOSOMA_KEYS, *METER_KEYS)
    for key in entry:
        if key not in allowed:
            detail = (f"is the walker task's, written once in tasks.{spec.task_id}.locomotion" if
                      walker and key in LOCOMOTION_KEYS else "unknown key")
            raise ConfigError(spec.source, f"{where}.{key}", detail, allowed)
    for key, names in (("experiment", None), ("robot", sorted(CARDS))):
        if key not in entry and not (key == "robot" and walker):
            raise ConfigError(spec.source, f"{where}.{key}",
                              "missing: name one (the task's robot card; Holosoma's experiment preset per "
                              "algorithm, e.g. {ppo: g1_29dof, fast_sac: g1_29dof_fast_sac})", names)
    block = {k: v for k, v in walker_settings(spec).items() if k != "rewards"} if walker else {}
    settings = {**OVERLAY_DEFAULTS, **dict(entry), **block}
    if isinstance(settings["experiment"], str):
        settings["experiment"] = {"ppo": settings["experiment"]}
    if settings["progress_mode"] not in ("velocity", "time"):
        raise ConfigError(spec.source, f"{where}.progress_mode", f"got {settings['progress_mode']!r}",
                          ("velocity", "time"))
    efficiency_key = f"{locomotion_where(spec)}.drivetrain_efficiency"
    if not 0.0 < as_float(settings["drivetrain_efficiency"], spec.source, efficiency_key) <= 1.0:
        raise ConfigError(spec.source, efficiency_key, "must be in (0, 1]")
    return settings


def meter_settings(task_id: str, settings: Mapping[str, Any], source: str, where: str | None = None
                   ) -> dict[str, float]:
    """The courier meter's constants of a task, under :class:`~econmotor.economics.courier_formulas.MeterConstants`'
    names (without the step): the one source of Holosoma's training terms, the walker env and the MJX couriers.

    ``leg_distance_m = unit_length_m``; ``fall_tilt_rad``: the fall rule of the robot card the settings name
    (``robot``), where risk reaches 1. A missing key or a value out of range is a ConfigError naming the
    catalog file and the key (under ``where``: default the task's ``locomotion`` block).
    """
    where = where or f"tasks.{task_id}.locomotion"
    missing = [k for k in METER_KEYS if k not in settings]
    if missing:
        raise ConfigError(source, f"{where}.{missing[0]}", "the courier meter needs it (training and pricing "
                          "alike; give its unit and source)", METER_KEYS)
    robot = robot_card(str(settings["robot"]), source)
    v = {k: as_float(settings[k], source, f"{where}.{k}") for k in METER_KEYS if k != "robot"}
    if not 0.0 < v["drivetrain_efficiency"] <= 1.0:
        raise ConfigError(source, f"{where}.drivetrain_efficiency", "must be in (0, 1]")
    if v["idle_power_w"] < 0.0:
        raise ConfigError(source, f"{where}.idle_power_w", f"must be >= 0, got {v['idle_power_w']}")
    if not robot.fall_tilt_rad > v["tilt_margin_rad"] >= 0.0:
        raise ConfigError(source, f"{where}.tilt_margin_rad", f"must be in [0, {robot.fall_tilt_rad}), the "
                          f"fall tilt of robot card {robot.name} (got {v['tilt_margin_rad']})")
    return {"leg_distance_m": v["unit_length_m"], "drivetrain_efficiency": v["drivetrain_efficiency"],
            "idle_power_w": v["idle_power_w"], "tilt_margin_rad": v["tilt_margin_rad"],
            "fall_tilt_rad": robot.fall_tilt_rad}


def meter_constants(meter: Mapping[str, float], dt_s: float) -> cf.MeterConstants:
    """The courier meter's constants from a task's meter settings (:func:`meter_settings`: ``leg_distance_m``,
    ``drivetrain_efficiency``, ``idle_power_w``, ``tilt_margin_rad``, ``fall_tilt_rad``), metering steps of ``dt_s``."""
    return cf.MeterConstants(leg_distance_m=float(meter["leg_distance_m"]),
                             drivetrain_efficiency=float(meter["drivetrain_efficiency"]),
                             idle_power_w=float(meter["idle_power_w"]), dt_s=float(dt_s),
                             tilt_margin_rad=float(meter["tilt_margin_rad"]),
                             fall_tilt_rad=float(meter["fall_tilt_rad"]))


def course_settings(settings: Mapping[str, Any], speed_m_per_s: float | None = None) -> CourseSettings:
    """The task's delivery course (``unit_length_m`` legs, ``dwell_s``, ``sim2sim_legs``) at the task's
    course speed or ``speed_m_per_s``."""
    return CourseSettings(leg_m=float(settings["unit_length_m"]), dwell_s=float(settings["dwell_s"]),
                          speed_m_per_s=float(speed_m_per_s or settings["course_speed_m_per_s"]),
                          legs=int(settings["sim2sim_legs"]))
