"""``econmotor shadow``: objective-conditioned SAC with shadow mode and the flip switch."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.markup import escape
from rich.table import Table

from econmotor.cli._app import app, console, err_console, progress_bars, set_cpu_threads
from econmotor.cli._interrupts import set_deadline_note
from econmotor.cli.validation import (
    FLAG_RULES,
    check_choice,
    check_db_url,
    check_flags,
    check_input_files,
    check_output_dir,
)
from econmotor.config.objective_profile import OBJECTIVE_TERMS, ObjectiveVector
from econmotor.errors import ConfigError
from econmotor.motor_backend.run_dir import new_run_dir
from econmotor.store.registry import Registry
from econmotor.tasks import load_catalog
from econmotor.valuation import load_constraint_set

#: the files of a shadow run; a --save-dir holding any of them (not empty) holds a run already.
SHADOW_RUN_FILES = ("run.json", "shadow_episodes.jsonl", "shadow_summary.json", "sac_model.zip")


def holds_a_run(run_dir: Path) -> bool:
    """True when ``run_dir`` holds a shadow run's files (an empty log left by bad input does not count)."""
    return any((run_dir / name).is_file() and (run_dir / name).stat().st_size > 0 for name in SHADOW_RUN_FILES)


@app.command("shadow")
def shadow_command(
    env: str = typer.Option("dishwashing", "--env", help="dishwashing, dishwashing_realistic or a MuJoCo task id."),
    objective_preset: str = typer.Option(None, "--objective-preset",
                                         help="throughput, safety, energy_saver, balanced, ..."),
    objective_vector: tuple[float, float, float, float, float] = typer.Option(
        None, "--objective-vector", help="5 weights: mpl error energy safety novelty."),
    total_steps: int = typer.Option(20_000, "--total-steps", help="SAC environment steps."),
    energy_term: str = typer.Option("wh", "--energy-term", help="J's energy term: wh (-Wh, the default) or usd "
                                    "(priced at the task's electricity price)."),
    use_objective_reward: bool = typer.Option(
        False, "--use-objective-reward", help="The flip: the learner sees the RewardBuilder reward, not legacy."),
    constraints: str = typer.Option(None, "--constraints", help="Constraint-set YAML."),
    constraint_mode: str = typer.Option("penalty", "--constraint-mode", help="penalty | lagrangian."),
    objective_sampling: str = typer.Option("fixed", "--objective-sampling", help="fixed | dirichlet (per episode)."),
    reward_weights: str = typer.Option("identity", "--reward-weights", help="identity | analytic | net."),
    reward_net: str = typer.Option(None, "--reward-net",
                                   help="With --reward-weights net: start from this saved econ_objective_net.pt."),
    seed: int = typer.Option(0, "--seed"),
    save_dir: str = typer.Option(None, "--save-dir", help="Run directory, which must not hold a run yet "
                                 "(default: a new runs/shadow/<env>-<time>-s<seed>-<pid>)."),
    db_url: str = typer.Option(None, "--db-url", help="Registry URL (default $ECONMOTOR_DB_URL or "
                               "sqlite:///./.econmotor/registry.sqlite)."),
    max_episode_steps: int = typer.Option(None, "--max-episode-steps", help="Episode length override."),
    lagrange_lr: float = typer.Option(1.0, "--lagrange-lr", help="Dual learning rate (lagrangian)."),
    learning_starts: int = typer.Option(1000, "--learning-starts", help="SAC random steps before updates."),
    eval_episodes: int = typer.Option(5, "--eval-episodes", help="Deterministic episodes per objective."),
    eval_preset: Annotated[list[str] | None, typer.Option(
        "--eval-preset", help="Evaluate under this preset too (repeatable); any preset for a conditioned policy.",
    )] = None,
) -> None:
    """Train SAC on the legacy reward while logging the RewardBuilder reward beside it (or flipped)."""
    check_flags(total_steps=total_steps, seed=seed, max_episode_steps=max_episode_steps, lagrange_lr=lagrange_lr,
                learning_starts=learning_starts, eval_episodes=eval_episodes)
    check_shadow_choices(objective_vector, constraint_mode, objective_sampling, reward_weights, constraints,
                         reward_net, save_dir)
    set_cpu_threads()
    from econmotor.rl.train_sac_objective import ShadowConfig

    run_dir = shadow_run_dir(save_dir, env, seed)
    label, vector = shadow_objective(objective_preset, objective_vector)
    config = ShadowConfig(
        env=env, objective=tuple(vector.to_list()), objective_label=label, energy_term=energy_term,
        total_steps=total_steps, use_objective_reward=use_objective_reward,
        constraints=load_constraint_set(Path(constraints)) if constraints else None, constraint_mode=constraint_mode,
        objective_sampling=objective_sampling, reward_weights=reward_weights, reward_net_path=reward_net,
        seed=seed, save_dir=str(run_dir), max_episode_steps=max_episode_steps, lagrange_lr=lagrange_lr,
        learning_starts=learning_starts, eval_episodes=eval_episodes,
        eval_objectives={label: tuple(vector.to_list()),
                         **{p: tuple(ObjectiveVector.from_preset(p).to_list()) for p in eval_preset}}
        if eval_preset else {})
    run_id, result = run_recorded(config, vector, check_db_url(db_url), run_dir)
    print_shadow(config, vector, run_id, result)


