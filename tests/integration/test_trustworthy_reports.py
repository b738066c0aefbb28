"""Reports a buyer can trust (issue 13): no price for a robot that fails, runs that never overwrite each
other, every run in the registry and named when priced, output that reads at 80 columns."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from econmotor.cli import main
from econmotor.motor_backend.results import MotorEvalResult, summarize_episodes
from econmotor.store import Registry
from econmotor.tasks import get_task, load_catalog


def _record_eval(url: str, raw_episodes: list[dict], task_id: str = "hopper_courier", name: str = "hand") -> int:
    task = get_task(task_id)
    raw, econ, eps = summarize_episodes(raw_episodes, task.economics)
    with Registry(url) as reg:
        reg.record_task(task)
        return reg.record_run("eval", MotorEvalResult("p", task_id, "mujoco", raw, econ, eps),
                              objective={"name": name}, seed=3)


#: a hopper that falls in every one of 5 evaluation episodes, 0.3 legs into each
ALL_FALLS = [{"units_completed": 0.3, "errors": 1, "episode_length_s": 3.0, "energy_wh": 0.05,
              "termination_reason": "fall"} for _ in range(5)]
#: 60 steady episodes of 8 s, 1.8-2.1 legs each, no fall: 117 legs, 95% upper bound 0.025
STEADY = [{"units_completed": 1.8 + 0.1 * (i % 4), "errors": 0, "episode_length_s": 8.0, "energy_wh": 0.2}
          for i in range(60)]


def test_a_policy_that_falls_in_every_episode_gets_no_price_in_any_output(workdir: Path, capsys) -> None:
    url = f"sqlite:///{workdir / 'reg.sqlite'}"
    run_id = _record_eval(url, ALL_FALLS)
    rc = main(["report", "--motor-backend", "none", "--task-id", "hopper_courier", "--db-url", url,
               "--output-dir", "out"])
    assert rc == 0  # a verdict, not an error
    out = " ".join(capsys.readouterr().out.split())
    assert f"pricing run #{run_id}: eval run of objective 'hand'" in out
    assert "the latest completed run of task 'hopper_courier'" in out
    assert "NOT DEPLOYABLE" in out and "Not deployable: falls in 5 of 5 episodes" in out
    assert "95% upper bound on the fall rate 0.972 vs 0.05 accepted (0.002 for a human)" in out
    assert "No price is recommended" in out and "Evidence: 5 evaluation episodes, 6.5 units attempted" in out
    doc = json.loads((workdir / "out" / f"hopper_courier_run{run_id}.json").read_text())
    assert doc["verdict"]["deployable"] is False and doc["recommendation"] is None
    assert doc["verdict"]["reasons"][0].startswith("falls in 5 of 5 episodes")
    assert doc["uncertainty"]["evidence"]["episodes"] == 5
    md = (workdir / "out" / f"hopper_courier_run{run_id}.md").read_text()
    page = (workdir / "out" / f"hopper_courier_run{run_id}.html").read_text()
    for text in (out, md, page):
        low = text.lower()
        assert "not deployable" in low and "recommended price" not in low and "charge " not in low
    assert "## Verdict: not deployable" in md and "## Diagnostics" in md
    assert "<h2>Verdict: not deployable</h2>" in page and 'class="verdict bad">NOT DEPLOYABLE<' in page


def test_a_steady_policy_is_deployable_and_priced_at_the_unfavourable_end(workdir: Path, capsys) -> None:
    url = f"sqlite:///{workdir / 'reg.sqlite'}"
    run_id = _record_eval(url, STEADY)
    assert main(["report", "--motor-backend", "none", "--task-id", "hopper_courier", "--db-url", url,
                 "--output-dir", "out", "--output-json", "doc.json"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    doc = json.loads((workdir / "doc.json").read_text())
    rec, iv = doc["recommendation"], doc["uncertainty"]["intervals"]
    assert doc["verdict"]["deployable"] is True
    assert rec["price_usd_per_unit"] > rec["point_price_usd_per_unit"] == doc["pricing"]["aggregate"][
        "price_usd_per_unit"]
    assert rec["price_usd_per_100_units"] == pytest.approx(100 * rec["price_usd_per_unit"])
    assert iv["error_rate"]["high"] == pytest.approx(1 - 0.05 ** (1 / 117))  # 0 falls in 117 legs
    assert "Deployable: falls in none of 60 episodes" in out and "Charge " in out
    assert "priced at the unfavourable end of the 90% intervals" in out and "x a human's wage" in out
    assert f"pricing run #{run_id}" in out


def test_report_from_the_registry_names_every_run_it_prices(workdir: Path, capsys) -> None:
    url = f"sqlite:///{workdir / 'reg.sqlite'}"
    first = _record_eval(url, STEADY, name="first")
    second = _record_eval(url, ALL_FALLS, name="second")
    assert main(["report", "--motor-backend", "none", "--task-id", "hopper_courier", "--db-url", url,
                 "--run-id", str(first), "--run-id", str(second), "--output-dir", "out"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"pricing run #{first}: eval run of objective 'first'" in out
    assert f"pricing run #{second}: eval run of objective 'second'" in out and "asked for with --run-id" in out
    assert {p.name for p in (workdir / "out").glob("*.json")} == {f"hopper_courier_run{first}.json",
                                                                  f"hopper_courier_run{second}.json"}
    # by default: the latest completed run of the task and the objective asked for
    assert main(["report", "--motor-backend", "none", "--task-id", "hopper_courier", "--db-url", url,
                 "--objective-name", "first", "--output-dir", "out2"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"pricing run #{first}:" in out and "task 'hopper_courier' and objective 'first'" in out


def _snapshot(root: Path) -> dict[str, tuple[str, int]]:
    return {str(p.relative_to(root)): (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mtime_ns)
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.slow
def test_train_is_recorded_and_resume_of_a_finished_run_changes_nothing(workdir: Path, capsys) -> None:
    url = f"sqlite:///{workdir / 'reg.sqlite'}"
    run_dir = workdir / "runs" / "hop"
    assert main(["train", "--task-id", "hopper_courier", "--num-envs", "1", "--max-steps", "512",
                 "--eval-episodes", "1", "--output-dir", str(run_dir), "--db-url", url]) == 0
    out = " ".join(capsys.readouterr().out.split())
    with Registry(url, create=False) as reg:
        (run,) = reg.runs()
    assert (run.kind, run.status, run.task_id, run.max_steps) == ("train", "completed", "hopper_courier", 512)
    assert run.policy_path == str(run_dir) and run.config["run_dir"] == str(run_dir)
    assert f"recorded as run #{run.id}" in out
    before = _snapshot(run_dir)
    assert main(["train", "--task-id", "hopper_courier", "--num-envs", "1", "--max-steps", "1024",
                 "--output-dir", str(run_dir), "--resume", "--db-url", url]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "is a complete run" in out and "nothing changed" in out
    assert _snapshot(run_dir) == before
    with Registry(url, create=False) as reg:
        assert len(reg.runs()) == 1  # nothing recorded either


@pytest.mark.slow
def test_two_shadow_runs_leave_two_complete_run_directories(workdir: Path, capsys) -> None:
    args = ["shadow", "--env", "dishwashing", "--total-steps", "120", "--learning-starts", "50",
            "--eval-episodes", "1", "--max-episode-steps", "30"]
    assert main([*args, "--seed", "1"]) == 0
    assert main([*args, "--seed", "2"]) == 0
    dirs = sorted(p for p in (workdir / "runs" / "shadow").iterdir())
    assert len(dirs) == 2
    with Registry(create=False) as reg:
        runs = reg.runs(kind="shadow")
    assert [r.status for r in runs] == ["completed", "completed"]
    assert sorted(str(Path(r.policy_path).resolve()) for r in runs) == [str(d.resolve()) for d in dirs]
    for seed, run_dir in zip((1, 2), sorted(dirs, key=lambda d: d.name.split("-s")[1]), strict=True):
        run = json.loads((run_dir / "run.json").read_text())
        summary = json.loads((run_dir / "shadow_summary.json").read_text())
        lines = (run_dir / "shadow_episodes.jsonl").read_text().splitlines()
        assert run["config"]["seed"] == seed and Path(run["config"]["save_dir"]).resolve() == run_dir.resolve()
        assert summary["steps"] == 120 and summary["episodes"] == len(lines) >= 4  # episodes of <= 30 steps
        assert (run_dir / "sac_model.zip").is_file()
    # an explicit --save-dir that already holds a run is refused, not overwritten
    assert main([*args, "--save-dir", str(dirs[0])]) == 2
    assert "already holds a shadow run" in " ".join(capsys.readouterr().err.split())


def test_tasks_at_80_columns_shows_every_task_id_whole(workdir: Path) -> None:
    env = {**os.environ, "COLUMNS": "80", "OMP_NUM_THREADS": "1"}
    entry = "import sys; from econmotor.cli import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", entry, "tasks"], env=env, capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert max(len(line) for line in lines) <= 80
    first_cells = {line.split("│")[1].strip() for line in lines if line.startswith("│")}
    assert set(load_catalog().ids()) <= first_cells
