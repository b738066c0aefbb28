"""A task's acceptance rule: what evaluation must show before a robot is priced.

The rule is applied by :func:`econmotor.economics.uncertainty.decide`. A catalog task
may carry it (``acceptance:`` beside ``economics:``); without one the limit on the
error rate is the human's own rate and any positive throughput is enough.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

#: the verdict's check of the error (fall) rate, by name (its ``bound`` is the one the verdict judged)
ERROR_RATE_CHECK = "error rate"


@dataclass(frozen=True)
class Acceptance:
    """A task's acceptance rule: what evaluation must show before the robot is priced.

    Attributes:
        max_error_rate: the error rate's upper bound must not exceed this (errors/attempted unit).
        min_units_per_hour: the MPL lower bound must reach this (units/h); 0 means any work.
        error_name: what one error is called in sentences ("fall", "broken dish").
        sources: field -> where the limit comes from.
    """

    max_error_rate: float
    min_units_per_hour: float = 0.0
    error_name: str = "error"
    sources: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def default_for(cls, error_rate_human: float) -> Acceptance:
        """No rule in the catalog: no worse than a human, any positive throughput."""
        return cls(error_rate_human, 0.0, "error",
                   {"max_error_rate": "default: the human's error rate (error_rate_human)",
                    "min_units_per_hour": "default: any positive throughput"})
