"""Train and evaluate through a motor backend, each run recorded in the registry.

:func:`train_and_record` trains a policy through a backend (its run is the backend's shared training
loop, ``motor_backend/training_loop.py``) and records the training run and an optional evaluation run;
:func:`evaluate_and_record` records the evaluation of a policy trained elsewhere. The CLI's ``train``,
``report``, ``compare`` and ``demo`` call them; ``report/pipeline.py`` builds reports from what they
recorded. Nothing here prints; long work reports through ``progress(label, done, total)``.

Failure rules: the run is recorded as ``running`` when training really starts, then ``completed``,
``failed`` or ``interrupted``; if anything fails after training, the trained run stays in the registry and
the error says how to report from it (``econmotor report --motor-backend none --run-id N``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from econmotor.config.datapacks import DatapackConfig
from econmotor.economics.sequential_rule import SequentialPlan
from econmotor.errors import BackendError, ConfigError, UnknownNameError
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.run_dir import REPORT_EVAL_SEED_OFFSET, new_run_dir
from econmotor.motor_backend.sequential import evaluate_sequentially
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.store.registry import Registry


@dataclass(frozen=True)
class TrainRequest:
    """A validated request to train and evaluate one policy.

    Attributes:
        task: the ``TaskSpec`` (from the catalog, with any user task files applied).
        backend_name: factory name of the motor backend.
        objective: the economic objective to train under.
        datapacks: datapack configs, in order (ids are their ``id``).
        num_envs / max_steps / seed: passed to ``train_policy``.
        train_eval_episodes: episodes the backend evaluates right after training.
        eval_episodes: episodes of an extra evaluation run (0: none, unless ``eval_plan``).
        eval_plan: a sequential evaluation run instead (``eval_episodes`` 0): episodes in batches until
            the acceptance rule is decided or a cap is reached (``motor_backend/sequential.py``).
        notes: free text recorded with the runs.
        runs_dir: where the backend writes policies (``<runs_dir>/<task>-<time>-s<seed>-<pid>``).
        output_dir: the run directory itself (``econmotor train --output-dir``), instead of a new one
            under ``runs_dir``.
        backend_options: extra keyword arguments of ``train_policy`` (mujoco: ``resume``, ``algorithm``).
    """

    task: Any
    backend_name: str
    objective: EconomicObjectiveSpec
    datapacks: tuple[DatapackConfig, ...] = ()
    num_envs: int = 1
    max_steps: int = 5000
    seed: int = 0
    train_eval_episodes: int = 5
    eval_episodes: int = 0
    eval_plan: SequentialPlan | None = None
    notes: str = ""
    runs_dir: Path = Path("runs")
    output_dir: Path | None = None
    backend_options: dict[str, Any] = field(default_factory=dict)

    @property
    def datapack_ids(self) -> list[str]:
        return [p.id for p in self.datapacks]

    @property
    def evaluates(self) -> bool:
        """An evaluation run follows (a fixed count, or a sequential plan)."""
        return self.eval_episodes > 0 or self.eval_plan is not None

    def eval_config(self) -> dict[str, Any]:
        """What the evaluation run records of how its episodes are chosen."""
        if self.eval_episodes > 0:
            return {"num_episodes": self.eval_episodes, "episodes_chosen": "fixed: --eval-episodes"}
        return {"num_episodes": None, "episodes_chosen": "sequential", "plan": self.eval_plan.to_dict()}

    def evaluate(self, backend: Any, policy_id: str, seed: int, output_dir: Path, progress: ProgressFn) -> Any:
        """The evaluation run's episodes: ``eval_episodes`` of them, or a sequential evaluation under ``eval_plan``."""
        kwargs = {"datapack_configs": list(self.datapacks), "output_dir": output_dir, "progress": progress}
        if self.eval_episodes > 0:
            return backend.evaluate_policy(policy_id, self.task.task_id, self.objective, self.eval_episodes, seed,
                                           **kwargs)
        return evaluate_sequentially(backend, policy_id, self.task, self.objective, self.eval_plan, seed, **kwargs)


def how_to_report_from(run_id: int, task_id: str, registry: Registry) -> str:
    """The command that reports from a recorded run."""
    return (f"econmotor report --motor-backend none --task-id {task_id} --run-id {run_id} "
            f"--db-url '{registry.display_url}'")


class _TrainRun:
    """Records the training run when training really starts (the backend's first progress
    report, or its return): input errors the backend finds first leave no trace."""

    def __init__(self, request: TrainRequest, backend: Any, open_registry: Callable[[], Registry]) -> None:
        self.request, self._open = request, open_registry
        self.run_dir = request.output_dir or new_run_dir(request.runs_dir, request.task.task_id, request.seed)
        self.registry: Registry | None = None
        self.run_id: int | None = None
        self.entry = dict(request.task.backends.get(request.backend_name) or {})
        self.robot_id = backend.robot_id(request.task)  # the robot's name, the same on every backend

    def common(self) -> dict[str, Any]:
        r = self.request
        return {"objective": r.objective, "datapack_ids": r.datapack_ids, "notes": r.notes, "robot_id": self.robot_id}

    def start(self) -> int:
        if self.run_id is not None:
            return self.run_id
        r = self.request
        self.registry = reg = self.registry or self._open()
        reg.record_task(r.task)
        if r.datapacks:
            reg.record_datapacks(r.datapacks)
        reg.record_robot(self.robot_id, r.backend_name, r.task.description, self.entry)
        config = {"datapacks": [p.to_dict() for p in r.datapacks], "task_backend_entry": self.entry,
                  "train_eval_episodes": r.train_eval_episodes, "run_dir": str(self.run_dir),
                  **({"backend_options": dict(r.backend_options)} if r.backend_options else {})}
        self.run_id = reg.start_run("train", r.task.task_id, r.backend_name, seed=r.seed, num_envs=r.num_envs,
                                    max_steps=r.max_steps, config=config, **self.common())
        return self.run_id

    def end_with(self, exc: BaseException, status: str) -> None:
        self.start()
        self.registry.mark_run(self.run_id, status, f"{type(exc).__name__}: {exc}")


