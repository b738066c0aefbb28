"""Economic objectives and their compilation into reward overlays."""

from econmotor.objectives.economic_objective import (
    OVERLAY_KEYS,
    CompiledRewardOverlay,
    EconomicObjectiveSpec,
    compile_economic_overlay,
)
from econmotor.objectives.loader import load_objective_spec, objective_from_vector, parse_objective_spec

__all__ = [
    "OVERLAY_KEYS",
    "CompiledRewardOverlay",
    "EconomicObjectiveSpec",
    "compile_economic_overlay",
    "load_objective_spec",
    "objective_from_vector",
    "parse_objective_spec",
]
