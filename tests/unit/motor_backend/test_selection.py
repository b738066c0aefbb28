"""Evaluation-driven selection (motor_backend/selection.py) on the real hopper_courier economics and
acceptance rule: the best acceptable policy is kept, not the last; each held-out evaluation is
sequential (a hopeless one is cut short at its first look, a passing one stops once decided);
held-out seeds are apart from the report's and the post-training evaluation's."""

from __future__ import annotations

import pytest

from econmotor.cli.demo import DEMO_OBJECTIVE
from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.errors import ConfigError
from econmotor.motor_backend.capabilities import HeldOutCadence
from econmotor.motor_backend.selection import SELECTION_SEED_OFFSET, Selection, SelectionConfig, selection_for
from econmotor.motor_backend.sequential import SequentialEvaluation, judge_raw
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


# a held-out evaluation of at most 160 episodes looks after every 16; the fall rate's bounds are its
# confidence sequence at 95% (0 falls in 64 legs pass the 0.05 limit), the bootstrap ones at 99.5%
SAFE = [episode(1.2, False) for _ in range(160)]  # no fall: 76.8 legs at 64 episodes bound it at 0.042
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
    assert "training stopped once that was known" in sel.kept_reason()


def test_a_hopeless_evaluation_is_cut_short_and_a_passing_one_stops_once_decided():
    sel = selection()
    falling, _ = sel.consider(1000, evaluation(FALLING))
    assert falling.cut_short and falling.episodes == 16 and not falling.deployable and falling.outcome == "fail"
    safe, _ = sel.consider(2000, evaluation(SAFE))
    assert safe.deployable and safe.outcome == "pass" and safe.episodes == 64  # 48 (57.6 legs) were too few
    b = 4 / 0.05 - 1  # the sequence's closed form for 0 falls (economics.uncertainty.error_rate_sequence)
    assert safe.fall_rate_upper == pytest.approx(1 - (0.05 * (0.5 + 0.5 * b / (76.8 + b))) ** (1 / 76.8))
    assert 0.04 < safe.fall_rate_upper < 0.05


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
    sel.admit(sel.assess(1500, evaluation(FALLING), beside_training=True))
    resumed.restore(sel.record())
    assert resumed.best == sel.best and resumed.history == sel.history
    assert [r.beside_training for r in resumed.history] == [False, True]
    assert resumed.record()["evaluation_cost"]["beside_training"] == 1
    _, better = resumed.consider(2000, evaluation(SAFE_SLOW))  # acceptable, lower J: the earlier one stays
    assert not better and resumed.best.env_steps == 1000


# mixed evaluations: a fall among clean episodes, before the 64 episodes that would pass it fall-free. 1 fall
# passes once ~140 legs are in (117 episodes of 1.2 legs); cutting it short at the fall would lose a pass
ONE_FALL_FIRST = [episode(1.2, i == 0) for i in range(160)]
ONE_FALL_IN_BATCH = [episode(1.2, i == 9) for i in range(160)]
ONE_FALL_LATE = [episode(1.2, i == 50) for i in range(160)]
ONE_FALL_FAST = [episode(3.0, i == 3) for i in range(160)]  # 1 fall in ~481 legs: a wide margin


@pytest.mark.parametrize("rows", [ONE_FALL_FIRST, ONE_FALL_IN_BATCH, ONE_FALL_LATE, ONE_FALL_FAST],
                         ids=["first", "in-first-batch", "late", "fast"])
def test_a_passing_evaluation_with_a_fall_among_clean_episodes_runs_on_and_passes(rows):
    sel = selection()
    result, better = sel.consider(1000, evaluation(rows))
    assert result.deployable and better and result.errors == 1.0  # not cut short as hopeless at its fall
    assert result.outcome == "pass" and result.episodes > 16  # it ran past the look where it fell


