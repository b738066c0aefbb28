"""A mujoco training run killed after a checkpoint resumes from it with ``--resume``."""

import os
import signal
import subprocess
import sys
import time
import zipfile

import pytest
from stable_baselines3 import PPO

from econmotor.cli import main
from econmotor.motor_backend.mujoco.training import latest_checkpoint
from econmotor.motor_backend.run_dir import read_run_config

pytestmark = pytest.mark.slow

TRAIN = """
import sys
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.objectives import EconomicObjectiveSpec
MujocoBackend().train_policy("hopper_courier", EconomicObjectiveSpec(), [], 2, 10_000_000, 0,
    output_dir=sys.argv[1], eval_episodes=0, checkpoint_every_steps=512,
    hyperparameters={"n_steps": 128, "batch_size": 64, "n_epochs": 1})
"""


def test_resume_after_kill_continues_from_the_last_checkpoint(tmp_path):
    run_dir = tmp_path / "run"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-c", TRAIN, str(run_dir)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            found = latest_checkpoint(run_dir, need_vecnormalize=True)
            if found and found[1] >= 1024:
                break
            time.sleep(0.2)
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert not (run_dir / "policy.zip").exists()  # killed mid-run: no final policy
    _, ckpt_steps = latest_checkpoint(run_dir, need_vecnormalize=True)
    # a checkpoint truncated by a kill is skipped in favour of the previous complete one
    (run_dir / "checkpoints" / f"ckpt_{ckpt_steps + 512}_steps.zip").write_bytes(b"PK\x03\x04 truncated")
    assert latest_checkpoint(run_dir, need_vecnormalize=True)[1] == ckpt_steps

    target = ckpt_steps + 1024
    assert main(["train", "--task", "hopper_courier", "--num-envs", "2", "--max-steps", str(target),
                 "--output-dir", str(run_dir), "--resume", "--eval-episodes", "1"]) == 0
    config = read_run_config(run_dir, "mujoco")
    assert config["resumed_from_steps"] == ckpt_steps and config["hyperparameters"]["n_steps"] == 128
    model = PPO.load(run_dir / "policy.zip", device="cpu")
    assert target <= model.num_timesteps < target + 2 * 128 * 2  # continued, not restarted from zero
    assert zipfile.is_zipfile(run_dir / "policy.zip") and (run_dir / "policy.onnx").is_file()


def test_resume_refuses_a_different_algorithm_or_hyperparameter(tmp_path):
    from econmotor.errors import ConfigError
    from econmotor.motor_backend.mujoco.backend import MujocoBackend
    from econmotor.objectives import EconomicObjectiveSpec

    run_dir = tmp_path / "run"
    hp = {"n_steps": 64, "batch_size": 64, "n_epochs": 1, "policy_kwargs": {"net_arch": (16, 16)}}
    backend = MujocoBackend()
    backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], 1, 64, 0, output_dir=run_dir,
                         eval_episodes=0, hyperparameters=hp)
    before = (run_dir / "run_config.json").read_text()
    with pytest.raises(ConfigError, match=r"hyperparameters\.n_steps.*trained with 64"):
        backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], 1, 256, 0, output_dir=run_dir,
                             eval_episodes=0, resume=True, hyperparameters={**hp, "n_steps": 128})
    with pytest.raises(ConfigError, match="'ppo'.*cannot switch to 'sac'"):
        backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], 1, 256, 0, output_dir=run_dir,
                             eval_episodes=0, resume=True, algorithm="sac")
    assert (run_dir / "run_config.json").read_text() == before  # nothing recorded was touched
    # the same request (tuples and all) resumes
    backend.train_policy("hopper_courier", EconomicObjectiveSpec(), [], 1, 128, 0, output_dir=run_dir,
                         eval_episodes=0, resume=True, hyperparameters=hp)
    assert read_run_config(run_dir, "mujoco")["max_steps"] == 128
