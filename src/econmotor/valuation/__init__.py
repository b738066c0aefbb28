"""Valuation: RewardBuilder terms, an episode's J (:func:`episode_j`) and constraint sets."""

from econmotor.valuation.constraints import (
    ConstraintSet,
    apply_constraint_penalties,
    load_constraint_set,
    load_constraint_sets,
    parse_constraint_set,
)
from econmotor.valuation.reward_builder import (
    REWARD_TERM_NAMES,
    build_reward_terms,
    combine_reward,
    default_objective_vector,
    episode_j,
    extract_step_summary,
)

__all__ = [
    "REWARD_TERM_NAMES",
    "ConstraintSet",
    "apply_constraint_penalties",
    "build_reward_terms",
    "combine_reward",
    "default_objective_vector",
    "episode_j",
    "extract_step_summary",
    "load_constraint_set",
    "load_constraint_sets",
    "parse_constraint_set",
]
