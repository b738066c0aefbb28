"""Sweeps: a grid of cells, every cell recorded in the registry.

A training *cell* (:class:`SweepCell`, a grid of objective x datapacks x seed) trains one policy
with ``backend.train_policy`` (which also evaluates it) and is recorded as a ``train`` run with
its evaluation episodes; an evaluation cell (:class:`econmotor.analysis.eval_sweep.EvalCell`, a
grid of commanded speed x datapacks x seed) evaluates a policy that exists and is recorded as an
``eval`` run. The runner takes any cell with the interface of :class:`Cell`. Each cell has a
deterministic key::

    cell_key = sha256(canonical JSON of {task_id, backend, objective weights, datapack ids and
                      their validated YAML content, seed, num_envs, max_steps, eval_episodes})[:20]

(an evaluation cell's: its policy and commanded speed in place of the objective and run size),
stored in the run's config (``config["cell_key"]``). A sweep first reads the keys of
completed runs of the task and backend and skips those cells, so an interrupted sweep
resumes where it stopped; a failed cell is recorded ``failed`` and retried next time.

Execution: sequential in this process by default. With Ray, each cell is a Ray task
declaring ``num_cpus`` / ``num_gpus`` so a cluster schedules it; the driver records
runs as results come back (so a SQLite registry on the driver works with a remote
cluster). Policies land under ``output_dir/<cell_key>/`` on the node that trained them;
every node of a cluster needs econmotor installed (``pip install 'econmotor[ray]'``).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import threading
from collections.abc import Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Protocol

from econmotor.analysis.objective_surface import Objective
from econmotor.config.datapacks import DatapackConfig
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.errors import BackendError, ConfigError
from econmotor.motor_backend.base import ProgressFn, no_progress
from econmotor.motor_backend.results import MotorTrainingResult
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.objectives.loader import objective_from_vector


class Cell(Protocol):
    """What the runner needs of a cell: its identity, how it is recorded and what it runs."""

    run_kind: ClassVar[str]  # the registry's run kind: "train" or "eval"
    task_id: str
    backend: str
    datapacks: tuple[DatapackConfig, ...]
    seed: int

    @property
    def key(self) -> str: ...

    def start_fields(self) -> dict[str, Any]: ...

    def execute(self, output_dir: str, progress: ProgressFn, backend_options: Mapping[str, Any]) -> Any: ...

    def mean_j(self, episodes: Sequence[Any]) -> float | None: ...


@dataclass(frozen=True)
class SweepCell:
    """One training job of the grid."""

    run_kind: ClassVar[str] = "train"

    task_id: str
    backend: str
    objective: Objective
    datapacks: tuple[DatapackConfig, ...]
    seed: int
    num_envs: int = 1
    max_steps: int = 2_000
    eval_episodes: int = 5

    @property
    def datapack_ids(self) -> tuple[str, ...]:
        return tuple(p.id for p in self.datapacks)

    @property
    def key(self) -> str:
        """Deterministic id of the cell (module docstring); equal inputs give equal keys."""
        payload = {"task_id": self.task_id, "backend": self.backend, "objective": list(self.objective.weights),
                   "datapacks": [p.to_dict() for p in self.datapacks], "seed": self.seed,
                   "num_envs": self.num_envs, "max_steps": self.max_steps, "eval_episodes": self.eval_episodes}
        text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def objective_spec(self) -> EconomicObjectiveSpec:
        vector = ObjectiveVector.from_list(list(self.objective.weights), energy_term=self.objective.energy_term)
        return objective_from_vector(vector, self.objective.name)

    def run_config(self) -> dict[str, Any]:
        """What the registry stores in the run's config."""
        return {"cell_key": self.key, "sweep": True, "objective_weights": list(self.objective.weights),
                "objective_kind": self.objective.kind, "eval_episodes": self.eval_episodes}

    def start_fields(self) -> dict[str, Any]:
        """``registry.start_run``'s keywords for this cell."""
        return {"objective": self.objective_spec(), "datapack_ids": self.datapack_ids, "config": self.run_config(),
                "seed": self.seed, "num_envs": self.num_envs, "max_steps": self.max_steps,
                "notes": "econmotor sweep"}

    def execute(self, output_dir: str, progress: ProgressFn, backend_options: Mapping[str, Any]) -> MotorTrainingResult:
        """Train and evaluate into ``<output_dir>/<cell key>`` (:func:`train_cell`)."""
        return train_cell(self, output_dir, progress=progress, backend_options=backend_options)

    def mean_j(self, episodes: Sequence[Any]) -> float | None:
        """:func:`cell_mean_j` of the cell's evaluation episodes."""
        return cell_mean_j(self, episodes)


