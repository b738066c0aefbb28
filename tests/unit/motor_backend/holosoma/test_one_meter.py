"""One meter per robot: a G1 trained in Holosoma and a G1 priced by the sim-to-sim evaluator are metered alike.

The same physics steps (joint forces and velocities, the base's pose) go through the training reward terms'
formulas (``econ_formulas.overlay_term_rates`` on ``cf.mechanical_power_w`` and ``base_tilt_rad``, on numpy
and on torch, the tensors Holosoma's terms see) and through the evaluator's meter (the batched walker env's
``WalkerBatch._meter``), each with the constants the backend hands it (``locomotion.task.meter_settings``
of the task catalog's entry): every step's energy and risk agree, idle power and the tilt margin included.

The evaluator meters a control step's ``[B, decimation]`` physics steps at once; on physics steps recorded
from its own rollout (a robot standing, one walking forward, one backward, one falling mid-step, one running
away) its sums equal the shared ``courier_formulas.meter_step`` applied step by step, each robot metered up
to and including its fall and no further.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from econmotor.couriers.physics import root_tilt_rad
from econmotor.economics import courier_formulas as cf
from econmotor.locomotion.course import CourseSettings
from econmotor.locomotion.env import WalkerBatch
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings, meter_constants, meter_settings, task_settings
from econmotor.motor_backend.holosoma.econ_formulas import (
    base_tilt_rad,
    overlay_term_rates,
    torch_namespace,
)
from econmotor.robots import card
from econmotor.tasks import get_task

STEPS, JOINTS = 400, 29
EPISODE_S = 20.0
ROBOTS = {"humanoid_locomotion_g1": "g1_29dof", "humanoid_locomotion_t1": "t1_29dof"}


def _meter(task_id: str) -> dict[str, float]:
    spec = get_task(task_id)
    return meter_settings(task_id, task_settings(spec), spec.source)


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


def _batch(task_id: str, num_slots: int) -> WalkerBatch:
    """The evaluator's env of the task's robot, metered with the catalog's constants (nominal, no course end)."""
    walker = WalkerModel.build(card(ROBOTS[task_id]))
    course = CourseSettings(leg_m=10.0, dwell_s=0.0, speed_m_per_s=0.5)
    return WalkerBatch(walker, course, MeterSettings(**_meter(task_id)), Stress(), EPISODE_S, num_slots)


