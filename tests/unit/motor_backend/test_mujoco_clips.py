"""Motion clips: file checks, pose-tracking reward alignment and reference-state init."""

import gymnasium as gym
import numpy as np
import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.mujoco.clips import (
    PoseTrackingWrapper,
    load_clip,
    record_clip,
    save_clip,
)


def test_replaying_the_recorded_actions_tracks_the_clip_perfectly(tmp_path):
    actions = np.random.default_rng(0).uniform(-0.3, 0.3, size=(40, 3))
    steps = iter(actions)
    path = record_clip(gym.make("Hopper-v5"), lambda obs: next(steps), 40, seed=5, path=tmp_path / "c.npz")
    clip = load_clip(path, nq=6)
    env = PoseTrackingWrapper(gym.make("Hopper-v5"), [clip], reference_init=False, seed=0)
    env.reset(seed=5)
    scores = [env.step(a)[4]["pose_tracking"] for a in actions[:30]]
    assert scores == pytest.approx([1.0] * 30)
    # a different motion scores lower
    env.reset(seed=5)
    off = [env.step(-a)[4]["pose_tracking"] for a in actions[:30]]
    assert max(off[5:]) < 0.999 and min(off) > 0.0


def test_reference_state_init_starts_in_a_clip_frame_with_its_velocity(tmp_path):
    rng = np.random.default_rng(1)
    qpos = np.cumsum(rng.normal(0, 0.01, size=(50, 6)), axis=0) + np.array([0, 1.25, 0, 0, 0, 0])
    clip = load_clip(save_clip(tmp_path / "walk.npz", qpos, fps=125.0), nq=6)
    env = PoseTrackingWrapper(gym.make("Hopper-v5"), [clip], reference_init=True, seed=0)
    starts = set()
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        data = env.unwrapped.data
        frame = int(np.argmin(np.abs(qpos[:, 1:] - data.qpos[1:]).max(axis=1)))
        assert np.allclose(data.qpos[1:], qpos[frame, 1:]) and data.qpos[0] == pytest.approx(0.0, abs=0.01)
        assert np.allclose(data.qvel, (qpos[frame + 1] - qpos[frame]) * 125.0)
        assert np.allclose(obs[:5], qpos[frame, 1:])  # the observation is of the new state
        starts.add(frame)
    assert len(starts) > 1


@pytest.mark.parametrize(("arrays", "match"), [
    ({"qpos": np.zeros((10, 4)), "fps": 30.0}, "nq = 6"),
    ({"qpos": np.zeros((10, 6))}, "'qpos' and 'fps'"),
    ({"qpos": np.full((10, 6), np.nan), "fps": 30.0}, "finite"),
])
def test_bad_clip_files_name_the_datapack_and_key(tmp_path, arrays, match):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(ConfigError, match=match) as err:
        load_clip(path, nq=6, origin="datapack 'mocap_v1'", key="motion_clips[0]")
    assert err.value.key == "motion_clips[0].path" and "mocap_v1" in str(err.value)


def test_clips_are_sampled_by_weight(tmp_path):
    rng = np.random.default_rng(2)
    base = np.array([0, 1.25, 0, 0, 0, 0])
    heavy = load_clip(save_clip(tmp_path / "a.npz", base + rng.normal(0, 0.01, (20, 6)), 125.0), 6, weight=3.0)
    never = load_clip(save_clip(tmp_path / "b.npz", base + 0.3 + rng.normal(0, 0.01, (20, 6)), 125.0), 6, weight=0.0)
    light = load_clip(save_clip(tmp_path / "c.npz", base - 0.2 + rng.normal(0, 0.01, (20, 6)), 125.0), 6, weight=1.0)
    env = PoseTrackingWrapper(gym.make("Hopper-v5"), [heavy, never, light], seed=0)
    picks = []
    for seed in range(200):
        env.reset(seed=seed)
        picks.append(env.current_clip.path)
    assert never.path not in picks
    share = picks.count(heavy.path) / len(picks)
    assert 0.65 < share < 0.85  # 3 : 1
