"""``econmotor shadow``: objective-conditioned SAC with shadow mode and the flip switch."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
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
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.errors import ConfigError
from econmotor.motor_backend.base import new_run_dir
from econmotor.store.registry import Registry
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
    set_cpu_threads()
    from econmotor.rl.train_sac_objective import ShadowConfig, train_sac_objective

    run_dir = Path(save_dir) if save_dir else new_run_dir(Path("runs") / "shadow", env, seed)
    if holds_a_run(run_dir):
        raise ConfigError("--save-dir", None, f"{run_dir} already holds a shadow run; a run never overwrites "
                          "another: give a new directory, or leave --save-dir out for a fresh one")
    if objective_preset and objective_vector:
        raise ConfigError("--objective-vector", None, "give --objective-preset or --objective-vector, not both")
    if objective_vector:
        vector, label = ObjectiveVector.from_list(list(objective_vector), source="--objective-vector"), "custom"
    elif objective_preset:
        vector, label = ObjectiveVector.from_preset(objective_preset), objective_preset
    else:
        vector, label = ObjectiveVector(), "default"
    config = ShadowConfig(
        env=env, objective=tuple(vector.to_list()), objective_label=label, energy_term=energy_term,
        total_steps=total_steps,
        use_objective_reward=use_objective_reward,
        constraints=load_constraint_set(Path(constraints)) if constraints else None, constraint_mode=constraint_mode,
        objective_sampling=objective_sampling, reward_weights=reward_weights, reward_net_path=reward_net,
        seed=seed, save_dir=str(run_dir),
        max_episode_steps=max_episode_steps, lagrange_lr=lagrange_lr, learning_starts=learning_starts,
        eval_episodes=eval_episodes,
        eval_objectives={label: tuple(vector.to_list()),
                         **{p: tuple(ObjectiveVector.from_preset(p).to_list()) for p in eval_preset}}
        if eval_preset else {})
    url = check_db_url(db_url)
    recorded: dict[str, Any] = {}

    def start() -> int:
        """Record the run when training really starts (bad input found before that records nothing)."""
        if "id" not in recorded:
            recorded["registry"] = registry = Registry(url)
            recorded["id"] = registry.start_run(
                "shadow", env, "shadow", objective={"name": label, "vector": vector.to_list()},
                config={"run_dir": str(run_dir), "total_steps": total_steps,
                        "use_objective_reward": use_objective_reward, "constraint_mode": constraint_mode,
                        "objective_sampling": objective_sampling, "reward_weights": reward_weights},
                seed=seed, max_steps=total_steps, policy_path=str(run_dir))
        return recorded["id"]

    def kept_note() -> str:
        kept = ", ".join(sorted(p.name for p in run_dir.iterdir())) if run_dir.is_dir() else ""
        return (f"Kept in {run_dir}: {kept or 'nothing'} (the episode log up to the interrupt; no model). Shadow "
                "runs do not resume: run the command again (it writes a new directory).")

    set_deadline_note(kept_note)
    try:
        with progress_bars() as bars:
            def progress(label_: str, done: float, total: float) -> None:
                start()
                bars(label_, done, total)

            result = train_sac_objective(config, progress)
        run_id = start()
        recorded["registry"].finish_run(run_id, raw_metrics=dict(result.summary), econ_metrics={},
                                        artifacts={"run_dir": str(run_dir), "evaluation": result.evaluation})
    except KeyboardInterrupt as exc:
        where = "nothing was recorded"
        if "id" in recorded:
            recorded["registry"].mark_run(recorded["id"], "interrupted", f"KeyboardInterrupt: {exc}")
            where = f"shadow run #{recorded['id']} is recorded as interrupted in {recorded['registry'].display_url}"
        err_console.print(f"[yellow]interrupted[/]: {where}. {kept_note()}", highlight=False)
        raise typer.Abort from None
    except BaseException as exc:
        if "id" in recorded:
            recorded["registry"].mark_run(recorded["id"], "failed", f"{type(exc).__name__}: {exc}")
        raise
    finally:
        if "registry" in recorded:
            recorded["registry"].close()
    s = result.summary
    console.print(f"[bold]shadow run[/] {env}, objective {label} {vector.normalize().to_list()}, "
                  f"learner reward: {'objective' if use_objective_reward else 'legacy'}, "
                  f"{result.steps_per_s:.0f} steps/s")
    console.print(f"correlation legacy vs objective: step Pearson {_fmt(s.get('step_pearson'))}, "
                  f"Spearman {_fmt(s.get('step_spearman'))}; episode Pearson {_fmt(s.get('episode_pearson'))}, "
                  f"Spearman {_fmt(s.get('episode_spearman'))}; legacy sum vs episode J Pearson "
                  f"{_fmt(s.get('legacy_vs_J_pearson'))}, Spearman {_fmt(s.get('legacy_vs_J_spearman'))} "
                  f"over {s.get('episodes')} episodes")
    table = Table(title="evaluation (deterministic)")
    for col in ("objective", "J", "MPL units/h", "error rate", "Wh/unit", "wage parity"):
        table.add_column(col)
    for name, row in result.evaluation.items():
        table.add_row(name, _fmt(row["J"]), _fmt(row["mpl_units_per_hour"]), _fmt(row["error_rate"], 4),
                      _fmt(row["energy_Wh_per_unit"], 4), _fmt(row["wage_parity"]))
    console.print(table)
    if result.multipliers:
        console.print(f"Lagrange multipliers (last): {result.multipliers[-1]}")
    console.print(f"shadow run #{run_id} saved under {result.save_dir}: shadow_episodes.jsonl, "
                  "shadow_summary.json, shadow_plot.png, run.json, sac_model.zip", highlight=False)


def _fmt(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}g}"
