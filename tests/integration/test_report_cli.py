"""`econmotor report` end to end: the spec's command line on real backends, pricing checked by
hand, bad input rejected before anything is written, failures and interrupts recorded."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from econmotor.cli import main
from econmotor.motor_backend.results import MotorEvalResult, summarize_episodes
from econmotor.store import Registry
from econmotor.tasks import get_task

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "report_task_pricing_and_performance.py"


def written(workdir: Path) -> list[str]:
    return sorted(p.name for p in workdir.iterdir() if p.name != "configs")


def run_script(args: list[str], cwd: Path, timeout: int = 240) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "COLUMNS": "120"}
    env.pop("ECONMOTOR_DB_URL", None)
    return subprocess.run([sys.executable, str(SCRIPT), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          check=False,
                          timeout=timeout)


def check_outputs(result: subprocess.CompletedProcess, out_dir: Path) -> dict:
    """All four outputs exist; returns the JSON document."""
    assert result.returncode == 0, result.stderr[-3000:]
    assert "metric (unit)" in result.stdout and "price per unit at the point estimate" in result.stdout  # the table
    html_line = [ln for ln in result.stdout.splitlines() if ln.startswith("HTML report: ")]
    assert html_line, result.stdout[-2000:]
    html = Path(html_line[0].removeprefix("HTML report: ").strip())
    assert html.parent.resolve() == out_dir.resolve() and "data:image/png;base64," in html.read_text()
    (doc_path,) = out_dir.glob("*.json")
    assert doc_path.with_suffix(".md").read_text().startswith("# Task pricing report")
    return json.loads(doc_path.read_text())


def check_prices_by_hand(doc: dict, share: float) -> None:
    """Recompute DESIGN.md §3 from the document's own inputs and measured metrics."""
    inputs = {r["name"]: r["value"] for r in doc["inputs"]}
    agg = doc["pricing"]["aggregate"]
    mpl, kwh_h = inputs["robot_mpl_units_per_hour"], inputs["robot_energy_kwh_per_hour"]
    cost_h = (inputs["robot_capex_usd"] / inputs["robot_lifetime_h"] + inputs["maintenance_usd_per_hour"]
              + inputs["supervision_usd_per_hour"] + inputs["energy_price_usd_per_kwh"] * kwh_h)
    human = inputs["wage_human_usd_per_hour"] / inputs["mp_human_units_per_hour"]
    assert agg["robot_cost_usd_per_hour"] == pytest.approx(cost_h)
    assert agg["human_unit_cost_usd"] == pytest.approx(human)
    if mpl > 0:
        unit = cost_h / mpl
        price = unit + share * max(human - unit, 0.0)
        assert agg["robot_unit_cost_usd"] == pytest.approx(unit)
        assert agg["price_usd_per_unit"] == pytest.approx(price)
        assert agg["price_usd_per_robot_hour"] == pytest.approx(price * mpl)
        assert agg["customer_saving_usd_per_hour"] == pytest.approx((human - price) * mpl)
    assert mpl == pytest.approx(doc["metrics"]["econ"]["mpl_units_per_hour"])


@pytest.mark.slow
def test_spec_command_line_on_dishwashing_writes_all_four_outputs(workdir: Path) -> None:
    out = workdir / "out"
    result = run_script([
        "--task-id", "dishwashing", "--motor-backend", "dishwashing",
        "--objective-config", "configs/objectives/example_objective.yaml",
        "--datapacks", "configs/datapacks/dishwashing_varied_crockery.yaml",
        "--objective-name", "baseline_logging_error_min",
        "--notes", "G1/T1 warehouse logging baseline with high error penalty",
        "--num-envs", "2", "--max-steps", "300", "--eval-episodes", "3",
        "--output-dir", str(out), "--spread-share", "0.4"], workdir)
    doc = check_outputs(result, out)
    check_prices_by_hand(doc, 0.4)
    assert doc["objective"]["name"] == "baseline_logging_error_min"
    assert doc["datapacks"] == ["dishwashing_varied_crockery"] and doc["notes"].startswith("G1/T1")
    assert doc["runs"]["train"]["status"] == "completed" and doc["runs"]["eval"]["parent_run_id"] == 1
    assert len(doc["episodes"]) == 3 and doc["training_curve"]
    reg = Registry(create=False)  # ./.econmotor/registry.sqlite, created on first use
    assert [(r.kind, r.status) for r in reg.runs()] == [("train", "completed"), ("eval", "completed")]
    assert len(reg.episodes(kind="eval")) == 3 and reg.known_datapack_ids() == ["dishwashing_varied_crockery"]
    assert reg.reports()[0].document["pricing"] == doc["pricing"]