def plan_sweep(task_id: str, backend: str, objectives: Sequence[Objective],
               datapack_groups: Sequence[Sequence[DatapackConfig]], seeds: Sequence[int], *,
               num_envs: int = 1, max_steps: int = 2_000, eval_episodes: int = 5) -> list[SweepCell]:
    """The grid ``objectives x datapack_groups x seeds`` (objective outermost, seed innermost).

    A datapack group is the list of datapacks one cell trains with (often a single pack);
    ``[[]]`` sweeps without datapacks.
    """
    if not objectives or not seeds or not datapack_groups:
        raise ConfigError("<sweep>", None, "a sweep needs at least one objective, datapack group and seed")
    if num_envs < 0 or max_steps < 1 or eval_episodes < 1:
        raise ConfigError("<sweep>", "num_envs/max_steps/eval_episodes",
                          "num_envs must be >= 0 (0: the task's default), the others >= 1")
    cells = [SweepCell(task_id, backend, o, tuple(g), int(s), num_envs, max_steps, eval_episodes)
             for o in objectives for g in datapack_groups for s in seeds]
    keys = [c.key for c in cells]
    if len(set(keys)) != len(keys):
        raise ConfigError("<sweep>", None, "the grid repeats a cell (same objective weights, datapacks and seed)")
    return cells


def run_cell(cell: Cell, output_dir: str, cpu_threads: int = 1, progress: ProgressFn = no_progress,
             backend_options: Mapping[str, Any] | None = None) -> Any:
    """Run one cell (in this process or as a Ray task) on ``cpu_threads`` threads: ``cell.execute``;
    ``backend_options``: constructor keywords the edge read for the backend (its ``environment_options``)."""
    os.environ.setdefault("OMP_NUM_THREADS", str(cpu_threads))
    try:
        import torch

        torch.set_num_threads(max(1, cpu_threads))
    except ImportError:
        pass
    return cell.execute(output_dir, progress, dict(backend_options or {}))


def train_cell(cell: SweepCell, output_dir: str, progress: ProgressFn = no_progress,
               backend_options: Mapping[str, Any] | None = None) -> MotorTrainingResult:
    """Train and evaluate one cell into ``<output_dir>/<cell key>``; ``backend_options``: the backend's
    constructor keywords."""
    from econmotor.motor_backend.factory import make_motor_backend

    backend = make_motor_backend(cell.backend, **dict(backend_options or {}))
    return backend.train_policy(cell.task_id, cell.objective_spec(), list(cell.datapack_ids), cell.num_envs,
                                cell.max_steps, cell.seed, datapack_configs=list(cell.datapacks),
                                output_dir=str(Path(output_dir) / cell.key), eval_episodes=cell.eval_episodes,
                                progress=progress)


@dataclass(frozen=True)
class CellOutcome:
    """What happened to one cell: ``completed``, ``skipped`` (done before) or ``failed``.

    ``mean_j``: the mean J of a completed training cell's evaluation episodes under the cell's objective,
    ``econmotor.valuation.episode_j`` — the J ``econmotor solve`` ranks the recorded run by (None for an
    evaluation cell, which has no objective). ``econ_metrics``: a completed cell's evaluation, pooled
    (the documented econ-metric keys).
    """

    cell: Cell
    status: str
    run_id: int | None = None
    error: str | None = None
    mean_j: float | None = None
    econ_metrics: Mapping[str, float] | None = None


