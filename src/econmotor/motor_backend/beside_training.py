"""Held-out evaluations beside training: a learner's :class:`PolicySnapshot` and the one thread that evaluates
the snapshots in the order they were taken.

A learner that gives snapshots (:meth:`~econmotor.motor_backend.training_loop.Learner.snapshot`: the mjx
backend's, whose compiled evaluation leaves the GIL) is judged while it learns on:
:class:`~econmotor.motor_backend.training_loop.TrainingLoop` queues a snapshot here (:class:`BesideTraining`,
at most :data:`MAX_BACKLOG` waiting or running) and enters each result after the chunk it ended in, so the same
policies are judged as between chunks and the kept one is the snapshot that passed, not the weights learned
while it was judged.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path
from typing import Any

from econmotor.motor_backend.base import StopFn
from econmotor.motor_backend.selection import HeldOutResult, Selection

#: held-out evaluations beside training that may wait or run at once (:class:`BesideTraining`)
MAX_BACKLOG = 4


class PolicySnapshot:
    """A learner's policy at one moment (``Learner.snapshot``): evaluated and saved while learning goes on."""

    def evaluate(self, num_episodes: int, first_seed: int, stop: StopFn) -> list[dict[str, Any]]:
        """As ``Learner.evaluate``, of the frozen policy."""
        raise NotImplementedError

    def save_policy(self, directory: Path) -> None:
        """As ``Learner.save_policy``, of the frozen policy."""
        raise NotImplementedError


class BesideTraining:
    """Held-out evaluations of snapshots, assessed in the order they were taken by one thread while the
    learner learns on; the loop enters each finished one into the selection (``TrainingLoop._settle``).

    At most :data:`MAX_BACKLOG` wait or run at once: taking one more first waits for the oldest, so a run
    whose evaluations are slower than its training learns no further than that ahead of them."""

    def __init__(self, selection: Selection) -> None:
        self.selection, self.cancel = selection, threading.Event()
        self.todo: queue.Queue[tuple[int, PolicySnapshot] | None] = queue.Queue()
        self.done: list[tuple[PolicySnapshot, HeldOutResult | None, BaseException | None]] = []
        self.ended = threading.Condition()
        self.taken = self.returned = 0
        # not a daemon: an interpreter never exits under a running XLA computation
        self.thread = threading.Thread(target=self._work, name="econmotor-held-out", daemon=False)
        self.thread.start()

    def _work(self) -> None:
        while (item := self.todo.get()) is not None:
            env_steps, snapshot = item
            if self.cancel.is_set():  # closing: what is queued is not evaluated
                continue

            def evaluate(num_episodes: int, first_seed: int, stop: StopFn, snapshot=snapshot) -> list[dict[str, Any]]:
                return snapshot.evaluate(num_episodes, first_seed, lambda rows: self.cancel.is_set() or stop(rows))

            result, error = None, None
            try:
                result = self.selection.assess(env_steps, evaluate, beside_training=True)
            except BaseException as exc:  # raised in the loop's thread when it enters this evaluation
                error = exc
            with self.ended:
                self.done.append((snapshot, result, error))
                self.ended.notify_all()

    def take(self, env_steps: int, snapshot: PolicySnapshot) -> None:
        """Queue the evaluation of ``snapshot``, taken at ``env_steps``."""
        self.taken += 1
        self.todo.put((env_steps, snapshot))

    def finished(self, wait_for: int = 0) -> list[tuple[PolicySnapshot, HeldOutResult]]:
        """The evaluations ended since the last call, in order, once at least ``wait_for`` have ended in all;
        an evaluation's error is raised here."""
        with self.ended:
            self.ended.wait_for(lambda: len(self.done) >= min(wait_for, self.taken))
            ended, self.returned = self.done[self.returned:], len(self.done)
        for _, _, error in ended:
            if error is not None:
                raise error
        return [(snapshot, result) for snapshot, result, _ in ended]  # type: ignore[misc]

    def close(self, cancel: bool = False) -> None:
        """End the thread after the queued evaluations (``cancel``: each stops at its next batch)."""
        if cancel:
            self.cancel.set()
        self.todo.put(None)
        self.thread.join()

