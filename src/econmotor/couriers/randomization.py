"""Domain randomization and curriculum of the couriers (datapack keys, validated here).

The mujoco backend applies them in ``mujoco/randomization.py`` (a Gymnasium wrapper); the mjx
backend honours a subset inside its jitted step (``mjx/env.py``).

``domain_randomization`` keys (all optional)::

    friction_range: [0.5, 1.0]     # multipliers of every geom's nominal sliding friction, one draw per episode
    mass_scale_range: [0.8, 1.2]   # multipliers of each body's nominal mass (and inertia), drawn per body
    push_interval_s: 2.0           # a horizontal push on the torso every this many seconds ...
    push_force_n: 50.0             # ... of this force, N, for one control step, random direction
    action_noise_std: 0.05         # Gaussian noise added to actions (then clipped to the action space)
    obs_noise_std: 0.01            # Gaussian noise added to observations
    terrain: flat | rough          # rough = a heightfield of random bumps ...
    terrain_max_height_m: 0.05     # ... up to this height at difficulty 1

``curriculum`` keys::

    initial_difficulty: 0.1        # difficulty d at step 0
    max_difficulty: 1.0            # ... reached after ramp_steps
    ramp_steps: 100000             # linear ramp over training environment steps

Difficulty ``d`` scales every range toward nominal: a multiplier range ``[lo, hi]``
becomes ``[1 + d (lo - 1), 1 + d (hi - 1)]``; forces, noise stds and terrain height
are multiplied by ``d``. Without a curriculum ``d = 1`` (the ranges as written).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from econmotor.config.loading import as_float, as_int, as_range, as_str, check_keys
from econmotor.errors import ConfigError

DR_KEYS = ("friction_range", "mass_scale_range", "push_interval_s", "push_force_n", "action_noise_std",
           "obs_noise_std", "terrain", "terrain_max_height_m")
CURRICULUM_KEYS = ("initial_difficulty", "max_difficulty", "ramp_steps")


@dataclass(frozen=True)
class DomainRandomization:
    """Validated ``domain_randomization`` settings (see module docstring)."""

    friction_range: tuple[float, float] | None = None
    mass_scale_range: tuple[float, float] | None = None
    push_interval_s: float = 0.0
    push_force_n: float = 0.0
    action_noise_std: float = 0.0
    obs_noise_std: float = 0.0
    terrain: str = "flat"
    terrain_max_height_m: float = 0.05

    @property
    def active(self) -> bool:
        return self != DomainRandomization()


@dataclass(frozen=True)
class Curriculum:
    """Validated ``curriculum``: ``d(step) = d0 + (d1 - d0) * min(1, step / ramp_steps)``."""

    initial_difficulty: float = 1.0
    max_difficulty: float = 1.0
    ramp_steps: int = 0

    def difficulty(self, step: int) -> float:
        if self.ramp_steps <= 0:
            return self.max_difficulty
        frac = min(1.0, max(0.0, step / self.ramp_steps))
        return self.initial_difficulty + (self.max_difficulty - self.initial_difficulty) * frac


def parse_randomization(dr: Mapping[str, Any], cur: Mapping[str, Any],
                        source: str = "<datapacks>") -> tuple[DomainRandomization, Curriculum]:
    """Validate merged datapack ``domain_randomization`` / ``curriculum`` blocks.

    ``source`` names the datapack(s) the keys came from; unknown keys, bad ranges and
    wrong types raise a ConfigError naming it, the key and the supported keys.
    """
    check_keys(dr, DR_KEYS, source, "domain_randomization")
    check_keys(cur, CURRICULUM_KEYS, source, "curriculum")
    kw: dict[str, Any] = {}
    for key in ("friction_range", "mass_scale_range"):
        if key in dr:
            low, high = as_range(dr[key], source, f"domain_randomization.{key}", min_value=0.0)
            if high <= 0:
                raise ConfigError(source, f"domain_randomization.{key}", "multipliers must be > 0")
            kw[key] = (low, high)
    for key in ("push_interval_s", "push_force_n", "action_noise_std", "obs_noise_std", "terrain_max_height_m"):
        if key in dr:
            kw[key] = as_float(dr[key], source, f"domain_randomization.{key}", allow_negative=False)
    if "terrain" in dr:
        kw["terrain"] = as_str(dr["terrain"], source, "domain_randomization.terrain", ("flat", "rough"))
    if kw.get("push_force_n", 0) > 0 and kw.get("push_interval_s", 0) <= 0:
        raise ConfigError(source, "domain_randomization.push_interval_s", "must be > 0 when push_force_n is set")
    ckw: dict[str, Any] = {}
    for key in ("initial_difficulty", "max_difficulty"):
        if key in cur:
            ckw[key] = as_float(cur[key], source, f"curriculum.{key}", min_value=0.0, max_value=1.0)
    if "ramp_steps" in cur:
        ckw["ramp_steps"] = as_int(cur["ramp_steps"], source, "curriculum.ramp_steps", min_value=0)
    if ckw and "initial_difficulty" in ckw and "ramp_steps" not in ckw:
        ckw["ramp_steps"] = 100_000
    curriculum = Curriculum(**ckw)
    if curriculum.initial_difficulty > curriculum.max_difficulty:
        raise ConfigError(source, "curriculum.initial_difficulty", "must not exceed max_difficulty")
    return DomainRandomization(**kw), curriculum