# hopeless mixed evaluations: even if every episode still to run were clean, too many falls to pass
FOUR_FALLS_EARLY = [episode(1.2, i in (2, 5, 11, 14)) for i in range(160)]  # 4 falls: bound > 0.05 even at 160
EVERY_THIRD_FALLS = [episode(1.2, i % 3 == 0) for i in range(160)]


@pytest.mark.parametrize("rows", [FOUR_FALLS_EARLY, EVERY_THIRD_FALLS], ids=["four-early", "every-third"])
def test_a_hopeless_mixed_evaluation_is_cut_short_at_the_first_check(rows):
    sel = selection()
    assert not sel.judge(rows[:16] + [episode(1.2, False)] * 144, sel.config.plan.look_confidence, True)[1].deployable
    result, _ = sel.consider(1000, evaluation(rows))
    assert result.cut_short and result.episodes == 16 and not result.deployable


# ---------------------------------------------------------------- what mutation testing found unchecked
def test_a_held_out_result_carries_the_evaluations_figures():
    sel = selection()
    sel.started -= 1.0  # the run started a second before this evaluation
    result, _ = sel.consider(123_456, evaluation(SAFE))
    assert (result.env_steps, result.episodes, result.episodes_planned) == (123_456, 64, 160)  # passed at 64
    assert result.units_per_hour == pytest.approx(1.2 * 3600 / 8.0)  # 540 legs/h
    assert result.units_per_hour_low <= result.units_per_hour and result.units_per_hour_low > 100.0
    assert result.errors == 0.0 and result.eval_env_steps == 64 * 1000
    assert 0.0 <= result.eval_s <= result.wall_s and result.wall_s >= 1.0 and result.wall_s < 3600.0
    assert result.wall_s == round(result.wall_s, 3) and result.eval_s == round(result.eval_s, 3)
    assert result.fall_rate_upper == pytest.approx(0.04179, abs=1e-5)  # the confidence sequence, 0 in 76.8 legs
    assert result.status() == "@123k: deployable" and sel.status() == result.status()
    falling, _ = sel.consider(40_000, evaluation(FALLING))
    assert falling.status() == f"@40k: not deployable (fall rate<={falling.fall_rate_upper:.2f})"
    assert falling.errors == 16.0 and falling.eval_env_steps == 16 * 1000 and falling.reasons
    assert isinstance(falling.to_dict()["reasons"], list) and falling.to_dict()["reasons"] == list(falling.reasons)
    # the look's energy and price per leg, pooled as a report prices them (ratios of sums)
    assert result.energy_wh_per_unit == pytest.approx(0.05 / 1.2)
    assert falling.energy_wh_per_unit == pytest.approx(0.05 / 0.1)
    assert result.price_usd_per_unit == pytest.approx(
        judge_raw(TASK, SAFE[:64], sequential=True).pricing.aggregate.price_usd_per_unit)
    assert result.price_usd_per_unit < falling.price_usd_per_unit
    assert result.scalars() == {"held_out/fall_rate_upper95": result.fall_rate_upper,
                                "held_out/units_per_hour": result.units_per_hour,
                                "held_out/units_per_hour_low95": result.units_per_hour_low,
                                "held_out/J": result.j_mean, "held_out/deployable": 1.0,
                                "held_out/eval_s": result.eval_s,
                                "held_out/energy_wh_per_unit": result.energy_wh_per_unit}
    # a look that completed no leg has no figure per leg
    none, _ = sel.consider(50_000, evaluation([episode(0.0, True) for _ in range(160)]))
    assert none.energy_wh_per_unit is None and none.price_usd_per_unit is None
    assert "held_out/energy_wh_per_unit" not in none.scalars()


