"""Evaluation-driven selection (motor_backend/selection.py) on the real hopper_courier economics and
acceptance rule: the best acceptable policy is kept, not the last; each held-out evaluation is
sequential (a hopeless one is cut short at its first look, a passing one stops once decided);
held-out seeds are apart from the report's and the post-training evaluation's."""

from __future__ import annotations

import pytest

from econmotor.cli.demo import DEMO_OBJECTIVE
from econmotor.motor_backend.selection import SELECTION_SEED_OFFSET, Selection, SelectionConfig, selection_for
from econmotor.objectives import load_objective_spec
from econmotor.tasks import get_task

TASK = get_task("hopper_courier")  # fall rate upper bound <= 0.05, >= 100 legs/h
OBJECTIVE = load_objective_spec(DEMO_OBJECTIVE)


def episode(legs: float, fell: bool, energy_wh: float = 0.05) -> dict:
    """One 8 s courier episode's raw metrics (a fall ends it and counts as an attempted leg)."""
    return {"units_completed": legs, "units_attempted": legs + (1.0 if fell else 0.0), "errors": 1.0 if fell else 0.0,
            "episode_length_s": 8.0, "energy_wh": energy_wh, "risk_score": 0.0, "novelty_score": 0.0,
            "return": 100.0 * legs, "length_steps": 1000.0, "termination_reason": "fall" if fell else "max_steps"}


def evaluation(rows: list[dict]):
    """An EvaluateFn handing out ``rows`` 16 at a time, asking ``stop`` after each batch, as the backends do."""

    def evaluate(num_episodes: int, first_seed: int, stop) -> list[dict]:
        assert first_seed == SELECTION_SEED_OFFSET
        out: list[dict] = []
        for row in rows[:num_episodes]:
            out.append(row)
            if len(out) % 16 == 0 and len(out) < num_episodes and stop(out):
                break
        return out

    return evaluate


# a held-out evaluation of at most 160 episodes looks at 16, 32, 64, 128 and 160, each bound at 99%
SAFE = [episode(1.2, False) for _ in range(160)]  # no fall: 153.6 legs at 128 episodes bound it at 0.030
SAFE_SLOW = [episode(1.0, False, energy_wh=0.5) for _ in range(160)]  # passes, lower J (fewer legs, more Wh)
FAST_FALLING = [episode(3.0, i % 4 == 0) for i in range(160)]  # many legs (the highest J), falls in a quarter
FALLING = [episode(0.1, True) for _ in range(160)]


def selection(until: bool = False) -> Selection:
    return Selection(TASK, OBJECTIVE, SelectionConfig(every_steps=1000, episodes=160, until_deployable=until))


def test_the_best_acceptable_policy_is_kept_not_the_last():
    sel = selection()
    outcomes = [sel.consider(steps, evaluation(rows)) for steps, rows in
                ((1000, FALLING), (2000, SAFE), (3000, SAFE_SLOW), (4000, FAST_FALLING))]
    assert [r.deployable for r, _ in outcomes] == [False, True, True, False]
    assert [better for _, better in outcomes] == [True, True, False, False]
    assert sel.best.env_steps == 2000  # not 4000, the last; not 3000, acceptable with a lower J
    assert outcomes[1][0].j_mean > outcomes[2][0].j_mean
    assert outcomes[3][0].j_mean > outcomes[1][0].j_mean  # the last has the highest J, but falls too often
    record = sel.record()
    assert record["kept"]["env_steps"] == 2000 and record["kept_acceptable"]
    assert record["became_deployable"]["env_steps"] == 2000
    assert "best J" in record["why"] and "2 held-out evaluations that passed" in record["why"]
    assert record["evaluation_cost"]["count"] == 4
    assert not sel.should_stop  # not asked to stop