def check_shadow_choices(objective_vector: tuple[float, ...] | None, constraint_mode: str, objective_sampling: str,
                         reward_weights: str, constraints: str | None, reward_net: str | None,
                         save_dir: str | None) -> None:
    """The shadow command's choices, files and output directory, before anything runs."""
    for weight in objective_vector or ():
        FLAG_RULES["--objective-vector"].check("--objective-vector", weight)
    check_choice("--constraint-mode", constraint_mode, ("penalty", "lagrangian"))
    check_choice("--objective-sampling", objective_sampling, ("fixed", "dirichlet"))
    check_choice("--reward-weights", reward_weights, ("identity", "analytic", "net"))
    if constraints:
        check_input_files("--constraints", [constraints])
    if reward_net:
        check_input_files("--reward-net", [reward_net])
    check_output_dir("--save-dir", save_dir)


def shadow_run_dir(save_dir: str | None, env: str, seed: int) -> Path:
    """``--save-dir`` (which must not hold a run) or a new ``runs/shadow/<env>-<time>-s<seed>-<pid>``;
    the env must be a task some backend builds a single Gymnasium env of."""
    from econmotor.rl.task_env import shadow_backend

    shadow_backend(load_catalog().get(env))
    run_dir = Path(save_dir) if save_dir else new_run_dir(Path("runs") / "shadow", env, seed)
    if holds_a_run(run_dir):
        raise ConfigError("--save-dir", None, f"{run_dir} already holds a shadow run; a run never overwrites "
                          "another: give a new directory, or leave --save-dir out for a fresh one")
    return run_dir


def shadow_objective(preset: str | None, weights: tuple[float, ...] | None) -> tuple[str, ObjectiveVector]:
    """(label, vector) of ``--objective-preset`` or ``--objective-vector`` (at most one; neither: default)."""
    if preset and weights:
        raise ConfigError("--objective-vector", None, "give --objective-preset or --objective-vector, not both")
    if weights:
        return "custom", ObjectiveVector.from_list(list(weights), source="--objective-vector")
    if preset:
        return preset, ObjectiveVector.from_preset(preset)
    return "default", ObjectiveVector()


