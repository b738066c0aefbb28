"""A short mjx run of a whole-course task is bounded by its ``--max-steps`` (issue 52, item 7): ``train --task-id
humanoid_locomotion_g1 --motor-backend mjx --num-envs 4 --max-steps 400`` wrote nothing in 8 minutes on a CPU, its
400 steps trained, because the default cadence (a held-out evaluation after any iteration, at most 10% of the
run's time) started a look of 16 whole-course episodes (240 s: 192,000 env steps) at the first iteration, and
queued more. Here the G1's real figures (the mjx backend's cadence, its CPU evaluation batch, the env's episode
length) meet :func:`econmotor.motor_backend.selection.fit_to_run`, which ``MjxBackend.train_policy`` calls."""

from __future__ import annotations

import pytest

from econmotor.cli.options import resolve_objective
from econmotor.motor_backend.mjx.backend import MjxBackend
from econmotor.motor_backend.selection import fit_to_run, selection_for

G1 = "humanoid_locomotion_g1"


@pytest.fixture(scope="module")
def g1():
    """The mjx backend, the G1 task, its objective, its env's episode length (control steps) and evaluation batch."""
    backend = MjxBackend()
    objective = resolve_objective(None)
    env, _ = backend.env(G1, objective, [], None)
    return backend, backend.catalog.get(G1), objective, env.max_episode_steps, backend.evaluation_batch(G1)


def selection(g1, every=None, until_deployable=False):
    backend, task, objective, _, batch = g1
    return selection_for(task, objective, every, None, until_deployable, 0, backend.held_out_cadence, batch)


def test_a_short_whole_course_run_starts_no_look_and_says_what_its_evaluation_costs(g1) -> None:
    steps = g1[3]
    assert steps == 12_000  # the whole course: 240 s at 50 Hz
    notes: list[str] = []
    assert fit_to_run(selection(g1), 400, steps, 5, notes.append) is None
    assert "no held-out selection" in notes[0] and "--select-every N" in notes[0] and "400-step run" in notes[0]
    assert "up to 60,000 env steps" in notes[1] and "--eval-episodes 0 skips it" in notes[1]


def test_what_was_asked_for_or_a_run_that_pays_for_its_looks_keeps_its_selection(g1) -> None:
    steps = g1[3]
    notes: list[str] = []
    for asked in (selection(g1, every=80), selection(g1, until_deployable=True)):
        assert fit_to_run(asked, 400, steps, 0, notes.append) is asked
    default = selection(g1)
    assert fit_to_run(default, 10_000_000, steps, 5, notes.append) is default  # the catalog's run: looks cost <10%
    assert notes == []
