"""MeteringSettings: the metering keys both couriers read from a task's backend entry, validated once.

Keys (``tasks/mujoco.yaml``; ``tasks/mjx.yaml`` inherits them with ``inherit: mujoco``)::

    env_id: Hopper-v5              # a Gymnasium v5 MuJoCo env id (couriers.robots.ROBOTS for mjx)
    leg_distance_m: 10.0           # one unit of work = a delivery leg of this forward distance, m (> 0)
    drivetrain_efficiency: 0.6     # electrical W = mechanical W / efficiency + idle W, in (0, 1]
    idle_power_w: 20.0             # electronics, sensors, compute while the robot is on, W
    tilt_margin_rad: 0.2           # risk grows once the torso tilts beyond this, rad
    fall_tilt_rad: 1.0             # ... and saturates at 1 here, rad (> tilt_margin_rad)
    novelty_dims: 5                # first observation dims hashed for visit counts
    novelty_bin: 0.25              # bin width of that hash, observation units
    overlay_normalization: human_baseline   # or none: divide each overlay term by a reference
    env_kwargs: {}                 # passed to gymnasium.make (mjx: the parameters it rebuilds)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from econmotor.config.loading import as_float, as_int, as_str, require_mapping
from econmotor.errors import ConfigError

OVERLAY_NORMALIZATIONS = ("human_baseline", "none")
#: the metering keys, in the catalog's order.
METERING_KEYS = ("env_id", "leg_distance_m", "drivetrain_efficiency", "idle_power_w", "tilt_margin_rad",
                 "fall_tilt_rad", "novelty_dims", "novelty_bin", "overlay_normalization", "env_kwargs")


@dataclass(frozen=True)
class MeteringSettings:
    """How a courier meters its robot (keys and units in the module docstring)."""

    env_id: str
    leg_distance_m: float = 10.0
    drivetrain_efficiency: float = 0.6
    idle_power_w: float = 20.0
    tilt_margin_rad: float = 0.2
    fall_tilt_rad: float = 1.0
    novelty_dims: int = 5
    novelty_bin: float = 0.25
    overlay_normalization: str = "human_baseline"
    env_kwargs: dict[str, Any] = field(default_factory=dict)

    def as_kwargs(self) -> dict[str, Any]:
        """The fields by name (to build a backend's settings from them)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def parse_metering_settings(entry: Mapping[str, Any], source: str, prefix: str) -> MeteringSettings:
    """Validate the metering keys of a backend ``entry`` (other keys are the caller's); errors name
    ``source`` and ``prefix.<key>``. ``env_id`` is required."""
    key = lambda name: f"{prefix}.{name}"
    if "env_id" not in entry:
        raise ConfigError(source, key("env_id"), "is required")
    kw: dict[str, Any] = {"env_id": as_str(entry["env_id"], source, key("env_id"))}
    for name in ("leg_distance_m", "idle_power_w", "tilt_margin_rad", "fall_tilt_rad", "novelty_bin"):
        if name in entry:
            kw[name] = as_float(entry[name], source, key(name), allow_negative=False)
    if "drivetrain_efficiency" in entry:
        kw["drivetrain_efficiency"] = as_float(entry["drivetrain_efficiency"], source, key("drivetrain_efficiency"),
                                               min_value=1e-3, max_value=1.0)
    if "novelty_dims" in entry:
        kw["novelty_dims"] = as_int(entry["novelty_dims"], source, key("novelty_dims"), min_value=1)
    if "overlay_normalization" in entry:
        kw["overlay_normalization"] = as_str(entry["overlay_normalization"], source, key("overlay_normalization"),
                                             OVERLAY_NORMALIZATIONS)
    if entry.get("env_kwargs"):
        kw["env_kwargs"] = require_mapping(entry["env_kwargs"], source, key("env_kwargs"))
    settings = MeteringSettings(**kw)
    if settings.leg_distance_m <= 0:
        raise ConfigError(source, key("leg_distance_m"), "must be > 0")
    if settings.fall_tilt_rad <= settings.tilt_margin_rad:
        raise ConfigError(source, key("fall_tilt_rad"), "must be greater than tilt_margin_rad")
    if settings.novelty_bin <= 0:
        raise ConfigError(source, key("novelty_bin"), "must be > 0")
    return settings
