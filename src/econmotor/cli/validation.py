"""The one validation layer at the CLI edge: every numeric flag, size, URL and output path.

Each command calls :func:`check_flags` with its numeric flags before any work starts
(``check_flags(seed=seed, max_steps=max_steps)``): the rule of each flag lives in
:data:`FLAG_RULES` (type, finite, range), so the same flag means the same thing in every
command. Sizes that decide how much work a command does (sweep cells, solve objectives,
seed lists) are checked against the limits below before anything is generated, with a
message that states the size and the limit. :func:`check_db_url` checks a registry URL
(scheme and, for the default SQLite file, that it can be created); :func:`check_output_dir`
and :func:`check_output_file` check where outputs go. Every failure is a
:class:`~econmotor.errors.ConfigError` whose message starts with the flag, so the CLI
prints one line and exits with status 2.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from econmotor.config.loading import path_name
from econmotor.errors import ConfigError

#: Environment steps of one training run (a billion: days of simulation; also fits a 32-bit column).
MAX_STEPS = 1_000_000_000
#: Seeds are stored in 32-bit columns and evaluation uses ``seed + 1000``.
MAX_SEED = 2_000_000_000
MAX_EPISODES = 100_000
#: Cells of one sweep (objectives x datapack groups x seeds); each cell trains a policy.
MAX_SWEEP_CELLS = 10_000
#: Seeds of one sweep.
MAX_SWEEP_SEEDS = 1_000
#: Objectives one ``solve`` scores (presets + vectors + grid): each is scored on every run.
MAX_SOLVE_OBJECTIVES = 50_000


@dataclass(frozen=True)
class Rule:
    """An integer or real flag: ``kind`` "int" or "float", inclusive bounds, optional choices."""

    kind: str = "int"
    low: float | None = None
    high: float | None = None
    low_open: bool = False  # low is exclusive

    def allowed(self) -> str:
        name = "an integer" if self.kind == "int" else "a finite number"
        fmt = (lambda v: f"{int(v):,}") if self.kind == "int" else (lambda v: f"{v:,g}")
        low = "" if self.low is None else (f"> {fmt(self.low)}" if self.low_open else f">= {fmt(self.low)}")
        high = "" if self.high is None else f"<= {fmt(self.high)}"
        return " ".join(x for x in (name, low, "and" if low and high else "", high) if x)

    def check(self, flag: str, value: Any) -> Any:
        if value is None:
            return None
        if self.kind == "int":
            if isinstance(value, bool) or not isinstance(value, int):
                raise ConfigError(flag, None, f"expected an integer, got {value!r}", self.allowed())
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError(flag, None, f"expected a number, got {value!r}", self.allowed())
            if not math.isfinite(value):
                raise ConfigError(flag, None, f"must be finite, got {value}", self.allowed())
        too_low = self.low is not None and (value <= self.low if self.low_open else value < self.low)
        too_high = self.high is not None and value > self.high
        if too_low or too_high:
            shown = f"{value:,}" if isinstance(value, int) and abs(value) < 10**30 else f"{value:.6g}"
            raise ConfigError(flag, None, f"{shown} is out of range", self.allowed())
        return value


#: The rule of every numeric CLI flag (the same flag means the same in every command).
FLAG_RULES: dict[str, Rule] = {
    "--seed": Rule("int", 0, MAX_SEED),
    "--max-steps": Rule("int", 1, MAX_STEPS),
    "--total-steps": Rule("int", 1, MAX_STEPS),
    "--learning-starts": Rule("int", 0, MAX_STEPS),
    "--max-episode-steps": Rule("int", 1, 10_000_000),
    "--num-envs": Rule("int", 0),  # the chosen backend checks its own limit (check_num_envs)
    "--eval-episodes": Rule("int", 0, MAX_EPISODES),
    "--select-every": Rule("int", 0, MAX_STEPS),
    "--select-episodes": Rule("int", 1, MAX_EPISODES),
    "--eval-max-episodes": Rule("int", 1, MAX_EPISODES),
    "--eval-max-seconds": Rule("float", 0.0, 1e7, low_open=True),
    "--episodes": Rule("int", 1, MAX_EPISODES),
    "--steps": Rule("int", 1, 10_000_000),
    "--run-id": Rule("int", 1, 2**31 - 1),
    "--grid": Rule("int", 0, 10_000),
    "--spread-share": Rule("float", 0.0, 1.0),
    "--command-speed": Rule("float", 0.05, 10.0),  # m/s
    "--lagrange-lr": Rule("float", 0.0, 1e6, low_open=True),
    "--ray-num-cpus": Rule("int", 1, 4096),
    "--cpus-per-cell": Rule("float", 0.0, 1024.0, low_open=True),
    "--gpus-per-cell": Rule("float", 0.0, 64.0),
    "--reference-point": Rule("float"),
    "--objective-vector": Rule("float", 0.0, 1e9),
}


def check_flags(**values: Any) -> None:
    """Check each ``name=value`` against the rule of ``--name`` (underscores become dashes); a repeatable
    flag's list is checked item by item."""
    for name, value in values.items():
        flag = "--" + name.replace("_", "-")
        for item in value if isinstance(value, (list, tuple)) else (value,):
            FLAG_RULES[flag].check(flag, item)


