"""Pricing a card robot's walker (G1, T1) sim-to-sim: one evaluation for every backend that runs them.

:func:`price_walker` reads the task's walker conditions (:func:`econmotor.locomotion.conditions.walker_setup`:
the policy's contract, the course, the meter, the datapacks' stress), runs the batched MuJoCo walker env
on worker processes (:func:`econmotor.locomotion.evaluation.evaluate`) and returns the evaluation with its
provenance (the evaluator, MuJoCo's version, the commanded and achieved speed, the power drawn). The
holosoma backend prices imported walkers and its own runs with it; the mujoco backend prices the walkers
its CPU trainer exports with it: a policy trained on this env is priced on this env. That trainer's held-out
looks price its exported actor with the same evaluator (``mujoco/walker_training.py``), so selection, the
evaluation after training and a report walk the same episodes for the same ONNX, seeds and conditions.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from econmotor.config.datapacks import DatapackProvider
from econmotor.couriers.policy_import import model_text
from econmotor.economics.courier_formulas import mechanical_from_electrical_w
from econmotor.locomotion.conditions import walker_setup
from econmotor.locomotion.evaluation import WalkerEvaluation
from econmotor.locomotion.evaluation import evaluate as evaluate_walkers
from econmotor.motor_backend.base import ProgressFn, StopFn
from econmotor.motor_backend.results import (
    EvalProvenance,
    MotorEvalResult,
    aggregate_raw,
    evaluation_result,
    mean_power_w,
    walking_speed_m_per_s,
)


def _mean_heat_power_w(episodes: Sequence[Mapping[str, Any]]) -> float:
    """The windings' mean heat over the episodes, W, weighted by their lengths (0 without episodes)."""
    seconds = sum(float(e["episode_length_s"]) for e in episodes)
    return sum(float(e.get("mean_heat_power_w", 0.0)) * float(e["episode_length_s"]) for e in episodes) / seconds \
        if seconds > 0 else 0.0


@dataclass(frozen=True)
class WalkerPricing:
    """Who prices what: the backend's name, the task (``spec`` and its walker ``settings``), the datapacks,
    the policy (an ONNX path or a shipped name; ``policy_id`` as the user named it), the worker processes
    and the look size; ``course_speed_m_per_s`` / ``episode_s``: overrides of the catalog's."""

    backend: str
    spec: Any
    settings: Mapping[str, Any]
    packs: Sequence[Any]
    policy: str
    policy_id: str
    imported: bool
    workers: int
    batch: int
    course_speed_m_per_s: float | None = None
    episode_s: float | None = None
    fallback_python: str | Path | None = None
    timeout_s: float | None = None
    label: str = "sim-to-sim"


def price_walker(w: WalkerPricing, num_episodes: int, seed: int, run_dir: Path, progress: ProgressFn,
                 stop: StopFn | None = None) -> MotorEvalResult:
    """``num_episodes`` seeded episodes (episode ``i`` seeded ``seed + i``) of the priced course, recorded in
    ``run_dir``; ``stop`` as the backend contract's."""
    import mujoco

    spec = w.spec
    packs = list(w.packs)
    bundle = DatapackProvider().resolve(spec.task_id, [p.id for p in packs], packs)
    setup = walker_setup(spec, w.settings, bundle, packs, w.policy, w.policy_id, w.course_speed_m_per_s,
                         w.episode_s, w.fallback_python)
    contract, course, episode_s, meter = setup.contract, setup.course, setup.episode_s, asdict(setup.meter)
    workers = max(1, min(w.workers, int(num_episodes)))
    notes = [*setup.notes, f"sim-to-sim: {contract.policy} ({contract.inference_preset} observations, "
             f"{contract.control_rate_hz:g} Hz policy, {1 / contract.physics_dt_s:g} Hz PD in MuJoCo "
             f"{mujoco.__version__}'s actuators) on {workers} process(es), "
             f"{'up to ' if stop is not None else ''}{num_episodes} episode(s) of "
             f"{course.legs or 'unlimited'} {course.leg_m:g} m leg(s) with a {course.dwell_s:g} s dwell "
             f"each (at most {episode_s:g} s) at {course.speed_m_per_s:g} m/s commanded"]
    for text in notes:
        progress(f"{w.label}: {text}", 1.0, 1.0)
    ev = WalkerEvaluation(policy=contract.onnx_path, course=course, meter=setup.meter, stress=setup.stress,
                          episode_s=episode_s, seed=int(seed))
    episodes, wall_s = evaluate_walkers(ev, int(num_episodes), workers, progress=progress, stop=stop,
                                        batch=w.batch, timeout_s=w.timeout_s)
    raw = aggregate_raw(episodes)
    power_w, heat_w = mean_power_w(raw) or 0.0, _mean_heat_power_w(episodes)
    stated = setup.card.stated_runtime
    contract_dict = contract.to_dict()
    provenance = EvalProvenance(
        evaluator="sim2sim", imported=w.imported,
        figures_from=f"MuJoCo {mujoco.__version__} sim-to-sim (the batched walker env in econmotor's "
                     "interpreter, the policy's ONNX, holosoma_inference's observations; "
                     f"{model_text(contract_dict)})",
        commanded_speed_m_per_s=course.speed_m_per_s,
        achieved_speed_m_per_s=walking_speed_m_per_s(episodes) or 0.0,
        mean_power_w=power_w, mean_mech_power_w=mechanical_from_electrical_w(
            power_w, meter["drivetrain_efficiency"], meter["idle_power_w"], heat_w), mean_heat_power_w=heat_w,
        stated_runtime_h=stated.hours if stated else None,
        stated_runtime=stated.activity if stated else None, stated_runtime_source=stated.source if stated else None)
    config = {
        "seed": int(seed), "policy": w.policy_id, "episode_length_s": episode_s, "course": asdict(course),
        "meter": meter, "datapacks": list(setup.datapack_ids),
        "stress": json.loads(json.dumps(asdict(setup.stress))),  # as evaluation.json holds it (lists)
        "contract": contract_dict, "wall_s": wall_s, "workers": workers, "mujoco": mujoco.__version__,
        "messages": notes}
    return evaluation_result(w.backend, w.policy_id, spec.task_id, episodes, spec.economics, config,
                             output_dir=run_dir, provenance=provenance)