@pytest.mark.slow
def test_spec_command_line_on_mujoco_courier_writes_all_four_outputs(workdir: Path) -> None:
    (workdir / "friction.yaml").write_text("id: courier_friction\ndomain_randomization:\n"
                                           "  friction_range: [0.8, 1.2]\n")
    out = workdir / "out"
    result = run_script([
        "--task-id", "hopper_courier", "--motor-backend", "mujoco",
        "--objective-config", "configs/objectives/throughput.yaml", "--datapacks", "friction.yaml",
        "--objective-name", "courier_throughput", "--notes", "hopper courier smoke",
        "--num-envs", "2", "--max-steps", "512", "--eval-episodes", "2", "--output-dir", str(out)], workdir)
    doc = check_outputs(result, out)
    check_prices_by_hand(doc, 0.5)
    assert doc["task"]["unit"].startswith("delivery leg") and doc["backend"] == "mujoco"
    assert doc["datapacks"] == ["courier_friction"] and len(doc["episodes"]) == 2


def _record_hand_made_eval(url: str) -> int:
    # Two 1-hour shifts: 60 dishes/0 errors/120 Wh and 40 dishes/10 errors/80 Wh.
    task = get_task("dishwashing")
    raw, econ, eps = summarize_episodes(
        [{"units_completed": 60, "errors": 0, "episode_length_s": 3600, "energy_wh": 120},
         {"units_completed": 40, "errors": 10, "episode_length_s": 3600, "energy_wh": 80}], task.economics)
    with Registry(url) as reg:
        reg.record_task(task)
        return reg.record_run("eval", MotorEvalResult("p", "dishwashing", "dishwashing", raw, econ, eps),
                              objective={"name": "hand", "mpl_weight": 1.0}, seed=3)


def test_report_from_recorded_runs_matches_the_worked_example(workdir: Path) -> None:
    url = f"sqlite:///{workdir / 'reg.sqlite'}"
    run_id = _record_hand_made_eval(url)
    assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--db-url", url,
                 "--output-dir", "out", "--output-json", "doc.json", "--spread-share", "0.25"]) == 0
    doc = json.loads((workdir / "doc.json").read_text())
    agg, dist = doc["pricing"]["aggregate"], doc["pricing"]["distributions"]
    # pool: 100 dishes / 2 h = 50/h; e = 10/110; E = 200 Wh / 2 h = 0.1 kWh/h
    # cost/h = 1.75 + 0.9 + 2.0 + 0.12*0.1 = 4.662; unit cost 0.09324; spread 0.30 - 0.09324 = 0.20676
    # price = 0.09324 + 0.25*0.20676 = 0.14493; /h = 7.2465; saving (0.30 - 0.14493)*50 = 7.7535
    # break-even 35000 / (7.2465 - 2.912) = 8074.75 h; wage 0.30*50 - 1.0*(10/110)*50 = 10.4545
    expected = {"mpl_units_per_hour": 50.0, "robot_cost_usd_per_hour": 4.662, "robot_unit_cost_usd": 0.09324,
                "spread_per_unit_usd": 0.20676, "price_usd_per_unit": 0.14493,
                "price_usd_per_robot_hour": 7.2465, "customer_saving_usd_per_hour": 7.7535,
                "break_even_hours": 35000 / 4.3345, "implied_wage_usd_per_hour": 15 - 50 / 11,
                "wage_parity": (15 - 50 / 11) / 18, "energy_productivity_units_per_kwh": 500.0}
    assert {k: agg[k] for k in expected} == pytest.approx(expected)
    # per shift unit costs: 4.6644/60 = 0.07774 and 4.6596/40 = 0.11649
    assert dist["robot_unit_cost_usd"]["mean"] == pytest.approx((0.07774 + 0.11649) / 2)
    assert dist["robot_unit_cost_usd"]["p10"] == pytest.approx(0.07774 + 0.1 * (0.11649 - 0.07774))
    assert doc["runs"]["priced"] == run_id and doc["registry"]["report_id"] == 1
    assert (workdir / "out" / f"dishwashing_run{run_id}.html").is_file()


