"""Robot cards: one per real robot (:mod:`.card`), its model (:mod:`.model`) and observation (:mod:`.observation`).

``card(name)`` looks a card up by name (``g1_29dof``, ``t1_29dof``); an unknown name is a
ConfigError listing the known ones. Imports NumPy and MuJoCo only (both interpreters load it).
"""

from __future__ import annotations

from econmotor.errors import ConfigError
from econmotor.robots.card import ObservationConvention, RobotCard
from econmotor.robots.g1_29dof import CARD as G1_29DOF
from econmotor.robots.t1_29dof import CARD as T1_29DOF

#: the cards by name
CARDS: dict[str, RobotCard] = {c.name: c for c in (G1_29DOF, T1_29DOF)}

__all__ = ["CARDS", "G1_29DOF", "T1_29DOF", "ObservationConvention", "RobotCard", "card"]


def card(name: str, source: str = "<robot>") -> RobotCard:
    """The card of robot ``name``; a ConfigError naming ``source`` lists the known robots."""
    if name not in CARDS:
        raise ConfigError(source, "robot", f"unknown robot '{name}'", sorted(CARDS))
    return CARDS[name]
