"""The robot cards (econmotor/robots) held to Holosoma's own presets, in .venv-holosoma.

As tests/unit/couriers/test_courier_robots.py holds the Gymnasium records to
Gymnasium, a script run in .venv-holosoma reads every fact a card copies from the installed
holosoma (experiment preset: robot, simulator, randomization, rewards), holosoma_inference
(inference preset: observation, task, robot) and the shipped ONNX walkers' metadata; each must
equal the card's, and the walker tasks' locomotion reward weights (their ``locomotion`` block) must be
Holosoma's reward preset of the robot's experiment. The same script drives the card's model in
MuJoCo C and records holosoma_inference's own ``actor_obs`` rows (its ``LocomotionPolicy`` code)
for those states: the observation the card builds in JAX, in the main interpreter, equals them.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.couriers.policy_import import find_holosoma_python
from econmotor.motor_backend.holosoma.host.jobs import job_environment
from econmotor.robots import CARDS
from econmotor.robots.observation import advance_phase, build_observation, initial_phase

pytestmark = [pytest.mark.holosoma]
REPO = Path(__file__).resolve().parents[2]

# Runs in .venv-holosoma: every fact of each card as Holosoma states it, and holosoma_inference's
# observation rows for states of the card's model (a walk, a stand, a walk again: the gait phase's
# three branches).
HOLOSOMA_FACTS = r"""
import json
import mujoco
import numpy as np
from holosoma.config_values.experiment import EXPERIMENT_REGISTRY
from holosoma_inference.config.config_values.inference import INFERENCE_REGISTRY
from holosoma_inference.policies.locomotion import LocomotionPolicy
import importlib
from pathlib import Path
from econmotor.couriers.policy_import import onnx_metadata, shipped_policy_path
from econmotor.robots import CARDS
from econmotor.robots.model import joint_indices, load_model, mjcf_path

def _resolve_asset(root, relative):
    # Holosoma's asset root: a directory, or "@package/sub" inside an installed package
    if root.startswith("@"):
        package, _, rest = root[1:].partition("/")
        root = str(Path(importlib.import_module(package).__file__).parent / rest)
    return Path(root) / relative

def by_group(names, gains):
    # Holosoma's per-joint gain: the value of the (first) group name the joint name contains
    return [float(next(v for k, v in gains.items() if k in n)) for n in names]

out = {}
for name, card in CARDS.items():
    inf = INFERENCE_REGISTRY[card.inference_preset]
    exp = EXPERIMENT_REGISTRY[card.holosoma_experiment]
    robot, sim, obs = exp.robot, exp.simulator.config.sim, inf.observation
    onnx = {algo: onnx_metadata(shipped_policy_path(f"holosoma:{name}/{algo}")) for algo in ("ppo", "fastsac")}
    push = dict(exp.randomization.setup_terms["push_randomizer_state"].params)
    model = load_model(card)
    bodies = [model.body(b).name for b in range(model.nbody)]
    facts = {
        "dof_names": [list(robot.dof_names), list(inf.robot.dof_names)] + [m["dof_names"] for m in onnx.values()],
        "default_dof_angles": [list(inf.robot.default_dof_angles),
                               [robot.init_state.default_joint_angles[n] for n in robot.dof_names]],
        "kp": [by_group(robot.dof_names, robot.control.stiffness)] + [m["kp"] for m in onnx.values()],
        "kd": [by_group(robot.dof_names, robot.control.damping)] + [m["kd"] for m in onnx.values()],
        "effort_limits": [list(robot.dof_effort_limit_list)],
        "action_scale": [inf.task.policy_action_scale, robot.control.action_scale],
        "action_clip": [robot.control.action_clip_value],
        "physics_dt_s": [1.0 / sim.fps],
        "decimation": [sim.control_decimation],
        "control_rate_hz": [inf.task.rl_rate],
        "init_pos": [list(robot.init_state.pos)],
        "torso_body": [robot.torso_name],
        "foot_bodies": [[b for b in bodies if b.endswith(robot.foot_body_name)]],
        "foot_contact_bodies": [list(robot.key_bodies), [b for b in bodies if b.endswith(robot.foot_height_name)]],
        "self_collisions": [robot.asset.enable_self_collisions],
        "mjcf": [str(_resolve_asset(robot.asset.asset_root, robot.asset.xml_file))],
        "command_ranges": [{k: v for k, v in m["command_ranges"].items() if k != "heading"} for m in onnx.values()],
        "push_preset": [{k: push[k] for k in ("push_interval_s", "max_push_vel")}],
        "obs_terms": [sorted(obs.obs_dict["actor_obs"])],
        "obs_dims": [{t: obs.obs_dims[t] for t in obs.obs_dict["actor_obs"]}],
        "obs_scales": [{t: obs.obs_scales[t] for t in obs.obs_dict["actor_obs"]}],
        "history_length": [obs.history_length_dict["actor_obs"]],
        "use_phase": [inf.task.use_phase],
        "gait_period_s": [inf.task.gait_period],
    }
    facts["card_mjcf"] = str(mjcf_path(card))
    facts["rewards"] = {k: {"weight": t.weight, **dict(t.params)} for k, t in exp.reward.terms.items()}

    ref = LocomotionPolicy.__new__(LocomotionPolicy)  # its observation code, without robot SDK or inputs
    ref.config = inf
    ref._init_robot_config(inf.robot)
    ref._init_obs_config()
    ref.rl_rate = inf.task.rl_rate
    ref._init_command_components()
    ref._init_phase_components()
    ref.is_standing = False
    ref.stand_command[0, 0] = 1
    qadr, dadr, act = joint_indices(model, card)
    data = mujoco.MjData(model)
    data.qpos[0:3] = card.init_pos
    data.qpos[qadr] = card.default_dof_angles
    rng = np.random.default_rng(11)
    rows = []
    for step, (vx, yaw) in enumerate([(0.8, 0.2)] * 4 + [(0.0, 0.0)] * 2 + [(0.6, -0.4)] * 3):
        data.ctrl[act] = rng.uniform(-1, 1, card.num_dofs) * np.asarray(card.effort_limits) * 0.3
        for _ in range(card.decimation):
            mujoco.mj_step(model, data)
        action = rng.normal(size=card.num_dofs)
        ref.last_policy_action = action[None, :]
        ref.lin_vel_command[0] = (vx, 0.0)
        ref.ang_vel_command[0, 0] = yaw
        ref.update_phase_time()
        state = np.concatenate([data.qpos[0:7], data.qpos[qadr], data.qvel[0:6], data.qvel[dadr]])
        theirs = ref.prepare_obs_for_rl(state[None, :])["actor_obs"]
        rows.append({"state": state.tolist(), "vx": vx, "yaw": yaw, "action": action.tolist(),
                     "phase": ref.phase[0].tolist(), "obs": np.asarray(theirs).reshape(-1).tolist()})
    out[name] = {"facts": facts, "rows": rows}