BAD_INPUTS = [
    (["--task-id", "no_such_task", "--motor-backend", "dishwashing"], "unknown task id 'no_such_task'"),
    (["--task-id", "dishwashing", "--motor-backend", "warp9"], "unknown motor backend 'warp9'"),
    (["--task-id", "dishwashing", "--motor-backend", "mujoco"],
     "--motor-backend: task 'dishwashing' does not run on 'mujoco' (allowed: dishwashing)"),
    (["--task-id", "dishwashing", "--motor-backend", "dishwashing", "--datapacks", "configs/datapacks/nope.yaml"],
     "nope.yaml: file not found"),
    (["--task-id", "dishwashing", "--motor-backend", "dishwashing",
      "--datapacks", "configs/datapacks/dishwashing_nominal.yaml,ghost_pack"],
     "--datapacks: key 'ghost_pack': unknown datapack id and not a YAML file"),
    (["--task-id", "dishwashing", "--motor-backend", "dishwashing", "--objective-config", "bad_objective.yaml"],
     "key 'mpl_weigth': unknown key (did you mean 'mpl_weight'?)"),
    (["--task-id", "dishwashing_cheap", "--motor-backend", "dishwashing", "--tasks-file", "negative_wage.yaml"],
     "wage_human_usd_per_hour.value': must not be negative"),
    (["--task-id", "dishwashing", "--motor-backend", "dishwashing", "--spread-share", "2"], "--spread-share"),
    (["--task-id", "hopper_courier", "--motor-backend", "mujoco",
      "--objective-config", "configs/objectives/example_objective.yaml"], "extra_weights.stability_margin"),
]


@pytest.mark.parametrize("args, message", BAD_INPUTS, ids=[m[:30] for _, m in BAD_INPUTS])
def test_bad_input_is_a_clear_error_and_writes_nothing(workdir: Path, capsys, args, message) -> None:
    (workdir / "bad_objective.yaml").write_text("mpl_weigth: 1.0\n")
    (workdir / "negative_wage.yaml").write_text(
        "tasks:\n  dishwashing_cheap:\n    unit: dish\n    economics:\n"
        "      wage_human_usd_per_hour: {value: -5.0, source: typo}\n    backends: {dishwashing: {}}\n")
    assert main(["report", *args, "--max-steps", "50"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert message in err
    if "task id" in message:
        assert "known task ids:" in err and "hopper_courier" in err
    assert [n for n in written(workdir) if n not in ("bad_objective.yaml", "negative_wage.yaml")] \
        in ([], ["runs"])  # no registry, no report (the MuJoCo backend may make its empty runs/ folder)
    assert not (workdir / ".econmotor").exists() and not (workdir / "reports").exists()


@pytest.mark.slow
def test_failure_after_training_keeps_the_run_and_says_how_to_report(workdir: Path, capsys, monkeypatch) -> None:
    (workdir / "blocked").write_text("a file where the report directory should go")
    args = ["report", "--task-id", "dishwashing", "--motor-backend", "dishwashing", "--max-steps", "200"]
    assert main([*args, "--output-dir", "blocked/out"]) == 2  # checked before training: nothing recorded
    assert "--output-dir" in capsys.readouterr().err and not (workdir / ".econmotor").exists()

    import econmotor.report.pipeline as pipeline

    def disk_full(*a, **k):  # the disk fills up while the report is written
        raise OSError(28, "No space left on device")

    with monkeypatch.context() as patch:
        patch.setattr(pipeline, "write_report", disk_full)
        code = main([*args, "--output-dir", "out"])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2 and "the report failed after training" in err
    assert "econmotor report --motor-backend none --task-id dishwashing --run-id 1" in err
    reg = Registry(create=False)
    assert reg.run(1).status == "completed" and len(reg.episodes(run_ids=[1])) == 5
    assert reg.reports() == []  # no report row naming files that were never written
    assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--run-id", "1",
                 "--output-dir", "out"]) == 0
    # run 1 is priced by its evaluation run (the sequential evaluation a report adds after training)
    assert [f.name for f in (workdir / "out").glob("dishwashing_run*.html")] == ["dishwashing_run2.html"]
    capsys.readouterr()
    # the same run asked for twice (or a training run and its evaluation run) is priced once
    assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--run-id", "1", "--run-id", "1",
                 "--output-dir", "twice"]) == 0
    out, err = capsys.readouterr()
    assert out.count("pricing run #2") == 1 and "each is priced once" in " ".join(err.split())