def test_the_run_record_says_every_field():
    sel = selection()
    assert sel.status() == "" and sel.kept_reason() == "no held-out evaluation ran: the last weights are kept"
    assert sel.record()["kept"] is None and sel.record()["kept_acceptable"] is False
    sel.consider(1000, evaluation(FALLING))
    assert sel.record()["kept_acceptable"] is False
    sel.consider(2000, evaluation(SAFE))
    record = sel.record()
    first = SELECTION_SEED_OFFSET
    assert {k: record[k] for k in ("every_steps", "episodes", "until_deployable", "seeds", "judged_by")} == {
        "every_steps": 1000, "episodes": 160, "until_deployable": False, "seeds": [first, first + 160],
        "judged_by": "economics.uncertainty.judge (the report's acceptance rule) at each look of a sequential "
                     "evaluation (motor_backend/sequential.py), J = mean episode_j"}
    assert record["kept"] == sel.history[1].to_dict() and record["kept_acceptable"] is True
    assert record["became_deployable"] == {"env_steps": 2000, "wall_s": sel.history[1].wall_s}
    assert record["evaluation_cost"] == {"count": 2, "episodes": 16 + 64, "env_steps": 80 * 1000,
                                         "wall_s": round(sel.history[0].eval_s + sel.history[1].eval_s, 3),
                                         "beside_training": 0}
    assert record["why"] == sel.kept_reason() == (
        f"the checkpoint at 2,000 env steps: the best J ({sel.history[1].j_mean:.4g}) of the 1 held-out "
        "evaluations that passed the task's acceptance rule (of 2)")


def test_the_kept_reason_in_words():
    sel = selection(until=True)
    sel.consider(3000, evaluation(SAFE))
    assert sel.kept_reason() == ("the checkpoint at 3,000 env steps: the first to pass the task's acceptance rule on "
                                 "64 held-out episodes (training stopped once that was known: --until-deployable)")
    sel = selection()
    sel.consider(4000, evaluation(FALLING))
    assert sel.kept_reason() == (f"the checkpoint at 4,000 env steps: none of 1 held-out evaluations passed the task's "
                                 f"acceptance rule, so the best by J ({sel.best.j_mean:.4g}) is kept; it is not "
                                 "deployable on held-out episodes")


def test_an_equal_later_evaluation_does_not_replace_the_kept_one():
    sel = selection()
    _, first = sel.consider(1000, evaluation(SAFE))
    _, again = sel.consider(2000, evaluation(SAFE))
    assert first and not again and sel.best.env_steps == 1000


def sequential(max_episodes: int = 160) -> SequentialEvaluation:
    return SequentialEvaluation(TASK, SequentialPlan(batch=16, max_episodes=max_episodes))


def test_a_full_evaluation_is_never_hopeless():
    ev = sequential()
    assert not ev.hopeless([]) and not ev.hopeless(FALLING)  # nothing left to run: not "hopeless"
    assert ev.hopeless(FALLING[:159])  # one episode left cannot rescue 159 falls
    assert not ev.hopeless(SAFE[:16])


def test_the_best_episode_is_a_fall_free_one_with_the_most_units():
    ev = sequential(80)
    rows = [episode(3.0, True)] + [episode(0.2, False)] * 14 + [episode(2.5, False)]
    # 64 more like the 2.5-leg fall-free episode: 1 fall in ~169 attempted legs passes at the looks; like the
    # 3-leg one that fell, or like a 0.2-leg one, it could not
    assert judge_raw(TASK, rows + [episode(2.5, False)] * 64, ev.plan.look_confidence, True).verdict.deployable
    assert not judge_raw(TASK, rows + [episode(0.2, False)] * 64, ev.plan.look_confidence, True).verdict.deployable
    assert not ev.hopeless(rows)


def test_selection_for_builds_the_requested_selection_and_names_its_refusal():
    sel = selection_for(TASK, OBJECTIVE, 1, 40, True, 3)
    assert sel.task is TASK and sel.objective is OBJECTIVE
    assert sel.config == SelectionConfig(every_steps=1, episodes=40, until_deployable=True, seed=3)
    with pytest.raises(ConfigError) as info:
        selection_for(TASK, OBJECTIVE, 0, 80, True, 0)
    assert (info.value.source, info.value.key, info.value.detail) == (
        "<train>", "until_deployable", "needs held-out evaluations (select_every_steps > 0)")
    with pytest.raises(ConfigError) as info:
        SelectionConfig(every_steps=0)
    assert (info.value.source, info.value.key, info.value.detail) == ("<selection>", "every_steps/episodes",
                                                                      "must be >= 1")
    SelectionConfig(every_steps=1, episodes=1)  # the smallest allowed


