"""The motor-backend contract, held for every backend in the registry.

Parametrised over ``known_backends()``: a backend added to the registry is covered here without
editing this file. Each one trains its declared ``smoke_run`` into ``output_dir`` (which must be
the run directory, holding ``run_config.json`` that names the backend), is evaluated by the
``policy_id`` it returned (the same seed gives the same episodes; another seed, or another policy
on the same seed, other episodes), records the evaluation after training as the base class does
(``<run>/eval/evaluation.json``, seeded from ``seed + TRAINING_EVAL_SEED_OFFSET``), deploys a handle
answering ``act`` and ``step``, names each task's robot apart from itself (one robot, one id on every
backend), and declares its
capabilities, defaults and limits, which the CLI reads instead of knowing backends by name, and says
how an evaluation's figures were made (``MotorEvalResult.provenance``). A
backend that declares ``evaluation_driven`` selects its policy by held-out evaluations: the policy
it keeps, evaluated again on the recorded held-out seeds, gives the J its kept evaluation recorded.
"""

from __future__ import annotations

import inspect
import json
import os
from pathlib import Path

import numpy as np
import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.base import MotorBackendBase, PolicyHandle
from econmotor.motor_backend.capabilities import BackendCapabilities, RunSize
from econmotor.motor_backend.factory import backend_class, environment_options, known_backends, make_motor_backend
from econmotor.motor_backend.results import PROVENANCE_KEY, EvalProvenance
from econmotor.motor_backend.run_dir import (
    EVALUATION_FILE,
    RUN_CONFIG_FILE,
    TRAINING_EVAL_DIR,
    TRAINING_EVAL_SEED_OFFSET,
)
from econmotor.motor_backend.selection import SELECTION_SEED_OFFSET, Selection, SelectionConfig
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.tasks import load_catalog

BACKENDS = known_backends()


def smoke_task(cls: type[MotorBackendBase]) -> str:
    """The backend's declared smoke task, else the first catalog task with an entry for it."""
    catalog = load_catalog()
    if cls.smoke_run.task_id is not None:
        return cls.smoke_run.task_id
    return catalog.ids(cls.name)[0]


@pytest.mark.parametrize("name", BACKENDS)
def test_every_backend_declares_the_contract(name: str) -> None:
    cls = backend_class(name)
    assert issubclass(cls, MotorBackendBase) and cls.name == name
    assert isinstance(cls.capabilities, BackendCapabilities)
    assert isinstance(cls.defaults, RunSize) and cls.defaults.max_steps >= 1 and cls.defaults.num_envs >= 0
    assert isinstance(cls.smoke_run, RunSize) and cls.smoke_run.max_steps <= cls.defaults.max_steps
    assert name in load_catalog().get(smoke_task(cls)).backends
    assert cls.final_policy_file and cls.max_num_envs >= 1
    cls.check_num_envs(cls.max_num_envs)
    with pytest.raises(ConfigError, match=f"more than the '{name}' backend can run.*{cls.max_num_envs:,}"):
        cls.check_num_envs(cls.max_num_envs + 1, "--num-envs")
    parameters = inspect.signature(cls.__init__).parameters
    assert {"task_files", "runs_dir"} <= set(parameters)  # one constructor convention
    for variable, keyword in cls.environment_options.items():  # the edge passes these; each is a keyword
        assert variable.startswith("ECONMOTOR_") and keyword in parameters
    if cls.capabilities.resume:
        assert cls.checkpoint_glob, "a backend that resumes declares its checkpoint files"
    # the evaluation after training is the base's, for every backend (one rule, one record)
    assert cls.evaluate_after_training is MotorBackendBase.evaluate_after_training
    assert cls.training_result is MotorBackendBase.training_result