def check_command_speeds(speeds: Iterable[float | None], policies: Iterable[str] = ()) -> None:
    """Each ``--command-speed`` (m/s; None: the catalog's) against its rule (finite, 0.05-10 m/s) and against
    the fastest forward command each of ``policies`` was trained for (``lin_vel_x``'s top in its ONNX metadata):
    the walker clips its command to that top (``locomotion/course.py``), so a faster speed would price the policy
    at a speed other than the one asked for."""
    from econmotor.couriers.onnx_actor import policy_command_ranges

    speeds = [s for s in speeds if s is not None]
    check_flags(command_speed=speeds)
    for policy in policies if speeds else ():
        top = (policy_command_ranges(policy).get("lin_vel_x") or (None, None))[1]
        beyond = [s for s in speeds if top is not None and s > float(top)]
        if beyond:
            raise ConfigError("--command-speed", None, f"{beyond[0]:g} m/s is beyond the command range of policy "
                              f"{policy} (its ONNX metadata: lin_vel_x up to {float(top):g} m/s); its walker would "
                              f"be commanded {float(top):g} m/s", f"a speed >= 0.05 and <= {float(top):g} m/s")


def evaluation_plan(backend: Any, task_id: str, eval_episodes: int | None, max_episodes: int | None,
                    max_seconds: float | None) -> Any:
    """How the evaluation run chooses its episodes: None for a fixed ``--eval-episodes N``, else the
    sequential plan (episodes in the backend's batches until the verdict is decided, or a cap). Bad
    combinations are errors naming the flag: ``--eval-episodes 0``, a cap below one batch, a negative cap,
    a cap beside a fixed count."""
    from econmotor.economics.sequential_rule import DEFAULT_MAX_EPISODES, DEFAULT_MAX_WALL_S, SequentialPlan

    check_flags(eval_episodes=eval_episodes, eval_max_episodes=max_episodes, eval_max_seconds=max_seconds)
    if eval_episodes is not None:
        if eval_episodes < 1:
            raise ConfigError("--eval-episodes", None, "0 episodes cannot show anything: give N >= 1 for a fixed "
                              "count, or leave --eval-episodes out for a sequential evaluation (episodes in batches "
                              "until the verdict is decided; caps --eval-max-episodes, --eval-max-seconds)")
        given = [f for f, v in (("--eval-max-episodes", max_episodes), ("--eval-max-seconds", max_seconds)) if v]
        if given:
            raise ConfigError(given[0], None, "caps a sequential evaluation: drop it, or drop --eval-episodes N "
                              "(a fixed count)")
        return None
    return SequentialPlan(batch=backend.evaluation_batch(task_id), max_episodes=max_episodes or DEFAULT_MAX_EPISODES,
                          max_wall_s=max_seconds or DEFAULT_MAX_WALL_S)


def check_task_backend(task: Any, backend: str, flag: str = "--motor-backend") -> None:
    """The task (a catalog ``TaskSpec``) has an entry for ``backend``: the error names the flag and
    the backends that can run the task, not the catalog file the user never wrote."""
    if backend not in task.backends:
        raise ConfigError(flag, None, f"task '{task.task_id}' does not run on '{backend}'", list(task.backends))


def check_choice(flag: str, value: str | None, choices: Iterable[str]) -> str | None:
    """``value`` must be one of ``choices`` (``None`` passes: the flag was not given)."""
    from econmotor.errors import did_you_mean

    choices = list(choices)
    if value is not None and value not in choices:
        raise ConfigError(flag, None, f"'{value}' is not one of the choices" + did_you_mean(value, choices), choices)
    return value


def check_size(flag: str, what: str, size: int, limit: int) -> None:
    """Refuse work of ``size`` units above ``limit`` before it starts, saying both numbers."""
    if size > limit:
        raise ConfigError(flag, None, f"{size:,} {what} is more than the limit of {limit:,}; "
                          "split the work or choose a smaller value")


def simplex_size(divisions: int, include_novelty: bool = False) -> int:
    """How many weight vectors ``simplex_grid(divisions)`` makes: ``C(m + d - 1, d - 1)``."""
    dims = 5 if include_novelty else 4
    return math.comb(divisions + dims - 1, dims - 1) if divisions > 0 else 0


