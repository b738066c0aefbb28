"""Sim-to-sim evaluation of imported locomotion policies (locomotion/env.py, evaluation.py).

The four policies holosoma_inference ships walk their course through the backend's evaluation
(the batched MuJoCo walker env in the main interpreter); the observation econmotor's evaluator
built at every control step (:mod:`econmotor.robots.observation` on the MuJoCo state of the card's
model, :mod:`econmotor.robots.model`) equals the one holosoma_inference's own ``LocomotionPolicy``
code builds, in .venv-holosoma, from the same states, commands and the actions the policy returned
(its last-action term is not read from the evaluator); a policy that does not fit the robot (joint
names, observation width) is a clear error naming both sides; and the evaluation's metering equals
the shared courier formulas replayed on the physics steps its rollouts recorded.
"""

from __future__ import annotations

import json
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from econmotor.couriers.physics import root_tilt_rad
from econmotor.couriers.policy_import import (
    PolicyContract,
    batched_onnx_policy,
    check_obs_size,
    find_holosoma_python,
    resolve_contract,
    robot_card_for,
)
from econmotor.economics import courier_formulas as cf
from econmotor.economics.termination import TerminationReason
from econmotor.errors import ConfigError
from econmotor.locomotion.course import CourseSettings
from econmotor.locomotion.env import WalkerBatch, run_episodes
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings
from econmotor.motor_backend.holosoma.host.backend import HolosomaBackend
from econmotor.motor_backend.holosoma.host.jobs import job_environment
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.robots import card

pytestmark = [pytest.mark.holosoma]
REPO = Path(__file__).resolve().parents[2]
SHIPPED = ("holosoma:g1_29dof/ppo", "holosoma:g1_29dof/fastsac", "holosoma:t1_29dof/ppo", "holosoma:t1_29dof/fastsac")
CHECKED = ("holosoma:g1_29dof/ppo", "holosoma:t1_29dof/fastsac")
EPISODE_S = 8.0
#: the recorded episodes: a 2 m leg with a 1 s dwell (the episode walks, stands, the gait phase's stand
#: branch, and walks again) for 7 s, a 3 kg payload; two robots stepped together (seeds 5 and 6)
COURSE = CourseSettings(2.0, 1.0, 0.8)
METER = MeterSettings(leg_distance_m=2.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.05,
                      fall_tilt_rad=0.8)
STRESS = Stress(payload_kg_range=(3.0, 3.0), initial_joint_noise_rad=0.05)
RECORDED_S, SEEDS = 7.0, (5, 6)

# Runs in .venv-holosoma: holosoma_inference's own observation code on the states, commands and returned
# actions the evaluator recorded (argv: the .npz of the recordings, {key: inference preset} as JSON).
CHECKS = r"""
import json, sys
import numpy as np
from holosoma_inference.config.config_values.inference import INFERENCE_REGISTRY
from holosoma_inference.policies.locomotion import LocomotionPolicy

recorded = np.load(sys.argv[1])
out = {}
for key, preset in json.loads(sys.argv[2]).items():
    cfg = INFERENCE_REGISTRY[preset]
    ref = LocomotionPolicy.__new__(LocomotionPolicy)  # its observation code, without robot SDK or input devices
    ref.config = cfg
    ref._init_robot_config(cfg.robot)
    ref._init_obs_config()
    ref.rl_rate = cfg.task.rl_rate
    ref._init_command_components()
    ref._init_phase_components()
    ref.is_standing = False
    ref.stand_command[0, 0] = 1
    states, commands, obs, actions = (recorded[f"{key}__{f}"] for f in ("states", "commands", "obs", "actions"))
    diffs = []
    for k in range(len(obs)):
        last = actions[k - 1] if k else np.zeros(actions.shape[1], dtype=np.float32)
        ref.last_policy_action = last[None, :].astype(np.float64)  # what the policy returned, clipped
        ref.lin_vel_command[0] = (commands[k, 0], 0.0)
        ref.ang_vel_command[0, 0] = commands[k, 1]
        ref.update_phase_time()
        theirs = ref.prepare_obs_for_rl(states[k][None, :])["actor_obs"]
        diffs.append(float(np.max(np.abs(theirs - obs[k]))))
    out[key] = {"steps": len(diffs), "max_abs_diff": max(diffs)}
print("@@checks " + json.dumps(out))
"""


@pytest.fixture(scope="module")
def python() -> Path:
    return find_holosoma_python(REPO / ".venv-holosoma")


