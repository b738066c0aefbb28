"""Pricing a walker on every core: seeded episodes of the batched MuJoCo env in worker processes.

:func:`evaluate` runs ``num_episodes`` episodes (episode ``i`` seeded ``seed + i``) of an ONNX walker
(a Holosoma-format file or a shipped ``holosoma:<robot>/<algo>``) on the course, episode ``i`` under
``conditions[i % len(conditions)]`` (:attr:`WalkerEvaluation.conditions`: the stress alone, or the stress
and the ones it alternates with), through :class:`~econmotor.locomotion.env.WalkerBatch`. It is the
one walker evaluator: a report's and the evaluation after training's (``motor_backend/walker_pricing.py``)
and the mujoco trainer's held-out looks (its actor exported to ONNX first) call it:

- ``workers`` processes (started with ``spawn``: no fork of a process whose threads run), worker ``w``
  running episodes ``w, w + W, ...`` on ``slots`` robots stepped together; one worker runs in this
  process. Why processes and not the rollout's C threads: the control step's Python (course,
  observation, policy, meter) runs beside the physics on each core, instead of one core's Python
  holding both threads back (``benchmarks/walker_throughput.py`` measures both; docs/architecture.md).
- a worker whose episodes fall under several conditions steps one batch of robots per condition, a control
  step of each in turn (:func:`~econmotor.locomotion.env.run_batches`), so every condition's robots stay
  busy and its episodes end in about their index order.
- every ``batch`` episodes finished in order, ``stop(episodes)`` may end the evaluation (a sequential
  verdict); the workers are then stopped. An episode's figures depend on its seed only.
- a worker ends when its parent process does (:func:`exit_with_parent`, which the walker trainer's collect
  workers call too): a parent killed with SIGKILL runs no cleanup, and its orphaned workers would step their
  remaining episodes at full CPU.
"""

from __future__ import annotations

import multiprocessing as mp
import multiprocessing.connection
import os
import queue as queue_module
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from econmotor.couriers.policy_import import PolicyContract, batched_onnx_policy, resolve_contract
from econmotor.errors import BackendError
from econmotor.locomotion.course import CourseSettings
from econmotor.locomotion.env import WalkerBatch, run_batches
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings

#: robots stepped together per worker: the Python of a control step (course, observation, policy, meter)
#: amortised over them (benchmarks/walker_throughput.py: 0.74 of raw mj_step on two cores at 16, 0.69 at
#: 8); the G1 report's sequential verdict, which discards the episodes in flight when it stops, took
#: 107 s at 16 and 111 s at 8 on the same machine
DEFAULT_SLOTS = 16

ProgressFn = Callable[[str, float, float], None]
StopFn = Callable[[list[dict[str, Any]]], bool]


@dataclass(frozen=True)
class WalkerEvaluation:
    """One evaluation's settings (what a worker process receives).

    ``stress``: the conditions of episode 0; ``alternate``: the conditions it alternates with, so episode ``i``
    runs under ``conditions[i % len(conditions)]`` (:attr:`conditions`; none: every episode under ``stress``)."""

    policy: str
    course: CourseSettings
    meter: MeterSettings
    stress: Stress
    episode_s: float
    seed: int
    slots: int = DEFAULT_SLOTS
    alternate: tuple[Stress, ...] = ()

    @property
    def conditions(self) -> tuple[Stress, ...]:
        """The conditions episodes cycle through: episode ``i`` under ``conditions[i % len(conditions)]``."""
        return (self.stress, *self.alternate)


def build_batch(ev: WalkerEvaluation, contract: PolicyContract | None = None,
                slots: int | None = None) -> tuple[WalkerBatch, Callable[[np.ndarray], np.ndarray]]:
    """The env of ``ev`` (the contract's card, its own PD gains and command ranges) and its batched policy."""
    contract = contract or resolve_contract(ev.policy)
    walker = WalkerModel.build(contract.card, np.asarray(contract.kp), np.asarray(contract.kd))
    batch = WalkerBatch(walker, ev.course, ev.meter, ev.stress, ev.episode_s, slots or ev.slots,
                        contract.command_ranges)
    return batch, batched_onnx_policy(contract)


EmitFn = Callable[[int, dict[str, Any]], bool | None]


def _run(ev: WalkerEvaluation, indices: list[int], emit: EmitFn, contract: PolicyContract | None = None) -> None:
    """Episodes ``indices`` of ``ev`` in this process, each under its condition, to ``emit`` as they end."""
    contract = contract or resolve_contract(ev.policy)
    conditions = ev.conditions
    groups = [(c, [i for i in indices if i % len(conditions) == k]) for k, c in enumerate(conditions)]
    groups = [(c, group) for c, group in groups if group]
    if not groups:
        return
    walker = WalkerModel.build(contract.card, np.asarray(contract.kp), np.asarray(contract.kd))
    batches = [WalkerBatch(walker, ev.course, ev.meter, c, ev.episode_s, min(ev.slots, len(group)),
                           contract.command_ranges) for c, group in groups]
    policy = batched_onnx_policy(contract)
    try:
        run_batches([(b, [(i, ev.seed + i) for i in group]) for b, (_, group) in zip(batches, groups, strict=True)],
                    policy, emit)
    finally:
        for batch in batches:
            batch.close()


