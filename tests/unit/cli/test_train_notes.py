"""The lines `train` ends with: which checkpoint it kept, and what held-out evaluations cost."""

from econmotor.cli.train import selection_note


def test_a_run_without_held_out_evaluations_does_not_count_zero_of_them():
    note = selection_note({"selection": {"why": "no held-out evaluation ran (training ended first); the last "
                                                "weights are kept",
                                         "evaluation_cost": {"count": 0, "wall_s": 0.0, "episodes": 0}}})
    assert note == "policy kept: no held-out evaluation ran (training ended first); the last weights are kept."


def test_the_cost_of_held_out_evaluations_is_said():
    note = selection_note({"selection": {"why": "the best by J", "became_deployable": {"env_steps": 50_000,
                                                                                        "wall_s": 21.4},
                                         "evaluation_cost": {"count": 2, "wall_s": 3.2, "episodes": 160}}})
    assert note == ("policy kept: the best by J. deployable on held-out episodes after 50,000 env steps (21 s); "
                    "2 held-out evaluations cost 3 s (160 episodes).")
    assert selection_note({}) is None


def test_evaluations_beside_training_are_said_to_have_run_beside_it_not_to_have_cost_it():
    cost = {"count": 3, "wall_s": 4.4, "episodes": 64, "beside_training": 3}
    note = selection_note({"selection": {"why": "the first to pass", "evaluation_cost": cost}})
    assert note == "policy kept: the first to pass. 3 held-out evaluations took 4 s, all beside training (64 episodes)."
    some = {**cost, "beside_training": 2}
    note = selection_note({"selection": {"why": "the first to pass", "evaluation_cost": some}})
    assert note.endswith("3 held-out evaluations took 4 s, 2 of them beside training (64 episodes).")
