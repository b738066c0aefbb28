"""The specification's command lines run as written: the backend, not a global CLI limit, says how
many environments it can run, and a CPU adapts a GPU-sized request and says so.

- ``scripts/report_task_pricing_and_performance.py ... --motor-backend holosoma --num-envs 2048
  --max-steps 50000`` (motor_backends.md) trains, evaluates and writes its report on the CPU:
  2048 envs become Holosoma's one classic-MuJoCo env, announced. The CPU step cap is lowered
  through the backend's environment option so the test takes seconds, not minutes; the command
  line itself is verbatim.
- ``econmotor train --motor-backend mjx --num-envs 8192`` is accepted and capped on a CPU with a
  message (the test stops the run once the message is out: compiling a 64-env batch takes
  minutes on two cores and shows nothing more).
- a request above what a backend can run on any device is one clear line naming the limit.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SPEC_LINE = [
    "--task-id", "humanoid_locomotion_g1",
    "--motor-backend", "holosoma",
    "--objective-config", "configs/objectives/example_holosoma_objective.yaml",
    "--datapacks", "configs/datapacks/example_holosoma_datapack.yaml",
    "--objective-name", "baseline_logging_error_min",
    "--notes", "G1/T1 warehouse logging baseline with high error penalty",
    "--num-envs", "2048",
    "--max-steps", "50000",
]


def cli_env(**extra: str) -> dict[str, str]:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "COLUMNS": "100", **extra}
    env.pop("ECONMOTOR_DB_URL", None)
    return env


@pytest.mark.slow
@pytest.mark.holosoma
def test_the_specs_holosoma_command_line_runs_on_a_cpu_adapted_and_announced(workdir: Path) -> None:
    if not (REPO / ".venv-holosoma" / ".econmotor-installed").exists():
        subprocess.run(["make", "holosoma"], cwd=REPO, check=True, timeout=1800)
    result = subprocess.run(
        [sys.executable, str(REPO / "scripts" / "report_task_pricing_and_performance.py"), *SPEC_LINE],
        cwd=workdir, env=cli_env(ECONMOTOR_HOLOSOMA_CPU_MAX_ENV_STEPS="240",
                                 ECONMOTOR_HOLOSOMA_VENV=str(REPO / ".venv-holosoma")),
        capture_output=True, text=True, timeout=1200, check=False)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    out = result.stdout + result.stderr
    assert "num_envs 2048 -> 1" in out  # the adaptation is announced, not an error
    assert "max_steps 50000 -> 240" in out.replace(",", "")
    (doc_path,) = (workdir / "reports" / "humanoid_locomotion_g1").glob("*.json")
    doc = json.loads(doc_path.read_text())
    assert doc["backend"] == "holosoma" and doc["objective"]["name"] == "baseline_logging_error_min"
    assert doc["runs"]["train"]["status"] == "completed"


@pytest.mark.slow
def test_mjx_accepts_thousands_of_envs_and_caps_them_on_a_cpu(workdir: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "econmotor", "train", "--task-id", "hopper_courier", "--motor-backend", "mjx",
         "--num-envs", "8192", "--max-steps", "20000", "--eval-episodes", "0"],
        cwd=workdir, env=cli_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    said: list[str] = []
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            said.append(line)
            if "capped at" in line:
                break
        text = "".join(said)
        assert "8192 envs requested; capped at 64 on a CPU" in text.replace(",", ""), text
        assert "out of range" not in text and proc.poll() is None  # accepted: it is training
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()


@pytest.mark.parametrize("backend,limit", [("mujoco", "256"), ("mjx", "1,048,576")])
def test_more_envs_than_a_backend_can_run_is_one_clear_line(workdir: Path, backend: str, limit: str) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "econmotor", "train", "--task-id", "hopper_courier", "--motor-backend", backend,
         "--num-envs", "2000000"], cwd=workdir, env=cli_env(), capture_output=True, text=True, timeout=120,
        check=False)
    assert result.returncode == 2
    assert f"more than the '{backend}' backend can run" in result.stderr and limit in result.stderr
    assert "Traceback" not in result.stderr
