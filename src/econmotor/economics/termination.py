"""Why an episode ended: one list for every env and backend (the raw metric ``termination_reason``)."""

from __future__ import annotations

from enum import StrEnum


class TerminationReason(StrEnum):
    """The values of ``termination_reason`` (a ``str``: raw metrics and reports carry the value)."""

    FALL = "fall"  # the robot fell, or its state blew up: one error
    MAX_STEPS = "max_steps"  # the episode's step (time) limit
    COURSE_DONE = "course_done"  # a walker walked every leg of its course and stood its last dwell
    CATASTROPHIC_ERROR = "catastrophic_error"  # dishwashing: a breakage that ends the shift
    SLA_VIOLATION = "sla_violation"  # dishwashing: the service level missed
    ZERO_THROUGHPUT = "zero_throughput"  # dishwashing: nothing washed for too long
