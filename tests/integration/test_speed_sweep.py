"""The operating-point sweep: the shipped G1 PPO evaluated at each commanded speed, every cell recorded as an eval
run with its speed, completed cells skipped on a re-run, and `econmotor solve` picking each preset's speed with
intervals; `--command-speed` refused where it cannot apply (issue 41, item 5)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from econmotor.analysis.eval_sweep import plan_eval_sweep
from econmotor.analysis.sweep import run_sweep
from econmotor.cli import main
from econmotor.couriers.policy_import import find_holosoma_python
from econmotor.motor_backend.run_dir import EVALUATION_FILE, REPORT_EVAL_SEED_OFFSET
from econmotor.store import Registry

REPO = Path(__file__).resolve().parents[2]
TASK, POLICY = "humanoid_locomotion_g1", "holosoma:g1_29dof/ppo"
SPEEDS = (0.5, 1.0)
#: short episodes (the backend's eval_episode_length_s): 8 s walk part of the first leg at either speed
SHORT = {"eval_episode_length_s": 8.0}


@pytest.fixture(scope="module")
def venv() -> dict[str, str]:
    return {"venv": str(find_holosoma_python(REPO / ".venv-holosoma").parent.parent)}


@pytest.mark.holosoma
def test_a_speed_sweep_records_each_speed_skips_done_cells_and_solve_picks_a_speed(tmp_path, venv, capsys):
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    registry = Registry(url)
    cells = plan_eval_sweep(TASK, "holosoma", POLICY, SPEEDS, [[]], [0], eval_episodes=3, eval_options=SHORT)
    outcomes = run_sweep(registry, cells, tmp_path / "cells", backend_options=venv)
    assert [o.status for o in outcomes] == ["completed", "completed"], [o.error for o in outcomes]

    runs = registry.runs(task_id=TASK, backend="holosoma", kind="eval")
    assert [r.config["commanded_speed_m_per_s"] for r in runs] == list(SPEEDS)
    for run, cell in zip(runs, cells, strict=True):
        assert run.status == "completed" and run.config["cell_key"] == cell.key and run.policy_path == POLICY
        assert run.config["provenance"]["commanded_speed_m_per_s"] == cell.command_speed_m_per_s
        assert run.config["backend_config"]["seed"] == REPORT_EVAL_SEED_OFFSET  # compare --seed 0's episodes
        episodes = registry.episodes(run_ids=[run.id])
        assert len(episodes) == 3 and {e.summary["episode_length_s"] for e in episodes} == {8.0}
        assert {e.summary["commanded_speed_m_per_s"] for e in episodes} == {cell.command_speed_m_per_s}
        assert (tmp_path / "cells" / cell.key / EVALUATION_FILE).is_file()

    again = run_sweep(registry, cells, tmp_path / "cells", backend_options=venv)
    assert [o.status for o in again] == ["skipped", "skipped"]
    assert len(registry.runs()) == 2
    longer = plan_eval_sweep(TASK, "holosoma", POLICY, SPEEDS, [[]], [0], eval_episodes=3,
                             eval_options={"eval_episode_length_s": 9.0})
    assert not {c.key for c in longer} & {c.key for c in cells}  # what is measured is part of the key

    out = tmp_path / "surface"
    assert main(["solve", "--db-url", url, "--task-id", TASK, "--motor-backend", "holosoma", "--run-kind", "eval",
                 "--output-dir", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "speed m/s" in printed and "operating points" in printed
    check_solved(json.loads((out / "objective_surface.json").read_text()), {r.id: r for r in runs})


def check_solved(doc: dict, runs: dict) -> None:
    """Each preset picks the run (speed) of highest mean J, with its interval and margin; every run's operating
    point is its recorded evaluation, pooled the same way."""
    by_id = {r["run_id"]: r for r in doc["runs"]}
    assert {r["commanded_speed_m_per_s"] for r in by_id.values()} == set(SPEEDS)
    assert {c["objective"] for c in doc["choices"]} == {"throughput", "safety", "energy_saver", "balanced",
                                                         "throughput_focused", "premium_safety"}
    for choice in doc["choices"]:
        name = choice["objective"]
        best = max(by_id.values(), key=lambda r: r["utility"][name])
        other = next(r for r in by_id.values() if r is not best)
        assert choice["run_id"] == best["run_id"]
        assert choice["commanded_speed_m_per_s"] == best["commanded_speed_m_per_s"]
        u, m = choice["utility"], choice["margin"]
        assert u["point"] == pytest.approx(best["utility"][name]) and u["low"] <= u["point"] <= u["high"]
        assert choice["runner_up_run_id"] == other["run_id"]
        assert m["point"] == pytest.approx(best["utility"][name] - other["utility"][name])
        assert m["low"] <= m["point"] <= m["high"]
        assert choice["separated"] == (m["low"] > 0)
    assert len(doc["operating_points"]) == 2
    for point in doc["operating_points"]:
        econ = runs[int(point["run_id"])].econ_metrics
        for name in ("mpl_units_per_hour", "energy_wh_per_unit", "battery_units_per_charge", "error_rate"):
            figure = point["figures"][name]
            assert figure["point"] == pytest.approx(econ[name], rel=1e-9), name
            assert figure["low"] <= figure["point"] <= figure["high"], name
        assert point["evidence"]["episodes"] == 3


@pytest.mark.holosoma
def test_the_cli_evaluates_a_shipped_walker_per_speed_and_skips_done_cells(tmp_path, capsys):
    """The command line itself (two speeds, one episode each of the catalog's course)."""
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    args = ["sweep", "--task-id", TASK, "--motor-backend", "holosoma", "--policy", POLICY, "--command-speed", "0.8,1.0",
            "--eval-episodes", "1", "--db-url", url, "--output-dir", str(tmp_path / "cells")]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "2 evaluation cells" in out and "--run-kind eval" in out
    runs = Registry(url, create=False).runs(kind="eval")
    assert [r.config["commanded_speed_m_per_s"] for r in runs] == [0.8, 1.0]
    assert {r.status for r in runs} == {"completed"} and {r.objective_name for r in runs} == {"default"}
    assert len(Registry(url, create=False).episodes(kind="eval")) == 2
    assert main(args) == 0
    assert "skipped" in capsys.readouterr().out
    assert len(Registry(url, create=False).runs()) == 2


@pytest.mark.parametrize(("extra", "words"), [
    (["--command-speed", "0.4,0.6"], ["--command-speed", "give --policy", "training one policy per commanded "
                                      "speed is not supported yet"]),
    (["--policy", POLICY, "--command-speed", "0.4,fast"], ["--command-speed", "expected comma-separated speeds",
                                                          "allowed: e.g. 0.4,0.6,0.8,1.0"]),
    (["--policy", POLICY, "--command-speed", "0.01"], ["--command-speed", "out of range", ">= 0.05"]),
    (["--policy", POLICY, "--command-speed", "0.4,0.4"], ["--command-speed", "named twice"]),
    (["--policy", POLICY, "--preset", "throughput"], ["--preset", "leave --preset out", "allowed: --command-speed"]),
    (["--policy", POLICY, "--max-steps", "100"], ["--max-steps", "leave --max-steps out"]),
    (["--policy", "no/such/run", "--command-speed", "0.4"], ["--policy", "no such run directory",
                                                            "a shipped name"]),
])
def test_command_speed_and_policy_refusals_name_flag_value_and_what_is_allowed(tmp_path, capsys, extra, words):
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    assert main(["sweep", "--task-id", TASK, "--motor-backend", "holosoma", *extra, "--db-url", url]) == 2
    err = " ".join(capsys.readouterr().err.split())
    for word in words:
        assert word in err, err


def test_a_backend_without_a_commanded_course_refuses_command_speed(tmp_path, capsys):
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    assert main(["sweep", "--task-id", "dishwashing", "--motor-backend", "dishwashing", "--policy", "runs/x",
                 "--command-speed", "0.5", "--db-url", url]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "--command-speed" in err and "backend 'dishwashing' walks no course at a commanded speed" in err
    assert "(allowed: holosoma)" in err
