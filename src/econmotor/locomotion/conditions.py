"""What prices (and trains) a card robot on a walker task: its policy contract, course, meter and stress.

:func:`walker_setup` reads them from the task's locomotion block (:func:`econmotor.locomotion.task.walker_settings`,
the one place per robot task) and the datapacks, for every backend that runs
the batched walker env (the holosoma backend's sim-to-sim evaluation, the mujoco backend's CPU trainer
and its evaluation): one reading, so what a policy is trained on is what it is priced on.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from econmotor.couriers.policy_import import PolicyContract, resolve_contract
from econmotor.errors import ConfigError
from econmotor.locomotion.course import CourseSettings
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import SIM2SIM_KEYS, MeterSettings, course_settings, meter_settings
from econmotor.robots import card as robot_card
from econmotor.robots.card import RobotCard


@dataclass(frozen=True)
class WalkerSetup:
    """A walker task's pricing conditions for one policy."""

    contract: PolicyContract | None  # None: a policy trained from scratch (the card's own gains and ranges)
    card: RobotCard
    course: CourseSettings
    meter: MeterSettings
    stress: Stress
    episode_s: float
    notes: tuple[str, ...]
    datapack_ids: tuple[str, ...]
    #: the conditions without the datapacks (the catalog's start-pose noise only): what a report prices by
    #: default, and what a training run's held-out looks alternate with its stress
    nominal_stress: Stress = field(default_factory=Stress)


def stress_notes(stress: Stress) -> list[str]:
    """What a sim-to-sim evaluation says of its conditions: datapack keys it does not apply, or that it is nominal."""
    notes = ["not applied in the sim-to-sim evaluation: " + "; ".join(stress.ignored)] if stress.ignored else []
    if stress.nominal:
        notes.append("nominal conditions (no datapack randomization): episodes differ by seed only in their "
                     f"start pose (joints within +-{stress.initial_joint_noise_rad:g} rad of the default); a "
                     "datapack such as configs/datapacks/humanoid_stress.yaml adds stress")
    return notes


def walker_setup(spec: Any, settings: Mapping[str, Any], bundle: Any, packs: Sequence[Any], policy: str | None,
                 policy_id: str | None = None, course_speed_m_per_s: float | None = None,
                 episode_s: float | None = None, fallback_python: str | Path | None = None,
                 refuse_unapplied: bool = False) -> WalkerSetup:
    """The conditions of task ``spec`` (its walker ``settings``, the datapacks' resolved ``bundle`` and
    ``packs``) for ``policy`` (an ONNX path or a shipped name; None: the task's robot card, for a policy
    trained from scratch); a ConfigError names a missing catalog key or a policy for another robot, and with
    ``refuse_unapplied`` (a training run: it would not train under what it was asked to) a datapack key the
    walker env cannot apply; pricing notes such keys instead (a policy trained under them elsewhere)."""
    task_id = spec.task_id
    missing = [k for k in SIM2SIM_KEYS if k not in settings]
    if missing:
        raise ConfigError(spec.source, f"tasks.{task_id}.locomotion.{missing[0]}",
                          "the walker's course needs it (with its unit and source)", SIM2SIM_KEYS)
    course = course_settings(settings, course_speed_m_per_s)
    meter = meter_settings(task_id, settings, spec.source)
    contract = resolve_contract(policy, fallback_python) if policy is not None else None
    card = contract.card if contract is not None else robot_card(str(settings["robot"]), spec.source)
    if contract is not None and contract.card.name != str(settings["robot"]):
        raise ConfigError("--policy", policy_id or policy, f"drives robot card '{contract.card.name}' (Holosoma's "
                          f"'{contract.experiment}') but task '{task_id}' is walked by '{settings['robot']}' (its "
                          "locomotion block's robot)", [str(settings["robot"])])
    noise = float(settings["sim2sim_start_joint_noise_rad"])
    by_id = {p.id: p for p in packs}  # the bundle's packs, each naming its own file in an error or note
    datapacks = [by_id[i] for i in bundle.datapack_ids] if set(bundle.datapack_ids) <= set(by_id) else [bundle]
    # a policy is priced under what it was trained under elsewhere (Holosoma applies a curriculum, clips,
    # rough terrain): what the walker env cannot apply is a note, not an error
    stress = Stress.from_datapacks(datapacks, card.push_preset, noise, refuse_unapplied=refuse_unapplied)
    return WalkerSetup(contract=contract, card=card, course=course, meter=MeterSettings(**meter), stress=stress,
                       episode_s=float(episode_s or settings["sim2sim_episode_s"]), notes=tuple(stress_notes(stress)),
                       datapack_ids=tuple(bundle.datapack_ids),
                       nominal_stress=Stress.from_datapacks([], card.push_preset, noise))
