"""The stress a walker is trained and priced under: a datapack's conditions, drawn per episode.

:class:`Stress` is read from a datapack's Holosoma-convention overrides
(:func:`econmotor.couriers.datapack_mapping.map_datapacks`) merged onto the robot's preset terms
(the card's ``push_preset``: Holosoma's push interval and velocity for ``pushes: true``). Every
walker env applies the same fields:

- ``friction_range``: the floor's sliding friction, one draw per episode;
- ``payload_kg_range``: a payload on the torso, kg, one draw per episode;
- ``push_interval_s`` / ``max_push_vel_m_per_s``: a base velocity kick of up to that many m/s in x
  and y, every interval drawn from the range (Holosoma's ``push_randomizer_state``);
- ``initial_joint_noise_rad``: each joint starts within +- this of its default angle;
- ``kp_range`` / ``kd_range``: the PD gains scaled per joint by a draw from the range (Holosoma's
  ``actuator_randomizer_state``), one draw per episode;
- ``ctrl_delay_steps``: the action applied is the one from that many control steps earlier (a draw
  per episode from the inclusive integer range; Holosoma's ``setup_action_delay_buffers``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

#: the Holosoma randomization terms a walker env applies (the others are named in ``Stress.ignored``)
APPLIED_TERMS = ("randomize_friction_startup", "mass_randomizer", "push_randomizer_state",
                 "actuator_randomizer_state", "setup_action_delay_buffers")


def _pair(value: Any) -> tuple[float, float] | None:
    return (float(value[0]), float(value[1])) if value is not None else None


@dataclass(frozen=True)
class Stress:
    """Datapack conditions applied per episode (None: nominal); the module docstring has each field."""

    friction_range: tuple[float, float] | None = None
    payload_kg_range: tuple[float, float] | None = None
    push_interval_s: tuple[float, float] | None = None
    max_push_vel_m_per_s: tuple[float, float] | None = None
    initial_joint_noise_rad: float = 0.0
    kp_range: tuple[float, float] | None = None
    kd_range: tuple[float, float] | None = None
    ctrl_delay_steps: tuple[int, int] | None = None
    ignored: tuple[str, ...] = ()

    @classmethod
    def from_overrides(cls, randomization: Mapping[str, Mapping[str, Any]], evaluation: Mapping[str, Any],
                       preset_terms: Mapping[str, Any], start_joint_noise_rad: float = 0.0) -> Stress:
        """From a datapack's Holosoma overrides merged onto the preset's terms.

        Only the terms a datapack sets apply (a datapack without randomization is nominal);
        ``preset_terms``: randomization term -> its preset parameters (what a datapack leaves out,
        e.g. the push interval when it only says ``pushes: true``); ``start_joint_noise_rad``: the
        catalog's per-seed start-pose noise, used unless the datapack's
        ``evaluation.initial_joint_noise_rad`` sets its own.
        """
        def params(term: str) -> dict[str, Any] | None:
            if term not in randomization:
                return None
            merged = {**dict(preset_terms.get(term, {})), **dict(randomization[term])}
            return merged if merged.get("enabled", True) else None

        friction, mass, push = (params(t) for t in APPLIED_TERMS[:3])
        actuators, delay = params("actuator_randomizer_state"), params("setup_action_delay_buffers")
        ignored = tuple(f"{term} ({', '.join(sorted(p))})" for term, p in randomization.items()
                        if term not in APPLIED_TERMS)
        if mass and "link_mass_range" in randomization.get("mass_randomizer", {}):
            ignored += ("mass_randomizer (link_mass_range)",)
        delay_range = delay.get("ctrl_delay_step_range") if delay else None
        return cls(
            friction_range=_pair(friction["friction_range"]) if friction else None,
            payload_kg_range=_pair(mass.get("added_mass_range")) if mass and "added_mass_range" in
            randomization.get("mass_randomizer", {}) else None,
            push_interval_s=_pair(push["push_interval_s"]) if push else None,
            max_push_vel_m_per_s=_pair(push["max_push_vel"]) if push else None,
            initial_joint_noise_rad=float(evaluation.get("initial_joint_noise_rad", start_joint_noise_rad)),
            kp_range=_pair(actuators.get("kp_range")) if actuators else None,
            kd_range=_pair(actuators.get("kd_range")) if actuators else None,
            ctrl_delay_steps=(int(delay_range[0]), int(delay_range[1])) if delay_range is not None else None,
            ignored=ignored)
