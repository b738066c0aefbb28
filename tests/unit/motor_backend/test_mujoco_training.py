"""The mujoco run's final files: ``policy.zip`` marks a complete run, so it is written last (issue 26)."""

from __future__ import annotations

import shutil
from pathlib import Path

import gymnasium as gym
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from econmotor.motor_backend.mujoco.training import POLICY_FILE, VECNORM_FILE, save_final
from econmotor.motor_backend.training_loop import install


@pytest.fixture
def model():
    venv = VecNormalize(DummyVecEnv([lambda: gym.make("Hopper-v5")]), norm_obs=True, norm_reward=False)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, device="cpu", seed=0)
    yield model
    venv.close()


def test_a_crash_while_saving_the_statistics_leaves_no_policy(model, tmp_path, monkeypatch):
    def crash(self, path):
        raise OSError("disk full")

    monkeypatch.setattr(VecNormalize, "save", crash)
    with pytest.raises(OSError, match="disk full"):
        save_final(model, tmp_path)
    # before the fix policy.zip was already in place here: a run that looked complete, without normalisation
    assert not (tmp_path / POLICY_FILE).exists() and not (tmp_path / VECNORM_FILE).exists()
    assert list(tmp_path.iterdir()) == []  # no temporary file left either


def test_the_statistics_are_written_before_the_policy(model, tmp_path, monkeypatch):
    written: list[str] = []
    real_save = PPO.save

    def spy(self, path, *args, **kwargs):
        written.append("policy" if not (tmp_path / VECNORM_FILE).exists() else "policy after statistics")
        return real_save(self, path, *args, **kwargs)

    monkeypatch.setattr(PPO, "save", spy)
    save_final(model, tmp_path)
    assert written == ["policy after statistics"]
    assert (tmp_path / POLICY_FILE).is_file() and (tmp_path / VECNORM_FILE).is_file()


def test_install_copies_the_kept_policy_statistics_first(model, tmp_path, monkeypatch):
    save_final(model, tmp_path / "best")
    copied: list[str] = []
    real_copy = shutil.copyfile
    monkeypatch.setattr(shutil, "copyfile", lambda src, dst: (copied.append(Path(src).name), real_copy(src, dst))[1])
    install(tmp_path / "best", tmp_path / "run", last=POLICY_FILE)
    assert copied == [VECNORM_FILE, POLICY_FILE]  # the file that marks a complete run last
    for name in (POLICY_FILE, VECNORM_FILE):
        assert (tmp_path / "run" / name).read_bytes() == (tmp_path / "best" / name).read_bytes()