print("@@facts " + json.dumps(out))
"""


@pytest.fixture(scope="module")
def holosoma() -> dict:
    python = find_holosoma_python(REPO / ".venv-holosoma")
    # this checkout's econmotor (the venv's editable install may point at another one)
    env = {**job_environment(), "PYTHONPATH": str(REPO / "src")}
    proc = subprocess.run([str(python), "-c", HOLOSOMA_FACTS], capture_output=True, text=True, env=env, timeout=300)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("@@facts ")), None)
    assert line is not None, proc.stdout[-2000:] + proc.stderr[-4000:]
    return json.loads(line[len("@@facts "):])


@pytest.mark.parametrize("name", sorted(CARDS))
def test_card_states_holosomas_own_presets(holosoma: dict, name: str) -> None:
    card = CARDS[name]
    facts = holosoma[name]["facts"]
    conv = card.observation
    ours = {
        "dof_names": list(card.dof_names), "default_dof_angles": list(card.default_dof_angles),
        "kp": list(card.kp), "kd": list(card.kd), "effort_limits": list(card.effort_limits),
        "action_scale": card.action_scale, "action_clip": card.action_clip, "physics_dt_s": card.physics_dt_s,
        "decimation": card.decimation, "control_rate_hz": card.control_rate_hz, "init_pos": list(card.init_pos),
        "torso_body": card.torso_body, "foot_bodies": list(card.foot_bodies),
        "foot_contact_bodies": list(card.foot_contact_bodies), "self_collisions": card.self_collisions,
        "mjcf": facts["card_mjcf"],
        "command_ranges": {k: list(v) for k, v in card.command_ranges.items()},
        "push_preset": {k: list(v) for k, v in card.push_preset.items()},
        "obs_terms": list(conv.terms), "obs_dims": dict(conv.dims), "obs_scales": dict(conv.scales),
        "history_length": conv.history_length, "use_phase": conv.use_phase, "gait_period_s": conv.gait_period_s,
    }
    for key, value in ours.items():
        for theirs in facts[key]:
            assert theirs == pytest.approx(value) if isinstance(value, float) else theirs == value, key


@pytest.mark.parametrize("name", sorted(CARDS))
def test_observation_built_in_jax_equals_holosoma_inference(holosoma: dict, name: str) -> None:
    card = CARDS[name]
    n = card.num_dofs
    obs_fn = jax.jit(lambda **s: build_observation(card, jnp, **s))
    phase_fn = jax.jit(lambda p, st, v, w: advance_phase(p, st, v, w, card, jnp))
    phase, standing = jnp.asarray(initial_phase(np), jnp.float32), jnp.asarray(False)
    for row in holosoma[name]["rows"]:
        s = np.asarray(row["state"])
        lin = jnp.asarray([row["vx"], 0.0], jnp.float32)
        phase, standing = phase_fn(phase, standing, lin, jnp.float32(row["yaw"]))
        np.testing.assert_allclose(np.asarray(phase), row["phase"], atol=1e-5)
        state = {"quat_wxyz": s[3:7], "q": s[7:7 + n], "ang_vel_body": s[10 + n:13 + n], "qd": s[13 + n:],
                 "lin_vel_cmd": lin, "ang_vel_cmd": row["yaw"], "last_action": np.asarray(row["action"]),
                 "phase": phase}
        ours = obs_fn(**{k: jnp.asarray(v, jnp.float32) for k, v in state.items()})
        np.testing.assert_allclose(np.asarray(ours), row["obs"], atol=2e-5, rtol=1e-5)


@pytest.mark.parametrize("name", sorted(CARDS))
def test_the_walker_tasks_reward_terms_are_holosomas_preset(holosoma: dict, name: str) -> None:
    """The one reward set of a robot's walker task (its locomotion block, every engine's learner) is Holosoma's."""
    from econmotor.tasks import load_catalog

    catalog = load_catalog()
    [task] = [t for t in catalog.ids() if (catalog.get(t).locomotion or {}).get("robot") == name]
    assert catalog.get(task).locomotion["rewards"] == holosoma[name]["facts"]["rewards"]
