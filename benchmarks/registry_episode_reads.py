"""Reading recorded episodes back: ``Registry.episode_arrays`` (column arrays) vs ``Registry.episodes``
(one record per episode with its whole summary), same SQLite registry, same run.

Prints the time of each and their ratio; also the time to record the episodes.
Usage: ``python benchmarks/registry_episode_reads.py [--runs 200] [--episodes-per-run 100]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from econmotor.motor_backend.results import MotorEvalResult, summarize_episodes
from econmotor.store import Registry
from econmotor.tasks import get_task

#: the smallest run (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--runs", "2", "--episodes-per-run", "2"]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--episodes-per-run", type=int, default=100)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    economics = get_task("dishwashing").economics
    with tempfile.TemporaryDirectory() as tmp:
        reg = Registry(f"sqlite:///{Path(tmp) / 'bench.sqlite'}")
        started = time.perf_counter()
        for run in range(args.runs):
            raw_eps = [{"units_completed": float(u), "errors": float(e), "episode_length_s": 14400.0,
                        "energy_wh": float(w)} for u, e, w in zip(rng.integers(0, 300, args.episodes_per_run),
                                                                  rng.integers(0, 20, args.episodes_per_run),
                                                                  rng.uniform(5, 50, args.episodes_per_run),
                                                                  strict=True)]
            raw, econ, eps = summarize_episodes(raw_eps, economics)
            reg.record_run("eval", MotorEvalResult("p", "dishwashing", "dishwashing", raw, econ, eps),
                           objective={"name": f"o{run % 6}"}, seed=run)
        write_s = time.perf_counter() - started
        n = args.runs * args.episodes_per_run

        started = time.perf_counter()
        arrays = reg.episode_arrays(["mpl_units_per_hour", "error_rate", "energy_wh"], task_id="dishwashing")
        arrays_s = time.perf_counter() - started
        started = time.perf_counter()
        records = reg.episodes(task_id="dishwashing")
        records_s = time.perf_counter() - started
        assert len(records) == len(arrays["run_id"]) == n
        assert np.allclose(arrays["mpl_units_per_hour"], [r["mpl_units_per_hour"] for r in records])
        reg.close()
    print(f"{n:,} episodes in {args.runs} runs: recorded in {write_s:.2f} s ({n / write_s:,.0f} episodes/s)")
    print(f"episodes() records: {records_s:.3f} s; episode_arrays(3 columns): {arrays_s:.3f} s; "
          f"ratio records/arrays = {records_s / arrays_s:.1f}x")


if __name__ == "__main__":
    main()