def test_no_acceptable_policy_keeps_the_best_by_j_and_says_so():
    sel = selection()
    sel.consider(1000, evaluation(FALLING))
    sel.consider(2000, evaluation(FAST_FALLING))
    assert sel.best.env_steps == 2000 and not sel.best.deployable
    assert sel.record()["became_deployable"] is None
    assert "none of 2 held-out evaluations passed" in sel.kept_reason() and "best by J" in sel.kept_reason()


def test_until_deployable_stops_at_the_first_pass():
    sel = selection(until=True)
    sel.consider(1000, evaluation(FALLING))
    assert not sel.should_stop and "not deployable" in sel.status()
    sel.consider(2000, evaluation(SAFE))
    assert sel.should_stop and sel.status() == "@2k: deployable"
    assert "training stopped there" in sel.kept_reason()


def test_a_hopeless_evaluation_is_cut_short_and_a_passing_one_stops_once_decided():
    sel = selection()
    falling, _ = sel.consider(1000, evaluation(FALLING))
    assert falling.cut_short and falling.episodes == 16 and not falling.deployable and falling.outcome == "fail"
    safe, _ = sel.consider(2000, evaluation(SAFE))
    assert safe.deployable and safe.outcome == "pass" and safe.episodes == 128  # 64 (76.8 legs) were too few
    assert safe.fall_rate_upper == pytest.approx(1 - 0.01 ** (1 / 153.6))  # the look's bound, at 99%


def test_an_evaluation_that_ran_out_before_a_decision_never_passes():
    sel = selection()
    short, _ = sel.consider(1000, lambda n, seed, stop: SAFE[:40])
    assert short.cut_short and not short.deployable and short.episodes == 32  # the last look it reached


def test_the_default_cadence_keeps_held_out_evaluations_under_their_share_of_wall_time():
    sel = Selection(TASK, OBJECTIVE, SelectionConfig(every_steps=1000, episodes=160, max_share=0.1))
    sel.started = 0.0
    assert sel.due(1000, 0, now=500.0)  # the first, whenever it comes (a long compile before it buys nothing)
    sel.consider(1000, evaluation(FALLING))
    last = sel.history[-1]
    ended = sel.started + last.wall_s
    assert not sel.due(2000, 1000, now=ended + 8.9 * last.eval_s)  # it would be over 10% of the time since
    assert sel.due(2000, 1000, now=ended + 9.0 * last.eval_s + 1e-6)
    assert not sel.due(1500, 1000, now=1e9)  # and never before every_steps
    exact = Selection(TASK, OBJECTIVE, SelectionConfig(every_steps=1000, episodes=160))
    exact.consider(1000, evaluation(FALLING))
    assert exact.due(2000, 1000, now=exact.started)  # --select-every N: exactly every N steps


def test_held_out_seeds_are_apart_from_the_reports_and_the_post_training_evaluations():
    cfg = SelectionConfig(episodes=160, seed=7)
    held_out = set(range(cfg.first_seed, cfg.first_seed + cfg.episodes))
    report = set(range(7 + 1_000, 7 + 1_000 + 10_000))  # report evaluation: seed + 1000 + i (even 10,000 episodes)
    after_training = set(range(7 + 10_000, 7 + 10_000 + 1_000))
    training_envs = set(range(7, 7 + 256))  # vector env i seeded seed + i
    assert not held_out & (report | after_training | training_envs)


def test_selection_off_and_until_deployable_needs_it():
    assert selection_for(TASK, OBJECTIVE, 0, 80, False, 0) is None
    with pytest.raises(Exception, match="until_deployable"):
        selection_for(TASK, OBJECTIVE, 0, 80, True, 0)


def test_a_resumed_run_keeps_its_earlier_best_unless_beaten():
    sel = selection()
    sel.consider(1000, evaluation(SAFE))
    resumed = selection()
    resumed.restore(sel.record())
    assert resumed.best == sel.best and resumed.history == sel.history
    _, better = resumed.consider(2000, evaluation(SAFE_SLOW))  # acceptable, lower J: the earlier one stays
    assert not better and resumed.best.env_steps == 1000
