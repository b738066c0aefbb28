"""EconomicMeter: a backend's raw metrics -> the econ metrics every layer reads.

Raw metric keys it reads (first name canonical, then accepted aliases):

==========================  =================================================  ==========================
key                         aliases                                            meaning
==========================  =================================================  ==========================
``units_completed``         ``completed_units``, ``good_units``, ``units``     good units of work done
``units_attempted``         ``attempts``, ``attempted_units``                  attempts (default: good + errors)
``errors``                  ``error_count``, ``num_errors``, ``falls``         failed units / falls
``episode_length_s``        ``duration_s``, ``elapsed_s``, ``time_s``          time worked, s
``episode_length_steps``    ``steps``                                          used with ``control_dt_s``
``control_dt_s``            ``dt_s``                                           seconds per step
``energy_wh``               ``energy_Wh``                                      electrical energy, Wh
``energy_kwh``              —                                                  electrical energy, kWh
``mpl_units_per_hour``      ``mpl_episode``, ``throughput_units_per_hour``     throughput given directly
``success``                 ``successes``, ``success_count``                   successful episodes (MPL fallback)
``risk_score``              —                                                  mean risk score
``novelty_score``           —                                                  mean novelty score
``num_episodes``            ``episodes``                                       episodes aggregated
==========================  =================================================  ==========================

Good units come from ``units_completed``; else from ``mpl_units_per_hour`` times
the hours; else from ``success`` (one unit per successful episode). Counts and
times must be finite and non-negative: anything else is a ConfigError naming the key.

The wage, cost and spread figures are :func:`econmotor.economics.pricing.price_task`'s, so the meter and
the price never disagree; for a task with a battery they are per paid robot-hour (working or charging)
and the summary adds :data:`BATTERY_METRIC_KEYS` (:mod:`econmotor.economics.battery`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import labour
from econmotor.economics.battery import BATTERY_UNITS
from econmotor.economics.pricing import price_task
from econmotor.errors import ConfigError

RAW_KEY_ALIASES: dict[str, tuple[str, ...]] = {
    "units_completed": ("completed_units", "good_units", "units"),
    "units_attempted": ("attempts", "attempted_units"),
    "errors": ("error_count", "num_errors", "falls"),
    "episode_length_s": ("duration_s", "elapsed_s", "time_s"),
    "episode_length_steps": ("steps",),
    "control_dt_s": ("dt_s",),
    "energy_wh": ("energy_Wh",),
    "energy_kwh": (),
    "mpl_units_per_hour": ("mpl_episode", "throughput_units_per_hour"),
    "success": ("successes", "success_count"),
    "risk_score": (),
    "novelty_score": (),
    "num_episodes": ("episodes",),
}

#: Keys of the dict :meth:`EconomicMeter.summarize` returns.
ECON_METRIC_KEYS: tuple[str, ...] = (
    "hours",
    "num_episodes",
    "units_completed",
    "units_attempted",
    "errors",
    "mpl_units_per_hour",
    "error_rate",
    "energy_wh",
    "energy_kwh",
    "energy_kwh_per_hour",
    "energy_wh_per_unit",
    "energy_cost_usd",
    "energy_cost_usd_per_hour",
    "implied_wage_usd_per_hour",
    "wage_parity",
    "energy_productivity_units_per_kwh",
    "robot_cost_usd_per_hour",
    "robot_unit_cost_usd",
    "human_unit_cost_usd",
    "spread_per_unit_usd",
    "risk_score",
    "novelty_score",
)
#: Keys :meth:`EconomicMeter.summarize` adds for a task whose robot runs on a battery.
BATTERY_METRIC_KEYS: tuple[str, ...] = tuple(BATTERY_UNITS)


def read_raw(raw: Mapping[str, Any], key: str, source: str = "raw_metrics") -> float | None:
    """Return the value of ``key`` or its first present alias, validated finite and >= 0."""
    for name in (key, *RAW_KEY_ALIASES.get(key, ())):
        if name in raw and raw[name] is not None:
            value = raw[name]
            if isinstance(value, bool):
                value = float(value)
            if not isinstance(value, (int, float)) and not hasattr(value, "__float__"):
                raise ConfigError(source, name, f"expected a number, got {type(value).__name__}")
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError(source, name, f"must be finite, got {value}")
            if value < 0:
                raise ConfigError(source, name, f"must not be negative, got {value}", ">= 0")
            return value
    return None


class EconomicMeter:
    """Turn raw rollout metrics into labour economics for one task.

    Args:
        economics: the task's economics (wage, value per unit, damage cost, prices, robot costs).
    """

    def __init__(self, economics: TaskEconomics) -> None:
        self.economics = economics

    def summarize(self, raw_metrics: Mapping[str, Any], source: str = "raw_metrics") -> dict[str, float]:
        """Return the econ metrics (keys in :data:`ECON_METRIC_KEYS`, plus :data:`BATTERY_METRIC_KEYS` for a
        task with a battery) of ``raw_metrics``."""
        if not isinstance(raw_metrics, Mapping):
            raise ConfigError(source, None, f"expected a mapping, got {type(raw_metrics).__name__}")
        get = lambda key: read_raw(raw_metrics, key, source)
        econ = self.economics

        seconds = get("episode_length_s")
        if seconds is None:
            steps, dt = get("episode_length_steps"), get("control_dt_s")
            if steps is None or dt is None:
                raise ConfigError(source, "episode_length_s",
                                  "no time worked: give episode_length_s or episode_length_steps and control_dt_s")
            seconds = steps * dt
        hours = seconds / 3600.0

        units = get("units_completed")
        if units is None:
            mpl_given = get("mpl_units_per_hour")
            if mpl_given is not None:
                units = mpl_given * hours
            else:
                success = get("success")
                if success is None:
                    raise ConfigError(source, "units_completed",
                                      "no throughput: give units_completed, mpl_units_per_hour or success")
                units = success
        errors = get("errors") or 0.0
        attempted = get("units_attempted")
        if attempted is None:
            attempted = units + errors

        energy_wh = get("energy_wh")
        if energy_wh is None:
            kwh = get("energy_kwh")
            energy_wh = kwh * 1000.0 if kwh is not None else 0.0
        energy_kwh = energy_wh / 1000.0

        mpl = labour.mpl_units_per_hour(units, hours)
        err = labour.error_rate(errors, attempted)
        kwh_per_hour = energy_kwh / hours if hours > 0 else 0.0
        price = price_task(econ, mpl, err, kwh_per_hour)
        summary = {
            "hours": hours,
            "num_episodes": get("num_episodes") or 1.0,
            "units_completed": units,
            "units_attempted": attempted,
            "errors": errors,
            "mpl_units_per_hour": mpl,
            "error_rate": err,
            "energy_wh": energy_wh,
            "energy_kwh": energy_kwh,
            "energy_kwh_per_hour": kwh_per_hour,
            "energy_wh_per_unit": energy_wh / units if units > 0 else math.inf,
            "energy_cost_usd": energy_kwh * econ.energy_price_usd_per_kwh,
            "energy_cost_usd_per_hour": kwh_per_hour * econ.energy_price_usd_per_kwh,
            "implied_wage_usd_per_hour": price.implied_wage_usd_per_hour,
            "wage_parity": price.wage_parity,
            "energy_productivity_units_per_kwh": price.energy_productivity_units_per_kwh,
            "robot_cost_usd_per_hour": price.robot_cost_usd_per_hour,
            "robot_unit_cost_usd": price.robot_unit_cost_usd,
            "human_unit_cost_usd": price.human_unit_cost_usd,
            "spread_per_unit_usd": price.spread_per_unit_usd,
            "risk_score": get("risk_score") or 0.0,
            "novelty_score": get("novelty_score") or 0.0,
        }
        if price.has_battery:
            summary.update({key: getattr(price, key) for key in BATTERY_METRIC_KEYS})
        return summary
