"""Where a walker's energy goes: walking against standing, and the stance's winding heat joint by joint.

Each policy (a shipped name or an ONNX path) walks ``--episodes`` nominal episodes of the task's priced
course (seeds ``--seed`` on, the course from the start, the env a report prices with:
:mod:`econmotor.locomotion.env`), and the meter's energy is split by the course's command at each control
step: **walking** (a leg's command, above 0) and **standing** (the dwell). Per phase: its seconds per leg
walked, its mean electrical power and the winding heat in it (W), and its Wh per leg.

Then the stance's winding heat ``sum_j k_j tau_j**2`` (:func:`econmotor.economics.courier_formulas.
winding_heat_w`) is split per joint into a **static** part (``k_j mean(tau_j)**2``: the torque the stance
holds) and a **dynamic** part (``k_j var(tau_j)``: the torque that comes and goes), with the joints whose
static heat is largest: a stance whose hip rolls push against each other through the floor, or whose
weight sits on one leg, holds torque it need not.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/walker_energy_phases.py
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/walker_energy_phases.py --policies \\
        holosoma:g1_29dof/fastsac benchmarks/results/g1_objectives_price_weighted/price_weighted_s0.onnx

These are simulation results (the same for the same seeds on any machine), not timings.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

#: the smallest run (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--episodes", "1", "--episode-s", "3", "--policies", "holosoma:g1_29dof/ppo"]


def phases(policy: str, task_id: str, episodes: int, seed: int, episode_s: float | None):
    """The policy's (per-phase sums, stance torques [steps, dofs], episodes, the batch)."""
    import numpy as np

    from econmotor.couriers.policy_import import resolve_contract
    from econmotor.locomotion.env import WalkerBatch, run_episodes
    from econmotor.locomotion.evaluation import batched_onnx_policy
    from econmotor.locomotion.model import WalkerModel
    from econmotor.locomotion.stress import Stress
    from econmotor.locomotion.task import MeterSettings, course_settings, meter_settings, walker_settings
    from econmotor.tasks import get_task

    spec = get_task(task_id)
    settings = walker_settings(spec)
    contract = resolve_contract(policy)
    card = contract.card
    sums = {name: np.zeros(3) for name in ("walking", "standing")}  # control steps, Wh, heat Wh
    stance: list[np.ndarray] = []

    class PhaseBatch(WalkerBatch):
        def _meter(self, slots, states, frc):  # the meter's sums, then each step's share by phase
            energy, heat = self.sums.energy_wh[slots].copy(), self.heat_wh[slots].copy()
            fell = super()._meter(slots, states, frc)
            standing = self.command[slots, 0] <= 0.0
            for name, rows in (("standing", standing), ("walking", ~standing)):
                sums[name] += [rows.sum(), (self.sums.energy_wh[slots] - energy)[rows].sum(),
                               (self.heat_wh[slots] - heat)[rows].sum()]
            stance.append(frc[standing].reshape(-1, frc.shape[-1]))
            return fell

    batch = PhaseBatch(WalkerModel.build(card, np.asarray(contract.kp), np.asarray(contract.kd)),
                       course_settings(settings), MeterSettings(**meter_settings(task_id, settings, spec.source)),
                       Stress.from_datapacks([], card.push_preset, float(settings["sim2sim_start_joint_noise_rad"])),
                       float(episode_s or settings["sim2sim_episode_s"]), min(episodes, 8), contract.command_ranges)
    rows: list[dict] = []
    try:
        run_episodes(batch, batched_onnx_policy(contract), [(i, seed + i) for i in range(episodes)],
                     lambda i, ep: rows.append(ep))
    finally:
        batch.close()
    return sums, np.concatenate(stance), rows, batch


def main() -> None:
    import numpy as np

    from econmotor.economics.courier_formulas import SECONDS_PER_HOUR

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--policies", nargs="+", default=["holosoma:g1_29dof/fastsac", "holosoma:g1_29dof/ppo"])
    parser.add_argument("--task-id", default="humanoid_locomotion_g1")
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1000, help="the first episode's seed (compare's: 1000)")
    parser.add_argument("--episode-s", type=float, default=None, help="the time limit (default: the task's)")
    parser.add_argument("--top", type=int, default=6, help="the stance's joints listed, by static heat")
    args = parser.parse_args()
    for policy in args.policies:
        sums, tau, rows, batch = phases(policy, args.task_id, args.episodes, args.seed, args.episode_s)
        legs = max(sum(r["units_completed"] for r in rows), 1e-9)
        falls = sum(r["errors"] for r in rows)
        dt = batch.card.control_dt_s
        print(f"{policy}: {len(rows)} episodes, {legs:.1f} legs, {falls:g} falls, "
              f"{sum(r['energy_wh'] for r in rows) / legs:.3f} Wh/leg")
        for name, (steps, wh, heat_wh) in sums.items():
            hours = steps * dt / SECONDS_PER_HOUR
            if steps:
                print(f"  {name:>8}: {steps * dt / legs:5.1f} s/leg {wh / hours:6.1f} W (heat {heat_wh / hours:5.1f} W)"
                      f" {wh / legs:.3f} Wh/leg")
        if len(tau):
            k = batch._heat_coeff
            static, dynamic = k * tau.mean(axis=0) ** 2, k * tau.var(axis=0)
            names = batch.card.dof_names
            top = np.argsort(static)[::-1][:args.top]
            print(f"  stance heat: static {static.sum():.1f} W, dynamic {dynamic.sum():.1f} W; largest static: "
                  + ", ".join(f"{names[j].removesuffix('_joint')} {static[j]:.1f} ({tau[:, j].mean():+.1f} N m)"
                              for j in top))


if __name__ == "__main__":
    main()
