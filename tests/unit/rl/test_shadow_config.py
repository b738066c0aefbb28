"""ShadowConfig rejects what cannot run, naming the option to fix; its SAC settings reach SAC."""

from __future__ import annotations

import pytest

from econmotor.errors import ConfigError
from econmotor.rl.train_sac_objective import ShadowConfig, eval_objectives, train_sac_objective
from econmotor.valuation import ConstraintSet


def test_bad_configs_name_the_option():
    with pytest.raises(ConfigError, match="--reward-weights"):
        ShadowConfig(reward_weights="learned")
    with pytest.raises(ConfigError, match="--objective-vector"):
        ShadowConfig(objective=(1.0, -1.0, 0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="all-zero"):
        ShadowConfig(objective=(0.0, 0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="shadow"):
        ShadowConfig(shadow=False, use_objective_reward=True)
    with pytest.raises(ConfigError, match="shadow"):
        ShadowConfig(shadow=False, constraints=ConstraintSet(max_error_rate=0.1))


def test_a_dirichlet_run_is_evaluated_under_the_three_presets_by_default():
    assert set(eval_objectives(ShadowConfig(objective_sampling="dirichlet"))) == {
        "default", "throughput", "energy_saver", "safety"}
    assert eval_objectives(ShadowConfig(objective=(2, 1, 0.5, 1, 0), objective_label="throughput")) == {
        "throughput": (2, 1, 0.5, 1, 0)}


def test_the_shipped_shadow_constraint_sets_load():
    from pathlib import Path

    from econmotor.valuation import load_constraint_set

    root = Path(__file__).resolve().parents[3] / "configs" / "constraints"
    files = sorted(root.glob("shadow_*.yaml"))
    assert len(files) >= 2
    sets = {f.stem: load_constraint_set(f) for f in files}
    assert sets["shadow_error_cap"].max_error_rate == 0.03
    assert sets["shadow_parity_energy"].energy_basis == "per_episode"


@pytest.mark.parametrize(("ent_coef", "low", "high"), [("auto", 0.5, 1.0), ("auto_0.01", 0.005, 0.0101)])
def test_the_entropy_coefficient_setting_reaches_sac(ent_coef, low, high):
    config = ShadowConfig(env="dishwashing", total_steps=120, learning_starts=100, eval_episodes=0,
                          max_episode_steps=20, net_arch=(16, 16), batch_size=16, ent_coef=ent_coef)
    model = train_sac_objective(config).model
    alpha = float(model.log_ent_coef.exp().item())  # auto-tuned: a few updates from its initial value
    assert low < alpha <= high
