"""econmotor.envs: Gymnasium environments.

``econmotor/Dishwashing-v0`` is registered on import:
``gymnasium.make("econmotor/Dishwashing-v0", econ_params=EconParams.preset("toy"))``.
"""

import gymnasium as gym

from econmotor.envs.dishwashing import REWARD_MODES, TERMINATION_REASONS, DishwashingEnv
from econmotor.envs.dishwashing_randomization import (
    SUPPORTED_CURRICULUM_KEYS,
    SUPPORTED_RANDOMIZATION_KEYS,
    EconRandomization,
    parse_econ_randomization,
)

DISHWASHING_ENV_ID = "econmotor/Dishwashing-v0"

if DISHWASHING_ENV_ID not in gym.registry:
    gym.register(id=DISHWASHING_ENV_ID, entry_point="econmotor.envs.dishwashing:DishwashingEnv")

__all__ = [
    "DISHWASHING_ENV_ID",
    "REWARD_MODES",
    "SUPPORTED_CURRICULUM_KEYS",
    "SUPPORTED_RANDOMIZATION_KEYS",
    "TERMINATION_REASONS",
    "DishwashingEnv",
    "EconRandomization",
    "parse_econ_randomization",
]
