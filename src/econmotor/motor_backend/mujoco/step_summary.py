"""A per-step summary for MuJoCo tasks, in the dishwashing key set shadow mode reads.

The MuJoCo metering wrapper (``econmotor.motor_backend.mujoco.metering``) keeps
running episode sums (its ``episode`` snapshot) and reports raw metrics only at the
episode's end, so :class:`MujocoStepSummaryWrapper` (placed outside it) differences
the sums around each step and writes ``info["step_summary"]``:

- ``units`` (fractional delivery legs this step), ``errors`` (1 on a fall),
  ``attempts = units + errors``, ``Wh`` (this step's electrical energy);
- ``mpl_t`` running units/h, ``d_mpl = mpl_t - mpl_{t-1}`` (``mpl_0 = 0``, so the sum
  over an episode is the episode MPL), ``mpl_step = units / dt_h``;
- ``error_rate_t = errors / attempts`` (0 with no attempt), ``implied_wage_t =
  p * mpl_step - c_d * error_rate_t * mpl_step``, ``wage_human``, ``wage_parity_t``;
- ``wage_parity_running``: the implied wage of the running MPL and error rate / human wage
  (what the episode would report if it ended now; constraint shaping reads it);
- ``ep_t``: the running energy productivity, good units per kWh so far (``EP = MP_r / E_r``,
  as the episode summary reports it);
- ``catastrophic`` (a fall), ``novelty`` (this step's novelty bonus), ``novelty_running``
  (the running episode novelty score, the mean bonus so far, as the episode reports it),
  ``termination_reason``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from econmotor.config.task_economics import TaskEconomics
from econmotor.economics import labour
from econmotor.economics.termination import TerminationReason
from econmotor.errors import ConfigError


class MujocoStepSummaryWrapper(gym.Wrapper):
    """Write ``info["step_summary"]`` from an inner ``EconomicMeteringWrapper``'s episode sums.

    Args:
        env: an env whose wrapper chain holds an ``EconomicMeteringWrapper``.
        economics: the task economics (value per unit, damage cost, human wage).
    """

    def __init__(self, env: gym.Env, economics: TaskEconomics) -> None:
        super().__init__(env)
        from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper, find_wrapper

        inner = find_wrapper(env, EconomicMeteringWrapper)
        if inner is None:
            raise ConfigError("<env>", "wrappers", "no EconomicMeteringWrapper inside this env")
        self.meter = inner
        self.dt_h = float(inner.dt_s) / 3600.0
        self.economics = economics
        self._prev_mpl = 0.0
        self._before = inner.episode  # the meter's sums before the next step

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self._prev_mpl = 0.0
        self._before = self.meter.episode
        return obs, info

    def step(self, action):
        before = self._before
        units0, errors0, wh0, novelty0 = before.units, before.errors, before.energy_wh, before.novelty_sum
        obs, reward, terminated, truncated, info = self.env.step(action)
        t = self._before = self.meter.episode  # the sums after the step (at an episode's end: the ended episode's)
        econ = self.economics
        units, errors = t.units - units0, t.errors - errors0
        attempts = units + errors
        mpl = t.mpl_per_hour()
        mpl_step = units / self.dt_h
        err = errors / attempts if attempts > 0 else 0.0
        wage = labour.implied_wage(econ.value_per_unit, mpl_step, econ.damage_cost_usd_per_error, err)
        ended = TerminationReason.FALL if terminated else TerminationReason.MAX_STEPS
        reason = ended if (terminated or truncated) else None
        info["step_summary"] = {
            "units": units, "errors": errors, "attempts": attempts, "Wh": t.energy_wh - wh0,
            "mpl_t": mpl, "d_mpl": mpl - self._prev_mpl, "mpl_step": mpl_step,
            "error_rate_t": err, "implied_wage_t": wage, "wage_human": econ.wage_human_usd_per_hour,
            "wage_parity_t": labour.wage_parity(wage, econ.wage_human_usd_per_hour),
            "wage_parity_running": labour.wage_parity(
                labour.implied_wage(econ.value_per_unit, mpl, econ.damage_cost_usd_per_error,
                                    labour.error_rate(t.errors, t.units + t.errors)),
                econ.wage_human_usd_per_hour),
            "ep_t": labour.energy_productivity(t.units, t.energy_wh / 1000.0),
            "catastrophic": bool(terminated), "novelty": t.novelty_sum - novelty0,
            "novelty_running": t.novelty_score(),
            "termination_reason": reason,
        }
        self._prev_mpl = mpl
        return obs, reward, terminated, truncated, info
