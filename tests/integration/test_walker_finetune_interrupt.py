"""A SIGTERM to a G1 fine-tune (``train --motor-backend mujoco --init-policy holosoma:g1_29dof/ppo``) says how to
resume what it kept (issue 52, item 7): the walker trainer keeps ``checkpoints/latest.pt``, and the note said
"no checkpoint to resume from, so start again" with a command that had dropped ``--init-policy``. Here the
note names the checkpoint and a ``--resume`` command, and that command, run as printed, continues from the
kept env steps; a run stopped before any checkpoint says to start again from the same ``--init-policy``."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from econmotor.cli.runs import interrupted_note

from .conftest import sigterm_when

pytestmark = [pytest.mark.holosoma]  # the shipped G1 walker
ECONMOTOR = Path(sys.executable).with_name("econmotor")
POLICY = "holosoma:g1_29dof/ppo"


def curve_steps(run_dir: Path) -> list[int]:
    path = run_dir / "curve.jsonl"
    lines = path.read_text().splitlines() if path.exists() else []
    return [json.loads(line)["env_steps"] for line in lines if line.endswith("}")]


def terminated_after_rows(args: list[str], cwd: Path, run_dir: Path, rows: int) -> str:
    """Run ``econmotor args``, SIGTERM it once ``run_dir``'s curve has ``rows`` rows; its stderr (exit 143)."""
    proc = subprocess.Popen([str(ECONMOTOR), *args], cwd=cwd, env={**os.environ, "OMP_NUM_THREADS": "1"},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    err = sigterm_when(proc, lambda: len(curve_steps(run_dir)) >= rows, f"curve row {rows}", hang_s=120)
    assert proc.returncode == 143, err[-2000:]
    return " ".join(err.split())


def test_sigterm_to_a_g1_finetune_says_how_to_resume_and_resume_continues(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    db = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    note = terminated_after_rows(["train", "--task-id", "humanoid_locomotion_g1", "--motor-backend", "mujoco",
                                  "--init-policy", POLICY, "--max-steps", "100000", "--num-envs", "1",
                                  "--select-every", "0",  # no held-out looks (the start's would come first)
                                  "--output-dir", str(run_dir), "--db-url", db], tmp_path, run_dir, rows=1)
    assert (run_dir / "checkpoints" / "latest.pt").is_file()
    assert "no checkpoint" not in note and "latest.pt" in note, note
    resume = re.search(r"Resume with: (econmotor train .*? --resume)", note)
    assert resume, note
    kept = curve_steps(run_dir)[-1]
    command = shlex.split(resume.group(1))[1:]
    assert "--init-policy" not in command and str(run_dir) in command  # the checkpoint holds the tuned actor
    before = len(curve_steps(run_dir))
    terminated_after_rows([*command, "--db-url", db], tmp_path, run_dir, rows=before + 1)
    assert curve_steps(run_dir)[before] > kept  # continued from the kept steps (a fresh start counts from 0)


def test_a_finetune_stopped_before_its_first_checkpoint_starts_again_from_its_init_policy(tmp_path: Path) -> None:
    (tmp_path / "run").mkdir()
    note = interrupted_note("mujoco", "humanoid_locomotion_g1", tmp_path / "run", 4000, init_policy=POLICY)
    assert "no checkpoint to resume from" in note and f"--init-policy {POLICY}" in note, note