#: runs argv[1:] with SIGINT ignored (the disposition a non-interactive shell hands to background
#: jobs; an ignored signal stays ignored across exec). A shim, not ``preexec_fn``: that would run
#: Python in a child forked from this JAX-threaded process (JAX warns: it can deadlock).
IGNORE_SIGINT_THEN_EXEC = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_IGN); "
                           "os.execv(sys.executable, [sys.executable, *sys.argv[1:]])")


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_training_run_is_recorded_as_interrupted(workdir: Path, signum: int) -> None:
    """Started with SIGINT ignored (as `(trap '' INT; make test)` does), the CLI still stops on the signal,
    records the run as interrupted and says what it kept; the child is always killed and reaped."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-c", IGNORE_SIGINT_THEN_EXEC, str(SCRIPT), "--task-id", "dishwashing",
                             "--motor-backend", "dishwashing", "--max-steps", "500000"], cwd=workdir, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        db = workdir / ".econmotor" / "registry.sqlite"
        deadline = time.monotonic() + 120
        status = None
        while time.monotonic() < deadline and status is None and proc.poll() is None:
            time.sleep(0.5)
            if db.exists():
                with sqlite3.connect(db, timeout=30) as conn:
                    try:
                        row = conn.execute("SELECT status FROM runs").fetchone()
                    except sqlite3.OperationalError:  # tables not created yet
                        row = None
                status = row[0] if row else None
        assert status == "running", proc.stderr.read() if proc.poll() is not None else "no run recorded in time"
        time.sleep(1.0)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=30)  # reap it and close its pipes, whatever happened above
    assert proc.returncode == 128 + signum, err[-2000:]  # 130 for SIGINT, 143 for SIGTERM
    err = " ".join(err.split())
    assert "interrupted" in err and "Kept:" in err and "start again: econmotor report --task-id dishwashing" in err
    run = Registry(create=False).run(1)
    assert run.status == "interrupted" and "KeyboardInterrupt" in run.error and run.finished_at is not None


def test_datapacks_flag_takes_commas_repeats_and_spaces(workdir: Path) -> None:
    from econmotor.cli.options import split_datapack_values
    from econmotor.config.datapacks import parse_datapack

    assert split_datapack_values(["a.yaml,b", "c d", " e "]) == ["a.yaml", "b", "c", "d", "e"]
    url = f"sqlite:///{workdir / 'reg.sqlite'}"
    first = _record_hand_made_eval(url)
    with Registry(url) as reg:
        reg.record_datapacks([parse_datapack({"id": i}, "<test>") for i in ("dp_a", "dp_b", "dp_c")])
        run = reg.run(first)
        result = MotorEvalResult("p", "dishwashing", "dishwashing", run.raw_metrics, run.econ_metrics,
                                 [e.summary for e in reg.episodes(run_ids=[first])])
        both = reg.record_run("eval", result, objective={"name": "hand"}, datapack_ids=["dp_a", "dp_b", "dp_c"])
        reg.record_run("eval", result, objective={"name": "hand"}, datapack_ids=["dp_a"])  # newest
    for flags in (["--datapacks", "dp_a", "dp_b"], ["--datapacks", "dp_a,dp_c"], ["--datapacks", "dp_b",
                                                                                   "--datapacks", "dp_c"]):
        assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--db-url", url,
                     *flags, "--output-json", "picked.json", "--output-dir", "out"]) == 0
        assert json.loads((workdir / "picked.json").read_text())["runs"]["priced"] == both


@pytest.mark.slow
def test_demo_prints_the_html_report_path_last(workdir: Path) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "COLUMNS": "120"}
    env.pop("ECONMOTOR_DB_URL", None)
    entry = "import sys; from econmotor.cli import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", entry, "demo", "--max-steps", "512", "--eval-episodes", "1"],
                            cwd=workdir, env=env, capture_output=True, text=True, timeout=240, check=False)
    assert result.returncode == 0, result.stderr[-3000:]
    last = result.stdout.strip().splitlines()[-1]
    assert last == "HTML report: reports/demo/hopper_courier_run2.html"
    doc = json.loads((workdir / "reports" / "demo" / "hopper_courier_run2.json").read_text())
    assert doc["task"]["task_id"] == "hopper_courier" and doc["runs"]["train"]["max_steps"] == 512
    from econmotor.motor_backend.mjx.backend import MjxBackend

    used, _ = MjxBackend.resolve_num_envs(MjxBackend(runs_dir=workdir).settings("hopper_courier"), 0)
    assert doc["runs"]["train"]["num_envs"] == used  # the catalog's default (capped on a CPU), as the backend used it
    from econmotor.cli.demo import DEMO_HYPERPARAMETERS, DEMO_SELECT_EPISODES

    run = doc["runs"]["train"]["config"]["backend_config"]  # the demo's own PPO and held-out cap, as recorded
    assert run["hyperparameters"]["hidden_sizes"] == DEMO_HYPERPARAMETERS["hidden_sizes"] == [128, 128]
    assert run["hyperparameters"]["reward_scaling"] == DEMO_HYPERPARAMETERS["reward_scaling"] == 0.1
    assert run["selection"]["episodes"] == DEMO_SELECT_EPISODES == 96
    # the demo's own objective file (package data), weights as written there
    assert doc["objective"]["name"] == "courier_safety_first"
    assert doc["objective"]["overlay"] == {"mpl_per_hour": 1.0, "energy_kwh": -0.1, "error_rate": -5.0,
                                           "risk_score": -200.0}
