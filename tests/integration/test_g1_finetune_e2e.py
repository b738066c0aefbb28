"""The G1 courier on MJX, trained on the CPU from scratch and from Holosoma's shipped PPO walker
(``--init-policy``), exported in Holosoma's format and ranked by ``econmotor compare`` beside the
shipped walkers on the same seeds, course and conditions (the sim-to-sim evaluator, .venv-holosoma).

Before any update the initialised actor acts as the shipped ONNX does on the env's own (G1 and T1)
observations; a run still in its critic warm-up exports that same actor, so on the same seed it walks
the course as the shipped walker does.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from econmotor.couriers.onnx_actor import read_actor
from econmotor.couriers.policy_import import find_holosoma_python, shipped_policy_path
from econmotor.motor_backend.mjx import ppo
from econmotor.motor_backend.mjx.backend import MjxBackend
from econmotor.motor_backend.mjx.onnx_import import warm_start
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.robots import G1_29DOF

pytestmark = [pytest.mark.holosoma, pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]
TASK = "humanoid_locomotion_g1"
SHIPPED = "holosoma:g1_29dof/ppo"


def shipped_file(name: str = SHIPPED) -> Path:
    return shipped_policy_path(name, find_holosoma_python(REPO / ".venv-holosoma"))


@pytest.mark.parametrize(("task", "name"), [(TASK, SHIPPED), ("humanoid_locomotion_t1", "holosoma:t1_29dof/ppo")])
def test_initialised_actor_acts_as_the_shipped_onnx_on_the_envs_observations(task: str, name: str) -> None:
    import onnxruntime as ort

    backend = MjxBackend(runs_dir="unused", compilation_cache_dir=None)
    env, _ = backend.env(task, EconomicObjectiveSpec())
    cfg = backend.ppo_config(backend.settings(task), None)
    actor = read_actor(shipped_file(name), name)
    cfg, learner, notes = warm_start(actor, env, cfg, None, seed=0)
    assert (cfg.hidden_sizes, cfg.activation, cfg.normalize_obs) == ((512, 256, 128), "elu", False)
    assert cfg.critic_warmup_iterations > 0 and any(name in n for n in notes)
    state = jax.jit(env.reset, static_argnums=1)(jax.random.PRNGKey(7), 8)
    obs = np.asarray(state.obs, np.float32)
    assert obs.shape == (8, 100) and np.std(obs) > 0.05  # start poses with joint noise: rows differ
    ours = np.asarray(ppo.deterministic_action(learner.params, learner.stats, jnp.asarray(obs), cfg,
                                               jnp.asarray(env.action_low), jnp.asarray(env.action_high)))
    session = ort.InferenceSession(str(shipped_file(name)), providers=["CPUExecutionProvider"])
    theirs = np.concatenate([session.run(None, {"actor_obs": row[None]})[0] for row in obs])
    np.testing.assert_allclose(ours, theirs, rtol=1e-4, atol=1e-4)


def test_g1_trains_from_scratch_and_from_the_shipped_walker_exports_and_is_compared(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from econmotor.cli import main

    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    # one iteration of 4 envs x 20 steps; no evaluation here: compare evaluates the exported files
    train = ["train", "--task-id", TASK, "--motor-backend", "mjx", "--num-envs", "4", "--max-steps", "80",
             "--eval-episodes", "0", "--select-every", "0", "--db-url", url]
    assert main([*train, "--output-dir", "scratch"]) == 0
    assert main([*train, "--output-dir", "warm", "--init-policy", SHIPPED]) == 0
    started = json.loads((tmp_path / "warm" / "run_config.json").read_text(encoding="utf-8"))["init_policy"]
    assert started["policy"] == SHIPPED
    assert started["sha256"] == hashlib.sha256(shipped_file().read_bytes()).hexdigest()
    scratch = json.loads((tmp_path / "scratch" / "run_config.json").read_text(encoding="utf-8"))
    assert "init_policy" not in scratch and scratch["hyperparameters"]["activation"] == "tanh"

    policies = ["scratch/policy.onnx", "warm/policy.onnx", SHIPPED, "holosoma:g1_29dof/fastsac"]
    assert main(["compare", "--task-id", TASK, *[a for p in policies for a in ("--policy", p)],
                 "--eval-episodes", "1", "--db-url", url, "--output-dir", "cmp"]) == 0
    result = json.loads((tmp_path / "cmp" / "compare.json").read_text(encoding="utf-8"))
    rows = {r["policy"]: r for r in result["ranking"]}
    assert set(rows) == set(policies)
    warm, shipped = rows["warm/policy.onnx"], rows[SHIPPED]
    # still in its critic warm-up, the fine-tuned run's actor is the shipped walker's: the same walk
    assert warm["falls"] == shipped["falls"] == 0.0
    assert warm["units_per_hour"] == pytest.approx(shipped["units_per_hour"], rel=0.02)
    assert warm["wh_per_unit"] == pytest.approx(shipped["wh_per_unit"], rel=0.02)
    # one PPO iteration from nothing does not walk: it falls (its legs/h are over the seconds before the fall)
    assert rows["scratch/policy.onnx"]["falls"] == 1.0 and not rows["scratch/policy.onnx"]["deployable"]
    for run in ("scratch", "warm"):  # both exported in Holosoma's format, with what they were trained for
        meta = read_actor(tmp_path / run / "policy.onnx").metadata
        assert meta["dof_names"] == list(G1_29DOF.dof_names) and meta["kp"] == list(G1_29DOF.kp)
        assert meta["econmotor_task_id"] == TASK and meta["econmotor_objective"]["name"] == "default"
    assert read_actor(tmp_path / "warm" / "policy.onnx").metadata["econmotor_init_policy"]["policy"] == SHIPPED