def cell_mean_j(cell: SweepCell, episodes: Sequence[Any]) -> float | None:
    """Mean ``episode_j`` of ``episodes`` under the cell's objective and its task's economics."""
    if not episodes:
        return None
    from econmotor.tasks import get_task
    from econmotor.valuation.reward_builder import episode_j

    economics = get_task(cell.task_id).economics
    js = [episode_j(ep, cell.objective.weights, economics, cell.objective.energy_term) for ep in episodes]
    return float(sum(js) / len(js))


@dataclass(frozen=True)
class RaySettings:
    """How to run cells on Ray.

    Attributes:
        address: a cluster address (``"auto"``, ``"ray://host:10001"``); ``None`` starts a local Ray in a
            process of its own (:mod:`econmotor.analysis.ray_head`)
            (or uses one already initialised in this process).
        num_cpus: CPUs of a local Ray (ignored with ``address``).
        cpus_per_cell, gpus_per_cell: the resources each cell's task declares.
    """

    address: str | None = None
    num_cpus: int | None = None
    cpus_per_cell: float = 1.0
    gpus_per_cell: float = 0.0
    init_kwargs: dict[str, Any] = field(default_factory=dict)


def completed_cell_keys(registry: Any, task_id: str, backend: str) -> set[str]:
    """Cell keys of this task and backend's completed runs (training and evaluation cells)."""
    runs = registry.runs(task_id=task_id, backend=backend, status="completed")
    return {r.config["cell_key"] for r in runs if r.config.get("cell_key")}


def run_sweep(registry: Any, cells: Sequence[Cell], output_dir: str | Path, *,
              ray: RaySettings | None = None, progress: ProgressFn = no_progress,
              backend_options: Mapping[str, Any] | None = None) -> list[CellOutcome]:
    """Run every cell not completed before and record it (run + episodes) in ``registry``.

    Each pending cell is recorded ``running`` before it starts; a cell that raises is
    recorded ``failed`` with its error and the sweep goes on; Ctrl-C marks the cells in
    flight ``interrupted``. Returns one outcome per cell, in grid order.
    """
    output_dir = str(Path(output_dir).resolve())
    done_before: dict[tuple[str, str], set[str]] = {}
    outcomes: dict[str, CellOutcome] = {}
    pending: list[Cell] = []
    for cell in cells:
        keys = done_before.setdefault((cell.task_id, cell.backend),
                                      completed_cell_keys(registry, cell.task_id, cell.backend))
        if cell.key in keys:
            outcomes[cell.key] = CellOutcome(cell, "skipped")
        else:
            pending.append(cell)
    total = len(cells)
    progress("sweep cells", len(outcomes), total)
    for pack in {p.id: p for cell in pending for p in cell.datapacks}.values():
        registry.record_datapacks([pack])
    tick = lambda: progress("sweep cells", len(outcomes), total)
    if ray is None:
        _run_here(registry, pending, output_dir, outcomes, tick, progress, backend_options)
    else:
        _run_on_ray(registry, pending, output_dir, outcomes, tick, ray, backend_options)
    return [outcomes[c.key] for c in cells]


def _start(registry: Any, cell: Cell) -> int:
    return registry.start_run(cell.run_kind, cell.task_id, cell.backend, **cell.start_fields())


def _finish(registry: Any, cell: Cell, run_id: int, result: Any, error: BaseException | None,
            outcomes: dict[str, CellOutcome]) -> None:
    if error is None:
        registry.finish_run(run_id, result)
        outcomes[cell.key] = CellOutcome(cell, "completed", run_id, mean_j=cell.mean_j(result.episodes),
                                         econ_metrics=dict(result.econ_metrics))
    else:
        text = f"{type(error).__name__}: {error}"
        registry.mark_run(run_id, "failed", text)
        outcomes[cell.key] = CellOutcome(cell, "failed", run_id, text)