def parse_seed_list(text: str, limit: int = MAX_SWEEP_SEEDS) -> list[int]:
    """``"0,1,2"`` or ``"0-4"`` -> seeds, each a valid ``--seed``; more than ``limit`` is refused
    before the list is built."""
    flag = "--seeds"
    parts: list[tuple[int, int]] = []
    try:
        for part in text.split(","):
            low, sep, high = part.strip().partition("-")
            parts.append((int(low), int(high)) if sep else (int(low), int(low)))
    except ValueError:
        raise ConfigError(flag, None, f"expected e.g. '0,1,2' or '0-4', got {text!r}") from None
    rule = FLAG_RULES["--seed"]
    for low, high in parts:
        for value in (low, high):
            try:
                rule.check(flag, value)
            except ConfigError as exc:
                raise ConfigError(flag, None, f"seed {exc.detail}", rule.allowed()) from None
        if high < low:
            raise ConfigError(flag, None, f"range {low}-{high} is empty (high below low)")
    check_size(flag, "seeds", sum(high - low + 1 for low, high in parts), limit)
    return list(dict.fromkeys(s for low, high in parts for s in range(low, high + 1)))


def check_name(flag: str, value: str | None) -> str | None:
    """A flag whose value becomes a file or directory name (``--objective-name``, run names)."""
    return None if value is None else path_name(value, flag, None)


def _nearest_existing(path: Path) -> Path:
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _check_writable_parent(flag: str, path: Path) -> None:
    base = _nearest_existing(path)
    if not base.is_dir():
        raise ConfigError(flag, None, f"{path}: {base} is a file, so nothing can be created below it")
    try:  # a real probe: os.access says yes to root even on a read-only file system
        fd, probe = tempfile.mkstemp(prefix=".econmotor-probe-", dir=base)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ConfigError(flag, None, f"{path}: directory {base} is not writable ({exc.strerror or exc})") from None


def check_output_dir(flag: str, path: str | Path | None) -> Path | None:
    """A directory outputs go into: an existing directory, or creatable (no file in the way, writable)."""
    if path is None:
        return None
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ConfigError(flag, None, f"{path} is a file; expected a directory")
    _check_writable_parent(flag, path)
    return path


def check_output_file(flag: str, path: str | Path | None) -> Path | None:
    """A file an output is written to: not a directory, its directory creatable and writable."""
    if path is None:
        return None
    path = Path(path)
    if path.is_dir():
        raise ConfigError(flag, None, f"{path} is a directory; expected a file name")
    if path.exists() and not os.access(path, os.W_OK):
        raise ConfigError(flag, None, f"{path} is not writable")
    _check_writable_parent(flag, path.parent)
    return path


def check_input_files(flag: str, paths: Iterable[str | Path]) -> None:
    """Files a flag reads: each must exist and be a regular, readable file."""
    for path in map(Path, paths):
        if path.is_dir():
            raise ConfigError(flag, None, f"{path} is a directory; expected a file")
        if not path.is_file():
            raise ConfigError(flag, None, f"{path}: file not found")
        if not os.access(path, os.R_OK):
            raise ConfigError(flag, None, f"{path} is not readable")


def check_db_url(url: str | None, *, create: bool = True, flag: str = "--db-url") -> str:
    """The registry URL the command will use (``url``, else ``$ECONMOTOR_DB_URL``, else the default
    SQLite file), checked now: a supported scheme, and for SQLite a file that can be created."""
    from econmotor.store.engine import DB_URL_ENV, default_db_url, sqlite_path
    from econmotor.store.engine import check_db_url as check_scheme

    if url:
        source = flag
    elif os.environ.get(DB_URL_ENV):
        url, source = os.environ[DB_URL_ENV], DB_URL_ENV
    else:
        url, source = default_db_url(), "default registry"
    check_scheme(url, source)
    path = sqlite_path(url)
    if path is not None and create and not path.exists():
        try:
            _check_writable_parent(source, path.parent)
        except ConfigError as exc:
            raise ConfigError(source, None, f"cannot create the registry {path}: {exc.detail}; pass --db-url "
                              f"(or set {DB_URL_ENV}) to a writable location") from None
    return url


def note_abandoned(registry: Any) -> None:
    """One stderr line when opening ``registry`` marked runs whose process is gone as abandoned."""
    ids = getattr(registry, "abandoned_run_ids", None)
    if ids:
        from econmotor.cli._app import err_console

        err_console.print(f"[yellow]note[/]: run(s) {', '.join(f'#{i}' for i in ids)} were 'running' but their "
                          "process is gone (killed?): marked abandoned", highlight=False, soft_wrap=True)
