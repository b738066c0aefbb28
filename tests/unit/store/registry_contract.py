"""Registry behaviour checks, run against SQLite (tests/unit/store/test_registry.py) and a
real PostgreSQL server (tests/integration/test_registry_postgres.py). Each check takes
the URL of an empty database."""

from __future__ import annotations

import math

import pytest
from sqlalchemy import update

from econmotor.config.datapacks import parse_datapack
from econmotor.errors import RegistryError, UnknownNameError
from econmotor.motor_backend.results import MotorEvalResult, MotorTrainingResult, summarize_episodes
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.store import Registry
from econmotor.store.models import SchemaVersionRow
from econmotor.tasks import get_task

RAW_EPISODES = [
    {"units_completed": 10, "errors": 1, "episode_length_s": 600, "energy_wh": 5.0, "return": 3.5},
    {"units_completed": 0, "errors": 3, "episode_length_s": 60, "energy_wh": 1.0,
     "termination_reason": "catastrophic_error"},
]


def _result(kind: str = "train", task_id: str = "dishwashing", backend: str = "dishwashing"):
    econ = get_task(task_id).economics
    raw, metrics, episodes = summarize_episodes(RAW_EPISODES, econ)
    if kind == "train":
        return MotorTrainingResult("runs/p1", task_id, backend, raw, metrics, episodes,
                                   training_curve=[{"timesteps": 100, "mean_return": 1.5}],
                                   config={"lr": 3e-4}, artifacts={"policy": "runs/p1/model.zip"})
    return MotorEvalResult("runs/p1", task_id, backend, raw, metrics, episodes)


def check_run_round_trip_keeps_metrics_and_infinities(url: str) -> None:
    reg = Registry(url)
    reg.record_task(get_task("dishwashing"))
    obj = EconomicObjectiveSpec(mpl_weight=2.0, error_weight=1.0, name="throughput")
    run_id = reg.record_run("train", _result(), objective=obj, datapack_ids=["dp_a", "dp_b"], seed=7,
                            num_envs=2, max_steps=500, notes="first")
    run = reg.run(run_id)
    assert (run.kind, run.status, run.seed, run.num_envs, run.max_steps) == ("train", "completed", 7, 2, 500)
    assert run.objective_name == "throughput" and run.objective["mpl_weight"] == 2.0
    assert run.datapack_ids == ("dp_a", "dp_b") and run.notes == "first"
    assert run.policy_path == "runs/p1" and run.artifacts == {"policy": "runs/p1/model.zip"}
    assert run.config["backend_config"] == {"lr": 3e-4}
    assert run.training_curve == [{"timesteps": 100, "mean_return": 1.5}]
    assert run.econ_metrics == _result().econ_metrics
    assert run.finished_at is not None and run.finished_at.tzinfo is not None
    episodes = reg.episodes()
    assert [e.episode_index for e in episodes] == [0, 1]
    assert episodes[1].termination_reason == "catastrophic_error"
    assert math.isinf(episodes[1]["robot_unit_cost_usd"]) and episodes[1]["spread_per_unit_usd"] == -math.inf
    assert episodes[0]["mpl_units_per_hour"] == pytest.approx(60.0)
    arrays = reg.episode_arrays(["mpl_units_per_hour", "robot_unit_cost_usd"])
    assert arrays["run_id"].tolist() == [run_id, run_id]
    assert arrays["mpl_units_per_hour"].tolist() == pytest.approx([60.0, 0.0])
    assert math.isinf(arrays["robot_unit_cost_usd"][1])
    reg.close()


def check_filters_select_runs_and_episodes(url: str) -> None:
    reg = Registry(url)
    a = reg.record_run("train", _result(), objective={"name": "throughput"}, datapack_ids=["dp_a", "dp_b"])
    b = reg.record_run("eval", _result("eval"), objective={"name": "safety"}, datapack_ids=["dp_a"],
                       parent_run_id=a)
    c = reg.record_run("train", _result(task_id="dishwashing_realistic"), objective={"name": "throughput"})
    d = reg.start_run("train", "dishwashing", "dishwashing", objective={"name": "throughput"})
    assert [r.id for r in reg.runs()] == [a, b, c, d]
    assert [r.id for r in reg.runs(task_id="dishwashing")] == [a, b, d]
    assert [r.id for r in reg.runs(datapacks=["dp_a"])] == [a, b]
    assert [r.id for r in reg.runs(datapacks="dp_b")] == [a]
    assert [r.id for r in reg.runs(datapacks=["dp_b", "dp_a"])] == [a]
    assert [r.id for r in reg.runs(datapacks=[])] == [c, d]
    assert [r.id for r in reg.runs(objective="safety")] == [b]
    assert [r.id for r in reg.runs(kind="train", status="completed")] == [a, c]
    assert [r.id for r in reg.runs(backend="mujoco")] == []
    assert reg.latest_run(task_id="dishwashing", status="completed").id == b
    assert [r.id for r in reg.child_runs(a)] == [b]
    episodes = reg.episodes(task_id="dishwashing", objective="throughput")
    assert {e.run_id for e in episodes} == {a}  # d is still running: no completed episodes
    assert episodes[0].datapack_ids == ("dp_a", "dp_b") and episodes[0].objective_name == "throughput"
    assert {e.run_id for e in reg.episodes(kind="eval")} == {b}
    assert len(reg.episodes(run_ids=[c])) == 2
    reg.close()


