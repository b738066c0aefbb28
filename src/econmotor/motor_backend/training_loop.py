"""The run around every learner, written once: resume, ``run_config.json``, the training curve, checkpoints,
held-out selection, the kept policy, timing.

:class:`TrainingLoop` drives the run (SB3's ``BaseAlgorithm.learn`` is its model: learn a chunk, then the
callbacks); a backend's learning algorithm plugs into it as a :class:`Learner`, which supplies its chunks of
learning, its checkpoints, its policy files and its export. What a loop-driven run directory holds::

    run_config.json    # the backend's description of the run, then resumed_from_steps, selection,
                       #   trained_steps and timing (written at the start, after each held-out
                       #   evaluation and at the end)
    curve.jsonl        # one row per chunk of learning: env_steps, wall_s and the learner's scalars
    checkpoints/       # the learner's own checkpoints, every checkpoint_every_steps env steps and/or
                       #   checkpoint_every_s wall seconds, at the end and when interrupted
    best/              # the best held-out policy so far (evaluation-driven runs; selection.py)
    <policy files>     # the kept policy (Learner.save_policy: the best held-out one, else the last)
    policy.onnx        # its export (Learner.export)

Held-out evaluations run between chunks, or, for a learner that gives a
:class:`~econmotor.motor_backend.beside_training.PolicySnapshot` (:meth:`Learner.snapshot`: the mjx backend's,
whose compiled evaluation leaves the GIL), beside training (``beside_training.py``: one thread evaluates the
snapshots in the order they were taken, at most ``MAX_BACKLOG`` waiting) and the loop enters each result after
the chunk it ended in, so the same policies are judged as between chunks and the kept one is the snapshot that
passed, not the weights learned while it was judged.

A run stops at ``max_steps`` env steps, at ``max_wall_s`` or once deployable (``--until-deployable``).
Interrupted (Ctrl-C, SIGTERM), it writes a checkpoint first when the learner keeps them, so ``--resume``
continues from there.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.beside_training import MAX_BACKLOG, BesideTraining, PolicySnapshot
from econmotor.motor_backend.run_dir import check_resume_request, read_run_config, write_run_config
from econmotor.motor_backend.selection import HeldOutResult, Selection

BEST_DIR = "best"
CURVE_FILE = "curve.jsonl"
#: ``stop(rows so far) -> bool``: asked after every batch of a held-out evaluation (selection.EvaluateFn)
StopFn = Callable[[list[dict[str, Any]]], bool]


class Learner:
    """What a learning algorithm supplies to :class:`TrainingLoop` (the defaults: no checkpoints, no export).

    ``env_steps`` counts the environment steps learned so far (all envs together).
    """

    env_steps: int = 0
    #: the policy file that marks a complete run: written last, after its companions
    policy_file: str = "policy"
    #: env steps a call to :meth:`learn` takes at least (one iteration); the loop reports between chunks
    chunk_steps: int = 1
    #: the policy a new run starts from (``--init-policy``), or None: a warm-started run's held-out selection
    #: judges it first, at env step 0, so the run keeps it unless a later look beats it
    warm_start: str | None = None

    def learn(self, until_steps: int) -> Mapping[str, Any] | None:
        """Learn until ``env_steps >= until_steps`` (one iteration at least); the chunk's curve row
        (``mean_return``, ``mean_length`` or the learner's own scalars), or None when nothing ended."""
        raise NotImplementedError

    def evaluate(self, num_episodes: int, first_seed: int, stop: StopFn) -> list[dict[str, Any]]:
        """Deterministic episodes of the current policy (episode ``i`` seeded ``first_seed + i``), asking
        ``stop`` after every batch in order; raw-metric dicts (``base.py``'s keys)."""
        raise NotImplementedError

    def save_checkpoint(self, run_dir: Path) -> None:
        """Everything ``--resume`` needs, under ``run_dir / "checkpoints"`` (none by default)."""

    def load_checkpoint(self, run_dir: Path) -> int:
        """Restore the newest intact checkpoint of ``run_dir``; its env steps (0: none found)."""
        return 0

    def save_policy(self, directory: Path) -> None:
        """The current policy's files into ``directory`` (``best/`` and the run directory)."""
        raise NotImplementedError

    def load_policy(self, directory: Path) -> None:
        """Make the policy saved in ``directory`` the current one (the kept policy, before its export)."""
        raise NotImplementedError

    def export(self, run_dir: Path) -> Path | None:
        """The deployable export of the current policy (``policy.onnx``), or None."""
        return None

    def status(self) -> str:
        """A few words on the latest chunk for the progress bar (empty: none)."""
        return ""

    def snapshot(self) -> PolicySnapshot | None:
        """The current policy frozen for a held-out evaluation in a thread beside training, or None (the
        default): held-out evaluations run between chunks. Worth it where an evaluation leaves the GIL
        (compiled rollouts on a core training does not use); Python envs would only share one core."""
        return None

    def log_scalars(self, scalars: Mapping[str, float], env_steps: int) -> None:
        """Scalars at env step ``env_steps`` (TensorBoard), e.g. a held-out evaluation's at the step of the policy
        it judged (earlier than the learner's own when it ran beside training)."""

    def timing(self) -> dict[str, Any]:
        """The learner's own timing entries (e.g. compilation) for the run's ``timing``."""
        return {}

    def close(self) -> None:
        """Release envs and writers."""


@dataclass(frozen=True)
class TrainingOutcome:
    """What a run gives its backend: the curve, the run config as written, where the export went."""

    curve: list[dict[str, float]]
    config: dict[str, Any]
    export: Path | None


@dataclass
class TrainingLoop:
    """One run of a :class:`Learner` into ``run_dir`` (module docstring).

    Attributes:
        run_dir / backend: the run directory and the backend's name (``run_config.json``'s ``backend``).
        config: the backend's description of the run (task, objective, hyperparameters, layouts, ...).
        max_steps / max_wall_s: stop at this many env steps in all, or after this many wall seconds.
        checkpoint_every_steps / checkpoint_every_s: the checkpoint cadence (None: not by that measure).
        selection: evaluation-driven training (selection.py), or None (the last weights are kept).
        curve_every_steps: the returned curve keeps a point at most this often (every row goes to the file).
        requested_hyperparameters: what a resumed run was asked for (it must match the recorded ones).
    """

    run_dir: Path
    backend: str
    config: dict[str, Any]
    max_steps: int
    max_wall_s: float = math.inf
    checkpoint_every_steps: int | None = None
    checkpoint_every_s: float | None = None
    selection: Selection | None = None
    curve_every_steps: int | None = None
    requested_hyperparameters: Mapping[str, Any] | None = None
    progress: ProgressFn = no_progress
    label: str = "train"
    _curve: list[dict[str, float]] = field(default_factory=list)
    _previous: dict[str, Any] | None = None
    _beside: BesideTraining | None = None

    # ------------------------------------------------------------------ resume
    def previous(self) -> dict[str, Any]:
        """The recorded config of the run to resume (its task and backend checked, and the request too: a
        resumed run keeps its hyperparameters); the backend builds its learner from it. Read and checked once."""
        if self._previous is None:
            self._previous = read_run_config(self.run_dir, self.backend)
            check_resume_request(self.run_dir, self._previous, str(self.config.get("task_id")),
                                 self.requested_hyperparameters)
        return self._previous

    def _start(self, learner: Learner, resume: bool) -> int:
        """Restore a resumed run (its checkpoint and its selection so far); write ``run_config.json``."""
        self.run_dir.mkdir(parents=True, exist_ok=True)
        steps = 0
        if resume:
            previous = self.previous()
            steps = learner.load_checkpoint(self.run_dir)
            if self.selection is not None and (self.run_dir / BEST_DIR).is_dir():
                self.selection.restore(previous.get("selection"))
        self.config = {**self.config, "backend": self.backend, "max_steps": self.max_steps,
                       "resumed_from_steps": steps}
        if self.selection is not None and self.selection.history:
            self.config["selection"] = self.selection.record()  # a resumed run's selection so far
        write_run_config(self.run_dir, self.config, self.backend)
        return steps

    # ------------------------------------------------------------------ the loop
    def run(self, learner: Learner, resume: bool = False) -> TrainingOutcome:
        """Train to the run's end (module docstring); the kept policy saved and exported."""
        started = time.perf_counter()
        first = self._start(learner, resume)
        if self.selection is not None:
            self.selection.started = started  # "deployable after N wall seconds" counts from here
        last_selected, last_ckpt = first, (first, started)
        self._report(learner, started)
        try:
            if self.selection is not None and learner.warm_start and first == 0 and not self.selection.history:
                self._consider(learner, beside=False)  # the policy it starts from: the look to beat
                self._report(learner, started)
            while not self._done(learner, started):
                row = learner.learn(self._next_stop(learner, last_selected, last_ckpt[0]))
                self._record(learner, row, started)
                self._settle(learner)
                if self.selection is not None and self.selection.due(learner.env_steps, last_selected):
                    last_selected = learner.env_steps
                    if not self.selection.should_stop:
                        self._consider(learner)
                if self._checkpoint_due(learner, last_ckpt):
                    learner.save_checkpoint(self.run_dir)
                    last_ckpt = (learner.env_steps, time.perf_counter())
                self._report(learner, started)
            if self._beside is not None:  # the evaluations still running beside training, then the bar says the last
                self._settle(learner, backlog=0)
                self._report(learner, started)
            if self.selection is not None and self.selection.final_due(learner.env_steps, last_selected):
                self._consider(learner, beside=False)  # the last weights are a candidate too
        except BaseException:  # interrupted (Ctrl-C, SIGTERM) or failed: what was learned is kept for --resume
            if self._beside is not None:
                self._beside.close(cancel=True)
                self._beside = None
            try:
                if learner.env_steps > last_ckpt[0]:
                    learner.save_checkpoint(self.run_dir)
            except Exception:  # the error that stopped the run is the one to raise
                pass
            finally:
                learner.close()
            raise
        if learner.env_steps > last_ckpt[0]:
            learner.save_checkpoint(self.run_dir)
        try:
            return self._finish(learner, started, first)
        finally:
            learner.close()

    def _done(self, learner: Learner, started: float) -> bool:
        return (learner.env_steps >= self.max_steps or time.perf_counter() - started >= self.max_wall_s
                or (self.selection is not None and self.selection.should_stop))

    def _next_stop(self, learner: Learner, last_selected: int, last_ckpt: int) -> int:
        """The env steps the next chunk learns to: the next event (selection, checkpoint, the end), or one
        chunk, whichever comes first."""
        stops = [self.max_steps, learner.env_steps + max(1, learner.chunk_steps)]
        if self.selection is not None:
            every = self.selection.config.every_steps
            stops.append((last_selected // every + 1) * every)
        if self.checkpoint_every_steps:
            every = self.checkpoint_every_steps
            stops.append((last_ckpt // every + 1) * every)
        return max(learner.env_steps + 1, min(stops))

    def _checkpoint_due(self, learner: Learner, last: tuple[int, float]) -> bool:
        every, every_s = self.checkpoint_every_steps, self.checkpoint_every_s
        return bool((every and learner.env_steps // every > last[0] // every)
                    or (every_s is not None and time.perf_counter() - last[1] >= every_s))

    def _record(self, learner: Learner, row: Mapping[str, Any] | None, started: float) -> None:
        """The chunk's row into ``curve.jsonl``; a point of the returned curve at most every
        ``curve_every_steps`` (and at the end)."""
        if row is None:
            return
        point = {"timesteps": float(learner.env_steps), **{k: v for k, v in row.items() if k != "timesteps"}}
        with (self.run_dir / CURVE_FILE).open("a", encoding="utf-8") as f:
            f.write(json.dumps({"env_steps": learner.env_steps, "wall_s": round(time.perf_counter() - started, 3),
                                **{k: v for k, v in point.items() if k != "timesteps"}}) + "\n")
        every = self.curve_every_steps or max(1, self.max_steps // 50)
        last = self._curve[-1]["timesteps"] if self._curve else -math.inf
        if learner.env_steps // every > last // every or learner.env_steps >= self.max_steps:
            self._curve.append(point)

    def _report(self, learner: Learner, started: float) -> None:
        """One bar (``"train · <the learner's status> · <the latest held-out verdict>"``), as far as the nearer
        of the run's two ends (env steps, wall time)."""
        said = [learner.status(), self.selection.status() if self.selection is not None else ""]
        done = min(learner.env_steps, self.max_steps)
        if math.isfinite(self.max_wall_s):
            done = max(done, min(1.0, (time.perf_counter() - started) / self.max_wall_s) * self.max_steps)
        self.progress(" · ".join([self.label, *(s for s in said if s)]), done, self.max_steps)

    def _consider(self, learner: Learner, beside: bool = True) -> None:
        """One held-out evaluation of the current policy: queued beside training when the learner gives a
        snapshot (entered later by :meth:`_settle`), else here and now."""
        snapshot = learner.snapshot() if beside else None
        if snapshot is None:
            self._enter(learner, self.selection.assess(learner.env_steps, learner.evaluate), learner.save_policy)
            return
        if self._beside is None:
            self._beside = BesideTraining(self.selection)
        self._settle(learner, backlog=MAX_BACKLOG - 1)  # room for this one
        if not self.selection.should_stop:
            self._beside.take(learner.env_steps, snapshot)

    def _settle(self, learner: Learner, backlog: int | None = None) -> None:
        """Enter the evaluations beside training that have ended, in order; with ``backlog``, first wait until
        at most that many are still waiting or running (0: all have ended, and the thread is closed)."""
        beside = self._beside
        if beside is None:
            return
        for snapshot, result in beside.finished(0 if backlog is None else beside.taken - backlog):
            if self.selection.should_stop:  # --until-deployable: the first pass is kept; later ones are moot
                break
            self._enter(learner, result, snapshot.save_policy)
        if backlog == 0 or self.selection.should_stop:
            beside.close(cancel=self.selection.should_stop)
            self._beside = None

    def _enter(self, learner: Learner, result: HeldOutResult, save_policy: Callable[[Path], None]) -> None:
        """An evaluation into the selection; its policy saved to ``best/`` when it is the best so far."""
        better = self.selection.admit(result)
        if better:
            _replace_dir(self.run_dir / BEST_DIR, save_policy)
        self.config = {**self.config, "selection": self.selection.record()}
        write_run_config(self.run_dir, self.config, self.backend)
        learner.log_scalars(result.scalars(), result.env_steps)

    def _finish(self, learner: Learner, started: float, first: int) -> TrainingOutcome:
        """The run's record first, then the kept policy (its files mark a complete run) and its export."""
        wall_s = time.perf_counter() - started
        trained = learner.env_steps - first
        self.config = {**self.config, "trained_steps": learner.env_steps,
                       "timing": {"total_steps": learner.env_steps, "train_wall_s": round(wall_s, 3),
                                  "env_steps_per_s": round(trained / wall_s, 1) if wall_s > 0 else None,
                                  **learner.timing()}}
        if self.selection is not None:
            self.config["selection"] = self.selection.record()
        write_run_config(self.run_dir, self.config, self.backend)
        if self.selection is not None and self.selection.best is not None:
            install(self.run_dir / BEST_DIR, self.run_dir, learner.policy_file)
            learner.load_policy(self.run_dir)
        else:
            learner.save_policy(self.run_dir)
        return TrainingOutcome(list(self._curve), self.config, learner.export(self.run_dir))


def _replace_dir(directory: Path, save: Callable[[Path], None]) -> None:
    """``save`` into a fresh temporary folder, then swap it in for ``directory`` (never half written)."""
    tmp = directory.with_name(f"{directory.name}.tmp{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    save(tmp)
    old = directory.with_name(f"{directory.name}.old{os.getpid()}")
    if directory.exists():
        directory.replace(old)
    tmp.replace(directory)
    shutil.rmtree(old, ignore_errors=True)


def install(source: Path, run_dir: Path, last: str) -> None:
    """Copy the policy files of ``source`` into ``run_dir``, each atomically (a temporary name, then renamed),
    ``last`` (the file that marks a complete run) after its companions."""
    run_dir.mkdir(parents=True, exist_ok=True)
    for path in sorted((p for p in source.iterdir() if p.is_file()), key=lambda p: (p.name == last, p.name)):
        tmp = run_dir / f".{path.name}.tmp{os.getpid()}"
        shutil.copyfile(path, tmp)
        tmp.replace(run_dir / path.name)
