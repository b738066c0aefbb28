"""The mjx backend end to end on the CPU: `econmotor report --motor-backend mjx` trains, evaluates,
records and writes the reports; `econmotor train --resume` continues from a checkpoint; the
trained policy's ONNX handle equals the JAX policy; training and evaluation compile once.

MJX compiles slowly on a CPU (minutes for the hopper's PPO iteration on a loaded machine), so
every test here uses the same task, objective, num_envs and catalog hyperparameters: the first
test compiles, the others read XLA's persistent compilation cache (``ECONMOTOR_JAX_CACHE_DIR``,
kept under .pytest_cache so a second `make test` skips compilation too)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
CACHE = REPO / ".pytest_cache" / "econmotor-jax"
NUM_ENVS = "8"  # x unroll_length 20 = 160 env steps per PPO iteration


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("mjx")
    (path / "configs").symlink_to(REPO / "configs")
    return path


def econmotor(args: list[str], cwd: Path, timeout: int = 900) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "COLUMNS": "120", "ECONMOTOR_JAX_CACHE_DIR": str(CACHE),
           "XLA_FLAGS": os.environ.get("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false "
                                                     "intra_op_parallelism_threads=1")}
    env.pop("ECONMOTOR_DB_URL", None)
    result = subprocess.run([sys.executable, "-m", "econmotor", *args], cwd=cwd, env=env, capture_output=True,
                            text=True, check=False, timeout=timeout)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    return result


@pytest.mark.slow
def test_report_on_mjx_trains_evaluates_records_and_writes_reports(workdir: Path) -> None:
    out = workdir / "out"
    result = econmotor(["report", "--task-id", "hopper_courier", "--motor-backend", "mjx",
                        "--num-envs", NUM_ENVS, "--max-steps", "1600", "--eval-episodes", "2",
                        "--select-every", "800", "--select-episodes", "2", "--output-dir", str(out)], workdir)
    assert "mjx: training on CPU" in result.stderr  # the device line
    assert "/s" in result.stderr  # the progress bar's env steps/s
    assert "metric (unit)" in result.stdout
    (doc_path,) = out.glob("*.json")
    doc = json.loads(doc_path.read_text())
    assert doc_path.with_suffix(".md").read_text().startswith("# Task pricing report")
    assert "data:image/png;base64," in doc_path.with_suffix(".html").read_text()
    assert doc["backend"] == "mjx" and doc["task"]["unit"].startswith("delivery leg")
    assert doc["runs"]["train"]["status"] == "completed" and doc["runs"]["eval"]["status"] == "completed"
    assert len(doc["episodes"]) == 2 and doc["training_curve"]
    assert {"units_completed", "errors", "energy_wh", "mpl_units_per_hour", "wage_parity"} <= set(doc["episodes"][0])
    # full raw episodes: the report's eval run, and the training run's own evaluation after training (eval/)
    evaluations = sorted((workdir / "runs").rglob("evaluation.json"))
    assert len(evaluations) == 2 and sum(e.parent.name == "eval" for e in evaluations) >= 1
    for evaluation in evaluations:
        episode = json.loads(evaluation.read_text())["episodes"][0]
        for key in ("units_completed", "units_attempted", "errors", "episode_length_s", "energy_wh", "risk_score",
                    "novelty_score", "return", "length_steps", "termination_reason", "overlay_return",
                    "overlay_mpl_per_hour_raw", "overlay_mpl_per_hour_weighted", "mpl_units_per_hour",
                    "wage_parity"):
            assert key in episode, key
    (run_dir,) = [p for p in (workdir / "runs").rglob("run_config.json") if "eval" not in p.parent.name]
    config = json.loads(run_dir.read_text())
    assert config["backend"] == "mjx" and config["device"].startswith("CPU") and config["num_envs"] == 8
    assert config["timing"]["iteration_compiled_ahead"] is True  # compiled once, beside the envs' reset
    # on a CPU the hopper's body steps in MuJoCo C (cpu_physics), and the record and the report say so
    assert config["physics"].startswith("MuJoCo") and "called from JAX" in config["physics"]
    assert config["physics"] in doc["runs"]["eval"]["config"]["provenance"]["figures_from"]
    assert (run_dir.parent / "policy.onnx").is_file()
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    (events,) = (run_dir.parent / "tb").rglob("events.*")
    tags = set(EventAccumulator(str(events)).Reload().Tags()["scalars"])
    assert {"rollout/ep_rew_mean", "overlay/return", "econ/energy_wh", "train/value_loss"} <= tags
    # evaluation-driven training (selection.py): held-out evaluations at 800 and 1600 steps, the best kept
    selection = config["selection"]
    assert [e["env_steps"] for e in selection["evaluations"]] == [800, 1600] and selection["kept"]
    assert {"held_out/fall_rate_upper95", "held_out/units_per_hour", "held_out/J"} <= tags
    assert (run_dir.parent / "best" / "policy.npz").is_file() and doc["selection"]["fresh_seeds"] is True
    assert {f"overlay/{k}_{kind}" for k in config["overlay"] for kind in ("raw", "weighted")} <= tags


@pytest.mark.slow
def test_train_resume_continues_from_the_last_checkpoint(workdir: Path) -> None:
    run = workdir / "resume_run"
    base = ["train", "--task", "hopper_courier", "--backend", "mjx", "--num-envs", NUM_ENVS,
            "--eval-episodes", "0", "--output-dir", str(run)]
    econmotor([*base, "--max-steps", "320"], workdir)
    assert (run / "checkpoints" / "ckpt_320_steps.npz").is_file()
    # a complete run is left as it is (issue 13): resuming it changes nothing
    before = {p: p.stat().st_mtime_ns for p in run.rglob("*") if p.is_file()}
    assert "complete run" in econmotor([*base, "--max-steps", "640", "--resume"], workdir).stdout
    assert {p: p.stat().st_mtime_ns for p in run.rglob("*") if p.is_file()} == before
    # the state a run killed after its last checkpoint leaves behind: checkpoints, no final policy
    (run / "policy.npz").unlink()
    econmotor([*base, "--max-steps", "640", "--resume"], workdir)
    config = json.loads((run / "run_config.json").read_text())
    assert config["resumed_from_steps"] == 320 and config["max_steps"] == 640
    assert config["timing"]["iteration_compiled_ahead"] is True  # the checkpoint's state has the shapes compiled for
    assert (run / "checkpoints" / "ckpt_640_steps.npz").is_file()


@pytest.mark.slow
def test_resume_refuses_other_hyperparameters_and_policy_compiles_once(workdir: Path) -> None:
    import jax
    import jax.numpy as jnp

    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.errors import ConfigError
    from econmotor.motor_backend.factory import make_motor_backend
    from econmotor.motor_backend.mjx import ppo
    from econmotor.motor_backend.mjx.training import load_learner, read_run_config
    from econmotor.objectives.loader import objective_from_vector
    from econmotor.valuation import default_objective_vector

    backend = make_motor_backend("mjx", compilation_cache_dir=str(CACHE))
    objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), name="default")
    run = workdir / "resume_run"
    with pytest.raises(ConfigError, match="hyperparameters.learning_rate"):
        backend.train_policy("hopper_courier", objective, [], 8, 960, 0, output_dir=run, resume=True,
                             hyperparameters={"learning_rate": 0.5})
    with pytest.raises(ConfigError, match="PPO only"):
        backend.train_policy("hopper_courier", objective, [], 8, 960, 0, algorithm="sac")

    # the deployed ONNX policy equals the JAX deterministic policy on random observations
    config = read_run_config(run)
    cfg = ppo.PPOConfig.from_mapping(config["hyperparameters"])
    learner = load_learner(run, config, cfg)
    (run / "policy.onnx").unlink()  # deploy exports it again from policy.npz
    handle = backend.deploy_policy_handle(str(run))
    obs = np.random.default_rng(0).normal(0.0, 2.0, size=(64, config["obs_layout"]["obs_dim"])).astype(np.float32)
    low, high = (jnp.asarray(config["action_layout"][k], jnp.float32) for k in ("low", "high"))
    expected = ppo.deterministic_action(learner.params, learner.stats, jnp.asarray(obs), cfg, low, high)
    np.testing.assert_allclose(handle.act(obs), np.asarray(expected), atol=1e-5)
    np.testing.assert_allclose(handle.step(obs[3]), np.asarray(expected)[3], atol=1e-5)
    assert handle.metadata["task_id"] == "hopper_courier" and handle.metadata["economics"]

    # compile once: several iterations and evaluations, one executable each
    env, _ = backend.env("hopper_courier", objective)
    state = ppo.init_train_state(env, cfg, 8, seed=1)
    iteration = ppo.make_train_iteration(env, cfg, 8)
    evaluate = ppo.make_evaluate(env, cfg, backend.evaluation_batch("hopper_courier"))
    for i in range(3):
        state, _ = iteration(state)
        evaluate(state.learner.params, state.learner.stats, jax.random.PRNGKey(i))
    assert iteration._cache_size() == 1 and evaluate._cache_size() == 1
