"""Holosoma jobs are dataclasses serialised once (JSON for the runner) and parsed once; a bad job is a
ConfigError naming the file and the field."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.holosoma.host.plan import RunPlan
from econmotor.motor_backend.holosoma.job_specs import (
    EvaluateJob,
    Overlay,
    ProbeJob,
    TrainJob,
    parse_job,
)

PLAN = RunPlan(experiment="g1_29dof", algo="ppo", simulator="mujoco", device="cpu", num_envs=1, iterations=2,
               env_steps=48, cpu_sized=True, messages=("classic MuJoCo runs one env",), requested={"num_envs": 4})
TRAIN = TrainJob(run_dir="/runs/r", run_name="t-seed0", plan=PLAN, seed=0, motion_task=False,
                 overlay=Overlay(weights={"mpl": 0.5}, params={"progress_mode": "velocity", "meter": {"a": 1.0}}),
                 overrides={"randomization": {}, "curriculum": {}, "terrain": None, "motion_file": None,
                            "evaluation": {}})
EVALUATE = EvaluateJob(run_dir="/r", checkpoint="/r/model_1.pt", num_steps=100, episode_length_s=4.0, seed=1,
                       simulator="mujoco")


@pytest.mark.parametrize("job", [ProbeJob(), TRAIN, replace(TRAIN, seed=7, motion_task=True), EVALUATE])
def test_a_job_round_trips_through_its_json(job) -> None:
    text = job.to_json()
    assert json.loads(text)["action"] == job.action
    assert parse_job(text, "job.json") == job


def test_the_json_layout_is_the_runners_and_each_job_names_its_log() -> None:
    values = json.loads(TRAIN.to_json())
    assert values["overlay"]["params"]["meter"] == {"a": 1.0} and values["plan"]["num_envs"] == 1
    assert (ProbeJob().log_name, TRAIN.log_name, EVALUATE.log_name) == ("probe", "train", "evaluate")


@pytest.mark.parametrize(("change", "key", "words"), [
    (lambda v: v.update(action="dance"), "action", "unknown job action 'dance'"),
    # the sim-to-sim evaluation runs in the main interpreter now (locomotion/evaluation.py), not as a job
    (lambda v: v.update(action="sim2sim"), "action", r"unknown job action 'sim2sim'.*evaluate, probe, train"),
    (lambda v: v.pop("seed"), "seed", "missing"),
    (lambda v: v.update(colour="red"), "colour", "not a field of a TrainJob"),
    (lambda v: v["plan"].update(num_envs="4"), "plan.num_envs", "must be a JSON int"),
    (lambda v: v["plan"].update(cpu_sized=1), "plan.cpu_sized", "must be a JSON bool"),
    (lambda v: v.update(motion_task=1), "motion_task", "must be a JSON bool"),
    (lambda v: v["overlay"].pop("weights"), "overlay.weights", "missing"),
])
def test_a_bad_job_names_the_file_and_the_field(change, key, words) -> None:
    values = json.loads(TRAIN.to_json())
    change(values)
    with pytest.raises(ConfigError, match=words) as info:
        parse_job(json.dumps(values), "train_job.json")
    assert info.value.source == "train_job.json" and info.value.key == key


def test_a_file_that_is_not_json_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="job.json.*not a JSON job"):
        parse_job("{not json", "job.json")
