"""Calibrate a robot card's winding-heat constant to the maker's stated runtime per charge.

Where no motor datasheet is published (the G1's and T1's joint motors), the card's motor model is
``k_j = a / tau_max,j`` (:func:`econmotor.robots.card.scaled_heat_model`): one constant ``a`` (W of
winding heat per N m at a joint's effort limit). Heat does not change the dynamics, so one evaluation
at ``a = 1`` gives the draw as a line in ``a``::

    P(a) = P_0 + a * H_1       (P_0: drivetrain and idle, W; H_1: sum_j tau_j^2 / tau_max,j, W per unit a)
    a    = (C / t_stated - P_0) / H_1

with ``C`` the task's battery (Wh) and ``t_stated`` the maker's runtime (h): the shipped walker on the
task's course at its default command (legs walked and their dwells stood, as priced) runs ``t_stated``
per charge. It also prints each robot's standing draw (the course's dwell) and walking draw at the
card's current constant, so a card's figure can be checked against it.

    .venv/bin/python benchmarks/motor_heat_calibration.py --episodes 16
    .venv/bin/python benchmarks/motor_heat_calibration.py --task-id humanoid_locomotion_t1 \
        --policy holosoma:t1_29dof/ppo
"""

from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np

from econmotor.config.datapacks import DatapackProvider
from econmotor.locomotion.conditions import walker_setup
from econmotor.locomotion.evaluation import WalkerEvaluation, _run
from econmotor.locomotion.task import walker_settings
from econmotor.robots.card import scaled_heat_model
from econmotor.tasks import get_task

SMOKE_ARGS: list[str] = ["--episodes", "2", "--episode-s", "4", "--stand-s", "1"]


def draw(task_id: str, policy: str, episodes: int, seed: int, heat_at_limit: float | None,
         episode_s: float | None = None) -> dict[str, float]:
    """Mean electrical, heat and mechanical power (W) over ``episodes`` of the task's course, the card's
    motor model replaced by ``scaled_heat_model(a=heat_at_limit)`` where given."""
    spec = get_task(task_id)
    settings = walker_settings(spec)
    bundle = DatapackProvider().resolve(task_id, [], [])
    setup = walker_setup(spec, settings, bundle, [], policy, episode_s=episode_s)
    contract = setup.contract
    if heat_at_limit is not None:
        card = dataclasses.replace(contract.card, motor_model=scaled_heat_model(
            contract.card.effort_limits, heat_at_limit, "calibration"))
        contract = dataclasses.replace(contract, card=card)
    ev = WalkerEvaluation(policy=contract.onnx_path, course=setup.course, meter=setup.meter, stress=setup.stress,
                          episode_s=setup.episode_s, seed=seed)
    rows: list[dict] = []
    _run(ev, list(range(episodes)), lambda i, ep: rows.append(ep), contract)
    length = np.array([r["episode_length_s"] for r in rows])
    mean = {k: float(np.sum([r[k] for r in rows] * length) / length.sum())
            for k in ("mean_power_w", "mean_heat_power_w", "mean_mech_power_w")}
    walking = float(np.sum([r["walking_s"] for r in rows]) / length.sum())
    return {**mean, "walking_share": walking, "falls": float(sum(r["errors"] for r in rows)),
            "legs": float(sum(r["units_completed"] for r in rows)),
            "energy_wh_per_leg": float(sum(r["energy_wh"] for r in rows) / max(1e-9, sum(r["units_completed"]
                                                                                          for r in rows)))}


def standing(task_id: str, policy: str, heat_at_limit: float | None, seconds: float = 20.0) -> dict[str, float]:
    """Mean electrical and heat power (W) of the robot standing still under its walker (a command of 0 m/s,
    as in the course's dwells), ``seconds`` long, nominal conditions: what the meter charges for standing."""
    from econmotor.locomotion.env import WalkerBatch, run_episodes
    from econmotor.locomotion.evaluation import batched_onnx_policy
    from econmotor.locomotion.model import WalkerModel

    spec = get_task(task_id)
    settings = walker_settings(spec)
    setup = walker_setup(spec, settings, DatapackProvider().resolve(task_id, [], []), [], policy)
    card = setup.contract.card
    if heat_at_limit is not None:
        model = scaled_heat_model(card.effort_limits, heat_at_limit, "calibration")
        card = dataclasses.replace(card, motor_model=model)
    walker = WalkerModel.build(card, np.asarray(setup.contract.kp), np.asarray(setup.contract.kd))
    course = dataclasses.replace(setup.course, speed_m_per_s=0.0)
    batch = WalkerBatch(walker, course, setup.meter, setup.stress, seconds, 2, setup.contract.command_ranges)
    rows: list[dict] = []
    run_episodes(batch, batched_onnx_policy(setup.contract), [(0, 1), (1, 2)], lambda i, ep: rows.append(ep))
    return {"stand_power_w": float(np.mean([r["mean_power_w"] for r in rows])),
            "stand_heat_w": float(np.mean([r["mean_heat_power_w"] for r in rows])),
            "stand_falls": float(sum(r["errors"] for r in rows))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task-id", default="humanoid_locomotion_g1")
    ap.add_argument("--policy", default="holosoma:g1_29dof/ppo")
    ap.add_argument("--episodes", type=int, default=16)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--episode-s", type=float, default=None, help="episode time limit (default: the task's)")
    ap.add_argument("--stand-s", type=float, default=20.0, help="seconds of standing metered")
    ap.add_argument("--stated-runtime-h", type=float, default=None,
                    help="the maker's runtime per charge (default: the robot card's)")
    args = ap.parse_args()
    spec = get_task(args.task_id)
    capacity_wh = spec.economics.battery_capacity_wh
    unit = draw(args.task_id, args.policy, args.episodes, args.seed, 1.0, args.episode_s)
    p0 = unit["mean_power_w"] - unit["mean_heat_power_w"]
    from econmotor.couriers.policy_import import resolve_contract

    card = resolve_contract(args.policy).card
    stated = args.stated_runtime_h or (card.stated_runtime.hours if card.stated_runtime else None)
    out = {"task_id": args.task_id, "policy": args.policy, "episodes": args.episodes, "battery_wh": capacity_wh,
           "P0_w": p0, "H1_w_per_a": unit["mean_heat_power_w"], "walking_share": unit["walking_share"],
           "runtime_without_heat_h": capacity_wh / p0}
    if stated:
        a = (capacity_wh / stated - p0) / unit["mean_heat_power_w"]
        out.update(stated_runtime_h=stated, target_w=capacity_wh / stated, fitted_heat_at_limit_w_per_nm=a,
                   **{f"fitted_{k}": v for k, v in standing(args.task_id, args.policy, a, args.stand_s).items()})
    if card.motor_model is not None:
        now = draw(args.task_id, args.policy, args.episodes, args.seed, None, args.episode_s)
        out.update(card_mean_power_w=now["mean_power_w"], card_heat_w=now["mean_heat_power_w"],
                   card_runtime_h=capacity_wh / now["mean_power_w"], card_wh_per_leg=now["energy_wh_per_leg"],
                   **{f"card_{k}": v for k, v in standing(args.task_id, args.policy, None, args.stand_s).items()})
    print(json.dumps(out, indent=1))
    print(f"runtime per charge: without heat {out['runtime_without_heat_h']:.3f} h, with the card's motor model "
          f"{out.get('card_runtime_h', float('nan')):.3f} h, the maker's {stated or float('nan'):g} h")


if __name__ == "__main__":
    main()