def test_a_status_rounds_to_thousands_of_steps_and_a_record_without_a_kept_one_restores_none():
    sel = selection()
    result, _ = sel.consider(1_500_000, evaluation(SAFE))
    assert result.status() == "@1500k: deployable"
    resumed = selection()
    resumed.restore({"evaluations": [result.to_dict()], "kept": None})
    assert resumed.history == [result] and resumed.best is None


def test_the_wall_time_share_is_in_0_1_and_comes_from_the_backends_cadence_unless_steps_are_given():
    assert SelectionConfig(max_share=1.0).max_share == 1.0  # all of the wall time is allowed
    for bad in (0.0, 1.5):
        with pytest.raises(ConfigError) as info:
            SelectionConfig(max_share=bad)
        assert str(info.value) == "<selection>: key 'max_share': must be in (0, 1]"
    cadence = HeldOutCadence(every_steps=5000, max_share=0.2)
    sel = selection_for(TASK, OBJECTIVE, None, None, False, 3, cadence)
    assert (sel.config.every_steps, sel.config.max_share, sel.config.seed) == (5000, 0.2, 3)
    record = sel.record()
    assert record["max_share"] == 0.2 and record["sequential"] == sel.config.plan.to_dict()
    default = selection_for(TASK, OBJECTIVE, None, None, False, 0)
    assert default.config.max_share is None and default.config.every_steps > 0
    exact = selection_for(TASK, OBJECTIVE, 2000, None, False, 0, cadence)
    assert (exact.config.every_steps, exact.config.max_share) == (2000, None)


def test_judge_bounds_the_fall_rate_at_its_confidence_fixed_n_or_as_a_look_and_j_is_the_episodes_mean():
    from econmotor.objectives.loader import objective_weights_vector
    from econmotor.valuation.reward_builder import episode_j

    sel, rows = selection(), SAFE[:64]  # 0 falls in 76.8 legs
    fixed, at_90, look = sel.judge(rows), sel.judge(rows, 0.90), sel.judge(rows, sequential=True)
    assert fixed[0].intervals["error_rate"].high == pytest.approx(1.0 - 0.05 ** (1.0 / 76.8))  # exact, 0.0383
    assert at_90[0].intervals["error_rate"].high == pytest.approx(1.0 - 0.10 ** (1.0 / 76.8))
    assert look[0].intervals["error_rate"].high == pytest.approx(0.04179, abs=1e-5)  # the confidence sequence
    mixed = [*SAFE[:60], episode(2.0, False), episode(0.5, True), episode(1.0, False), episode(3.0, False)]
    summaries = judge_raw(TASK, mixed).summaries
    js = [episode_j(s, objective_weights_vector(OBJECTIVE), TASK.economics) for s in summaries]
    assert len(set(js)) > 1 and sel.judge(mixed)[2] == pytest.approx(sum(js) / len(js))


class FakeClock:
    """``time`` as selection.py sees it: ``perf_counter`` reads ``now``, which a scripted evaluation moves."""

    def __init__(self, now: float) -> None:
        self.now = now

    def perf_counter(self) -> float:
        return self.now