def _run_here(registry: Any, cells: Sequence[Cell], output_dir: str, outcomes: dict[str, CellOutcome],
              tick: Any, progress: ProgressFn, backend_options: Mapping[str, Any] | None) -> None:
    for cell in cells:
        run_id = _start(registry, cell)
        try:
            result = run_cell(cell, output_dir, progress=progress, backend_options=backend_options)
        except (KeyboardInterrupt, SystemExit) as exc:
            registry.mark_run(run_id, "interrupted", f"{type(exc).__name__}: {exc}")
            raise
        except Exception as exc:
            _finish(registry, cell, run_id, None, exc, outcomes)
        else:
            _finish(registry, cell, run_id, result, None, outcomes)
        tick()


@contextmanager
def _callers_sigterm_kept() -> Iterator[None]:
    """Put the caller's SIGTERM handler back after ``ray.init``, which replaces it with ``sys.exit(1)``
    (and a C++ handler that prints a stack): the caller decides what SIGTERM does (the CLI records
    the cells in flight as interrupted and says so, as for Ctrl-C)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.getsignal(signal.SIGTERM)
    try:
        yield
    finally:
        if before is not None:  # None: a handler not installed from Python, which cannot be put back
            signal.signal(signal.SIGTERM, before)


def _run_on_ray(registry: Any, cells: Sequence[Cell], output_dir: str, outcomes: dict[str, CellOutcome],
                tick: Any, settings: RaySettings, backend_options: Mapping[str, Any] | None) -> None:
    try:
        import ray
    except ImportError as exc:
        raise BackendError("Ray is not installed: pip install 'econmotor[ray]' (or run without --ray)") from exc
    with ExitStack() as stack:
        if not ray.is_initialized():
            _connect(ray, settings, stack)
        _run_cells_on_ray(ray, registry, cells, output_dir, outcomes, tick, settings, backend_options)


def _connect(ray: Any, settings: RaySettings, stack: ExitStack) -> None:
    """Connect this process to ``settings.address``, else to a local Ray started in a process of its own
    (:func:`~econmotor.analysis.ray_head.local_ray_head`: started here, Ray would fork this process, where JAX
    or torch threads may run); ``stack`` disconnects, then stops that local Ray."""
    from econmotor.analysis.ray_head import local_ray_head

    kwargs: dict[str, Any] = {"include_dashboard": False, "configure_logging": False, "log_to_driver": False,
                              **settings.init_kwargs}
    address = settings.address
    if not address:
        address = stack.enter_context(local_ray_head(
            {**kwargs, **({"num_cpus": settings.num_cpus} if settings.num_cpus else {})}))
    with _callers_sigterm_kept():
        ray.init(address=address, **kwargs)
    stack.callback(ray.shutdown)


def _run_cells_on_ray(ray: Any, registry: Any, cells: Sequence[Cell], output_dir: str,
                      outcomes: dict[str, CellOutcome], tick: Any, settings: RaySettings,
                      backend_options: Mapping[str, Any] | None) -> None:
    threads = max(1, int(settings.cpus_per_cell))
    remote = ray.remote(num_cpus=settings.cpus_per_cell, num_gpus=settings.gpus_per_cell,
                        max_retries=0)(run_cell)
    in_flight: dict[Any, tuple[Cell, int]] = {}
    try:
        for cell in cells:
            in_flight[remote.remote(cell, output_dir, threads, no_progress, backend_options)] = \
                (cell, _start(registry, cell))
        while in_flight:
            (ref,), _ = ray.wait(list(in_flight), num_returns=1)
            cell, run_id = in_flight.pop(ref)
            try:
                result = ray.get(ref)
            except Exception as exc:
                _finish(registry, cell, run_id, None, getattr(exc, "cause", None) or exc, outcomes)
            else:
                _finish(registry, cell, run_id, result, None, outcomes)
            tick()
    except (KeyboardInterrupt, SystemExit) as exc:
        for ref, (_cell, run_id) in in_flight.items():
            ray.cancel(ref, force=True)
            registry.mark_run(run_id, "interrupted", f"{type(exc).__name__}: {exc}")
        raise
