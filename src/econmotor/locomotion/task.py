"""A walker task's settings: the catalog entry of a locomotion task, its course and its meter.

Read alike by every backend that trains or prices the card robots (the ``holosoma`` backend's
training terms, the ``mjx`` humanoid couriers, the batched MuJoCo walker env): the task's
``backends.holosoma`` catalog entry (its robot card, Holosoma's experiment names per
algorithm, the overlay's physical parameters over :data:`OVERLAY_DEFAULTS`)
(:func:`task_settings`); the meter's constants (:func:`meter_settings`, :class:`MeterSettings`);
the delivery course (:func:`course_settings`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

from econmotor.config.loading import as_float
from econmotor.economics import courier_formulas as cf
from econmotor.errors import ConfigError
from econmotor.locomotion.course import CourseSettings
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
#: (the entry names its robot card and Holosoma's experiment presets: the catalog is their one place)
OVERLAY_DEFAULTS: dict[str, Any] = {
    "progress_mode": "velocity",   # progress = base velocity along the command / unit_length_m
    "unit_length_m": 10.0,         # metres of commanded travel per unit of work
    "unit_duration_s": 10.0,       # seconds per unit in "time" mode (tracking a clip)
    "drivetrain_efficiency": 0.8,  # electrical -> joint mechanical power
    "novelty_rate": 0.01,          # running-statistics rate of the joint-space novelty
    "overlay_gain": 0.05,          # reward units per metric unit (keeps the overlay near the task terms)
    "uses_motion_clip": False,
}
#: the courier meter's settings, read alike by the training terms and the sim-to-sim evaluator (:func:`meter_settings`;
#: idle power and the tilt margin have no default: each is sourced in the task catalog; the fall tilt is the
#: robot card's)
METER_KEYS = ("robot", "unit_length_m", "drivetrain_efficiency", "idle_power_w", "tilt_margin_rad")
#: the sim-to-sim evaluation's settings (no defaults: each is sourced in the task catalog, see holosoma.yaml)
SIM2SIM_KEYS = ("dwell_s", "course_speed_m_per_s", "sim2sim_legs", "sim2sim_episode_s",
                "sim2sim_start_joint_noise_rad")
_SETTING_KEYS = ("robot", "experiment", "progress_mode", "unit_length_m", "unit_duration_s", "drivetrain_efficiency",
                 "novelty_rate", "overlay_gain", "uses_motion_clip", "algo", "idle_power_w",
                 "tilt_margin_rad", *SIM2SIM_KEYS)


def task_settings(task_id: str, entry: Mapping[str, Any], source: str) -> dict[str, Any]:
    """The task's Holosoma settings: the catalog entry over :data:`OVERLAY_DEFAULTS`."""
    unknown = [k for k in entry if k not in _SETTING_KEYS]
    if unknown:
        raise ConfigError(source, f"tasks.{task_id}.backends.holosoma.{unknown[0]}", "unknown key", _SETTING_KEYS)
    for key, allowed in (("experiment", None), ("robot", sorted(CARDS))):
        if key not in entry:
            raise ConfigError(source, f"tasks.{task_id}.backends.holosoma.{key}",
                              "missing: name one (the task's robot card; Holosoma's experiment preset per "
                              "algorithm, e.g. {ppo: g1_29dof, fast_sac: g1_29dof_fast_sac})", allowed)
    settings = {**OVERLAY_DEFAULTS, **dict(entry)}
    if isinstance(settings["experiment"], str):
        settings["experiment"] = {"ppo": settings["experiment"]}
    if settings["progress_mode"] not in ("velocity", "time"):
        raise ConfigError(source, f"tasks.{task_id}.backends.holosoma.progress_mode",
                          f"got {settings['progress_mode']!r}", ("velocity", "time"))
    efficiency_key = f"tasks.{task_id}.backends.holosoma.drivetrain_efficiency"
    if not 0.0 < as_float(settings["drivetrain_efficiency"], source, efficiency_key) <= 1.0:
        raise ConfigError(source, efficiency_key, "must be in (0, 1]")
    return settings


def meter_settings(task_id: str, settings: Mapping[str, Any], source: str) -> dict[str, float]:
    """The courier meter's constants of a task, under :class:`~econmotor.economics.courier_formulas.MeterConstants`'
    names (without the step): the one source of Holosoma's training terms and of the sim-to-sim evaluator.

    ``leg_distance_m = unit_length_m``; ``fall_tilt_rad``: the fall rule of the robot card the entry names
    (``robot``), where risk reaches 1. A missing key or a value out of range is a ConfigError naming the
    catalog file and the key.
    """
    where = f"tasks.{task_id}.backends.holosoma"
    missing = [k for k in METER_KEYS if k not in settings]
    if missing:
        raise ConfigError(source, f"{where}.{missing[0]}", "the courier meter needs it (training and sim-to-sim "
                          "alike; give its unit and source)", METER_KEYS)
    robot = robot_card(str(settings["robot"]), source)
    v = {k: as_float(settings[k], source, f"{where}.{k}") for k in METER_KEYS if k != "robot"}
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
