"""Concurrent first use of a new task: 8 processes record the first run of the same new task
at once, 20 rounds, on PostgreSQL and on SQLite. Every attempt succeeds and every run is
recorded (get-or-create of tasks, robots and datapacks is one INSERT ... ON CONFLICT).
"""

from __future__ import annotations

import multiprocessing as mp
import uuid
from dataclasses import replace
from pathlib import Path

import pytest

PROCESSES = 8
ROUNDS = 20


def _writer(url: str, task_ids: list[str], barrier, results, index: int) -> None:
    """One writer: each round, wait for the others, then record the task, its datapack, its
    robot and a run (start + finish), exactly as a report's first training run does."""
    from econmotor.config.datapacks import DatapackConfig
    from econmotor.store import Registry
    from econmotor.tasks import get_task

    base = get_task("dishwashing")
    with Registry(url) as reg:
        for task_id in task_ids:
            try:
                barrier.wait(60)
            except Exception as exc:  # a broken barrier: another writer died
                results.put(("fail", index, task_id, f"barrier: {exc!r}"))
                return
            try:
                reg.record_task(replace(base, task_id=task_id))
                reg.record_datapacks([DatapackConfig(id=f"{task_id}-pack", description="race")])
                robot = f"dishwashing:{task_id}"
                reg.record_robot(robot, "dishwashing", "race")
                with reg.track_run("train", task_id, "dishwashing", robot_id=robot, seed=index,
                                   datapack_ids=[f"{task_id}-pack"], objective={"name": "race"}) as run_id:
                    reg.finish_run(run_id, raw_metrics={"writer": index})
                results.put(("ok", index, task_id, run_id))
            except BaseException as exc:
                results.put(("fail", index, task_id, f"{type(exc).__name__}: {exc}"))


def race(url: str) -> dict[str, int]:
    """Run the 8 x 20 race against ``url``; return the counts (asserting nothing)."""
    from econmotor.store import Registry

    Registry(url).close()  # the schema exists before the race (its creation is tested elsewhere)
    task_ids = [f"race_{r}_{uuid.uuid4().hex[:8]}" for r in range(ROUNDS)]
    ctx = mp.get_context("spawn")  # fork would copy a parent that may hold JAX or torch threads
    barrier, results = ctx.Barrier(PROCESSES), ctx.Queue()
    procs = [ctx.Process(target=_writer, args=(url, task_ids, barrier, results, i)) for i in range(PROCESSES)]
    for p in procs:
        p.start()
    outcomes = [results.get(timeout=300) for _ in range(PROCESSES * ROUNDS)]
    for p in procs:
        p.join(60)
    failures = [o for o in outcomes if o[0] == "fail"]
    with Registry(url) as reg:
        recorded = {t: [r for r in reg.runs(task_id=t) if r.status == "completed"] for t in task_ids}
        tasks = {r for r in task_ids if any(x.task_id == r for x in reg.runs(task_id=r))}
        packs = set(reg.known_datapack_ids())
    counts = {"attempts": len(outcomes), "failures": len(failures),
              "runs_recorded": sum(len(v) for v in recorded.values()),
              "lost_rows": PROCESSES * ROUNDS - sum(len(v) for v in recorded.values()),
              "tasks": len(tasks), "datapacks": len({f"{t}-pack" for t in task_ids} & packs)}
    print(f"\n{url.split(':')[0]}: {PROCESSES} processes x {ROUNDS} rounds: {counts}; first failures: "
          f"{[f[3] for f in failures[:3]]}")
    return counts


def assert_race_clean(counts: dict[str, int]) -> None:
    assert counts == {"attempts": PROCESSES * ROUNDS, "failures": 0, "runs_recorded": PROCESSES * ROUNDS,
                      "lost_rows": 0, "tasks": ROUNDS, "datapacks": ROUNDS}


@pytest.mark.postgres
def test_eight_processes_record_the_first_run_of_a_new_task_on_postgresql(pg_url: str) -> None:
    assert_race_clean(race(pg_url))


def test_eight_processes_record_the_first_run_of_a_new_task_on_sqlite(tmp_path: Path) -> None:
    assert_race_clean(race(f"sqlite:///{tmp_path / 'race.sqlite'}"))
