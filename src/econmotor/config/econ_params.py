"""EconParams: the workcell economics and dynamics of the dishwashing model.

Two presets ship: ``toy`` and ``realistic`` (``EconParams.preset(name)``).
Units: money in USD, energy in Wh, time in seconds unless the name says otherwise;
rates (``base_rate``) are attempts per minute.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from econmotor.errors import ConfigError, UnknownNameError


@dataclass(frozen=True)
class EconParams:
    """Parameters of the analytic dishwashing workcell and its unit economics.

    Attributes:
        price_per_unit: value of one good unit, USD.
        damage_cost: cost of one error (a broken dish), USD.
        energy_Wh_per_attempt: electrical energy per attempted unit, Wh.
        time_step_s: length of one environment step, s.
        base_rate: attempts per minute at speed 0.5 and no care cost.
        p_min: error probability floor.
        k_err: error probability gain on speed and lack of care.
        q_speed: exponent on speed in the error model.
        q_care: exponent on (1 - care) in the error model.
        care_cost: fraction of the rate lost at full care.
        max_steps: episode length limit (truncation), steps.
        max_catastrophic_errors: catastrophic steps (all attempts failed) before termination.
        max_error_rate_sla: errors / completed above which the SLA is violated.
        min_steps_for_sla: steps before the SLA is enforced.
        zero_throughput_patience: steps without any completed unit before termination.
        wage_human: human wage, USD/h (EconContext default).
        mpl_human: human throughput, units/h (EconContext default).
        energy_price_usd_per_kwh: electricity price, USD/kWh; ``None`` means the
            RewardBuilder energy term is ``-Wh`` rather than a dollar cost.
    """

    price_per_unit: float = 0.30
    damage_cost: float = 1.0
    energy_Wh_per_attempt: float = 0.05
    time_step_s: float = 60.0
    base_rate: float = 2.0
    p_min: float = 0.02
    k_err: float = 0.12
    q_speed: float = 1.2
    q_care: float = 1.5
    care_cost: float = 0.25
    max_steps: int = 240
    max_catastrophic_errors: int = 3
    max_error_rate_sla: float = 0.12
    min_steps_for_sla: int = 5
    zero_throughput_patience: int = 10
    wage_human: float = 18.0
    mpl_human: float = 60.0
    energy_price_usd_per_kwh: float | None = None

    @classmethod
    def preset(cls, name: str) -> EconParams:
        """Return the named preset (``toy`` or ``realistic``)."""
        try:
            return ECON_PRESETS[name]
        except KeyError:
            raise UnknownNameError("EconParams preset", name, ECON_PRESETS) from None

    def with_overrides(self, overrides: dict[str, Any], source: str = "<overrides>") -> EconParams:
        """Return a copy with some fields replaced; unknown names are a ConfigError."""
        names = {f.name for f in fields(self)}
        for key in overrides:
            if key not in names:
                raise ConfigError(source, key, "not an EconParams field", names)
        return replace(self, **overrides)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


ECON_PRESETS: dict[str, EconParams] = {
    "toy": EconParams(),
    "realistic": EconParams(
        price_per_unit=0.25,
        damage_cost=1.5,
        base_rate=1.6,
        max_error_rate_sla=0.08,
        energy_Wh_per_attempt=0.08,
    ),
}