def run_recorded(config: Any, vector: ObjectiveVector, url: str, run_dir: Path) -> tuple[int, Any]:
    """Record the run in the registry, train it, and record how it ended: ``(run id, result)``.

    Interrupted: the run is recorded as interrupted, the console says what was kept, and the
    command aborts; failed: recorded as failed with the error, which propagates."""
    from econmotor.rl.train_sac_objective import train_sac_objective

    def kept_note() -> str:
        kept = ", ".join(sorted(p.name for p in run_dir.iterdir())) if run_dir.is_dir() else ""
        return (f"Kept in {run_dir}: {kept or 'nothing'} (the episode log up to the interrupt; no model). Shadow "
                "runs do not resume: run the command again (it writes a new directory).")

    set_deadline_note(kept_note)
    with Registry(url) as registry:
        run_id = registry.start_run(
            "shadow", config.env, "shadow",
            objective=recorded_objective(config.objective_label, vector, config.objective_sampling),
            config={"run_dir": str(run_dir), "total_steps": config.total_steps,
                    "use_objective_reward": config.use_objective_reward, "constraint_mode": config.constraint_mode,
                    "objective_sampling": config.objective_sampling, "reward_weights": config.reward_weights},
            seed=config.seed, max_steps=config.total_steps, policy_path=str(run_dir))
        try:
            with progress_bars() as bars:
                result = train_sac_objective(config, bars)
        except KeyboardInterrupt as exc:
            registry.mark_run(run_id, "interrupted", f"KeyboardInterrupt: {exc}")
            err_console.print(f"[yellow]interrupted[/]: shadow run #{run_id} is recorded as interrupted in "
                              f"{registry.display_url}. {kept_note()}", highlight=False)
            raise typer.Abort from None
        except BaseException as exc:
            registry.mark_run(run_id, "failed", f"{type(exc).__name__}: {exc}")
            raise
        registry.finish_run(run_id, raw_metrics=dict(result.summary), econ_metrics={},
                            artifacts={"run_dir": str(run_dir), "evaluation": result.evaluation})
    return run_id, result


def print_shadow(config: Any, vector: ObjectiveVector, run_id: int, result: Any) -> None:
    """What was trained, the correlations, the evaluation table, the multipliers and the files."""
    for line in header_lines(config.env, config.objective_label, vector, config.objective_sampling,
                             config.use_objective_reward, result.steps_per_s, list(result.evaluation)):
        console.print(line, highlight=False)
    for line in correlation_lines(result.summary):
        console.print(line, highlight=False)
    table = Table(title="evaluation (deterministic)")
    for col in ("objective", "J", "MPL units/h", "error rate", "Wh/unit", "wage parity"):
        table.add_column(col, overflow="fold")
    for name, row in result.evaluation.items():
        table.add_row(name, _fmt(row["J"]), _fmt(row["mpl_units_per_hour"]), _fmt(row["error_rate"], 4),
                      _fmt(row["energy_Wh_per_unit"], 4), _fmt(row["wage_parity"]))
    console.print(table)
    for line in multiplier_lines(result.multipliers, config.lagrange_update_every):
        console.print(line, highlight=False)
    for line in saved_lines(run_id, result.save_dir):
        console.print(line, highlight=False)


#: the console lines of ``econmotor shadow`` are built to fit this many columns (a path may not).
CONSOLE_WIDTH = 80


def weights_text(vector: ObjectiveVector) -> str:
    """The weights normalised to sum 1, by name, 3 significant digits (JSON and registry keep them exact)."""
    return ", ".join(f"{name} {_fmt(weight)}"
                     for name, weight in zip(OBJECTIVE_TERMS, vector.normalize().to_list(), strict=True))


def _wrapped(text: str, first: str = "", indent: str = "  ") -> list[str]:
    """``text`` in lines of at most :data:`CONSOLE_WIDTH` columns (a word longer than that, such as
    a path, stays whole): the first starts with ``first``, the later ones with ``indent``."""
    return textwrap.wrap(text, CONSOLE_WIDTH, initial_indent=first, subsequent_indent=indent,
                         break_long_words=False, break_on_hyphens=False) or [first]


def recorded_objective(label: str, vector: ObjectiveVector, sampling: str) -> dict[str, Any]:
    """The run's objective in the registry: with dirichlet sampling it trained on sampled objectives,
    not on ``label`` (the first objective it is evaluated on), so the name says so."""
    if sampling == "dirichlet":
        return {"name": "dirichlet", "first_evaluated_on": {"name": label, "vector": vector.to_list()}}
    return {"name": label, "vector": vector.to_list()}


