"""Shadow mode on the real dishwashing env: both rewards by hand, and what the flip changes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from econmotor.config.econ_params import EconParams
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.envs.dishwashing import DishwashingEnv
from econmotor.networks.econ_objective_net import identity_reward_weights
from econmotor.rl.conditioning import ObjectiveConditioningWrapper
from econmotor.rl.constraint_shaping import ConstraintShaper
from econmotor.rl.shadow import ShadowRewardWrapper
from econmotor.rl.shadow_log import EPISODES_FILE, PLOT_FILE, SUMMARY_FILE, ShadowRecorder
from econmotor.tasks import get_task
from econmotor.valuation import ConstraintSet

THROUGHPUT = ObjectiveVector.from_preset("throughput")
ALL_TERMS = ObjectiveVector.from_list([2.0, 1.0, 0.5, 1.0, 0.5])
#: catastrophe-prone toy workcell: 3 catastrophic steps end the shift, no SLA termination.
CLUMSY = EconParams.preset("toy").with_overrides({"k_err": 0.6, "max_error_rate_sla": 10.0})


def make_env(flip=False, constraints=None, recorder=None, conditioned=False, params=None, objective=THROUGHPUT):
    base = DishwashingEnv(params or EconParams.preset("toy"), reward_mode="legacy")
    env = ObjectiveConditioningWrapper(base, objective, "fixed") if conditioned else base
    return ShadowRewardWrapper(env, economics=get_task("dishwashing").economics,
                               weights_for=identity_reward_weights, objective=objective,
                               use_objective_reward=flip, constraints=constraints, recorder=recorder)


def actions(n, seed=5):
    return np.random.default_rng(seed).uniform(0, 1, size=(n, 2)).astype(np.float32)


def rollout(env, acts, seed=11):
    obs0, _ = env.reset(seed=seed)
    steps = []
    for a in acts:
        obs, reward, terminated, truncated, info = env.step(a)
        steps.append({"obs": obs, "reward": reward, "info": info, "action": a})
        if terminated or truncated:
            break
    return obs0, steps


def test_both_rewards_equal_hand_computed_values_on_recorded_steps():
    # a catastrophe-prone shift: catastrophic steps happen before the one that ends it
    _, steps = rollout(make_env(params=CLUMSY, objective=ALL_TERMS), actions(300))
    catastrophic_steps = [s["info"]["step_summary"]["errors"] == s["info"]["step_summary"]["attempts"]
                          for s in steps]
    assert steps[-1]["info"]["step_summary"]["termination_reason"] == "catastrophic_error"
    assert sum(catastrophic_steps[:-1]) == 2 and catastrophic_steps[-1]
    w = np.array([2, 1, 0.5, 1, 0.5]) / 5.0
    dt_h = 60.0 / 3600.0
    units_total = errors_total = attempts_total = 0
    mpl_prev = err_rate_prev = 0.0
    cells = set()
    for t, step in enumerate(steps, start=1):
        s = step["info"]["step_summary"]
        units_total += s["units"]
        errors_total += s["errors"]
        attempts_total += s["attempts"]
        mpl_run = units_total / (t * dt_h)
        err_rate_run = errors_total / attempts_total
        err = s["errors"] / s["attempts"]
        mpl_step = s["units"] / dt_h
        wage = 0.30 * mpl_step - 1.0 * err * mpl_step  # p*MP - c_d*e*MP, toy prices
        legacy = (mpl_run - mpl_prev) - 1.0 * err - 0.1 * abs(wage / 18.0 - 1.0)
        wh = s["attempts"] * 0.05  # r_energy = -Wh (spec §7; the catalog's price is not used by default)
        ends_in_catastrophe = 1.0 if t == len(steps) else 0.0  # once, on the step that ends the shift
        speed, care = (float(x) for x in step["action"])
        cell = (min(int(speed * 5), 4), min(int(care * 5), 4))
        novelty = 0.0 if cell in cells else 1.0 / 25.0  # share of the 5x5 (speed, care) grid visited
        cells.add(cell)
        objective = (w[0] * (mpl_run - mpl_prev) - w[1] * (err_rate_run - err_rate_prev) - w[2] * wh
                     - w[3] * ends_in_catastrophe + w[4] * novelty)
        assert step["info"]["shadow"]["legacy"] == pytest.approx(legacy, rel=1e-9, abs=1e-9)
        assert step["info"]["shadow"]["objective"] == pytest.approx(objective, rel=1e-9, abs=1e-9)
        assert step["reward"] == step["info"]["shadow"]["legacy"]
        mpl_prev, err_rate_prev = mpl_run, err_rate_run


def test_episode_record_sums_terms_and_episode_j_by_hand():
    _, steps = rollout(make_env(), actions(300))
    last = steps[-1]["info"]
    record, ep = last["shadow_episode"], last["episode_summary"]
    assert record["steps"] == len(steps)
    assert record["legacy_sum"] == pytest.approx(sum(s["info"]["shadow"]["legacy"] for s in steps))
    assert record["objective_sum"] == pytest.approx(sum(s["info"]["shadow"]["objective"] for s in steps))
    units, errors, attempts = (
        sum(s["info"]["step_summary"][k] for s in steps) for k in ("units", "errors", "attempts")
    )
    hours = len(steps) * 60.0 / 3600.0
    assert record["term_totals"]["r_mpl"] == pytest.approx(units / hours, rel=1e-9)
    assert record["term_totals"]["r_error"] == pytest.approx(-errors / attempts, rel=1e-9)
    assert record["term_totals"]["r_energy"] == pytest.approx(-0.05 * attempts, rel=1e-9)
    w = np.array([2, 1, 0.5, 1, 0]) / 4.5
    catastrophic = 1.0 if ep["termination_reason"] == "catastrophic_error" else 0.0
    j = w[0] * units / hours - w[1] * errors / attempts - w[2] * 0.05 * attempts - w[3] * catastrophic
    assert record["episode_J"] == pytest.approx(j, rel=1e-9)
    assert record["econ"]["termination_reason"] == ep["termination_reason"]


PRICED = EconParams.preset("realistic").with_overrides({"energy_price_usd_per_kwh": 0.12})
ALL_TERMS_USD = ObjectiveVector.from_list(ALL_TERMS.to_list(), energy_term="usd")


@pytest.mark.parametrize("params, objective", [(EconParams.preset("toy"), ALL_TERMS), (CLUMSY, ALL_TERMS),
                                               (PRICED, ALL_TERMS), (PRICED, ALL_TERMS_USD)],
                         ids=["toy", "catastrophe_prone", "realistic_priced", "priced_energy_term_usd"])
def test_step_objective_rewards_sum_to_the_episode_j(params, objective):
    """The invariant: sum_t objective_t == combine_reward(w, build_reward_terms(episode summary))."""
    env = make_env(params=params, objective=objective)
    for episode in range(3):
        _, steps = rollout(env, actions(300, seed=episode), seed=episode)
        record = steps[-1]["info"]["shadow_episode"]
        total = sum(s["info"]["shadow"]["objective"] for s in steps)
        assert total == pytest.approx(record["episode_J"], rel=1e-6, abs=1e-9)
        assert record["objective_sum"] == pytest.approx(record["episode_J"], rel=1e-6, abs=1e-9)
        for name, value in record["episode_terms"].items():
            assert record["term_totals"][name] == pytest.approx(value, rel=1e-6, abs=1e-9), name


def test_the_flip_changes_only_which_reward_the_learner_sees():
    acts = actions(300)
    obs_a, shadow = rollout(make_env(flip=False, conditioned=True), acts)
    obs_b, flipped = rollout(make_env(flip=True, conditioned=True), acts)
    assert np.array_equal(obs_a, obs_b) and len(shadow) == len(flipped)
    for a, b in zip(shadow, flipped, strict=True):
        assert np.array_equal(a["obs"], b["obs"])
        assert a["info"]["shadow"]["legacy"] == b["info"]["shadow"]["legacy"]
        assert a["info"]["shadow"]["objective"] == b["info"]["shadow"]["objective"]
        assert a["info"]["step_summary"] == b["info"]["step_summary"]
        assert a["reward"] == a["info"]["shadow"]["legacy"]
        assert b["reward"] == b["info"]["shadow"]["objective"]
    rec_a, rec_b = shadow[-1]["info"]["shadow_episode"], flipped[-1]["info"]["shadow_episode"]
    differing = {k for k in rec_a if rec_a[k] != rec_b[k]}
    assert differing == {"flipped", "learner_sum"}
    assert rec_b["learner_sum"] == pytest.approx(rec_b["objective_sum"])


def test_constraint_penalty_changes_the_learner_reward_not_the_shadow_rewards():
    shaper = ConstraintShaper(ConstraintSet(max_error_rate=0.02), "penalty")
    acts = actions(60)
    _, plain = rollout(make_env(), acts)
    _, penalised = rollout(make_env(constraints=shaper), acts)
    for a, b in zip(plain, penalised, strict=True):
        assert a["info"]["shadow"] == {**b["info"]["shadow"], "learner": a["info"]["shadow"]["learner"]}
    # the step penalties telescope to the spec §5 penalty of the episode summary
    report = penalised[-1]["info"]["shadow_episode"]["constraints"]
    assert report["violations"]["max_error_rate"] > 0
    charged = sum(a["reward"] - b["reward"] for a, b in zip(plain, penalised, strict=True))
    assert charged == pytest.approx(10.0 * report["violations"]["max_error_rate"], rel=1e-6)


def test_recorder_writes_jsonl_summary_and_plot(tmp_path):
    recorder = ShadowRecorder(tmp_path, window=50)
    env = make_env(recorder=recorder)
    for episode in range(3):
        rollout(env, actions(300, seed=episode), seed=episode)
    summary = recorder.finish()
    lines = (tmp_path / EPISODES_FILE).read_text().splitlines()
    assert len(lines) == 3 == summary["episodes"]
    first = json.loads(lines[0])
    assert set(first["correlation"]) >= {"step_pearson", "step_spearman_window", "episode_pearson",
                                          "episode_spearman", "legacy_vs_J_pearson", "legacy_vs_J_spearman"}
    assert json.loads((tmp_path / SUMMARY_FILE).read_text())["steps"] == summary["steps"] > 0
    assert -1.0 <= summary["step_pearson"] <= 1.0
    records = [json.loads(line) for line in lines]
    legacy, j = np.array([r["legacy_sum"] for r in records]), np.array([r["episode_J"] for r in records])
    dl, dj = legacy - legacy.mean(), j - j.mean()
    assert summary["legacy_vs_J_pearson"] == pytest.approx(dl @ dj / np.sqrt((dl @ dl) * (dj @ dj)))
    assert (tmp_path / PLOT_FILE).stat().st_size > 1000
