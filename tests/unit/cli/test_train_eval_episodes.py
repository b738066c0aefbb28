"""How many episodes a training run is evaluated on right after training (and priced on, when no
evaluation run follows): five by default, and after --until-deployable as many as a held-out
evaluation, so the price can carry the verdict the training stopped on."""

from econmotor.cli.options import TRAINING_EVAL_EPISODES, training_eval_episodes
from econmotor.motor_backend.selection import DEFAULT_SELECT_EPISODES


def test_until_deployable_evaluates_as_many_episodes_as_a_held_out_evaluation():
    assert training_eval_episodes(None, False, None) == TRAINING_EVAL_EPISODES == 5
    assert training_eval_episodes(None, True, None) == DEFAULT_SELECT_EPISODES
    assert training_eval_episodes(None, True, 40) == 40
    assert training_eval_episodes(3, True, 40) == 3  # asked for: as asked
    assert training_eval_episodes(0, False, None) == 0