def train_and_record(request: TrainRequest, backend: Any, open_registry: Callable[[], Registry],
                     progress: ProgressFn = no_progress) -> tuple[Registry | None, int, int | None]:
    """Train (and optionally evaluate) through ``backend``, recording each run.

    Returns ``(registry, train run id, eval run id or None)``. The registry is opened
    (``open_registry()``) and the run recorded as ``running`` when the backend first
    reports progress; a ``ConfigError`` / ``UnknownNameError`` raised before that is bad
    input and records nothing. Any other failure marks the run ``failed`` (or
    ``interrupted`` on Ctrl-C) and re-raises. An error in the evaluation run leaves the
    training run ``completed`` and raises a :class:`BackendError` that says how to report from it.
    """
    task_id = request.task.task_id
    run = _TrainRun(request, backend, open_registry)

    def tracked(label: str, done: float, total: float) -> None:
        run.start()
        progress(label, done, total)

    try:
        result = backend.train_policy(
            task_id, request.objective, request.datapack_ids, request.num_envs, request.max_steps, request.seed,
            datapack_configs=list(request.datapacks), output_dir=run.run_dir,
            eval_episodes=request.train_eval_episodes, progress=tracked, **request.backend_options)
    except (ConfigError, UnknownNameError):
        if run.run_id is None:
            raise
        run.end_with(sys.exc_info()[1], "failed")
        raise
    except (KeyboardInterrupt, SystemExit) as exc:
        run.end_with(exc, "interrupted")
        raise
    except BaseException as exc:
        run.end_with(exc, "failed")
        raise
    train_id = run.start()
    registry = run.registry
    used_envs = (result.config or {}).get("num_envs")  # e.g. the catalog default behind num_envs=0
    registry.finish_run(train_id, result, **({"num_envs": used_envs} if isinstance(used_envs, int) else {}))
    if not request.evaluates:
        return registry, train_id, None
    eval_seed = request.seed + REPORT_EVAL_SEED_OFFSET
    try:
        with registry.track_run("eval", task_id, request.backend_name, seed=eval_seed, parent_run_id=train_id,
                                config=request.eval_config(), policy_path=result.policy_id,
                                **run.common()) as eval_id:
            evaluation = request.evaluate(backend, result.policy_id, eval_seed, Path(f"{run.run_dir}-eval{eval_id}"),
                                          progress)
            registry.finish_run(eval_id, evaluation)
    except (KeyboardInterrupt, SystemExit):
        raise
    except Exception as exc:
        raise BackendError(f"evaluation failed after training: {exc}. The trained run #{train_id} is in the "
                           f"registry; report from it with: {how_to_report_from(train_id, task_id, registry)}") from exc
    return registry, train_id, eval_id


def with_objective_name(objective: EconomicObjectiveSpec, name: str | None) -> EconomicObjectiveSpec:
    """The objective renamed (``--objective-name``), or unchanged when ``name`` is empty."""
    return replace(objective, name=name) if name else objective


def evaluate_and_record(request: TrainRequest, backend: Any, policy_id: str, open_registry: Callable[[], Registry],
                        progress: ProgressFn = no_progress) -> tuple[Registry, int]:
    """Evaluate a policy trained elsewhere (``policy_id``: a file or a shipped name the backend imports)
    and record the evaluation run; nothing is trained. Returns ``(registry, eval run id)``.

    The run's seed is ``request.seed + REPORT_EVAL_SEED_OFFSET`` (episode ``i``: that plus ``i``), so
    policies evaluated with the same request share seeds, course and conditions. A failure marks the
    run ``failed`` (``interrupted`` on Ctrl-C) and re-raises.
    """
    task_id, name = request.task.task_id, request.backend_name
    registry = open_registry()
    registry.record_task(request.task)
    if request.datapacks:
        registry.record_datapacks(request.datapacks)
    entry = dict(request.task.backends.get(name) or {})
    robot_id = backend.robot_id(request.task)  # the task's robot, whichever policy drives it
    registry.record_robot(robot_id, name, request.task.description, entry)
    run_dir = request.output_dir or new_run_dir(request.runs_dir, task_id, request.seed)
    eval_seed = request.seed + REPORT_EVAL_SEED_OFFSET
    config = {**request.eval_config(), "imported_policy": policy_id, "run_dir": str(run_dir),
              "datapacks": [p.to_dict() for p in request.datapacks], "task_backend_entry": entry}
    with registry.track_run("eval", task_id, name, seed=eval_seed, config=config, policy_path=policy_id,
                            objective=request.objective, datapack_ids=request.datapack_ids, notes=request.notes,
                            robot_id=robot_id) as eval_id:
        evaluation = request.evaluate(backend, policy_id, eval_seed, run_dir, progress)
        registry.finish_run(eval_id, evaluation)
    return registry, eval_id
