"""Holosoma iteration time with the econ overlay reward terms over without them, in one run.

Trains G1 locomotion (Holosoma PPO, classic MuJoCo, 1 env, CPU) twice per round with the
same seed: once with the spec's example objective (4 econ reward terms active), once with
an empty overlay (mpl_weight 0: no econ terms). Rounds alternate the order so machine load
hits both alike. Per-iteration times come from Holosoma's own collection/learn timers;
the first iterations (warm-up) are dropped. Because run-to-run noise on a shared CPU can
exceed the overlay's cost, the with-overlay run also times the econ terms themselves
(``econ_term_seconds``), giving the in-run ratio ``total / (total - econ term time)``.
Goal: ratio <= 1.05.

    .venv/bin/python benchmarks/holosoma_overlay_overhead.py [--iterations 40] [--rounds 2]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

from econmotor.motor_backend.holosoma.host.backend import HolosomaBackend
from econmotor.objectives import EconomicObjectiveSpec, load_objective_spec

REPO = Path(__file__).resolve().parents[1]
WARMUP = 3
#: the smallest run (tests/integration/test_benchmarks.py): one round of 4 iterations (the warm-up's 3 dropped)
SMOKE_ARGS: list[str] = ["--iterations", "4", "--rounds", "1"]


def iteration_times(backend: HolosomaBackend, objective: EconomicObjectiveSpec, iterations: int,
                    out: Path) -> tuple[list[float], list[float], int, float]:
    result = backend.train_policy("humanoid_locomotion_g1", objective, [], num_envs=1, max_steps=24 * iterations,
                                  seed=0, output_dir=out, eval_episodes=0)
    all_rows = result.config["iteration_times_s"]
    rows = all_rows[WARMUP:]
    econ_terms = sum(1 for t in result.config["reward_terms"] if t.startswith("econ_"))
    total_s = sum(r["collection_s"] + r["learn_s"] for r in all_rows)
    share = result.config["econ_term_seconds"] / total_s
    return ([r["collection_s"] + r["learn_s"] for r in rows], [r["collection_s"] for r in rows], econ_terms, share)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    backend = HolosomaBackend(simulator="mujoco", cpu_max_env_steps=10**9)
    with_overlay = load_objective_spec(REPO / "configs" / "objectives" / "example_holosoma_objective.yaml")
    without = EconomicObjectiveSpec(mpl_weight=0.0, name="no_overlay")
    runs: dict[str, dict[str, list[float]]] = {"with": {"it": [], "col": []}, "without": {"it": [], "col": []}}
    terms: dict[str, int] = {}
    shares: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            order = [("with", with_overlay), ("without", without)]
            for name, objective in (order if r % 2 == 0 else order[::-1]):
                it, col, n_terms, share = iteration_times(backend, objective, args.iterations,
                                                          Path(tmp) / f"{name}{r}")
                if name == "with":
                    shares.append(share)
                runs[name]["it"] += it
                runs[name]["col"] += col
                terms[name] = n_terms
                print(f"round {r} {name:7s}: {n_terms} econ terms, median iteration {statistics.median(it):.4f} s")
    med = {k: (statistics.median(v["it"]), statistics.median(v["col"])) for k, v in runs.items()}
    print(f"econ reward terms: with={terms['with']} without={terms['without']}")
    print(f"median iteration time  with overlay {med['with'][0]:.4f} s, without {med['without'][0]:.4f} s")
    print(f"median rollout time    with overlay {med['with'][1]:.4f} s, without {med['without'][1]:.4f} s")
    print(f"ratio iteration (with / without) = {med['with'][0] / med['without'][0]:.3f}   (goal <= 1.05)")
    print(f"ratio rollout   (with / without) = {med['with'][1] / med['without'][1]:.3f}")
    share = statistics.median(shares)
    print(f"econ terms' own time: {100 * share:.2f} % of training time in the with-overlay runs")
    print(f"in-run ratio (total / (total - econ term time)) = {1 / (1 - share):.4f}   (goal <= 1.05)")


if __name__ == "__main__":
    main()
