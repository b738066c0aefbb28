"""``econmotor demo`` (``make demo``): the task pricing report of a hopper courier trained on this machine.

Trains a ``hopper_courier`` policy (the Gymnasium Hopper-v5 body on the mjx backend: its JAX PPO on 64
batched envs with :data:`DEMO_HYPERPARAMETERS`, the body stepped by MuJoCo C on a CPU (the task's
``cpu_physics``) and by MJX on an accelerator: on a CPU it learns several times faster than SB3's PPO on the
``mujoco`` backend, XLA compilation included; its held-out evaluations run beside training, on the other
core; ``benchmarks/time_to_deployable.py``) under the
safety-first objective :data:`DEMO_OBJECTIVE` until a held-out evaluation passes the task's
acceptance rule (``--until-deployable``, at most :data:`DEMO_MAX_STEPS` steps; a held-out evaluation
every :data:`DEMO_SELECT_EVERY` steps: a failing one costs a fraction of a second), evaluates the kept
policy on fresh episodes until the verdict is decided (a sequential evaluation: the hopper covers ~1
leg of 10 m per episode, and the fall rate's confidence sequence bounds it inside the 5% limit after
64 fall-free legs), the evidence behind the verdict and the price's interval,
decides whether it is deployable, prices a delivery leg against a human courier and writes
the JSON, Markdown and HTML reports; the HTML path is printed last.
"""

from __future__ import annotations

from pathlib import Path

import typer

from econmotor.cli._app import app, console
from econmotor.cli.options import EVAL_MAX_EPISODES_OPTION, EVAL_MAX_SECONDS_OPTION
from econmotor.cli.reporting import ReportArgs, run_report

DEMO_TASK = "hopper_courier"
#: the backend the demo trains and prices on (its catalog entry: 64 envs on a CPU)
DEMO_BACKEND = "mjx"
#: the demo trains until a held-out evaluation passes the task's acceptance rule (--until-deployable,
#: motor_backend/selection.py), at most this many steps; seeds 0-4 passed at 200k-350k
#: (benchmarks/time_to_deployable.py)
DEMO_MAX_STEPS = 600_000
#: env steps between the held-out evaluations: the backend's own cadence (at most a tenth of the wall time)
#: found seed 1's deployable policy at 600k steps in 94 s, this one at 225k in 57 s (warm cache, idle cores)
DEMO_SELECT_EVERY = 25_000
#: the cap of a held-out evaluation (the default is 160): a fall-free policy passes within it (0 falls in
#: about 72 legs bound the fall rate inside the 5% limit), and an evaluation with a fall is cut short at its
#: first look (one fall needs some 140 legs), so the evaluations of the policies that are nearly there cost a
#: batch of 16 episodes, not ten, and keep up with training
DEMO_SELECT_EPISODES = 96
#: the demo's PPO over the catalog's:
#: - policy and value MLPs of 128 x 128 (the catalog's 256 x 256 suit the thousands of envs of a GPU): on a
#:   CPU the 128 minibatch updates of an iteration take ~25 ms instead of ~125 ms, beside a ~50 ms rollout
#:   of 64 envs, and the seeds are as deployable within the same steps;
#: - rewards scaled by 0.1 for learning (the reported figures are unscaled): the demo's objective prices a
#:   fall at ~1,250, so unscaled returns run to thousands, and the value loss's gradient shares one
#:   global-norm clip with the policy's;
#: - an entropy bonus of 0.01 (the catalog's 0.001): a hopper that stands still is safe under this objective,
#:   and with the catalog's bonus one seed in five stood until 450k steps and was not deployable by 600k.
#: Seeds 0-4 passed at 150k-325k steps (median 250k); with the catalog's bonus, or unscaled, one seed in five
#: did not pass by 600k (2 idle cores, benchmarks/RESULTS.md)
DEMO_HYPERPARAMETERS = {"hidden_sizes": [128, 128], "reward_scaling": 0.1, "entropy_cost": 0.01}
#: the demo's objective (a package file; its comments give the weights' reasons): falls and lean are
#: weighted at the scale of Hopper-v5's own reward, so PPO learns an upright gait within the demo's
#: steps (the default vector's hopper falls in most episodes; see benchmarks/demo_reliability.py).
DEMO_OBJECTIVE = Path(__file__).resolve().parent.parent / "objectives" / "courier_demo.yaml"


@app.command("demo")
def demo_command(
    max_steps: int = typer.Option(DEMO_MAX_STEPS, "--max-steps", min=1, help="Training environment steps at most "
                                  "(training stops once a held-out evaluation passes the task's acceptance)."),
    eval_episodes: int = typer.Option(None, "--eval-episodes",
                                      help="Exactly N episodes in the evaluation run (default: a sequential "
                                      "evaluation, until the verdict is decided)."),
    eval_max_episodes: int = EVAL_MAX_EPISODES_OPTION,
    eval_max_seconds: float = EVAL_MAX_SECONDS_OPTION,
    output_dir: Path = typer.Option(Path("reports") / "demo", "--output-dir", help="Where the reports go."),
    db_url: str = typer.Option(None, "--db-url", help="Registry URL (default ./.econmotor/registry.sqlite)."),
    seed: int = typer.Option(0, "--seed"),
) -> None:
    """Train a hopper courier until deployable, price its delivery legs, write the reports."""
    console.print(f"[bold]econmotor demo[/]: training {DEMO_TASK} (Hopper-v5 in MuJoCo, JAX PPO on the CPU) under the "
                  "safety-first objective courier_safety_first until a held-out evaluation every "
                  f"{DEMO_SELECT_EVERY:,} steps passes the task's acceptance (at most {max_steps:,} steps), then "
                  "pricing a 10 m delivery leg against a human courier on fresh episodes.")
    run_report(ReportArgs(
        task_id=DEMO_TASK, motor_backend=DEMO_BACKEND, objective_config=DEMO_OBJECTIVE,
        notes="econmotor demo: hopper courier on the mjx backend", max_steps=max_steps,
        eval_episodes=eval_episodes, eval_max_episodes=eval_max_episodes, eval_max_seconds=eval_max_seconds,
        seed=seed, output_dir=output_dir, db_url=db_url, until_deployable=True, select_every=DEMO_SELECT_EVERY,
        select_episodes=DEMO_SELECT_EPISODES, hyperparameters=DEMO_HYPERPARAMETERS))
