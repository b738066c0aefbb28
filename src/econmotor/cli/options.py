"""The flags several commands share, and what each becomes in a request.

The Typer options every command that evaluates or trains declares the same way (``--until-deployable``,
``--eval-max-episodes``, ``--init-policy``, ...), and one function per shared flag that checks it and
turns it into what the library takes: an objective, datapack configs, backend options. Commands import
these from here (a command module never imports another command module); a flag's rule lives in
:mod:`econmotor.cli.validation`. Nothing here registers a command.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import typer

from econmotor.cli.validation import check_flags, check_input_files
from econmotor.config.datapacks import DatapackConfig, load_datapack_configs
from econmotor.config.objective_profile import OBJECTIVE_PRESETS, ObjectiveVector
from econmotor.errors import ConfigError, did_you_mean
from econmotor.motor_backend.base import MotorBackendBase
from econmotor.motor_backend.factory import backend_class, known_backends
from econmotor.objectives import load_objective_spec, objective_from_vector
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.recording import with_objective_name
from econmotor.store.engine import DB_URL_ENV, registry_exists
from econmotor.store.registry import Registry
from econmotor.valuation import default_objective_vector

# pricing commands (report, compare)
TASK_ID_OPTION = typer.Option(..., "--task-id", help="Task id from the catalog (`econmotor tasks`).")
TASKS_FILE_OPTION = typer.Option([], "--tasks-file", help="Extra task catalog YAML files.")
SPREAD_SHARE_OPTION = typer.Option(0.5, "--spread-share", help="Seller's share of the spread, 0..1.")
# evaluation-driven training (motor_backend/selection.py): train and report
UNTIL_DEPLOYABLE_OPTION = typer.Option(
    False, "--until-deployable", help="Stop as soon as a held-out evaluation passes the task's acceptance rule "
    "(or at --max-steps); the run records when it became deployable.")
SELECT_EVERY_OPTION = typer.Option(None, "--select-every", help="Env steps between held-out evaluations that "
                                   "choose the kept checkpoint, exactly (0: none, keep the last weights; default: "
                                   "the backend's cadence, at most 10% of the run's wall time).")
SELECT_EPISODES_OPTION = typer.Option(None, "--select-episodes", help="The most episodes of a held-out evaluation "
                                      "(each is sequential: it stops once its verdict is decided; default 160).")
# a sequential evaluation's caps (report, compare, demo)
EVAL_MAX_EPISODES_OPTION = typer.Option(None, "--eval-max-episodes", help="Cap on a sequential evaluation's "
                                        "episodes (default 640).")
EVAL_MAX_SECONDS_OPTION = typer.Option(None, "--eval-max-seconds", help="Cap on a sequential evaluation's wall "
                                       "seconds, checked at each look (default 900).")
INIT_POLICY_OPTION = typer.Option(
    None, "--init-policy", help="Start from a walker that exists: an ONNX file in Holosoma's format or a shipped "
    "name (holosoma:g1_29dof/ppo; with mujoco also a FastSAC walker, holosoma:g1_29dof/fastsac); its actor is "
    "fine-tuned for the objective after a critic warm-up.")
HYPERPARAMETERS_OPTION = typer.Option(
    [], "--hyperparameters", help="KEY=VALUE: one setting of the learner's recipe for this run, over the task "
    "catalog's (repeatable; VALUE read as YAML: 0.998, true, [1.0e-6, 1.0e-3]); the run records the recipe it used.")

#: episodes the backend evaluates right after training, unless asked otherwise
TRAINING_EVAL_EPISODES = 5


def resolve_objective(config: Path | None, preset: str | None = None, name: str | None = None) -> EconomicObjectiveSpec:
    """The objective of ``--objective-config`` (a YAML file) or ``--objective-preset`` (a preset name), else
    RewardBuilder's default vector [1, 0.2, 0.1, 0.05, 0] named 'default'; renamed ``name``
    (``--objective-name``) when given. Both a file and a preset is an error."""
    if config is not None and preset is not None:
        raise ConfigError("<command line>", "--objective-preset", "give --objective-config or --objective-preset")
    if preset is not None and preset not in OBJECTIVE_PRESETS:
        raise ConfigError("<command line>", "--objective-preset", f"unknown preset '{preset}'", OBJECTIVE_PRESETS)
    if config is not None:
        check_input_files("--objective-config", [config])
        objective = load_objective_spec(config)
    elif preset is not None:
        objective = objective_from_vector(ObjectiveVector.from_preset(preset), name=preset)
    else:
        objective = objective_from_vector(ObjectiveVector.from_list(default_objective_vector()), name="default")
    return with_objective_name(objective, name)


def split_datapack_values(values: list[str]) -> list[str]:
    """``["a.yaml,b", "c d"]`` -> ``["a.yaml", "b", "c", "d"]`` (commas and spaces separate)."""
    return [tok for value in values for tok in re.split(r"[,\s]+", value) if tok]


def split_ids(values: list[str]) -> list[str]:
    """``["a,b", "c"]`` -> ``["a", "b", "c"]``."""
    return [v.strip() for value in values for v in value.split(",") if v.strip()]


def _looks_like_path(token: str) -> bool:
    return token.endswith((".yaml", ".yml")) or "/" in token or os.sep in token or Path(token).exists()


def resolve_datapacks(tokens: list[str], db_url: str) -> list[DatapackConfig]:
    """YAML paths are loaded; other tokens are ids registered in the registry (read only)."""
    configs: list[DatapackConfig] = []
    ids = [t for t in tokens if not _looks_like_path(t)]
    registered: dict[str, DatapackConfig] = {}
    known: list[str] = []
    if ids and registry_exists(db_url):
        with Registry(db_url, create=False) as reg:
            known = reg.known_datapack_ids()
            registered = {c.id: c for c in reg.datapack_configs([i for i in ids if i in known])}
    for token in tokens:
        if _looks_like_path(token):
            configs.extend(load_datapack_configs([token]))  # a missing file is a ConfigError
        elif token in registered:
            configs.append(registered[token])
        else:
            raise ConfigError("--datapacks", token, "unknown datapack id and not a YAML file; a datapack is "
                              "registered when a report first uses its YAML path" + did_you_mean(token, known),
                              sorted(known) or "a YAML path (no datapack ids registered yet)")
    seen: set[str] = set()
    return [c for c in configs if not (c.id in seen or seen.add(c.id))]


def open_registry(db_url: str | None, create: bool = True) -> Registry:
    """The registry at ``--db-url``, else ``$ECONMOTOR_DB_URL``, else ``./.econmotor/registry.sqlite``."""
    return Registry(db_url or os.environ.get(DB_URL_ENV) or None, create=create)


def _backends_with(capability: str) -> list[str]:
    return [b for b in known_backends() if getattr(backend_class(b).capabilities, capability)]


def check_imports_policies(backend: type[MotorBackendBase], flag: str) -> None:
    """``backend`` (the class the command resolved) must evaluate policies trained elsewhere (its
    ``capabilities.imported_policies``)."""
    if not backend.capabilities.imported_policies:
        raise ConfigError(flag, backend.name, "this backend evaluates its own run directories only, not imported "
                          "policies", _backends_with("imported_policies"))


def course_speed_options(backend: type[MotorBackendBase], speed_m_per_s: float | None) -> dict[str, Any]:
    """The backend option of ``--command-speed`` (the contract's ``course_speed_m_per_s``); an error for a
    backend that walks no commanded course (no ``capabilities.course_speed``)."""
    if speed_m_per_s is None:
        return {}
    if not backend.capabilities.course_speed:
        raise ConfigError("--command-speed", None, f"backend '{backend.name}' walks no course at a commanded speed: "
                          "leave --command-speed out", _backends_with("course_speed"))
    return {"course_speed_m_per_s": speed_m_per_s}


def time_budget_options(backend: type[MotorBackendBase], max_minutes: float | None) -> dict[str, Any]:
    """The backend option of ``--max-minutes``; an error for a backend without a time budget or a bad value."""
    if max_minutes is None:
        return {}
    if not max_minutes > 0:
        raise ConfigError("--max-minutes", None, f"must be > 0, got {max_minutes}")
    if not backend.capabilities.time_budget:
        raise ConfigError("--max-minutes", None, f"backend '{backend.name}' trains to --max-steps only")
    return {"max_wall_s": 60.0 * float(max_minutes)}


def hyperparameter_options(backend: type[MotorBackendBase], values: list[str],
                           resume: bool = False) -> dict[str, Any]:
    """The backend option of ``--hyperparameters KEY=VALUE ...`` (``{"hyperparameters": {KEY: VALUE read as
    YAML}}``, nothing when none is given); an error for a backend whose recipe cannot be set, a resumed run
    (it continues with the recipe it recorded) or an item that is not KEY=VALUE. The learner checks the keys
    and values when the run starts."""
    import yaml

    if not values:
        return {}
    if not backend.capabilities.hyperparameters:
        raise ConfigError("--hyperparameters", None, f"backend '{backend.name}' has no recipe to set",
                          _backends_with("hyperparameters"))
    if resume:
        raise ConfigError("--hyperparameters", None, "a resumed run continues with the recipe it recorded")
    out: dict[str, Any] = {}
    for item in values:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError("--hyperparameters", item, "expected KEY=VALUE, such as gamma=0.998")
        try:
            out[key.strip()] = yaml.safe_load(raw)
        except yaml.YAMLError as exc:
            raise ConfigError("--hyperparameters", key.strip(), f"VALUE is not YAML: {raw!r}") from exc
    return {"hyperparameters": out}


def init_policy_options(backend: type[MotorBackendBase], init_policy: str | None,
                        resume: bool = False) -> dict[str, Any]:
    """The backend option of ``--init-policy``; an error for a backend that cannot start from one."""
    if init_policy is None:
        return {}
    if not backend.capabilities.init_policies:
        raise ConfigError("--init-policy", init_policy, f"backend '{backend.name}' cannot start from a policy trained "
                          "elsewhere", _backends_with("init_policies"))
    if resume:
        raise ConfigError("--init-policy", init_policy, "starts a new run; --resume continues one from its "
                          "checkpoints (the run records what it started from)")
    return {"init_policy": init_policy}


def selection_options(backend: type[MotorBackendBase], until_deployable: bool, select_every: int | None,
                      select_episodes: int | None) -> dict[str, Any]:
    """The backend options of evaluation-driven training; an error for a backend without it."""
    check_flags(select_every=select_every, select_episodes=select_episodes)
    options: dict[str, Any] = {}
    if until_deployable:
        options["until_deployable"] = True
    if select_every is not None:
        options["select_every_steps"] = select_every
    if select_episodes is not None:
        options["select_episodes"] = select_episodes
    if until_deployable and select_every == 0:
        raise ConfigError("<command line>", "--until-deployable", "needs held-out evaluations: drop --select-every 0")
    if options and not backend.capabilities.evaluation_driven:
        raise ConfigError("<command line>", "--until-deployable/--select-every/--select-episodes",
                          f"backend '{backend.name}' does not select checkpoints by held-out evaluation",
                          _backends_with("evaluation_driven"))
    return options


def training_eval_episodes(requested: int | None, until_deployable: bool, select_episodes: int | None) -> int:
    """The episodes to evaluate right after training: ``requested``, else enough for a verdict
    after ``--until-deployable`` (the held-out evaluations' count), else :data:`TRAINING_EVAL_EPISODES`.

    A run trained until deployable is priced on these episodes; five cannot show a fall rate
    under the acceptance rule's bound, so its report would say NOT DEPLOYABLE for lack of evidence."""
    from econmotor.motor_backend.selection import DEFAULT_SELECT_EPISODES

    if requested is not None:
        return requested
    return (select_episodes or DEFAULT_SELECT_EPISODES) if until_deployable else TRAINING_EVAL_EPISODES