def test_wall_and_evaluation_seconds_come_from_the_clock_and_the_share_rule_is_inclusive(monkeypatch):
    import econmotor.motor_backend.selection as selection_module

    clock = FakeClock(100.0)
    monkeypatch.setattr(selection_module, "time", clock)
    sel = Selection(TASK, OBJECTIVE, SelectionConfig(every_steps=1000, episodes=160, max_share=0.5))
    sel.started = 100.0  # the run's start (its default is read when the class is defined)
    clock.now = 110.123456  # training until the first evaluation

    def timed(rows):
        def evaluate(num_episodes, first_seed, stop):
            clock.now += 2.0  # the evaluation takes 2 s
            return evaluation(rows)(num_episodes, first_seed, stop)
        return evaluate

    result, _ = sel.consider(1000, timed(FALLING))
    assert (result.wall_s, result.eval_s) == (12.123, 2.0)  # rounded to ms, from the run's start / the evaluation's
    ended = sel.started + result.wall_s
    clock.now = ended + 2.0  # as long since the last evaluation as it took: exactly half the time at share 0.5
    assert sel.due(2000, 1000) and sel.due(2000, 1000, now=ended + 2.0)
    assert not sel.due(2000, 1000, now=ended + 1.999)
    sel.consider(2000, timed(FALLING))
    assert sel.record()["evaluation_cost"]["wall_s"] == 4.0


def test_the_last_weights_are_evaluated_at_the_end_unless_just_evaluated_deployable_or_never_due():
    sel = selection()
    assert not sel.final_due(500, 0)  # shorter than one interval: nothing evaluated, the last weights kept
    assert selection(until=True).final_due(500, 0)  # --until-deployable judges them anyway
    sel.consider(1000, evaluation(FALLING))
    assert sel.final_due(1500, 1000) and not sel.final_due(1000, 1000)  # not the weights just evaluated
    until = selection(until=True)
    until.consider(1000, evaluation(SAFE))
    assert until.should_stop and not until.final_due(1500, 1000)  # stopped deployable: nothing left to judge


def test_why_is_given_for_every_verdict_but_a_pass_and_a_full_evaluation_is_not_cut_short():
    sel = selection()
    passed, _ = sel.consider(1000, evaluation(SAFE))
    failed, _ = sel.consider(2000, evaluation(FALLING))
    ran_out, _ = sel.consider(3000, lambda n, seed, stop: SAFE[:40])
    assert passed.outcome == "pass" and passed.why == "" and passed.reasons == ()
    assert failed.outcome == "fail" and failed.why and failed.reasons
    assert ran_out.outcome != "fail" and not ran_out.deployable and ran_out.why.startswith("stopped after 40")
    # 48 fall-free legs at the first look: not enough to pass, but 16 more such episodes would be; at 32, 96 pass
    full = Selection(TASK, OBJECTIVE, SelectionConfig(every_steps=1000, episodes=32)).consider(
        1000, evaluation([episode(3.0, False) for _ in range(32)]))[0]
    assert full.deployable and full.episodes == full.episodes_planned == 32 and not full.cut_short


def test_an_evaluation_shorter_than_its_first_look_is_an_error_not_a_verdict():
    with pytest.raises(ValueError, match=r"returned 0 episodes, fewer than its first look \(16\)"):
        selection().consider(1000, lambda n, seed, stop: SAFE[:10])


def test_selection_keeps_the_checkpoint_the_objectives_own_j_prefers_with_a_priced_energy_term():
    """``energy_term: usd``: J counts energy as its bill (0.12 USD/kWh on the hopper), not as Wh. A checkpoint that
    covers more legs on 2 Wh an episode beats one that saves 1.95 Wh for fewer legs; counted in Wh it loses."""
    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.objectives import objective_from_vector
    from econmotor.valuation.reward_builder import episode_j

    priced = objective_from_vector(ObjectiveVector.from_preset("energy_saver", energy_term="usd"), "priced")
    sel = Selection(TASK, priced, SelectionConfig(every_steps=1000, episodes=160))
    far = [episode(1.2, False, energy_wh=2.0) for _ in range(160)]  # 540 legs/h, 2 Wh an episode
    frugal = [episode(1.19, False, energy_wh=0.05) for _ in range(160)]  # 535.5 legs/h, 0.05 Wh
    first, _ = sel.consider(1000, evaluation(far))
    second, better = sel.consider(2000, evaluation(frugal))
    assert first.deployable and second.deployable and not better and sel.best.env_steps == 1000
    summaries = judge_raw(TASK, far[:first.episodes]).summaries
    usd = [episode_j(s, [1, 1, 3, 1, 0], TASK.economics, "usd") for s in summaries]
    wh = [episode_j(s, [1, 1, 3, 1, 0], TASK.economics, "wh") for s in summaries]
    assert first.j_mean == pytest.approx(sum(usd) / len(usd)) and first.j_mean != pytest.approx(sum(wh) / len(wh))


