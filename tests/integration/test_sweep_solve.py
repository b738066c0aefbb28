"""A Ray sweep of 3 presets x 2 datapacks x 2 seeds on the dishwashing backend, then `solve` on it. The sweep starts
its own local Ray, in a process of its own: this one, where JAX or torch threads may run (an earlier test in the
same worker), never forks."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from econmotor.analysis.pareto import PARETO_CRITERIA
from econmotor.cli import main
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.store import Registry
from econmotor.tasks import get_task
from econmotor.valuation import build_reward_terms, combine_reward, load_constraint_sets

REPO = Path(__file__).resolve().parents[2]
CONSTRAINTS = REPO / "configs" / "constraints" / "default.yaml"
PRESETS = ("throughput", "safety", "energy_saver")

DATAPACKS = {
    "dw_forgiving": "domain_randomization:\n  p_min_range: [0.0, 0.01]\n",
    "dw_fragile": "domain_randomization:\n  p_min_range: [0.03, 0.06]\n  k_err_range: [0.2, 0.4]\n",
}

#: the pids of this process's forks in Python (os.fork, a subprocess with preexec_fn, multiprocessing's fork):
#: after JAX has started its threads each one warns "os.fork() was called ... will likely lead to a deadlock"
FORKS: list[int] = []
os.register_at_fork(before=lambda: FORKS.append(os.getpid()))


@pytest.fixture()
def ray_env(monkeypatch):
    pytest.importorskip("ray", reason="Ray is the optional extra `econmotor[ray]`")
    for key, value in {"RAY_USAGE_STATS_ENABLED": "0", "RAY_DEDUP_LOGS": "0", "OMP_NUM_THREADS": "1",
                       "RAY_enable_metrics_collection": "0"}.items():
        monkeypatch.setenv(key, value)


def sweep_args(tmp_path: Path, db_url: str) -> list[str]:
    packs = []
    for pack_id, body in DATAPACKS.items():
        path = tmp_path / f"{pack_id}.yaml"
        path.write_text(f"id: {pack_id}\n{body}")
        packs.append(str(path))
    return ["sweep", "--task-id", "dishwashing", "--motor-backend", "dishwashing",
            "--preset", ",".join(PRESETS), "--datapacks", ",".join(packs), "--seeds", "0,1",
            "--max-steps", "300", "--eval-episodes", "3", "--db-url", db_url,
            "--output-dir", str(tmp_path / "policies")]


@pytest.mark.slow
def test_ray_sweep_then_solve(tmp_path, ray_env):
    db_url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    forks = len(FORKS)
    assert main([*sweep_args(tmp_path, db_url), "--ray", "--ray-num-cpus", "2", "--cpus-per-cell", "1"]) == 0
    assert len(FORKS) == forks, "the sweep forked this process to start Ray"

    registry = Registry(db_url, create=False)
    runs = registry.runs(task_id="dishwashing", backend="dishwashing", kind="train")
    assert len(runs) == 12 and {r.status for r in runs} == {"completed"}
    cells = {(r.objective_name, r.datapack_ids, r.seed) for r in runs}
    assert cells == {(p, (d,), s) for p in PRESETS for d in DATAPACKS for s in (0, 1)}
    assert len({r.config["cell_key"] for r in runs}) == 12
    assert all((Path(r.policy_path) / "policy.zip").is_file() for r in runs)  # the cell's run directory
    episodes = registry.episodes(task_id="dishwashing")
    assert len(episodes) == 12 * 3

    # resumable: the same grid again trains nothing and records nothing new
    assert main(sweep_args(tmp_path, db_url)) == 0
    assert len(registry.runs(task_id="dishwashing")) == 12

    out = tmp_path / "surface"
    export = tmp_path / "episodes.jsonl"
    assert main(["solve", "--db-url", db_url, "--task-id", "dishwashing", "--constraints", str(CONSTRAINTS),
                 "--output-dir", str(out), "--export-jsonl", str(export)]) == 0
    doc = json.loads((out / "objective_surface.json").read_text())
    assert len(doc["runs"]) == 12 and doc["num_episodes"] == 36
    sets = [s.name for s in load_constraint_sets(CONSTRAINTS)]
    assert len(doc["cells"]) == 6 * len(sets)
    assert (out / "objective_surface.md").read_text().startswith("# Objective surface")
    assert (out / "pareto_front.png").read_bytes()[:4] == b"\x89PNG"

    # utility = mean episodic combine_reward(preset, RewardBuilder terms), recomputed the scalar way
    price = get_task("dishwashing").economics
    by_run: dict[str, list] = {}
    for ep in episodes:
        by_run.setdefault(str(ep.run_id), []).append(build_reward_terms(ep.summary, price))
    for run in doc["runs"]:
        for preset in ("throughput", "safety", "energy_saver", "balanced"):
            w = ObjectiveVector.from_preset(preset)
            expected = np.mean([combine_reward(w, t) for t in by_run[run["run_id"]]])
            assert run["utility"][preset] == pytest.approx(expected, rel=1e-9, abs=1e-12)

    # every cell: a valid best run with the highest utility among valid runs, or an explicit "no run"
    for cell in doc["cells"]:
        valid = [r for r in doc["runs"] if r["valid"][cell["constraint_set"]]]
        if cell["valid"]:
            best = max(r["utility"][cell["objective"]] for r in valid)
            chosen = next(r for r in doc["runs"] if r["run_id"] == cell["best_run_id"])
            assert chosen["utility"][cell["objective"]] == best
            assert cell["datapacks"] == chosen["datapacks"] and cell["runs_valid"] == len(valid)
        else:
            assert not valid and cell["best_run_id"] is None
            assert cell["note"].startswith(f"no run meets constraint set '{cell['constraint_set']}'")
    unconstrained = [c for c in doc["cells"] if c["constraint_set"] == "unconstrained"]
    assert all(c["valid"] and c["valid_fraction"] == 1.0 for c in unconstrained)

    # Pareto front: no front run dominated; every other run dominated by a front run
    signs = np.array([1.0 if c == "mpl_units_per_hour" else -1.0 for c in PARETO_CRITERIA])
    points = {r["run_id"]: signs * np.array([r["metrics"][c] for c in PARETO_CRITERIA]) for r in doc["runs"]}

    def dominates(a, b):
        return bool(np.all(a >= b) and np.any(a > b))

    front = set(doc["pareto_front"]["run_ids"])
    assert front and doc["pareto_front"]["hypervolume"] > 0
    for run_id, p in points.items():
        dominated = any(dominates(q, p) for q in points.values())
        assert dominated == (run_id not in front), run_id

    # registry filters: one objective's runs on one datapack (the two seeds)
    out3 = tmp_path / "surface_filtered"
    assert main(["solve", "--db-url", db_url, "--objective", "safety", "--datapacks", "dw_fragile",
                 "--motor-backend", "dishwashing", "--output-dir", str(out3)]) == 0
    doc3 = json.loads((out3 / "objective_surface.json").read_text())
    assert sorted((r["objective"], tuple(r["datapacks"]), r["seed"]) for r in doc3["runs"]) == \
        [("safety", ("dw_fragile",), 0), ("safety", ("dw_fragile",), 1)]
    assert main(["solve", "--db-url", db_url, "--task-id", "dishwashing_realistic"]) == 2

    # the JSONL export solves to the same answer
    out2 = tmp_path / "surface_from_jsonl"
    assert main(["solve", "--episodes-jsonl", str(export), "--constraints", str(CONSTRAINTS),
                 "--output-dir", str(out2)]) == 0
    doc2 = json.loads((out2 / "objective_surface.json").read_text())
    assert doc2["cells"] == doc["cells"] and doc2["pareto_front"] == doc["pareto_front"]