def _full_state(batch: WalkerBatch, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """MuJoCo's full physics state of the batch's model at a base pose and joint angles / velocities (card order)."""
    w = batch.walker
    data = mujoco.MjData(w.model)
    data.qpos[0:7], data.qpos[w.qpos_adr] = qpos[:7], qpos[7:]
    data.qvel[w.dof_adr] = qvel
    state = np.zeros(w.nstate)
    mujoco.mj_getState(w.model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return state


def _evaluator(steps: dict[str, np.ndarray], task_id: str) -> tuple[np.ndarray, np.ndarray]:
    """Each step's Wh and risk as the sim-to-sim evaluator meters them (its meter, its constants): every step
    metered alone (a step past the fall tilt included), its figures the change of the episode's sums."""
    batch = _batch(task_id, 1)
    slot = np.array([0])
    energy_wh, risk = [], []
    for qpos, qfrc, qvel in zip(steps["qpos"], steps["qfrc"], steps["qvel"], strict=True):
        before_wh, before_risk = float(batch.sums.energy_wh[0]), float(batch.sums.risk_sum[0])
        batch._meter(slot, _full_state(batch, qpos, qvel)[None, None], qfrc[None, None])
        energy_wh.append(float(batch.sums.energy_wh[0]) - before_wh)
        risk.append(float(batch.sums.risk_sum[0]) - before_risk)
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
    dt_s = card(ROBOTS[task_id]).physics_dt_s  # the evaluator meters every physics step
    steps = _steps(seed=11)
    quat_xyzw = steps["qpos"][:, [4, 5, 6, 3]]  # Holosoma's base_quat order
    heat_w = cf.winding_heat_w(array(steps["qfrc"]), array(card(ROBOTS[task_id]).heat_coeff()), xp)
    rates = overlay_term_rates(
        progress_units_per_s=array(np.zeros(STEPS)), fell=array(np.zeros(STEPS)), novelty=array(np.zeros(STEPS)),
        mechanical_w=cf.mechanical_power_w(array(steps["qfrc"]), array(steps["qvel"]), xp), heat_w=heat_w,
        tilt_rad=base_tilt_rad(array(quat_xyzw), xp), constants=meter_constants(meter, dt_s),
        episode_s=EPISODE_S, xp=xp)
    # Holosoma's reward manager adds raw * dt per step: kWh per step, and risk / T
    trained_wh = np.asarray(rates["energy_kwh"]) * dt_s * cf.WH_PER_KWH
    trained_risk = np.asarray(rates["risk_score"]) * EPISODE_S
    priced_wh, priced_risk = _evaluator(steps, task_id)
    np.testing.assert_allclose(trained_wh, priced_wh, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(trained_risk, priced_risk, rtol=1e-9, atol=1e-12)
    # non-trivial figures compared: the windings' heat a sizeable share of every step's draw (the robot card's
    # motor model), idle power and heat at rest (a step without motion), no risk within the margin, full
    # risk past a fall
    heat_wh = np.asarray(heat_w) * dt_s / cf.SECONDS_PER_HOUR
    assert np.all(heat_wh > 0.1 * trained_wh)
    at_rest = meter["idle_power_w"] * dt_s / cf.SECONDS_PER_HOUR + heat_wh[0]
    assert meter["idle_power_w"] > 0 and trained_wh[0] == pytest.approx(at_rest)
    within, fallen = steps["tilt"] < meter["tilt_margin_rad"], steps["tilt"] >= meter["fall_tilt_rad"]
    assert within.any() and np.all(trained_risk[within] == 0.0)
    assert fallen.any() and np.allclose(trained_risk[fallen], 1.0)
    assert 0.0 < trained_risk[~within & ~fallen].min() and trained_risk[~within & ~fallen].max() < 1.0


def test_the_robots_are_metered_with_the_catalogs_constants() -> None:
    """Both robots' training and evaluation read their meter from the catalog (a walker task's locomotion block,
    the whole-body tracking task's holosoma entry) and the robot card it names (no default hides in code)."""
    for task_id in ("humanoid_locomotion_g1", "humanoid_locomotion_t1", "humanoid_wbt_g1"):
        spec = get_task(task_id)
        entry = spec.locomotion or spec.backend_entry("holosoma")
        meter = _meter(task_id)
        assert (meter["idle_power_w"], meter["tilt_margin_rad"]) == (entry["idle_power_w"], entry["tilt_margin_rad"])
        assert meter["fall_tilt_rad"] == card(entry["robot"]).fall_tilt_rad  # the robot card's fall rule



class StepwiseMeter:
    """The shared formula one physics step at a time (``cf.meter_step`` on Python floats), one robot: the
    reference the evaluator's vectorised meter is held to."""

    def __init__(self, batch: WalkerBatch, best_x: float) -> None:
        self.batch, self.sums, self.fell = batch, cf.MeterSums(best_x=best_x), False

    def control_step(self, states: np.ndarray, sensors: np.ndarray) -> None:
        """Meter a control step's recorded physics steps up to and including a fall (the card's tilt or
        height, a non-finite state or a base faster than the runaway speed), none after it."""
        b, w = self.batch, self.batch.walker
        nq, nv = w.model.nq, w.model.nv
        for state, sensor in zip(states, sensors, strict=True):
            if self.fell:
                return
            qpos, qvel = state[1:1 + nq], state[1 + nq:1 + nq + nv]
            tilt = root_tilt_rad(qpos[:7].tolist(), True, cf.PY)
            speed = math.sqrt(sum(float(v) ** 2 for v in qvel[0:3]))
            self.fell = bool(tilt > b.card.fall_tilt_rad or qpos[2] < b.card.min_base_z_m
                             or not np.isfinite(state).all() or speed > b.runaway)
            mechanical = cf.mechanical_power_w(sensor[w.frc_adr].tolist(), qvel[w.dof_adr].tolist(), cf.PY)
            heat = float(cf.winding_heat_w(sensor[w.frc_adr], b.card.heat_coeff(), np))
            cf.meter_step(self.sums, cf.StepReading(x_m=float(qpos[0]), mechanical_w=mechanical, tilt_rad=tilt,
                                                    fell=self.fell, heat_w=heat), b.constants, cf.PY)


def _tilted(angle_rad: float) -> tuple[float, float, float, float]:
    """The base quaternion (w, x, y, z) rolled ``angle_rad`` about x (its tilt from upright)."""
    return (math.cos(angle_rad / 2.0), math.sin(angle_rad / 2.0), 0.0, 0.0)


@pytest.mark.parametrize("task_id", sorted(ROBOTS))
def test_the_evaluators_meter_is_the_shared_formula_step_by_step_on_recorded_steps(task_id: str) -> None:
    batch = _batch(task_id, 5)
    w, c = batch.walker, batch.card
    for slot in range(batch.n):
        batch.start(slot, slot, seed=slot)
    qpos, qvel = batch._qpos(batch.state), batch._qvel(batch.state)  # views: the starts set up below
    qvel[1, 0] = 1.0  # 1: shoved forward (the units' high-water mark rises)
    qvel[2, 0] = -1.0  # 2: shoved backward (nothing gained until it is past its start again)
    qpos[3, 3:7], qvel[3, 3] = _tilted(c.fall_tilt_rad - 0.015), 2.0  # 3: tipping over, falls inside a control step
    qvel[4, 0] = 1.5 * batch.runaway  # 4: a blow-up: runs away at its first physics step
    batch.load_state(np.arange(batch.n))
    reference = [StepwiseMeter(batch, float(batch.sums.best_x[s])) for s in range(batch.n)]
    rng = np.random.default_rng(0)
    slots, fell_in = np.arange(batch.n), {}
    for step in range(12):
        actions = np.zeros((len(slots), c.num_dofs))
        actions[slots > 0] = rng.uniform(-0.5, 0.5, (int(np.sum(slots > 0)), c.num_dofs))  # robot 0 stands still
        states, sensors = batch._rollout(slots, batch.default + c.action_scale * actions)
        assert states.shape[:2] == (len(slots), c.decimation)
        fell = batch._meter(slots, states, sensors[:, :, w.frc_adr])
        for row, slot in enumerate(slots):
            ref = reference[slot]
            ref.control_step(states[row], sensors[row])
            assert bool(fell[row]) == ref.fell, (step, slot)
            for name in ("steps", "units", "best_x", "errors", "energy_wh", "risk_sum"):
                got, want = float(getattr(batch.sums, name)[slot]), float(getattr(ref.sums, name))
                assert got == pytest.approx(want, rel=1e-12, abs=1e-15), (step, slot, name)
            if ref.fell:
                fell_in[int(slot)] = step
        batch.state[slots] = states[:, -1]
        slots = slots[~fell]  # a fallen robot's episode ends: it is stepped no further
    steps = batch.sums.steps
    # the cases were all met: standing and shoved robots up, the tipping one fell part-way through a
    # control step (its later physics steps unmetered), the runaway at its first physics step
    assert set(fell_in) == {3, 4} and fell_in[4] == 0
    assert steps[0] == steps[1] == steps[2] == 12 * c.decimation and steps[3] % c.decimation != 0
    assert steps[4] == 1 and batch.sums.errors.tolist() == [0.0, 0.0, 0.0, 1.0, 1.0]
    assert batch.sums.units[1] > 0.0 and batch.sums.units[2] < batch.sums.units[1]
    assert batch.sums.energy_wh[1] > batch.sums.energy_wh[0] > 0.0 and batch.sums.risk_sum[3] > 0.0
