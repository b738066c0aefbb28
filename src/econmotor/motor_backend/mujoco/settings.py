"""MujocoTaskSettings: a task catalog entry's ``backends.mujoco`` block, validated.

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
from econmotor.errors import ConfigError
from econmotor.tasks.catalog import TaskSpec

ALGORITHMS = ("ppo", "sac")
OVERLAY_NORMALIZATIONS = ("human_baseline", "none")
SETTINGS_KEYS = (
    "env_id", "leg_distance_m", "drivetrain_efficiency", "idle_power_w", "tilt_margin_rad", "fall_tilt_rad",
    "novelty_dims", "novelty_bin", "pose_tracking_scale", "algorithm", "num_envs", "normalize_obs",
    "checkpoint_every_steps", "env_kwargs", "hyperparameters", "overlay_normalization",
)


@dataclass(frozen=True)
class MujocoTaskSettings:
    """How the mujoco backend runs one catalog task (keys as in the module docstring)."""

    task_id: str
    env_id: str
    leg_distance_m: float = 10.0
    drivetrain_efficiency: float = 0.6
    idle_power_w: float = 20.0
    tilt_margin_rad: float = 0.2
    fall_tilt_rad: float = 1.0
    novelty_dims: int = 5
    novelty_bin: float = 0.25
    pose_tracking_scale: float = 1.0
    algorithm: str = "ppo"
    num_envs: int = 4
    normalize_obs: bool = True
    checkpoint_every_steps: int = 20_000
    overlay_normalization: str = "human_baseline"
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    hyperparameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = "<catalog>"

    def algo_hyperparameters(self, algorithm: str) -> dict[str, Any]:
        """The catalog's SB3 constructor kwargs for ``algorithm`` (a copy)."""
        return dict(self.hyperparameters.get(algorithm, {}))

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in ("task_id", *SETTINGS_KEYS)}


def parse_mujoco_settings(spec: TaskSpec) -> MujocoTaskSettings:
    """Validate ``spec``'s ``backends.mujoco`` entry; errors name the catalog file and key."""
    entry = spec.backend_entry("mujoco")
    src, prefix = spec.source, f"tasks.{spec.task_id}.backends.mujoco"
    check_keys(entry, SETTINGS_KEYS, src, prefix, required=("env_id",))
    key = lambda name: f"{prefix}.{name}"
    kw: dict[str, Any] = {"task_id": spec.task_id, "source": src}
    kw["env_id"] = as_str(entry["env_id"], src, key("env_id"))
    for name in ("leg_distance_m", "idle_power_w", "tilt_margin_rad", "fall_tilt_rad", "novelty_bin",
                 "pose_tracking_scale"):
        if name in entry:
            kw[name] = as_float(entry[name], src, key(name), allow_negative=False)
    if "drivetrain_efficiency" in entry:
        kw["drivetrain_efficiency"] = as_float(entry["drivetrain_efficiency"], src, key("drivetrain_efficiency"),
                                               min_value=1e-3, max_value=1.0)
    for name in ("novelty_dims", "num_envs", "checkpoint_every_steps"):
        if name in entry:
            kw[name] = as_int(entry[name], src, key(name), min_value=1)
    if "algorithm" in entry:
        kw["algorithm"] = as_str(entry["algorithm"], src, key("algorithm"), ALGORITHMS)
    if "overlay_normalization" in entry:
        kw["overlay_normalization"] = as_str(entry["overlay_normalization"], src, key("overlay_normalization"),
                                             OVERLAY_NORMALIZATIONS)
    if "normalize_obs" in entry:
        if not isinstance(entry["normalize_obs"], bool):
            raise ConfigError(src, key("normalize_obs"), "expected true or false")
        kw["normalize_obs"] = entry["normalize_obs"]
    if entry.get("env_kwargs"):
        kw["env_kwargs"] = require_mapping(entry["env_kwargs"], src, key("env_kwargs"))
    if entry.get("hyperparameters"):
        hp = require_mapping(entry["hyperparameters"], src, key("hyperparameters"))
        check_keys(hp, ALGORITHMS, src, key("hyperparameters"))
        kw["hyperparameters"] = {a: require_mapping(v, src, key(f"hyperparameters.{a}")) for a, v in hp.items()}
    settings = MujocoTaskSettings(**kw)
    if settings.leg_distance_m <= 0:
        raise ConfigError(src, key("leg_distance_m"), "must be > 0")
    if settings.fall_tilt_rad <= settings.tilt_margin_rad:
        raise ConfigError(src, key("fall_tilt_rad"), "must be greater than tilt_margin_rad")
    return settings


def merge_hyperparameters(base: Mapping[str, Any], overrides: Mapping[str, Any] | None) -> dict[str, Any]:
    """``base`` updated by ``overrides`` (the user's per-run hyperparameters win)."""
    out = dict(base)
    out.update(overrides or {})
    return out
