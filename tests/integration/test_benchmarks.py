"""Every script in benchmarks/ runs end to end, as its docstring says, at its smallest sizes.

Each benchmark declares ``SMOKE_ARGS: list[str]``, the command-line arguments of its smallest run
(read here from the source, the script is not imported), or ``SMOKE_ARGS = None`` with a comment
saying why it cannot run on this machine. A new script without it fails here. Each runs in a
subprocess of its own, from an empty working directory with ``$TMPDIR`` inside it (where every
output goes), one thread, ``src/`` first on ``PYTHONPATH``, with the interpreter its docstring names
(``.venv-holosoma/bin/python`` or this one). It must exit 0 and print its figures line: the marker
in ``FIGURES``. The numbers at these sizes mean nothing; that the script gets to them does.
A run past its time limit is killed with its whole process group.

JAX's persistent compilation cache (the suite's ``$ECONMOTOR_JAX_CACHE_DIR``, see tests/conftest.py) serves
later runs the MJX programs the first one compiled: the MJX scripts then take about a minute each instead of
several (measured on 2 shared cores: the whole file 1,445 s wall cold, 580 s warm).

The :data:`SLOW` and :data:`HEAVY` scripts (they train policies, compile MJX programs for minutes on a
CPU, or run Holosoma jobs) run only with ``ECONMOTOR_BENCHMARKS=all`` (``make bench-smoke``): with
them ``make test`` would come too close to CI's 30 minutes. The quick ones run in ``make test``, and
every script's ``SMOKE_ARGS`` and figures line are checked there.
"""

from __future__ import annotations

import ast
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BENCHMARKS = sorted((REPO / "benchmarks").glob("*.py"))
HOLOSOMA_PYTHON = ".venv-holosoma/bin/python"

#: a line every script prints with its figures, once it has measured them
FIGURES = {
    "cli_startup.py": "ratio --help lazy / eager imports:",
    "conditioned_vs_specialists.py": "conditioned / specialist: return ratio",
    "constraints_dishwashing.py": "MPL ratio to unconstrained:",
    "demo_reliability.py": '"fall_rate_upper95":',
    "economic_layers_cost.py": "layers in situ",
    "holosoma_overlay_overhead.py": "in-run ratio",
    "g1_objectives.py": "ranked first by compare:",
    "hypervolume.py": "ratio HSO/grid",
    "mjx_compile.py": "ratio flags / default, compile_iteration_s:",
    "motor_heat_calibration.py": "runtime per charge: without heat",
    "mjx_eval_timeline.py": "evaluation per episode: before",
    "mjx_humanoid_throughput.py": "ratio",
    "mjx_model_options.py": "ratio",
    "mjx_physics_gap.py": "(ratio to mjx options in brackets)",
    "mjx_throughput.py": "PPO training throughput ratio mjx / mujoco",
    "mjx_time_to_courier.py": " s wall",
    "overlay_overhead.py": "hopper_courier",
    "preset_differentiation.py": "best preset MPL / random policy MPL",
    "registry_episode_reads.py": "ratio records/arrays",
    "shadow_overhead.py": "SAC steps/s with shadow / without",
    "walker_throughput.py": "env_processes / raw_2:",
    "walker_energy_phases.py": "walking:",
    "solver_throughput.py": "speed-up (loop / vectorised)",
    "time_to_deployable.py": "ratio median demo / median old",
    "training_throughput.py": "ratio",
}
#: the heavy ones (train a policy, or compile MJX programs): end-to-end tests like the other slow ones
SLOW = {"conditioned_vs_specialists.py", "constraints_dishwashing.py", "demo_reliability.py",
        "economic_layers_cost.py", "holosoma_overlay_overhead.py", "mjx_compile.py", "mjx_model_options.py",
        "mjx_physics_gap.py", "mjx_throughput.py", "mjx_time_to_courier.py", "preset_differentiation.py",
        "time_to_deployable.py", "training_throughput.py", "shadow_overhead.py"}
#: minutes each on a CPU (MJX compilation, Holosoma training): only with ECONMOTOR_BENCHMARKS=all
HEAVY = {"mjx_compile.py", "mjx_model_options.py", "mjx_physics_gap.py", "mjx_throughput.py",
         "mjx_time_to_courier.py", "mjx_humanoid_throughput.py", "mjx_eval_timeline.py", "g1_objectives.py",
         "holosoma_overlay_overhead.py", "time_to_deployable.py"}