class StepLearner:
    """A loop learner whose policy is the env steps it had learned: ``GOOD_AT`` is the one safe policy.

    Its snapshot's evaluation of the policy at 2,000 steps waits until learning has gone 500 steps past it
    (which it can only do beside training, not between chunks) and records the learner's steps then."""

    GOOD_AT = 2000
    policy_file = "policy.txt"
    chunk_steps = 100
    warm_start = None

    def __init__(self, beside: bool, interrupt_at: int | None = None) -> None:
        import threading

        self.env_steps, self.beside, self.interrupt_at = 0, beside, interrupt_at
        self.progressed = threading.Condition()
        self.seen_while_evaluating: list[int] = []
        self.logged_at: list[int] = []

    def learn(self, until_steps: int):
        while self.env_steps < until_steps:
            if self.interrupt_at is not None and self.env_steps >= self.interrupt_at:
                raise KeyboardInterrupt
            with self.progressed:
                self.env_steps += self.chunk_steps
                self.progressed.notify_all()
        return {"mean_return": float(self.env_steps)}

    def rows_of(self, policy_steps: int, stop) -> list[dict]:
        if policy_steps == self.GOOD_AT and self.beside:
            with self.progressed:
                self.progressed.wait_for(lambda: self.env_steps >= self.GOOD_AT + 500, timeout=30)
                self.seen_while_evaluating.append(self.env_steps)
        return evaluation(SAFE if policy_steps in self.good_at() else FALLING)(160, SELECTION_SEED_OFFSET, stop)

    def good_at(self) -> tuple[int, ...]:
        return (self.GOOD_AT,)

    def evaluate(self, num_episodes: int, first_seed: int, stop) -> list[dict]:
        return self.rows_of(self.env_steps, stop)

    def snapshot(self):
        if not self.beside:
            return None
        learner, steps = self, self.env_steps

        class Frozen:
            def evaluate(self, num_episodes: int, first_seed: int, stop) -> list[dict]:
                return learner.rows_of(steps, stop)

            def save_policy(self, directory) -> None:
                (directory / StepLearner.policy_file).write_text(str(steps))

        return Frozen()

    def save_policy(self, directory) -> None:
        (directory / self.policy_file).write_text(str(self.env_steps))

    def load_policy(self, directory) -> None:
        self.env_steps = int((directory / self.policy_file).read_text())

    def save_checkpoint(self, run_dir) -> None: ...
    def load_checkpoint(self, run_dir) -> int: return 0
    def export(self, run_dir): return None
    def status(self) -> str: return ""
    def log_scalars(self, scalars, env_steps: int) -> None:
        self.logged_at.append(env_steps)
    def timing(self) -> dict: return {}
    def close(self) -> None: ...


def run_steps(tmp_path, beside: bool, until: bool = False, interrupt_at: int | None = None):
    from econmotor.motor_backend.training_loop import TrainingLoop

    learner = StepLearner(beside, interrupt_at)
    loop = TrainingLoop(tmp_path / f"run-{beside}-{until}", "mujoco", {"task_id": "hopper_courier"}, 5000,
                        selection=selection(until))
    return learner, loop.run(learner), loop