#: a worker's exit status when its parent died under it (its episodes went nowhere)
ORPHANED_EXIT = 70


def exit_with_parent() -> None:
    """End this process as soon as its parent dies, from a daemon thread that waits on the parent's
    sentinel (multiprocessing's pipe from the parent, whose end of it closes only when the parent exits).
    Waiting instead of polling ``os.getppid()``: no wake-ups, and no window in which a reused pid passes."""
    parent = mp.parent_process()
    if parent is None:  # not started by multiprocessing
        return

    def watch() -> None:
        mp.connection.wait([parent.sentinel])
        os._exit(ORPHANED_EXIT)  # no cleanup to run: nobody reads this worker's queue any more

    threading.Thread(target=watch, name="econmotor-parent-watch", daemon=True).start()


def _worker(ev: WalkerEvaluation, contract: PolicyContract, indices: list[int], out: Any, stop: Any) -> None:
    """A worker process: episodes to ``out`` as ``("episode", index, metrics)``; ``("end", None, None)``."""
    exit_with_parent()
    try:
        _run(ev, indices, lambda i, episode: out.put(("episode", i, episode)) or stop.is_set(), contract)
        out.put(("end", None, None))
    except BaseException:
        out.put(("error", None, traceback.format_exc()))


class _Prefix:
    """Episodes gathered by index; the unbroken run from episode 0 is what a look may judge."""

    def __init__(self) -> None:
        self.rows: dict[int, dict[str, Any]] = {}

    def prefix(self) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        while len(out) in self.rows:
            out.append(self.rows[len(out)])
        return out


def evaluate(ev: WalkerEvaluation, num_episodes: int, workers: int = 1, *, progress: ProgressFn | None = None,
             stop: StopFn | None = None, batch: int = 10, timeout_s: float | None = None,
             ) -> tuple[list[dict[str, Any]], float]:
    """``num_episodes`` seeded episodes on ``workers`` processes: (the episodes finished in order, wall s).

    ``stop(episodes)`` is asked at every ``batch`` boundary of the episodes finished in order, one boundary
    after another, the last one included when ``num_episodes`` is a multiple of ``batch`` (the held-out looks
    of ``motor_backend/selection.py`` are judged there); once it says stop, the evaluation returns the
    episodes it was asked about then (the ones still in flight are dropped, however many there were), else
    every episode. Episode ``i`` runs under ``ev.conditions[i % len(ev.conditions)]``.
    """
    contract = resolve_contract(ev.policy)  # a bad policy is a ConfigError here, before any worker starts
    gathered, asked, stopped_at, start = _Prefix(), 0, None, time.monotonic()
    report = progress or (lambda label, done, total: None)
    report("sim-to-sim episodes", 0, num_episodes)

    def take(index: int, episode: dict[str, Any]) -> bool:
        nonlocal asked, stopped_at
        gathered.rows[index] = episode
        report("sim-to-sim episodes", len(gathered.rows), num_episodes)
        if stop is None or stopped_at is not None:
            return stopped_at is not None
        done = gathered.prefix()
        while asked + batch <= min(len(done), num_episodes):
            asked += batch
            if stop(done[:asked]):
                stopped_at = asked
                return True
        return False

    workers = max(1, min(int(workers), num_episodes))
    if workers == 1:
        _run(ev, list(range(num_episodes)), take, contract)
    else:
        _in_processes(ev, contract, num_episodes, workers, take, timeout_s, start)
    return gathered.prefix()[:stopped_at], time.monotonic() - start


def _in_processes(ev: WalkerEvaluation, contract: PolicyContract, num_episodes: int, workers: int,
                  take: Callable[[int, dict[str, Any]], bool], timeout_s: float | None, start: float) -> None:
    """``workers`` spawned processes, each given the contract resolved here (its ONNX read once)."""
    ctx = mp.get_context("spawn")
    out, stop_event = ctx.Queue(), ctx.Event()
    procs = [ctx.Process(target=_worker, args=(ev, contract, list(range(w, num_episodes, workers)), out, stop_event),
                         daemon=True, name=f"econmotor-walker-{w}") for w in range(workers)]
    try:
        for proc in procs:
            proc.start()
        ended = 0
        while ended < workers:
            try:
                kind, index, payload = out.get(timeout=1.0)
            except queue_module.Empty:
                if timeout_s is not None and time.monotonic() - start > timeout_s:
                    raise BackendError(f"the walker evaluation exceeded {timeout_s:.0f} s") from None
                if any(not p.is_alive() and p.exitcode not in (0, None) for p in procs):
                    raise BackendError("a walker worker process died: exit codes "
                                       f"{[p.exitcode for p in procs]}") from None
                continue
            if kind == "error":
                raise BackendError(f"a walker worker failed:\n{payload}")
            if kind == "end":
                ended += 1
            elif take(int(index), payload):
                stop_event.set()
                return
    finally:
        stop_event.set()
        for proc in (p for p in procs if p.pid is not None):  # a start that failed left the rest unstarted
            if proc.is_alive():
                proc.terminate()
            proc.join(timeout=10)
        out.close()
        out.cancel_join_thread()