#: need the isolated Holosoma environment (the script runs in it, or starts jobs in it)
HOLOSOMA = {"holosoma_overlay_overhead.py"}
TIMEOUT_S = 900  # generous: minutes on 2 shared cores with a cold compilation cache


def smoke_args(script: Path) -> list[str] | None:
    """The script's module-level ``SMOKE_ARGS`` (a literal), read without importing it."""
    for node in ast.parse(script.read_text(encoding="utf-8")).body:
        targets = [node.target] if isinstance(node, ast.AnnAssign) else getattr(node, "targets", [])
        if any(isinstance(t, ast.Name) and t.id == "SMOKE_ARGS" for t in targets) and node.value is not None:
            args = ast.literal_eval(node.value)
            assert args is None or (isinstance(args, list) and all(isinstance(a, str) for a in args)), (
                f"{script.name}: SMOKE_ARGS must be a list of strings or None, not {args!r}")
            return args
    pytest.fail(f"benchmarks/{script.name} has no module-level SMOKE_ARGS: add `SMOKE_ARGS: list[str] = [...]`, "
                "the command-line arguments of its smallest run (seconds), or `SMOKE_ARGS = None` with a comment "
                "saying why it cannot run here; and its figures line to FIGURES in this test", pytrace=False)


def interpreter(script: Path) -> str:
    """The Python the script's docstring says to run it with."""
    doc = ast.get_docstring(ast.parse(script.read_text(encoding="utf-8"))) or ""
    return str(REPO / HOLOSOMA_PYTHON) if HOLOSOMA_PYTHON in doc else sys.executable


def run_group(command: list[str], cwd: Path, env: dict[str, str], timeout_s: float) -> tuple[int, str]:
    """(exit code, stdout and stderr) of ``command``. Its output goes to a file, not a pipe, so a process
    it left behind cannot hold the test; its whole process group is killed when it ends or times out."""
    log = cwd / "output.txt"
    with log.open("w", encoding="utf-8") as out:
        proc = subprocess.Popen(command, cwd=cwd, env=env, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)
        try:
            code: int | None = proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            code = None
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)  # on timeout, and anything it started and left behind
            except ProcessLookupError:
                pass
            proc.wait()
    text = log.read_text(encoding="utf-8", errors="replace")
    if code is None:
        pytest.fail(f"{Path(command[1]).name} ran past {timeout_s} s and was killed:\n{text[-4000:]}", pytrace=False)
    return code, text


def marks(name: str) -> list[pytest.MarkDecorator]:
    heavy = pytest.mark.skipif(name in SLOW | HEAVY and os.environ.get("ECONMOTOR_BENCHMARKS") != "all",
                               reason="trains a policy, compiles MJX programs or runs Holosoma jobs: "
                                      "ECONMOTOR_BENCHMARKS=all (make bench-smoke) runs it")
    return ([pytest.mark.slow] if name in SLOW | HEAVY else []) + \
        ([pytest.mark.holosoma] if name in HOLOSOMA else []) + [heavy]


@pytest.mark.timeout(TIMEOUT_S + 60)
@pytest.mark.parametrize("script", [pytest.param(p, id=p.stem, marks=marks(p.name)) for p in BENCHMARKS])
def test_benchmark_runs_at_its_smallest_sizes(script: Path, tmp_path: Path) -> None:
    args = smoke_args(script)
    if args is None:
        pytest.skip(f"{script.name}: SMOKE_ARGS = None (see the comment there)")
    assert script.name in FIGURES, f"add {script.name}'s figures line (a substring it prints) to FIGURES"
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(REPO / "src"),
           "TMPDIR": str(tmp_path / "tmp"), "MPLBACKEND": "Agg",
           "JAX_COMPILATION_CACHE_DIR": os.environ["ECONMOTOR_JAX_CACHE_DIR"]}
    code, out = run_group([interpreter(script), str(script), *args], tmp_path, env, TIMEOUT_S)
    assert code == 0, f"{script.name} {' '.join(args)} exited {code}:\n{out[-6000:]}"
    assert FIGURES[script.name] in out, f"{script.name} did not print {FIGURES[script.name]!r}:\n{out[-4000:]}"


@pytest.mark.parametrize("script", BENCHMARKS, ids=[p.stem for p in BENCHMARKS])
def test_every_benchmark_declares_its_smallest_run_and_figures_line(script: Path) -> None:
    """Checked for every script, also those only ``make bench-smoke`` runs."""
    args = smoke_args(script)
    assert args is None or args, f"{script.name}: SMOKE_ARGS is an empty list"
    assert script.name in FIGURES, f"add {script.name}'s figures line (a substring it prints) to FIGURES"
