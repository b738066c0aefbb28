"""Objective-surface solver throughput: 100,000 episodes x 64 weight vectors x 8 constraint sets.

Claim (issue 8): the vectorised solver (``solve_objective_surface``) takes under 1 s on
2 cores. Measured side by side with a straightforward per-episode Python loop that uses
the scalar RewardBuilder / ConstraintSet API (``build_reward_terms``, ``combine_reward``,
``ConstraintSet.satisfied``) and accumulates per-run sums. The loop is timed on a
subsample of whole runs and extrapolated linearly to all episodes (its cost is linear in
episodes); the script checks both give the same utilities and validity fractions on
that subsample.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/solver_throughput.py``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from econmotor.analysis.episode_table import METRIC_COLUMNS, EpisodeTable, RunInfo
from econmotor.analysis.objective_surface import (
    Objective,
    preset_objectives,
    solve_objective_surface,
)
from econmotor.valuation import ConstraintSet, build_reward_terms, combine_reward
from econmotor.valuation.reward_builder import REWARD_TERM_NAMES

#: the smallest run (tests/integration/test_benchmarks.py)
SMOKE_ARGS: list[str] = ["--episodes", "200", "--runs", "4", "--objectives", "8", "--constraint-sets", "2",
                         "--loop-runs", "1", "--repeats", "1"]


class _Price:
    energy_price_usd_per_kwh = 0.12


def synthetic_table(num_episodes: int, num_runs: int, seed: int = 0) -> EpisodeTable:
    """Episodes shaped like dishwashing evaluations (MPL 20-90 units/h, errors 0-20%, ...)."""
    rng = np.random.default_rng(seed)
    runs = [RunInfo(f"run-{r}", task_id="dishwashing", backend="dishwashing",
                    datapacks=(f"dp_{r % 4}",), seed=r % 3) for r in range(num_runs)]
    quality = rng.uniform(0, 1, num_runs)[rng.integers(0, num_runs, num_episodes)]
    run_index = np.sort(rng.integers(0, num_runs, num_episodes))
    run_index = np.searchsorted(np.unique(run_index), run_index)
    mpl = rng.normal(20 + 70 * quality, 5).clip(0)
    return EpisodeTable.from_arrays(
        runs[: run_index.max() + 1], run_index,
        mpl_units_per_hour=mpl,
        error_rate=rng.beta(2, 20 - 10 * quality),
        energy_wh=rng.uniform(5, 40, num_episodes),
        energy_wh_per_unit=rng.uniform(0.2, 2.5, num_episodes),
        wage_parity=mpl * 0.3 / 18.0,
        novelty_score=np.zeros(num_episodes),
        risk_score=rng.uniform(0, 1, num_episodes),
        catastrophic=rng.random(num_episodes) < 0.03,
        energy_price_usd_per_kwh=0.12,
    )


def objectives(n: int, seed: int = 1) -> list[Objective]:
    rng = np.random.default_rng(seed)
    presets = preset_objectives()
    extra = rng.dirichlet(np.ones(4), size=n - len(presets))
    return presets + [Objective(f"w{i}", (*map(float, w), 0.0)) for i, w in enumerate(extra)]


def constraint_sets(n: int) -> list[ConstraintSet]:
    return [ConstraintSet(min_wage_parity=0.5 + 0.1 * i, max_error_rate=0.05 + 0.02 * (i % 4),
                          max_energy_Wh=[1.5, 20.0][i % 2], energy_basis=["per_unit", "per_episode"][i % 2],
                          name=f"set{i}") for i in range(n)]


def python_loop(table: EpisodeTable, objs: list[Objective], sets: list[ConstraintSet], episodes: np.ndarray):
    """The straightforward way: one summary dict per episode through the scalar API."""
    weights = [list(o.weights) for o in objs]
    utility_sum: dict[int, list[float]] = {}
    ok_count: dict[int, list[int]] = {}
    metric_sums: dict[int, dict[str, float]] = {}
    count: dict[int, int] = {}
    for i in episodes:
        r = int(table.run_index[i])
        summary = {name: float(table.columns[name][i]) for name in METRIC_COLUMNS}
        summary.update(mpl=summary["mpl_units_per_hour"], catastrophic=bool(table.catastrophic[i]),
                       energy_Wh=summary["energy_wh"], energy_Wh_per_unit=summary["energy_wh_per_unit"])
        terms = build_reward_terms(summary, _Price)
        us = utility_sum.setdefault(r, [0.0] * len(objs))
        for k, w in enumerate(weights):
            us[k] += combine_reward(w, terms)
        oks = ok_count.setdefault(r, [0] * len(sets))
        for c, cset in enumerate(sets):
            oks[c] += cset.satisfied(summary)
        sums = metric_sums.setdefault(r, dict.fromkeys(METRIC_COLUMNS, 0.0))
        for name in METRIC_COLUMNS:
            sums[name] += summary[name]
        count[r] = count.get(r, 0) + 1
    valid = {r: [cset.satisfied({**{k: v / count[r] for k, v in metric_sums[r].items()},
                                 "energy_Wh": metric_sums[r]["energy_wh"] / count[r]}) for cset in sets]
             for r in count}
    return ({r: [u / count[r] for u in us] for r, us in utility_sum.items()},
            {r: [o / count[r] for o in oks] for r, oks in ok_count.items()}, valid)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100_000)
    parser.add_argument("--runs", type=int, default=1_000)
    parser.add_argument("--objectives", type=int, default=64)
    parser.add_argument("--constraint-sets", type=int, default=8)
    parser.add_argument("--loop-runs", type=int, default=20, help="whole runs timed in the Python loop")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    t0 = time.perf_counter()
    table = synthetic_table(args.episodes, args.runs)
    build_s = time.perf_counter() - t0
    objs, sets = objectives(args.objectives), constraint_sets(args.constraint_sets)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        surface = solve_objective_surface(table, objs, sets)
        times.append(time.perf_counter() - t0)
    solve_s = float(np.median(times))

    sample_runs = np.arange(min(args.loop_runs, table.num_runs))
    sample = np.flatnonzero(np.isin(table.run_index, sample_runs))
    t0 = time.perf_counter()
    loop_utility, loop_fraction, loop_valid = python_loop(table, objs, sets, sample)
    loop_sample_s = time.perf_counter() - t0
    loop_s = loop_sample_s * table.num_episodes / len(sample)

    for r in sample_runs:
        np.testing.assert_allclose(surface.utility[r], loop_utility[int(r)], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(surface.valid_fraction[r], loop_fraction[int(r)], rtol=1e-12)
        assert surface.valid[r].tolist() == loop_valid[int(r)], r
    print(f"episodes {table.num_episodes:,} in {table.num_runs} runs; {len(objs)} weight vectors "
          f"x {len(sets)} constraint sets; terms {len(REWARD_TERM_NAMES)}")
    print(f"table from arrays:              {build_s:8.3f} s (once, not in the solve time)")
    print(f"vectorised solve (median of {args.repeats}):  {solve_s:8.3f} s   goal < 1 s: "
          f"{'met' if solve_s < 1.0 else 'MISSED'}")
    print(f"per-episode Python loop:        {loop_s:8.3f} s   (timed on {len(sample):,} episodes of "
          f"{len(sample_runs)} runs: {loop_sample_s:.3f} s, extrapolated linearly)")
    print(f"speed-up (loop / vectorised):   {loop_s / solve_s:8.0f} x   (results agree on the subsample)")


if __name__ == "__main__":
    main()