def header_lines(env: str, label: str, vector: ObjectiveVector, sampling: str, use_objective_reward: bool,
                 steps_per_s: float, evaluated: list[str]) -> list[str]:
    """What was trained on, and (dirichlet) what was evaluated on.

    ``fixed`` trains on the one normalised vector. ``dirichlet`` draws a new vector every
    episode (the first one included) from ``Dirichlet(DEFAULT_CONCENTRATION)``, so the given
    preset or vector is never trained on: it is only the first evaluation target.
    """
    from econmotor.rl.conditioning import DEFAULT_CONCENTRATION  # what build_env samples from

    lines = [f"[bold]shadow run[/] {escape(env)}: learner reward "
             f"{'objective' if use_objective_reward else 'legacy'}, {steps_per_s:.0f} steps/s"]
    if sampling != "dirichlet":
        return [*lines, f"trained on objective {escape(label)}, weights normalised to sum 1:",
                f"  {weights_text(vector)}"]
    conc = dict(zip(OBJECTIVE_TERMS, DEFAULT_CONCENTRATION, strict=True))
    active = [name for name, c in conc.items() if c > 0]
    pinned = [name for name, c in conc.items() if c <= 0]
    over = f"  over the weights of {', '.join(active)}"
    if pinned:
        over += f"; {', '.join(pinned)} {'stays' if len(pinned) == 1 else 'stay'} 0"
    lines += [f"trained on objectives sampled per episode from "
              f"Dirichlet({', '.join(_fmt(c) for c in DEFAULT_CONCENTRATION)})", over]
    if not evaluated:
        return [*lines, "not evaluated (--eval-episodes 0)"]
    lines += [escape(line) for line in _wrapped(f"evaluated (table below) on: {', '.join(evaluated)}")]
    return [*lines, f"weights of {escape(label)}, normalised to sum 1:", f"  {weights_text(vector)}"]


def correlation_lines(summary: dict[str, Any]) -> list[str]:
    """The shadow summary's correlations of the legacy and the objective reward, one kind a line."""
    def pair(key: str) -> str:
        return f"Pearson {_fmt(summary.get(key + '_pearson'))}, Spearman {_fmt(summary.get(key + '_spearman'))}"

    return [f"correlation of legacy and objective reward over {summary.get('episodes')} episodes:",
            f"  per step: {pair('step')}",
            f"  episode sums: {pair('episode')}",
            f"  legacy episode sum vs episode J: {pair('legacy_vs_J')}"]


def multiplier_lines(history: list[dict[str, float]], update_every: int) -> list[str]:
    """The last Lagrange multipliers (3 significant digits) and, in words, how many updates led there."""
    if not history:
        return []
    every = "one per episode" if update_every == 1 else f"one per {update_every} episodes"
    values = ", ".join(f"{name} {_fmt(value)}" for name, value in history[-1].items())
    return [f"Lagrange multipliers at the end ({len(history)} dual updates, {every}):",
            *_wrapped(values, first="  ")]


def saved_lines(run_id: int, save_dir: str | None) -> list[str]:
    """Where the run went, and its files (those written; the plot needs an episode, the net ``net`` mode)."""
    from econmotor.rl.shadow_log import EPISODES_FILE, PLOT_FILE, SUMMARY_FILE
    from econmotor.rl.train_sac_objective import NET_FILE

    if not save_dir:
        return [f"shadow run #{run_id}: nothing saved"]
    files = [name for name in (EPISODES_FILE, SUMMARY_FILE, PLOT_FILE, "run.json", "sac_model.zip", NET_FILE)
             if (Path(save_dir) / name).is_file()]
    return [escape(f"shadow run #{run_id} saved under {save_dir}:"),
            *(escape(line) for line in _wrapped(", ".join(files) or "no files", first="  "))]


def _fmt(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}g}"
