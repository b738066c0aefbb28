"""Per-episode raw metrics from a Holosoma evaluation recording (numpy only).

The recording (:mod:`econmotor.motor_backend.holosoma.venv.recording`) holds one row per control step of env 0. Episodes
are split where ``reset`` is set (a fall or a time-out); the first ``num_episodes``
episodes are kept (a last, unfinished one counts when fewer finished). Per episode,
with ``dt`` the control step (s) and the same formulas and constants as the training reward terms
and the sim-to-sim evaluator (:mod:`..econ_formulas`, the couriers' meter):

- ``units_completed = sum_t progress_t * dt`` (progress in units/s: velocity along the
  command / ``unit_length_m``, or 1 / ``unit_duration_s`` while tracking a clip);
- ``errors`` = falls (a reset that is not a time-out);
- ``energy_wh = sum_t P_elec,t * dt / 3600`` with ``P_elec = P_mech / efficiency + P_heat + idle_power_w``,
  ``P_mech`` from torque x joint velocity and ``P_heat`` the windings' heat (the robot card's motor model),
  each averaged over the physics sub-steps;
- ``risk_score`` = mean tilt risk; ``novelty_score`` = mean joint-space novelty;
- ``episode_length_s = steps * dt``; ``return`` = sum of Holosoma's step rewards.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.economics import courier_formulas as cf
from econmotor.economics.termination import TerminationReason
from econmotor.errors import BackendError
from econmotor.locomotion.task import meter_constants
from econmotor.motor_backend.holosoma.econ_formulas import (
    base_tilt_rad,
    commanded_progress_m_per_s,
    novelty_step,
)
from econmotor.robots import card as robot_card

REQUIRED_CHANNELS = ("dof_pos", "torques_substep", "dof_vel_substep", "root_quat_xyzw", "reset", "time_out",
                     "reward", "base_lin_vel")


def step_series(data: Any, settings: Mapping[str, Any], meter: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Per-step progress (units/s), electrical power (W), fall flag, risk and novelty of a recording
    (``meter``: the courier meter's settings, :func:`econmotor.locomotion.task.meter_settings`)."""
    c = meter_constants(meter, 0.0)  # the control step does not enter power or risk
    steps = len(data["dof_pos"])
    if settings["progress_mode"] == "time":
        progress = np.full(steps, 1.0 / float(settings["unit_duration_s"]))
    else:
        command = data["commanded_velocity"] if "commanded_velocity" in data else np.zeros((steps, 3))
        progress = commanded_progress_m_per_s(data["base_lin_vel"][:, :2], command[:, :2]) / c.leg_distance_m
    tau = data["torques_substep"]  # [steps, sub-steps, joints]
    mechanical = cf.mechanical_power_w(tau, data["dof_vel_substep"], np).mean(-1)
    heat = cf.winding_heat_w(tau, robot_card(str(settings["robot"]), "<recording>").heat_coeff(), np).mean(-1)
    power = cf.electrical_power_w(mechanical, c.drivetrain_efficiency, c.idle_power_w, heat)
    risk = cf.tilt_risk(base_tilt_rad(data["root_quat_xyzw"], np), c.tilt_margin_rad, c.fall_tilt_rad, np)
    q = data["dof_pos"].astype(np.float64)
    mean, var = q[0].copy(), np.ones_like(q[0])
    novelty = np.empty(steps)
    for t in range(steps):
        novelty[t], mean, var = novelty_step(q[t], mean, var, float(settings["novelty_rate"]))
    fell = data["reset"].astype(bool) & ~data["time_out"].astype(bool)
    return {"progress": progress, "power": power, "fell": fell, "risk": risk, "novelty": novelty,
            "reward": data["reward"].astype(np.float64), "reset": data["reset"].astype(bool),
            "time_out": data["time_out"].astype(bool)}


def episode_bounds(reset: np.ndarray, num_episodes: int) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the first ``num_episodes`` episodes (split after each reset)."""
    bounds, start = [], 0
    for end in np.nonzero(reset)[0]:
        bounds.append((start, int(end) + 1))
        start = int(end) + 1
    if start < len(reset):
        bounds.append((start, len(reset)))
    return bounds[:num_episodes]


def episodes_from_recording(path: str | Path, settings: Mapping[str, Any], meter: Mapping[str, float],
                            num_episodes: int) -> list[dict[str, Any]]:
    """Raw metrics of each evaluation episode in the recording (see the module docstring); ``settings``: the
    run's Holosoma settings, ``meter``: its courier meter's (:func:`econmotor.locomotion.task.meter_settings`)."""
    try:
        with np.load(path, allow_pickle=False) as npz:
            missing = [c for c in REQUIRED_CHANNELS if c not in npz.files]
            if missing:
                raise BackendError(f"Holosoma recording {path} lacks channels {missing}")
            data = {k: npz[k] for k in npz.files}
    except (OSError, ValueError) as exc:
        raise BackendError(f"cannot read Holosoma recording {path}: {exc}") from exc
    meta = json.loads(str(data["_metadata_json"]))
    dt = float(meta["dt"])
    series = step_series(data, settings, meter)
    episodes = []
    for start, stop in episode_bounds(series["reset"], num_episodes):
        window = slice(start, stop)
        last = stop - 1
        reason = TerminationReason.FALL if series["fell"][last] else TerminationReason.MAX_STEPS
        units = float(np.sum(series["progress"][window]) * dt)
        episodes.append({
            "units_completed": units,
            "errors": float(np.sum(series["fell"][window])),
            "episode_length_s": (stop - start) * dt,
            "length_steps": float(stop - start),
            "energy_wh": float(np.sum(series["power"][window]) * dt / 3600.0),
            "mean_power_w": float(np.mean(series["power"][window])),
            "distance_m": units * float(meter["leg_distance_m"]) if settings["progress_mode"] != "time" else 0.0,
            "risk_score": float(np.mean(series["risk"][window])),
            "novelty_score": float(np.mean(series["novelty"][window])),
            "return": float(np.sum(series["reward"][window])),
            "termination_reason": reason,
        })
    return episodes
