"""Labour economics: MPL, implied wage, wage parity, energy productivity, unit costs."""

from econmotor.config.econ_params import ECON_PRESETS, EconParams
from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.labour import (
    energy_productivity,
    error_rate,
    human_unit_cost,
    implied_wage,
    mpl_units_per_hour,
    robot_cost_per_hour,
    robot_unit_cost,
    spread_per_unit,
    wage_parity,
)
from econmotor.economics.legacy_reward import LegacyRewardWeights, compute_econ_reward
from econmotor.economics.meter import ECON_METRIC_KEYS, RAW_KEY_ALIASES, EconomicMeter

__all__ = [
    "ECON_METRIC_KEYS",
    "ECON_PRESETS",
    "RAW_KEY_ALIASES",
    "EconParams",
    "EconomicMeter",
    "LegacyRewardWeights",
    "TaskEconomics",
    "compute_econ_reward",
    "energy_productivity",
    "error_rate",
    "human_unit_cost",
    "implied_wage",
    "mpl_units_per_hour",
    "robot_cost_per_hour",
    "robot_unit_cost",
    "spread_per_unit",
    "wage_parity",
]
