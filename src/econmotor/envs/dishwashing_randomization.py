"""Per-episode randomization of the dishwashing EconParams, with an optional curriculum.

A datapack's ``domain_randomization`` names ranges of EconParams fields as
``<field>_range: [low, high]`` (e.g. ``base_rate_range: [1.5, 2.5]``); its
``curriculum`` ramps how much of each range is used::

    difficulty(n) = initial + (max - initial) * min(1, n / ramp_steps)
    low'  = nominal + difficulty * (low  - nominal)
    high' = nominal + difficulty * (high - nominal)
    value ~ Uniform(low', high')

where ``n`` is the number of environment steps the environment has taken so far
and ``nominal`` the field's value in the base EconParams. Difficulty 0 is the
nominal task, difficulty 1 the full ranges. Without a curriculum the difficulty is 1.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from econmotor.config.econ_params import EconParams
from econmotor.config.loading import as_float, as_int, as_range
from econmotor.errors import ConfigError, did_you_mean

#: EconParams field -> (min, max) allowed for sampled values.
RANDOMIZABLE_FIELDS: dict[str, tuple[float, float | None]] = {
    "base_rate": (0.0, None),
    "p_min": (0.0, 0.5),
    "k_err": (0.0, None),
    "q_speed": (0.0, None),
    "q_care": (0.0, None),
    "care_cost": (0.0, 1.0),
    "energy_Wh_per_attempt": (0.0, None),
    "price_per_unit": (0.0, None),
    "damage_cost": (0.0, None),
    "time_step_s": (1e-6, None),
}
SUPPORTED_RANDOMIZATION_KEYS: tuple[str, ...] = tuple(f"{name}_range" for name in RANDOMIZABLE_FIELDS)
SUPPORTED_CURRICULUM_KEYS: tuple[str, ...] = ("initial_difficulty", "max_difficulty", "ramp_steps")
DEFAULT_RAMP_STEPS = 10_000


@dataclass(frozen=True)
class EconRandomization:
    """Validated ranges and curriculum; :meth:`sample` draws one episode's EconParams.

    Attributes:
        ranges: EconParams field -> (low, high).
        initial_difficulty: difficulty at step 0, in [0, 1].
        max_difficulty: difficulty after ``ramp_steps`` steps, in [0, 1].
        ramp_steps: environment steps over which difficulty ramps (per environment).
    """

    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    initial_difficulty: float = 1.0
    max_difficulty: float = 1.0
    ramp_steps: int = DEFAULT_RAMP_STEPS

    def difficulty(self, env_steps: int) -> float:
        """``initial + (max - initial) * min(1, env_steps / ramp_steps)``."""
        frac = min(1.0, env_steps / self.ramp_steps) if self.ramp_steps > 0 else 1.0
        return self.initial_difficulty + (self.max_difficulty - self.initial_difficulty) * frac

    def sample(self, base: EconParams, rng: np.random.Generator, env_steps: int = 0) -> EconParams:
        """Draw one episode's parameters (see the module docstring for the formula)."""
        if not self.ranges:
            return base
        d = self.difficulty(env_steps)
        values = {}
        for name, (low, high) in self.ranges.items():
            nominal = float(getattr(base, name))
            lo, hi = nominal + d * (low - nominal), nominal + d * (high - nominal)
            values[name] = float(rng.uniform(min(lo, hi), max(lo, hi)))
        return replace(base, **values)

    def to_dict(self) -> dict[str, Any]:
        return {
            "ranges": {k: list(v) for k, v in self.ranges.items()},
            "initial_difficulty": self.initial_difficulty,
            "max_difficulty": self.max_difficulty,
            "ramp_steps": self.ramp_steps,
        }


def parse_econ_randomization(
    domain_randomization: Mapping[str, Any] | None,
    curriculum: Mapping[str, Any] | None = None,
    source: str = "<datapack>",
) -> EconRandomization:
    """Validate datapack ``domain_randomization`` / ``curriculum`` for the dishwashing env.

    Args:
        domain_randomization: ``<field>_range: [low, high]`` entries
            (supported: :data:`SUPPORTED_RANDOMIZATION_KEYS`).
        curriculum: ``initial_difficulty`` / ``max_difficulty`` in [0, 1] and ``ramp_steps``
            (steps); absent means full ranges from the start.
        source: the datapack file(s), named in errors.

    Raises:
        ConfigError: an unsupported key (listing the supported ones) or a bad value.
    """
    ranges: dict[str, tuple[float, float]] = {}
    for key, value in dict(domain_randomization or {}).items():
        if key not in SUPPORTED_RANDOMIZATION_KEYS:
            raise ConfigError(
                source, f"domain_randomization.{key}",
                "not supported by the dishwashing backend" + did_you_mean(key, SUPPORTED_RANDOMIZATION_KEYS),
                SUPPORTED_RANDOMIZATION_KEYS,
            )
        name = key[: -len("_range")]
        lo_bound, hi_bound = RANDOMIZABLE_FIELDS[name]
        ranges[name] = as_range(value, source, f"domain_randomization.{key}", min_value=lo_bound, max_value=hi_bound)
    cur = dict(curriculum or {})
    for key in cur:
        if key not in SUPPORTED_CURRICULUM_KEYS:
            raise ConfigError(
                source, f"curriculum.{key}",
                "not supported by the dishwashing backend" + did_you_mean(key, SUPPORTED_CURRICULUM_KEYS),
                SUPPORTED_CURRICULUM_KEYS,
            )
    if not cur:
        return EconRandomization(ranges=ranges)
    initial = as_float(cur.get("initial_difficulty", 0.0), source, "curriculum.initial_difficulty",
                       min_value=0.0, max_value=1.0)
    maximum = as_float(cur.get("max_difficulty", 1.0), source, "curriculum.max_difficulty",
                       min_value=0.0, max_value=1.0)
    if initial > maximum:
        raise ConfigError(source, "curriculum.initial_difficulty", f"{initial} exceeds max_difficulty {maximum}")
    ramp = as_int(cur.get("ramp_steps", DEFAULT_RAMP_STEPS), source, "curriculum.ramp_steps", min_value=1)
    return EconRandomization(ranges=ranges, initial_difficulty=initial, max_difficulty=maximum, ramp_steps=ramp)
