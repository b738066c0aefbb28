"""MjxTaskSettings: a task's ``backends.mjx`` entry (``tasks/mjx.yaml``), validated.

Schema::

    backends:
      mjx:
        inherit: mujoco              # metering keys from the task's backends.mujoco entry (below)
        num_envs: 2048               # environments simulated at once (capped to cpu_num_envs_cap on a CPU)
        cpu_physics: mujoco          # on a CPU: mjx (default) or mujoco (MuJoCo C, mjx/host_physics.py)
        normalize_obs: true
        checkpoint_every_steps: 5000000
        ppo: {unroll_length: 20, ...}   # the JAX PPO trainer's hyperparameters, passed through
        model_options:               # MJX-speed physics options applied at load (mjx/assets.py)
          integrator: euler          # euler | implicitfast | rk4 (Gymnasium's MJCF: rk4)
          iterations: 4              # constraint solver iterations (Gymnasium's MJCF: 50-100)
          ls_iterations: 8           # line-search iterations (MuJoCo's default: 50)
          eulerdamp: false           # implicit joint damping in the Euler integrator (default true)
          contact_geoms: [foot_geom] # the only robot geoms that collide (default: all of them)

A real robot's courier (``mjx/humanoid_env.py``) takes its task's locomotion block instead of a Gymnasium env::

        inherit: locomotion          # robot card, meter, course and reward terms: the task's locomotion block

The metering keys (:data:`INHERITED_KEYS`) are the couriers' (``couriers/settings.py``): with
``inherit: mujoco`` they are read from the task's ``backends.mujoco`` entry, so the two backends
cannot drift; with ``inherit: locomotion`` from the task's ``locomotion`` block
(:func:`~econmotor.locomotion.task.walker_settings`: the robot card, the meter every backend reads
(:func:`~econmotor.locomotion.task.meter_settings`), the course (:data:`LOCOMOTION_COURSE`) and the reward
terms); without it they may be written here with the same meaning. Both go through
:func:`~econmotor.couriers.settings.parse_metering_settings`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from econmotor.config.loading import as_int, as_str, check_keys, require_mapping
from econmotor.couriers.settings import METERING_KEYS, MeteringSettings, parse_metering_settings
from econmotor.errors import ConfigError
from econmotor.locomotion.task import meter_settings, reward_terms, walker_settings
from econmotor.tasks.catalog import TaskSpec

#: keys shared with the mujoco backend's entry (the economics of the physics).
INHERITED_KEYS = METERING_KEYS
OWN_KEYS = ("inherit", "num_envs", "cpu_num_envs_cap", "cpu_physics", "normalize_obs", "checkpoint_every_steps", "ppo",
            "novelty_table_size", "model_options")
INHERITS = ("mujoco", "locomotion")
#: the locomotion block's course keys -> the course's (``locomotion/course.py``)
LOCOMOTION_COURSE = {"unit_length_m": "leg_m", "dwell_s": "dwell_s", "course_speed_m_per_s": "speed_m_per_s",
                   "sim2sim_legs": "legs"}
#: ``model_options`` keys; values are validated by :func:`parse_model_options`.
MODEL_OPTION_KEYS = ("integrator", "iterations", "ls_iterations", "eulerdamp", "contact_geoms")
INTEGRATORS = ("euler", "implicitfast", "rk4")
#: the physics a task may step on a CPU (``cpu_physics``; mjx/host_physics.py)
PHYSICS = ("mjx", "mujoco")


@dataclass(frozen=True)
class MjxTaskSettings:
    """How the mjx backend runs one catalog task; the :data:`INHERITED_KEYS` read through to ``metering``."""

    task_id: str
    metering: MeteringSettings  # env_id, leg_distance_m, ... validated by the couriers' parser
    num_envs: int = 2048
    cpu_num_envs_cap: int = 64
    cpu_physics: str = "mjx"  # on a CPU: "mjx", or "mujoco" (MuJoCo C called from the rollout, host_physics.py)
    normalize_obs: bool = True
    checkpoint_every_steps: int = 5_000_000
    novelty_table_size: int = 4096
    ppo: dict[str, Any] = field(default_factory=dict)
    model_options: dict[str, Any] = field(default_factory=dict)
    robot: str | None = None  # a robot card (econmotor.robots): the task runs mjx/humanoid_env.py
    #: a walker task's time limit and reward terms (``episode_s``, ``weights``, ``params``: its locomotion block)
    locomotion: dict[str, Any] = field(default_factory=dict)
    course: dict[str, Any] = field(default_factory=dict)  # locomotion/course.py CourseSettings keys
    start_joint_noise_rad: float = 0.0  # each joint's start drawn within +- this of the default pose, rad
    source: str = "<catalog>"

    def __getattr__(self, name: str) -> Any:
        if name in INHERITED_KEYS:
            return getattr(self.metering, name)
        raise AttributeError(name)

    def to_dict(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "metering"}
        out.update({k: getattr(self.metering, k) for k in INHERITED_KEYS})
        return out


def parse_mjx_settings(spec: TaskSpec) -> MjxTaskSettings:
    """Validate ``spec``'s ``backends.mjx`` entry; errors name the catalog file and key."""
    entry = spec.backend_entry("mjx")
    src, prefix = spec.backend_source("mjx"), f"backend_entries.mjx.{spec.task_id}"
    check_keys(entry, OWN_KEYS + INHERITED_KEYS, src, prefix)
    key = lambda name: f"{prefix}.{name}"
    inherit = entry.get("inherit")
    robot: str | None = None
    course: dict[str, Any] = {}
    start_noise = 0.0
    locomotion: dict[str, Any] = {}
    if inherit is not None:
        as_str(inherit, src, key("inherit"), INHERITS)
        repeated = [k for k in INHERITED_KEYS if k in entry]
        if repeated:
            raise ConfigError(src, key(repeated[0]), f"comes from the {inherit} entry (inherit: {inherit}); "
                              "remove it here")
    if inherit == "locomotion":  # the walker task's one place: robot, meter, course, reward terms
        walker = walker_settings(spec)
        robot = str(walker["robot"])
        parent = {"env_id": robot, **meter_settings(spec.task_id, walker, spec.source)}
        course = {ours: walker[theirs] for theirs, ours in LOCOMOTION_COURSE.items()}
        start_noise = float(walker["sim2sim_start_joint_noise_rad"])
        weights, params = reward_terms(spec)
        locomotion = {"episode_s": float(walker["sim2sim_episode_s"]), "weights": weights, "params": params}
        base = parse_metering_settings(parent, spec.source, f"tasks.{spec.task_id}.locomotion")
    elif inherit is not None:
        base = parse_metering_settings(spec.backend_entry(inherit), spec.source,
                                       f"tasks.{spec.task_id}.backends.{inherit}")
    else:  # the metering keys written here, with the same rules
        base = parse_metering_settings(entry, src, prefix)
    kw: dict[str, Any] = {"task_id": spec.task_id, "metering": base, "source": src, "robot": robot,
                          "course": course, "start_joint_noise_rad": start_noise, "locomotion": locomotion}
    for name in ("num_envs", "cpu_num_envs_cap", "checkpoint_every_steps", "novelty_table_size"):
        if name in entry:
            kw[name] = as_int(entry[name], src, key(name), min_value=1)
    if "cpu_physics" in entry:
        kw["cpu_physics"] = as_str(entry["cpu_physics"], src, key("cpu_physics"), PHYSICS)
        if robot is not None and kw["cpu_physics"] != "mjx":
            raise ConfigError(src, key("cpu_physics"), "a robot card's courier steps in MJX (its PD, contacts and "
                              "course read MJX data)", ["mjx"])
    if "normalize_obs" in entry:
        if not isinstance(entry["normalize_obs"], bool):
            raise ConfigError(src, key("normalize_obs"), "expected true or false")
        kw["normalize_obs"] = entry["normalize_obs"]
    if entry.get("ppo"):
        kw["ppo"] = dict(require_mapping(entry["ppo"], src, key("ppo")))
    if entry.get("model_options"):
        kw["model_options"] = parse_model_options(entry["model_options"], src, key("model_options"))
    return MjxTaskSettings(**kw)


def parse_model_options(data: Any, src: str, prefix: str) -> dict[str, Any]:
    """A ``model_options`` mapping, validated; geom names are checked against the model at load."""
    options = dict(require_mapping(data, src, prefix))
    check_keys(options, MODEL_OPTION_KEYS, src, prefix)
    key = lambda name: f"{prefix}.{name}"
    if "integrator" in options:
        options["integrator"] = as_str(options["integrator"], src, key("integrator"), INTEGRATORS)
    for name in ("iterations", "ls_iterations"):
        if name in options:
            options[name] = as_int(options[name], src, key(name), min_value=1)
    if "eulerdamp" in options and not isinstance(options["eulerdamp"], bool):
        raise ConfigError(src, key("eulerdamp"), "expected true or false")
    if "contact_geoms" in options:
        geoms = options["contact_geoms"]
        if not isinstance(geoms, list) or not geoms or not all(isinstance(g, str) and g for g in geoms):
            raise ConfigError(src, key("contact_geoms"), "expected a non-empty list of the model's geom names")
    return options
