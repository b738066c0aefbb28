"""EconParams: the workcell economics and dynamics of the dishwashing model.

Two presets ship: ``toy`` and ``realistic`` (``EconParams.preset(name)``).
Units: money in USD, energy in Wh, time in seconds unless the name says otherwise;
rates (``base_rate``) are attempts per minute.

:func:`load_econ_params` (spec §3: ``econ_params = load_econ_params(args.config)``) takes a
preset name or a YAML file::

    preset: realistic            # optional base (default toy)
    base_rate: 1.8               # any EconParams field overrides it
    energy_price_usd_per_kwh: null
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

from econmotor.config.loading import as_float, as_int, as_str, check_keys, join_key, read_yaml_mapping
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
        energy_price_usd_per_kwh: electricity price, USD/kWh, in the workcell's step profit;
            ``None``: energy is free there. The RewardBuilder energy term is ``-Wh`` either way
            (spec §1, §7); only an objective with ``energy_term="usd"`` prices it.
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


def load_econ_params(path_or_preset: str | Path | EconParams) -> EconParams:
    """EconParams from a preset name (``toy``, ``realistic``) or a YAML file (module docstring).

    An :class:`EconParams` is returned as is. A string that names an existing file is read
    as YAML; any other string must be a preset name. Every field is validated (numbers
    finite, integers integral, prices and costs not negative); unknown keys are a
    ConfigError naming the file, the key and the allowed names.
    """
    if isinstance(path_or_preset, EconParams):
        return path_or_preset
    path = Path(path_or_preset)
    if isinstance(path_or_preset, str) and not path.is_file():
        if path_or_preset in ECON_PRESETS:
            return ECON_PRESETS[path_or_preset]
        if path.suffix not in (".yaml", ".yml"):
            raise UnknownNameError("EconParams preset", path_or_preset, ECON_PRESETS)
    data = read_yaml_mapping(path)
    names = [f.name for f in fields(EconParams)]
    check_keys(data, ("preset", *names), path)
    base = ECON_PRESETS[as_str(data.pop("preset", "toy"), path, "preset", ECON_PRESETS)]
    return econ_params_with(base, data, path)


def econ_params_with(base: EconParams, overrides: dict[str, Any], source: str | Path,
                     prefix: str | None = None) -> EconParams:
    """``base`` with ``overrides`` (a YAML mapping) validated field by field: names known, numbers
    finite, integers integral, none negative; errors name ``source`` and ``prefix.<field>``."""
    names = [f.name for f in fields(EconParams)]
    check_keys(overrides, names, source, prefix)
    values: dict[str, Any] = {}
    for f in fields(EconParams):
        if f.name not in overrides:
            continue
        value, key = overrides[f.name], join_key(prefix, f.name)
        if f.name == "energy_price_usd_per_kwh" and value is None:
            values[f.name] = None
        elif isinstance(getattr(base, f.name), int) and not isinstance(getattr(base, f.name), bool):
            values[f.name] = as_int(value, source, key, min_value=0)
        else:
            values[f.name] = as_float(value, source, key, allow_negative=False)
    return replace(base, **values)
