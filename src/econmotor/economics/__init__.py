"""Labour economics: MPL, implied wage, wage parity, energy productivity, unit costs, battery charging."""

from econmotor.config.econ_params import ECON_PRESETS, EconParams
from econmotor.config.task_economics import TaskEconomics
from econmotor.economics.battery import BATTERY_UNITS, DutyCycle, duty_cycle
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
from econmotor.economics.meter import BATTERY_METRIC_KEYS, ECON_METRIC_KEYS, RAW_KEY_ALIASES, EconomicMeter

__all__ = [
    "BATTERY_METRIC_KEYS",
    "BATTERY_UNITS",
    "ECON_METRIC_KEYS",
    "ECON_PRESETS",
    "RAW_KEY_ALIASES",
    "DutyCycle",
    "EconParams",
    "EconomicMeter",
    "LegacyRewardWeights",
    "TaskEconomics",
    "compute_econ_reward",
    "duty_cycle",
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