@pytest.mark.slow
@pytest.mark.parametrize("name", BACKENDS)
def test_train_into_output_dir_evaluate_by_policy_id_and_deploy(name: str, tmp_path: Path) -> None:
    cls = backend_class(name)
    backend = make_motor_backend(name, runs_dir=tmp_path / "runs", **environment_options(name, os.environ))
    task_id, size = smoke_task(cls), cls.smoke_run
    objective = EconomicObjectiveSpec(name="contract", mpl_weight=1.0, error_weight=1.0)
    run_dir = tmp_path / "run"
    trained = backend.train_policy(task_id, objective, [], size.num_envs, size.max_steps, 3, output_dir=run_dir,
                                   eval_episodes=1)
    assert Path(trained.policy_id) == run_dir and trained.backend == name
    config = json.loads((run_dir / RUN_CONFIG_FILE).read_text())
    assert config["task_id"] == task_id and config["backend"] == name
    config["backend"] = "another"
    (run_dir / RUN_CONFIG_FILE).write_text(json.dumps(config))
    with pytest.raises(ConfigError, match=f"a 'another' run, not an? {name} one"):
        backend.deploy_policy_handle(trained.policy_id)  # every backend checks the run before loading it
    config["backend"] = name
    (run_dir / RUN_CONFIG_FILE).write_text(json.dumps(config))
    assert cls.is_complete_run(run_dir) and not (tmp_path / "runs").exists()  # nothing nested elsewhere
    # the evaluation after training: recorded the same way by every backend, seeded from seed + the offset
    recorded = json.loads((run_dir / TRAINING_EVAL_DIR / EVALUATION_FILE).read_text())
    assert trained.raw_metrics["num_episodes"] == 1 and recorded["raw_metrics"] == pytest.approx(trained.raw_metrics)
    assert trained.config["evaluation"] == recorded["config"] and recorded["config"][PROVENANCE_KEY]["evaluator"]
    assert trained.artifacts["evaluation"] == str(run_dir / TRAINING_EVAL_DIR / EVALUATION_FILE)
    after = backend.evaluate_policy(trained.policy_id, task_id, objective, 1, 3 + TRAINING_EVAL_SEED_OFFSET)
    assert outcome(after) == outcome(trained)

    evaluated = backend.evaluate_policy(trained.policy_id, task_id, objective, 1, 11)
    assert evaluated.raw_metrics["num_episodes"] == 1 and len(evaluated.episodes) == 1
    assert np.isfinite(evaluated.econ_metrics["mpl_units_per_hour"])
    # every backend says how its figures were made (report and compare read these declared fields)
    assert evaluated.provenance.evaluator != EvalProvenance().evaluator and evaluated.provenance.figures_from
    assert evaluated.config[PROVENANCE_KEY] == evaluated.provenance.to_dict()
    # an evaluation is a function of its seed and its policy
    again = backend.evaluate_policy(trained.policy_id, task_id, objective, 1, 11)
    other_seed = backend.evaluate_policy(trained.policy_id, task_id, objective, 1, 12)
    other = backend.train_policy(task_id, objective, [], size.num_envs, size.max_steps, 4,
                                 output_dir=tmp_path / "other", eval_episodes=0)
    other_policy = backend.evaluate_policy(other.policy_id, task_id, objective, 1, 11)
    assert "evaluation" not in other.config and not other.episodes  # eval_episodes=0: no evaluation, no record
    assert not (tmp_path / "other" / TRAINING_EVAL_DIR).exists()
    assert outcome(again) == outcome(evaluated)
    assert outcome(other_seed) != outcome(evaluated)
    assert outcome(other_policy) != outcome(evaluated)

    handle = backend.deploy_policy_handle(trained.policy_id)
    assert isinstance(handle, PolicyHandle)
    obs = np.zeros(handle.obs_dim, dtype=np.float32)
    assert np.array_equal(handle.step(obs), handle.act(obs)) and np.all(np.isfinite(handle.act(obs)))


@pytest.mark.parametrize("name", BACKENDS)
def test_run_size_defaults_fill_what_a_request_leaves_out(name: str) -> None:
    defaults = backend_class(name).defaults
    assert defaults.max_steps >= 1 and defaults.num_envs >= 0
    assert defaults.filled(None, None) == defaults
    assert defaults.filled(3, None).num_envs == 3 and defaults.filled(None, 77).max_steps == 77
    assert defaults.filled(0, 5).num_envs == 0  # 0: the task's catalog default, kept


