"""One meter per robot: a G1 trained in Holosoma and a G1 priced by the sim-to-sim evaluator are metered alike.

The same physics steps (joint forces and velocities, the base's pose) go through the training reward terms'
formulas (``econ_formulas.overlay_term_rates`` on ``cf.mechanical_power_w`` and ``base_tilt_rad``, on numpy
and on torch, the tensors Holosoma's terms see) and through the evaluator's meter (``sim2sim.step_reading``
and ``courier_formulas.meter_step``), each with the constants the backend hands it (``walker_task.meter_settings``
of the task catalog's entry): every step's energy and risk agree, idle power and the tilt margin included.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from econmotor.couriers.walker_task import meter_settings, task_settings
from econmotor.economics import courier_formulas as cf
from econmotor.motor_backend.holosoma import sim2sim
from econmotor.motor_backend.holosoma.econ_formulas import (
    base_tilt_rad,
    meter_constants,
    overlay_term_rates,
    torch_namespace,
)
from econmotor.robots import card
from econmotor.tasks import get_task

STEPS, JOINTS = 400, 29
CONTROL_DT_S, EPISODE_S = 0.02, 20.0


def _meter(task_id: str) -> dict[str, float]:
    spec = get_task(task_id)
    return meter_settings(task_id, task_settings(task_id, spec.backend_entry("holosoma"), spec.source), spec.source)


def _steps(seed: int) -> dict[str, np.ndarray]:
    """Physics steps of a walking humanoid: base tilts from upright to past a fall, about random horizontal
    axes; joint forces and velocities of either sign (braking counts), a tenth of the steps at rest."""
    rng = np.random.default_rng(seed)
    tilt = np.linspace(0.0, 1.1, STEPS)
    axis = rng.uniform(0.0, 2.0 * math.pi, STEPS)
    s = np.sin(tilt / 2.0)
    quat_wxyz = np.stack([np.cos(tilt / 2.0), s * np.cos(axis), s * np.sin(axis), np.zeros(STEPS)], axis=1)
    qpos = np.concatenate([np.tile([0.0, 0.0, 0.78], (STEPS, 1)), quat_wxyz, rng.normal(0, 0.3, (STEPS, JOINTS))],
                          axis=1)
    qfrc, qvel = rng.normal(0.0, 20.0, (STEPS, JOINTS)), rng.normal(0.0, 2.0, (STEPS, JOINTS))
    qvel[::10] = 0.0
    return {"qpos": qpos, "qfrc": qfrc, "qvel": qvel, "tilt": tilt}


def _evaluator(steps: dict[str, np.ndarray], meter: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Each step's Wh and risk as the sim-to-sim evaluator meters them (its functions, its constants)."""
    constants = sim2sim.meter_constants(sim2sim.MeterSettings(**meter), CONTROL_DT_S)
    sums = cf.MeterSums()
    energy_wh, risk = [], []
    for qpos, qfrc, qvel in zip(steps["qpos"], steps["qfrc"], steps["qvel"], strict=True):
        before_wh, before_risk = sums.energy_wh, sums.risk_sum
        cf.meter_step(sums, sim2sim.step_reading(qpos, qfrc, qvel, meter["fall_tilt_rad"], 0.0), constants, cf.PY)
        energy_wh.append(sums.energy_wh - before_wh)
        risk.append(sums.risk_sum - before_risk)
    return np.array(energy_wh), np.array(risk)


def _namespaces() -> list:
    torch = pytest.importorskip("torch")
    return [pytest.param((np, np.asarray), id="numpy"),
            pytest.param((torch_namespace(), lambda a: torch.as_tensor(a, dtype=torch.float64)), id="torch")]


@pytest.mark.parametrize("task_id", ["humanoid_locomotion_g1", "humanoid_locomotion_t1"])
@pytest.mark.parametrize("namespace", _namespaces())
def test_training_terms_meter_each_step_as_the_evaluator_does(task_id: str, namespace) -> None:
    xp, array = namespace
    meter = _meter(task_id)
    steps = _steps(seed=11)
    quat_xyzw = steps["qpos"][:, [4, 5, 6, 3]]  # Holosoma's base_quat order
    rates = overlay_term_rates(
        progress_units_per_s=array(np.zeros(STEPS)), fell=array(np.zeros(STEPS)), novelty=array(np.zeros(STEPS)),
        mechanical_w=cf.mechanical_power_w(array(steps["qfrc"]), array(steps["qvel"]), xp),
        tilt_rad=base_tilt_rad(array(quat_xyzw), xp), constants=meter_constants(meter, CONTROL_DT_S),
        episode_s=EPISODE_S, xp=xp)
    # Holosoma's reward manager adds raw * dt per step: kWh per step, and risk / T
    trained_wh = np.asarray(rates["energy_kwh"]) * CONTROL_DT_S * cf.WH_PER_KWH
    trained_risk = np.asarray(rates["risk_score"]) * EPISODE_S
    priced_wh, priced_risk = _evaluator(steps, meter)
    np.testing.assert_allclose(trained_wh, priced_wh, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(trained_risk, priced_risk, rtol=1e-9, atol=1e-12)
    # non-trivial figures compared: idle power at rest, no risk within the margin, full risk past a fall
    at_rest = meter["idle_power_w"] * CONTROL_DT_S / cf.SECONDS_PER_HOUR
    assert meter["idle_power_w"] > 0 and trained_wh[0] == pytest.approx(at_rest)
    within, fallen = steps["tilt"] < meter["tilt_margin_rad"], steps["tilt"] >= meter["fall_tilt_rad"]
    assert within.any() and np.all(trained_risk[within] == 0.0)
    assert fallen.any() and np.allclose(trained_risk[fallen], 1.0)
    assert 0.0 < trained_risk[~within & ~fallen].min() and trained_risk[~within & ~fallen].max() < 1.0


def test_the_robots_are_metered_with_the_catalogs_constants() -> None:
    """Both robots' training and evaluation read their meter from the catalog entry and the robot card it names
    (no default hides in code)."""
    for task_id in ("humanoid_locomotion_g1", "humanoid_locomotion_t1", "humanoid_wbt_g1"):
        entry = get_task(task_id).backend_entry("holosoma")
        meter = _meter(task_id)
        assert (meter["idle_power_w"], meter["tilt_margin_rad"]) == (entry["idle_power_w"], entry["tilt_margin_rad"])
        assert meter["fall_tilt_rad"] == card(entry["robot"]).fall_tilt_rad  # the robot card's fall rule