class RecordingBatch(WalkerBatch):
    """The evaluator's env, keeping what each rollout returned (the physics steps its meter read) per episode."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.rollouts: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}

    def _rollout(self, slots: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        states, sensors = super()._rollout(slots, targets)
        for row, slot in enumerate(slots):
            self.rollouts.setdefault(self.episodes[slot].index, []).append(
                (states[row].copy(), sensors[row][:, self.walker.frc_adr].copy()))
        return states, sensors


def holosoma_state_vector(batch: WalkerBatch, slot: int) -> np.ndarray:
    """A slot's state as holosoma_inference's ``robot_state_data`` row: base pos, quat (wxyz), joint q, base
    linear velocity, body angular velocity, joint qd (``13 + 2 n``)."""
    w = batch.walker
    qpos, qvel = batch._qpos(batch.state[slot]), batch._qvel(batch.state[slot])
    return np.concatenate([qpos[0:3], qpos[3:7], qpos[w.qpos_adr], qvel[0:3], qvel[3:6], qvel[w.dof_adr]])


def record_episodes(contract: PolicyContract) -> dict:
    """Two seeded episodes of ``contract``'s policy on the recording env: per episode what each control step's
    policy call saw (holosoma state vector, command, observation row) and returned (clipped), the rollouts'
    physics steps and the episode's figures; and the evaluator model's colliders."""
    c = contract.card
    walker = WalkerModel.build(c, np.asarray(contract.kp), np.asarray(contract.kd))
    batch = RecordingBatch(walker, COURSE, METER, STRESS, RECORDED_S, len(SEEDS), contract.command_ranges)
    act = batched_onnx_policy(contract)
    steps: dict[int, list[tuple]] = {i: [] for i in range(len(SEEDS))}

    def policy(rows: np.ndarray) -> np.ndarray:
        actions = act(rows)
        for row, slot in enumerate(np.flatnonzero(batch.active())):
            returned = np.clip(np.asarray(actions[row], dtype=np.float32), -c.action_clip, c.action_clip)
            steps[batch.episodes[slot].index].append(
                (holosoma_state_vector(batch, slot), batch.command[slot].copy(), rows[row].copy(), returned))
        return actions

    episodes: dict[int, dict] = {}
    run_episodes(batch, policy, list(enumerate(SEEDS)), lambda i, ep: episodes.__setitem__(i, ep))
    m = walker.model
    colliders = [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0 and (m.geom_contype[g] or m.geom_conaffinity[g])]
    self_pairs = sum(1 for i in colliders for j in colliders if i < j and m.geom_bodyid[i] != m.geom_bodyid[j]
                     and bool(m.geom_contype[i] & m.geom_conaffinity[j] or m.geom_contype[j] & m.geom_conaffinity[i]))
    arrays = {i: {name: np.stack([s[k] for s in steps[i]]) for k, name in
                  enumerate(("states", "commands", "obs", "actions"))} for i in steps}
    return {"contract": contract, "batch": batch, "episodes": episodes, "steps": arrays,
            "colliders": len(colliders), "self_pairs": self_pairs}


@pytest.fixture(scope="module")
def recorded(python: Path) -> dict[str, dict]:
    return {name: record_episodes(resolve_contract(name, python)) for name in CHECKED}


@pytest.fixture(scope="module")
def checks(python: Path, recorded: dict[str, dict], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """holosoma_inference's observations beside the evaluator's, per recorded episode (key: policy and episode)."""
    arrays, presets = {}, {}
    for name, rec in recorded.items():
        for i, fields in rec["steps"].items():
            key = f"{name.replace(':', '_').replace('/', '_')}_{i}"
            presets[key] = rec["contract"].inference_preset
            arrays.update({f"{key}__{f}": v for f, v in fields.items()})
    path = tmp_path_factory.mktemp("recorded") / "steps.npz"
    np.savez(path, **arrays)
    proc = subprocess.run([str(python), "-c", CHECKS, str(path), json.dumps(presets)], capture_output=True, text=True,
                          env=job_environment(), timeout=300)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("@@checks ")), None)
    assert line is not None, proc.stdout[-2000:] + proc.stderr[-4000:]
    out = json.loads(line[len("@@checks "):])
    assert len(out) == len(CHECKED) * len(SEEDS)
    return out


@pytest.fixture(scope="module")
def backend(python: Path) -> HolosomaBackend:
    return HolosomaBackend(venv=python.parent.parent, eval_episode_length_s=EPISODE_S)


@pytest.mark.parametrize("policy", SHIPPED)
def test_shipped_policy_walks_its_course_without_falling(backend: HolosomaBackend, policy: str,
                                                         tmp_path: Path) -> None:
    task = "humanoid_locomotion_g1" if "g1_29dof" in policy else "humanoid_locomotion_t1"
    result = backend.evaluate_policy(policy, task, EconomicObjectiveSpec(), 2, 7, output_dir=tmp_path)
    assert [ep["termination_reason"] for ep in result.episodes] == [TerminationReason.MAX_STEPS] * 2
    assert result.raw_metrics["errors"] == 0.0
    for ep in result.episodes:
        assert ep["distance_m"] > 2.0  # walking at the commanded 1 m/s, it covers metres in 8 s
        assert ep["max_lateral_m"] < 0.5  # the heading controller keeps it on the course
    assert result.provenance.imported and result.provenance.evaluator == "sim2sim"
    assert 0.0 < result.provenance.achieved_speed_m_per_s <= result.provenance.commanded_speed_m_per_s + 0.2
    assert result.econ_metrics["mpl_units_per_hour"] > 0.0
    assert (tmp_path / "evaluation.json").is_file()


def test_observation_equals_holosoma_inferences_own(recorded: dict[str, dict], checks: dict) -> None:
    for key, got in checks.items():
        assert got["steps"] == 350, key  # 7 s at 50 Hz: every observation compared
        assert got["max_abs_diff"] == 0.0, key  # every term, the last action's included
    for name, rec in recorded.items():
        for i, ep in rec["episodes"].items():
            assert np.any(np.abs(rec["steps"][i]["actions"]) > 1e-3), name  # compared on actions the policy returned
            assert ep["legs_reached"] >= 1.0, name  # it walked, stood at the leg end and walked on
            assert np.any(rec["steps"][i]["commands"][:, 0] == 0.0), name  # the stand command was compared


def replay(rollouts: list[tuple[np.ndarray, np.ndarray]], batch: WalkerBatch) -> dict[str, float]:
    """An episode's figures from its recorded physics steps by the shared formulas (numpy), up to its first
    fall (the card's rule): units from the start's x, energy summed (the card's winding heat included), risk
    averaged over the steps."""
    w, c = batch.walker, batch.card
    states = np.concatenate([s for s, _ in rollouts])
    frc = np.concatenate([f for _, f in rollouts])
    qpos, qvel = batch._qpos(states), batch._qvel(states)
    tilt = root_tilt_rad(qpos[:, :7].T, True, np)
    fell = (tilt > c.fall_tilt_rad) | (qpos[:, 2] < c.min_base_z_m)
    n = int(np.argmax(fell)) + 1 if fell.any() else len(states)
    mech = cf.mechanical_power_w(frc[:n], qvel[:n, w.dof_adr], np)
    heat = cf.winding_heat_w(frc[:n], c.heat_coeff(), np)
    energy = cf.electrical_energy_wh(mech, METER.drivetrain_efficiency, METER.idle_power_w, c.physics_dt_s, heat)
    risk = cf.tilt_risk(tilt[:n], METER.tilt_margin_rad, METER.fall_tilt_rad, np)
    units = (np.max(qpos[:n, 0]) - c.init_pos[0]) / METER.leg_distance_m
    return {"units_completed": float(max(units, 0.0)), "energy_wh": float(np.sum(energy)),
            "risk_score": float(np.mean(risk)), "episode_length_s": n * c.physics_dt_s, "errors": float(fell.any())}


def test_metering_equals_the_shared_courier_formulas_on_recorded_steps(recorded: dict[str, dict]) -> None:
    for name, rec in recorded.items():
        batch = rec["batch"]
        for i, ep in rec["episodes"].items():
            replayed = replay(batch.rollouts[i], batch)
            for key, value in replayed.items():
                assert ep[key] == pytest.approx(value, rel=1e-9, abs=1e-12), (name, i, key)
            assert ep["units_completed"] > 0.5 and ep["energy_wh"] > 0.0, name  # non-trivial figures compared
            assert ep["stress_payload_kg"] == 3.0 and ep["termination_reason"] == TerminationReason.MAX_STEPS, name
        assert any(ep["risk_score"] > 0.0 for ep in rec["episodes"].values()), name  # a tilt past the margin too


def test_robot_collides_as_holosomas_simulator_models_it(recorded: dict[str, dict]) -> None:
    """Holosoma's G1 and T1 walkers train with enable_self_collisions=False: no two robot colliders may touch."""
    for name, rec in recorded.items():
        assert rec["contract"].card.self_collisions is False, name
        assert rec["colliders"] > 20 and rec["self_pairs"] == 0, name


def _contract(**changes) -> PolicyContract:
    g1 = card("g1_29dof")
    base = PolicyContract(policy="p.onnx", onnx_path="/x/p.onnx", input_name="actor_obs", obs_dim=g1.obs_dim,
                          action_dim=g1.num_dofs, dof_names=g1.dof_names, kp=g1.kp, kd=g1.kd, command_ranges={},
                          card=g1)
    return replace(base, **changes)


def test_wrong_observation_size_names_both_sides() -> None:
    check_obs_size(_contract(), "p.onnx")
    with pytest.raises(ConfigError) as info:
        check_obs_size(_contract(obs_dim=50), "p.onnx")
    text = str(info.value)
    width = card("g1_29dof").obs_dim
    assert "takes 50 observations" in text and f"robot card 'g1_29dof' builds {width}" in text
    assert "actions 29 + base_ang_vel 3" in text
    with pytest.raises(ConfigError, match="outputs 12 actions for 29 dof_names"):
        check_obs_size(_contract(action_dim=12), "p.onnx")


def test_joints_of_a_card_in_another_order_name_both_sides() -> None:
    names = card("t1_29dof").dof_names
    assert robot_card_for(names, "p.onnx") is card("t1_29dof")
    with pytest.raises(ConfigError) as info:
        robot_card_for((names[1], names[0], *names[2:]), "p.onnx")
    text = str(info.value)
    assert "p.onnx" in text and "robot card 't1_29dof' in another order" in text and names[0] in text


def evaluation_error(backend: HolosomaBackend, python: Path, script: str, onnx_file: Path) -> str:
    """Write ``onnx_file`` with ``script`` in Holosoma's interpreter, evaluate it, return the error's text."""
    subprocess.run([str(python), "-c", script, str(onnx_file)], check=True, env=job_environment(), timeout=120)
    with pytest.raises(Exception) as info:
        backend.evaluate_policy(str(onnx_file), "humanoid_locomotion_g1", EconomicObjectiveSpec(), 1, 0,
                                output_dir=onnx_file.parent / "eval")
    return str(info.value)


def test_onnx_whose_joints_fit_no_robot_is_a_clear_error(backend: HolosomaBackend, python: Path,
                                                          tmp_path: Path) -> None:
    """Joint names renamed in a shipped policy's metadata: the error names the policy's joints and the presets'."""
    onnx_file = tmp_path / "renamed.onnx"
    script = ("import json, sys, onnx; from econmotor.couriers.policy_import import shipped_policy_path\n"
              "m = onnx.load(str(shipped_policy_path('holosoma:g1_29dof/ppo')))\n"
              "for p in m.metadata_props:\n"
              "    if p.key == 'dof_names': p.value = json.dumps(['knee_x'] + json.loads(p.value)[1:])\n"
              "onnx.save(m, sys.argv[1])\n")
    text = evaluation_error(backend, python, script, onnx_file)
    assert "knee_x" in text and "no robot card has" in text and "g1_29dof (29 joints" in text


def test_report_prices_an_imported_policy_without_training(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from econmotor.cli import main
    from econmotor.store import Registry

    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    assert main(["report", "--task-id", "humanoid_locomotion_t1", "--motor-backend", "holosoma", "--policy",
                 "holosoma:t1_29dof/fastsac", "--eval-episodes", "1", "--db-url", url, "--output-dir", "out"]) == 0
    with Registry(url, create=False) as reg:
        runs = reg.runs(task_id="humanoid_locomotion_t1")
    assert [(r.kind, r.status, r.policy_path) for r in runs] == [("eval", "completed", "holosoma:t1_29dof/fastsac")]
    doc = json.loads(next((tmp_path / "out").glob("*.json")).read_text(encoding="utf-8"))
    assert doc["runs"]["train"] is None and doc["training_curve"] == []
    assert doc["episodes"][0]["termination_reason"] == "course_done"  # three legs, each with its dwell
    markdown = next((tmp_path / "out").glob("*.md")).read_text(encoding="utf-8")
    import mujoco

    assert "imported policy holosoma:t1_29dof/fastsac" in markdown
    assert f"MuJoCo {mujoco.__version__} sim-to-sim" in markdown  # the figures' source names its MuJoCo release
    assert "self-collisions off" in markdown  # the robot as its maker's simulator models it
    assert "m/s commanded" in markdown


def test_compare_ranks_policies_on_the_same_seeds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from econmotor.cli import main

    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    assert main(["compare", "--task-id", "humanoid_locomotion_g1", "--policy", "holosoma:g1_29dof/ppo", "--policy",
                 "holosoma:g1_29dof/fastsac", "--eval-episodes", "1", "--command-speed", "0.8", "--db-url", url,
                 "--output-dir", "cmp"]) == 0
    result = json.loads((tmp_path / "cmp" / "compare.json").read_text(encoding="utf-8"))
    ranked = result["ranking"]
    assert {r["policy"] for r in ranked} == {"holosoma:g1_29dof/ppo", "holosoma:g1_29dof/fastsac"}
    assert ranked[0]["price_usd_per_unit"] <= ranked[1]["price_usd_per_unit"]
    assert all(r["commanded_speed_m_per_s"] == 0.8 and r["falls"] == 0.0 for r in ranked)
    assert not any(r["deployable"] for r in ranked)  # 1 episode cannot clear the fall-rate bound
    assert result["summary"].startswith("no winner: none of the 2 policies is deployable")
    assert (tmp_path / "cmp" / "compare.png").stat().st_size > 0 and (tmp_path / "cmp" / "compare.md").is_file()


def test_onnx_with_the_wrong_observation_width_is_a_clear_error(backend: HolosomaBackend, python: Path,
                                                                  tmp_path: Path) -> None:
    """A policy taking 50 observations with G1's metadata: the error names its width and the card's 100."""
    onnx_file = tmp_path / "narrow.onnx"
    script = ("import sys, onnx\nfrom onnx import TensorProto, helper\n"
              "from econmotor.couriers.policy_import import shipped_policy_path\n"
              "shipped = onnx.load(str(shipped_policy_path('holosoma:g1_29dof/ppo')))\n"
              "w = helper.make_tensor('w', TensorProto.FLOAT, [50, 29], [0.0] * (50 * 29))\n"
              "graph = helper.make_graph([helper.make_node('MatMul', ['actor_obs', 'w'], ['action'])], 'narrow',\n"
              "    [helper.make_tensor_value_info('actor_obs', TensorProto.FLOAT, [1, 50])],\n"
              "    [helper.make_tensor_value_info('action', TensorProto.FLOAT, [1, 29])], [w])\n"
              "model = helper.make_model(graph, opset_imports=[helper.make_opsetid('', 13)])\n"
              "model.ir_version = shipped.ir_version\n"
              "model.metadata_props.extend(shipped.metadata_props)\n"
              "onnx.save(model, sys.argv[1])\n")
    text = evaluation_error(backend, python, script, onnx_file)
    assert "takes 50 observations" in text and "robot card 'g1_29dof' builds 100" in text



def test_two_worker_processes_give_each_seed_the_episode_one_process_gives(python: Path, tmp_path: Path) -> None:
    policy, task, kwargs = "holosoma:g1_29dof/fastsac", "humanoid_locomotion_g1", {"eval_episode_length_s": 4.0}
    one = HolosomaBackend(venv=python.parent.parent, eval_workers=1, **kwargs)
    two = HolosomaBackend(venv=python.parent.parent, eval_workers=2, **kwargs)
    a = one.evaluate_policy(policy, task, EconomicObjectiveSpec(), 3, 11, output_dir=tmp_path / "one")
    b = two.evaluate_policy(policy, task, EconomicObjectiveSpec(), 3, 11, output_dir=tmp_path / "two")
    assert a.config["workers"] == 1 and b.config["workers"] == 2
    # episode 1 of 3 is the second process's (episodes w, w + W, ...): it ran episodes too
    assert len(a.episodes) == len(b.episodes) == 3
    assert a.episodes == b.episodes  # per seed, the same floats
    assert len({ep["energy_wh"] for ep in a.episodes}) == 3  # and the seeds differ from one another


def test_a_stop_after_the_first_batch_ends_the_workers_early(python: Path, tmp_path: Path) -> None:
    backend = HolosomaBackend(venv=python.parent.parent, eval_workers=2, eval_episode_length_s=2.0)
    seen: list[int] = []

    def stop(rows: list) -> bool:
        seen.append(len(rows))
        return True

    result = backend.evaluate_policy("holosoma:g1_29dof/fastsac", "humanoid_locomotion_g1", EconomicObjectiveSpec(),
                                     60, 0, output_dir=tmp_path, stop=stop)
    # asked once, at the first batch: two workers stream episodes out of order, so the contiguous prefix
    # the stop sees can pass the batch when one worker runs ahead
    batch = backend.evaluation_batch("humanoid_locomotion_g1")
    assert len(seen) == 1 and batch <= seen[0] < 60
    assert backend.evaluation_batch("humanoid_locomotion_g1") <= len(result.episodes) < 60
