"""MujocoTaskSettings: a task catalog entry's ``backends.mujoco`` block, validated.

The metering keys (env_id ... novelty_bin, overlay_normalization, env_kwargs) are the couriers'
(``couriers/settings.py``); the others are this backend's.

Catalog schema (``src/econmotor/tasks/mujoco.yaml``)::

    backends:
      mujoco:
        env_id: Hopper-v5              # a registered Gymnasium MuJoCo env id
        leg_distance_m: 10.0           # one unit of work = a delivery leg of this forward distance
        drivetrain_efficiency: 0.6     # electrical W = mechanical W / efficiency + idle W
        idle_power_w: 20.0             # electronics, sensors, compute while the robot is on
        tilt_margin_rad: 0.2           # risk grows once the torso tilts beyond this
        fall_tilt_rad: 1.0             # ... and saturates at 1 here
        novelty_dims: 5                # first observation dims hashed for visit counts
        novelty_bin: 0.25              # bin width of that hash
        pose_tracking_scale: 1.0       # reward scale of the pose-tracking term when clips are given
        overlay_normalization: human_baseline   # or none: divide each overlay term by a reference
        algorithm: ppo                 # default SB3 algorithm: ppo | sac
        num_envs: 4                    # default in-process environments
        normalize_obs: true            # VecNormalize observation statistics (exported to ONNX)
        checkpoint_every_steps: 20000
        env_kwargs: {}                 # passed to gymnasium.make
        hyperparameters:               # per algorithm, passed to the SB3 constructor
          ppo: {n_steps: 512, ...}
          sac: {learning_starts: 5000, ...}
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from econmotor.config.loading import as_float, as_int, as_str, check_keys, require_mapping
from econmotor.couriers.settings import MeteringSettings, parse_metering_settings
from econmotor.errors import ConfigError
from econmotor.tasks.catalog import TaskSpec

ALGORITHMS = ("ppo", "sac")
SETTINGS_KEYS = (
    "env_id", "leg_distance_m", "drivetrain_efficiency", "idle_power_w", "tilt_margin_rad", "fall_tilt_rad",
    "novelty_dims", "novelty_bin", "pose_tracking_scale", "algorithm", "num_envs", "normalize_obs",
    "checkpoint_every_steps", "env_kwargs", "hyperparameters", "overlay_normalization",
)


@dataclass(frozen=True, kw_only=True)
class MujocoTaskSettings(MeteringSettings):
    """How the mujoco backend runs one catalog task (keys as in the module docstring; the metering
    keys are :class:`~econmotor.couriers.settings.MeteringSettings`')."""

    task_id: str
    pose_tracking_scale: float = 1.0
    algorithm: str = "ppo"
    num_envs: int = 4
    normalize_obs: bool = True
    checkpoint_every_steps: int = 20_000
    hyperparameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = "<catalog>"

    def algo_hyperparameters(self, algorithm: str) -> dict[str, Any]:
        """The catalog's SB3 constructor kwargs for ``algorithm`` (a copy)."""
        return dict(self.hyperparameters.get(algorithm, {}))

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in ("task_id", *SETTINGS_KEYS)}


def parse_mujoco_settings(spec: TaskSpec) -> MujocoTaskSettings:
    """Validate ``spec``'s ``backends.mujoco`` entry; errors name the catalog file and key.

    The metering keys go through the couriers' parser (:func:`parse_metering_settings`), the one
    the mjx backend's entries use too.
    """
    entry = spec.backend_entry("mujoco")
    src, prefix = spec.source, f"tasks.{spec.task_id}.backends.mujoco"
    check_keys(entry, SETTINGS_KEYS, src, prefix, required=("env_id",))
    key = lambda name: f"{prefix}.{name}"
    kw: dict[str, Any] = {"task_id": spec.task_id, "source": src}
    kw.update(parse_metering_settings(entry, src, prefix).as_kwargs())
    if "pose_tracking_scale" in entry:
        kw["pose_tracking_scale"] = as_float(entry["pose_tracking_scale"], src, key("pose_tracking_scale"),
                                             allow_negative=False)
    for name in ("num_envs", "checkpoint_every_steps"):
        if name in entry:
            kw[name] = as_int(entry[name], src, key(name), min_value=1)
    if "algorithm" in entry:
        kw["algorithm"] = as_str(entry["algorithm"], src, key("algorithm"), ALGORITHMS)
    if "normalize_obs" in entry:
        if not isinstance(entry["normalize_obs"], bool):
            raise ConfigError(src, key("normalize_obs"), "expected true or false")
        kw["normalize_obs"] = entry["normalize_obs"]
    if entry.get("hyperparameters"):
        hp = require_mapping(entry["hyperparameters"], src, key("hyperparameters"))
        check_keys(hp, ALGORITHMS, src, key("hyperparameters"))
        kw["hyperparameters"] = {a: require_mapping(v, src, key(f"hyperparameters.{a}")) for a, v in hp.items()}
    return MujocoTaskSettings(**kw)


def merge_hyperparameters(base: Mapping[str, Any], overrides: Mapping[str, Any] | None) -> dict[str, Any]:
    """``base`` updated by ``overrides`` (the user's per-run hyperparameters win)."""
    out = dict(base)
    out.update(overrides or {})
    return out
