"""MjxTaskSettings: a task's ``backends.mjx`` entry (``tasks/mjx.yaml``), validated.

Schema::

    backends:
      mjx:
        inherit: mujoco              # metering keys from the task's backends.mujoco entry (below)
        num_envs: 2048               # environments simulated at once (capped to cpu_num_envs_cap on a CPU)
        normalize_obs: true
        checkpoint_every_steps: 5000000
        ppo: {unroll_length: 20, ...}   # the JAX PPO trainer's hyperparameters, passed through
        model_options:               # MJX-speed physics options applied at load (mjx/assets.py)
          integrator: euler          # euler | implicitfast | rk4 (Gymnasium's MJCF: rk4)
          iterations: 4              # constraint solver iterations (Gymnasium's MJCF: 50-100)
          ls_iterations: 8           # line-search iterations (MuJoCo's default: 50)
          eulerdamp: false           # implicit joint damping in the Euler integrator (default true)
          contact_geoms: [foot_geom] # the only robot geoms that collide (default: all of them)

The metering keys (:data:`INHERITED_KEYS`) are the couriers' (``couriers/settings.py``): with
``inherit: mujoco`` they are read from the task's ``backends.mujoco`` entry, so the two backends
cannot drift; without it they may be written here with the same meaning. Both go through
:func:`~econmotor.motor_backend.couriers.settings.parse_metering_settings`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from econmotor.config.loading import as_int, as_str, check_keys, require_mapping
from econmotor.errors import ConfigError
from econmotor.motor_backend.couriers.settings import METERING_KEYS, MeteringSettings, parse_metering_settings
from econmotor.tasks.catalog import TaskSpec

#: keys shared with the mujoco backend's entry (the economics of the physics).
INHERITED_KEYS = METERING_KEYS
OWN_KEYS = ("inherit", "num_envs", "cpu_num_envs_cap", "normalize_obs", "checkpoint_every_steps", "ppo",
            "novelty_table_size", "model_options")
#: ``model_options`` keys; values are validated by :func:`parse_model_options`.
MODEL_OPTION_KEYS = ("integrator", "iterations", "ls_iterations", "eulerdamp", "contact_geoms")
INTEGRATORS = ("euler", "implicitfast", "rk4")


@dataclass(frozen=True)
class MjxTaskSettings:
    """How the mjx backend runs one catalog task; the :data:`INHERITED_KEYS` read through to ``metering``."""

    task_id: str
    metering: MeteringSettings  # env_id, leg_distance_m, ... validated by the couriers' parser
    num_envs: int = 2048
    cpu_num_envs_cap: int = 64
    normalize_obs: bool = True
    checkpoint_every_steps: int = 5_000_000
    novelty_table_size: int = 4096
    ppo: dict[str, Any] = field(default_factory=dict)
    model_options: dict[str, Any] = field(default_factory=dict)
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
    if inherit is not None:
        as_str(inherit, src, key("inherit"), ("mujoco",))
        repeated = [k for k in INHERITED_KEYS if k in entry]
        if repeated:
            raise ConfigError(src, key(repeated[0]), "comes from the mujoco entry (inherit: mujoco); remove it here")
        base = parse_metering_settings(spec.backend_entry("mujoco"), spec.source,
                                       f"tasks.{spec.task_id}.backends.mujoco")
    else:  # the metering keys written here, with the same rules
        base = parse_metering_settings(entry, src, prefix)
    kw: dict[str, Any] = {"task_id": spec.task_id, "metering": base, "source": src}
    for name in ("num_envs", "cpu_num_envs_cap", "checkpoint_every_steps", "novelty_table_size"):
        if name in entry:
            kw[name] = as_int(entry[name], src, key(name), min_value=1)
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