def test_every_backend_names_its_tasks_robot_apart_from_itself() -> None:
    """The registry's robot id is the robot's name, declared by each backend from its task entry: one robot
    has one id on every backend that runs it (no backend name, env id or policy in it)."""
    catalog = load_catalog()
    ids = {(name, task_id): backend_class(name).robot_id(catalog.get(task_id))
           for name in BACKENDS for task_id in catalog.ids(name)}
    for (name, task_id), robot in ids.items():
        assert robot and ":" not in robot and robot != name, (name, task_id, robot)
        assert {r for (_, t), r in ids.items() if t == task_id} == {robot}, task_id  # the same on every backend
    assert ids["mujoco", "hopper_courier"] == ids["mjx", "hopper_courier"] == "hopper"
    assert ids["mujoco", "humanoid_courier"] == ids["mjx", "humanoid_courier"] == "humanoid"
    assert ids["holosoma", "humanoid_locomotion_g1"] == ids["mjx", "humanoid_locomotion_g1"] == "g1_29dof"
    assert ids["holosoma", "humanoid_wbt_g1"] == "g1_29dof" and ids["holosoma", "humanoid_locomotion_t1"] == "t1_29dof"
    assert ids["dishwashing", "dishwashing"] == ids["dishwashing", "dishwashing_realistic"]


class DuckBackend:
    """A plugin with the specification's three methods that does not extend MotorBackendBase."""

    def train_policy(self, *args, **kwargs): ...

    def evaluate_policy(self, *args, **kwargs): ...

    def deploy_policy_handle(self, policy_id): ...


def test_a_duck_typed_plugin_is_refused_with_one_clear_line() -> None:
    from econmotor.errors import BackendError
    from econmotor.motor_backend import factory

    factory.register_motor_backend("duck", f"{__name__}:DuckBackend")
    try:
        with pytest.raises(BackendError, match="'duck' .*DuckBackend.* does not extend .*MotorBackendBase") as info:
            factory.backend_class("duck")
        assert "\n" not in str(info.value)
    finally:
        factory._REGISTRY.pop("duck")


def outcome(result) -> tuple[float, ...]:
    """What an evaluation measured, episode by episode (the raw metrics every backend reports)."""
    keys = ("units_completed", "units_attempted", "errors", "episode_length_s", "energy_wh", "risk_score")
    return tuple(float(ep[k]) for ep in result.episodes for k in keys)


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in BACKENDS if backend_class(n).capabilities.evaluation_driven])
def test_an_evaluation_driven_backend_keeps_the_policy_its_held_out_evaluations_select(name: str,
                                                                                      tmp_path: Path) -> None:
    cls = backend_class(name)
    backend = make_motor_backend(name, runs_dir=tmp_path / "runs", **environment_options(name, os.environ))
    task_id, size = smoke_task(cls), cls.smoke_run
    objective = EconomicObjectiveSpec(name="contract", mpl_weight=1.0, error_weight=1.0)
    episodes, seed = 3, 5
    trained = backend.train_policy(task_id, objective, [], size.num_envs, size.max_steps, seed,
                                   output_dir=tmp_path / "run", eval_episodes=0,
                                   select_every_steps=max(1, size.max_steps // 2), select_episodes=episodes)
    record = json.loads((Path(trained.policy_id) / RUN_CONFIG_FILE).read_text())["selection"]
    first = seed + SELECTION_SEED_OFFSET
    assert record["seeds"] == [first, first + episodes]
    evaluations = record["evaluations"]
    assert len(evaluations) >= 2 and all(e["episodes"] + e["cut_short"] >= 1 for e in evaluations)
    assert record["kept"] == max(evaluations, key=lambda e: (e["deployable"], e["j_mean"]))
    # the policy kept, evaluated again on the recorded held-out seeds, is the checkpoint that was judged
    kept = record["kept"]
    again = backend.evaluate_policy(trained.policy_id, task_id, objective, kept["episodes"], first)
    task = load_catalog().get(task_id)
    j_mean = Selection(task, objective, SelectionConfig(episodes=episodes, seed=seed)).judge(again.episodes)[2]
    assert j_mean == pytest.approx(kept["j_mean"], rel=1e-6)


def test_default_run_directories_are_new_and_under_runs_dir(tmp_path: Path) -> None:
    backend = make_motor_backend(BACKENDS[0], runs_dir=tmp_path)
    first = backend.run_dir(None, "some_task", 7)
    assert first.parent == tmp_path and first.name.startswith("some_task-") and first.name.endswith(f"-{os.getpid()}")
    assert backend.run_dir(tmp_path / "mine", "some_task", 7) == tmp_path / "mine"
