"""SB3 trainings without TensorBoard leave nothing in the temp dir (SB3's default logger makes an
empty ``$TMPDIR/SB3-<time>`` folder at every ``learn``; they use ``quiet_logger``)."""

from __future__ import annotations

import tempfile
from pathlib import Path

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.motor_backend.factory import make_motor_backend
from econmotor.objectives import objective_from_vector
from econmotor.rl.train_sac_objective import ShadowConfig, train_sac_objective


def test_sac_trainings_make_no_sb3_folders_in_the_temp_dir(tmp_path, monkeypatch):
    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))  # where SB3's default logger makes its folder
    monkeypatch.delenv("SB3_LOGDIR", raising=False)  # (the suite's conftest sends other folders elsewhere)
    objective = objective_from_vector(ObjectiveVector.from_preset("throughput"), "throughput")
    result = make_motor_backend("dishwashing").train_policy("dishwashing", objective, [], 1, 200, 0,
                                                            output_dir=tmp_path / "run", eval_episodes=1)
    assert (Path(result.policy_id) / "run_config.json").is_file()  # trained and recorded
    shadow = train_sac_objective(ShadowConfig(env="dishwashing", total_steps=60, max_episode_steps=20,
                                              eval_episodes=0, net_arch=(8, 8), batch_size=16, learning_starts=30))
    assert shadow.model.num_timesteps == 60
    assert [p.name for p in temp.iterdir() if p.name.startswith("SB3-")] == []