@pytest.mark.parametrize("until", [False, True])
def test_an_evaluation_beside_training_keeps_the_policy_it_judged_as_one_between_chunks_would(tmp_path, until):
    between, outcome_between, _ = run_steps(tmp_path, beside=False, until=until)
    beside, outcome_beside, loop = run_steps(tmp_path, beside=True, until=until)
    assert beside.seen_while_evaluating and beside.seen_while_evaluating[0] >= StepLearner.GOOD_AT + 500  # in parallel
    picked = [(e["env_steps"], e["deployable"]) for e in outcome_beside.config["selection"]["evaluations"]]
    assert picked == [(e["env_steps"], e["deployable"]) for e in outcome_between.config["selection"]["evaluations"]]
    assert picked[:2] == [(1000, False), (2000, True)] and len(picked) == (2 if until else 5)
    # the kept policy is the one judged at 2,000 steps, not the weights learned while it was judged
    assert (loop.run_dir / "policy.txt").read_text() == "2000" and (loop.run_dir / "best" / "policy.txt").is_file()
    assert beside.env_steps == 2000  # the kept policy is the learner's at the end
    assert outcome_beside.config["selection"]["kept"]["env_steps"] == 2000
    # the record says which evaluations ran beside training: here all of them
    cost = {name: outcome.config["selection"]["evaluation_cost"] for name, outcome in
            (("between", outcome_between), ("beside", outcome_beside))}
    assert cost["between"]["beside_training"] == 0 and cost["beside"]["beside_training"] == len(picked)
    # each evaluation's scalars at the step of the policy it judged, not at the learner's step when it was entered
    assert beside.logged_at == between.logged_at == [step for step, _ in picked]
    if until:  # stopped once the pass was known, having learned on meanwhile; between chunks: at once
        assert between.env_steps == 2000 and outcome_between.config["trained_steps"] == 2000
        assert outcome_beside.config["trained_steps"] >= 2500


def test_an_interrupt_ends_the_evaluation_beside_training_and_leaves_no_thread(tmp_path):
    import threading

    with pytest.raises(KeyboardInterrupt):
        run_steps(tmp_path, beside=True, interrupt_at=2300)  # the evaluation of 2,000 steps waits for 2,500
    assert not [t for t in threading.enumerate() if t.name == "econmotor-held-out"]


class WarmLearner(StepLearner):
    """A StepLearner started from a shipped policy (the one at 0 steps), safe where ``safe_at`` says."""

    warm_start = "holosoma:g1_29dof/ppo"

    def __init__(self, safe_at: tuple[int, ...]) -> None:
        super().__init__(beside=False)
        self.safe_at = safe_at

    def good_at(self) -> tuple[int, ...]:
        return self.safe_at


@pytest.mark.parametrize("safe_at", [(0,), (0, 3000), (3000,)])
def test_a_warm_started_run_judges_its_start_first_and_keeps_it_unless_a_later_look_beats_it(tmp_path, safe_at):
    from econmotor.motor_backend.training_loop import TrainingLoop

    learner = WarmLearner(safe_at)
    loop = TrainingLoop(tmp_path / "run", "mujoco", {"task_id": "hopper_courier"}, 4000, selection=selection())
    record = loop.run(learner).config["selection"]
    looks = [(e["env_steps"], e["deployable"]) for e in record["evaluations"]]
    assert looks == [(0, 0 in safe_at), (1000, False), (2000, False), (3000, 3000 in safe_at), (4000, False)]
    kept = 0 if 0 in safe_at else 3000  # an equal later look does not replace the start
    assert record["kept"]["env_steps"] == kept and (loop.run_dir / "policy.txt").read_text() == str(kept)
    assert ("the policy the run started from" in record["why"]) == (kept == 0)
    cold = StepLearner(beside=False)  # no warm start: no look before any learning
    cold_record = TrainingLoop(tmp_path / "cold", "mujoco", {"task_id": "hopper_courier"}, 2000,
                               selection=selection()).run(cold).config["selection"]
    assert [e["env_steps"] for e in cold_record["evaluations"]] == [1000, 2000]