def check_failed_and_interrupted_runs_keep_their_status(url: str) -> None:
    reg = Registry(url)
    kept = reg.record_run("train", _result(), objective={"name": "o"})
    with pytest.raises(ValueError, match="boom"), \
            reg.track_run("train", "dishwashing", "dishwashing", seed=1) as run_id:
        raise ValueError("boom")
    failed = reg.run(run_id)
    assert failed.status == "failed" and "boom" in failed.error and failed.finished_at is not None
    with pytest.raises(KeyboardInterrupt), \
            reg.track_run("eval", "dishwashing", "dishwashing", parent_run_id=kept) as run_id2:
        raise KeyboardInterrupt
    assert reg.run(run_id2).status == "interrupted"
    assert reg.run(kept).status == "completed" and len(reg.episodes(run_ids=[kept])) == 2
    with reg.track_run("eval", "dishwashing", "dishwashing") as run_id3:
        reg.finish_run(run_id3, _result("eval"))
    assert reg.run(run_id3).status == "completed"
    reg.close()


def check_a_failed_write_changes_nothing(url: str) -> None:
    reg = Registry(url)
    run_id = reg.start_run("eval", "dishwashing", "dishwashing")
    bad_episode = {"episode_index": 0, "unserialisable": {1, 2}}
    with pytest.raises(RegistryError, match="registry write failed"):
        reg.finish_run(run_id, raw_metrics={"units_completed": 3.0}, episodes=[bad_episode])
    run = reg.run(run_id)
    assert run.status == "running" and run.raw_metrics == {} and reg.episodes(status=None) == []
    assert reg.record_episodes(run_id, [{"mpl_units_per_hour": 5.0}]) == 1
    assert reg.record_episodes(run_id, [{"mpl_units_per_hour": 6.0}]) == 1
    assert [e.episode_index for e in reg.episodes(status=None)] == [0, 1]
    with pytest.raises(RegistryError, match="no run with id 999"):
        reg.mark_run(999, "failed")
    with pytest.raises(RegistryError, match="status must be one of"):
        reg.mark_run(run_id, "done")
    reg.close()


def check_datapacks_and_reports_round_trip(url: str) -> None:
    reg = Registry(url)
    pack = parse_datapack({"id": "dr_v1", "description": "d",
                           "domain_randomization": {"friction_range": [0.5, 1.0]}}, "configs/dr.yaml")
    assert reg.record_datapacks([pack]) == ["dr_v1"]
    assert reg.known_datapack_ids() == ["dr_v1"]
    (back,) = reg.datapack_configs(["dr_v1"])
    assert back.to_dict() == pack.to_dict()
    with pytest.raises(UnknownNameError, match="known datapack ids: dr_v1"):
        reg.datapack_configs(["dr_v2"])
    reg.record_task(get_task("dishwashing"))
    report_id = reg.record_report("dishwashing", {"schema_version": 1, "x": math.inf},
                                  {"html": "/tmp/r.html"}, train_run_id=None)
    (rep,) = reg.reports("dishwashing")
    assert rep.id == report_id and rep.document["x"] == math.inf and rep.files == {"html": "/tmp/r.html"}
    reg.close()


def check_schema_version_mismatch_is_refused(url: str) -> None:
    Registry(url).close()
    reg = Registry(url)  # reopening a current database works
    with reg.engine.begin() as conn:
        conn.execute(update(SchemaVersionRow).values(version=99))
    reg.close()
    with pytest.raises(RegistryError, match=r"schema version \[99\].*move the database aside"):
        Registry(url)


CHECKS = [
    check_run_round_trip_keeps_metrics_and_infinities,
    check_filters_select_runs_and_episodes,
    check_failed_and_interrupted_runs_keep_their_status,
    check_a_failed_write_changes_nothing,
    check_datapacks_and_reports_round_trip,
    check_schema_version_mismatch_is_refused,
]
