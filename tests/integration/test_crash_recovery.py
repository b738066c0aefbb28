"""kill -9 in the middle of a report and of checkpoint writes (issue 15): the next command shows
the run as ``abandoned`` (never ``running``) and training resumes from the newest intact
checkpoint; a truncated checkpoint (policy zip or VecNormalize statistics) is detected and skipped."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from econmotor.cli import main

pytestmark = pytest.mark.slow

COUNTS = {"kills": 0}


def _econmotor(*args: str, cwd: Path) -> subprocess.Popen:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": os.pathsep.join(sys.path)}
    return subprocess.Popen([sys.executable, "-m", "econmotor", *args], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _kill_when(proc: subprocess.Popen, ready, timeout_s: float = 120.0) -> None:
    try:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and proc.poll() is None and not ready():
            time.sleep(0.2)
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    COUNTS["kills"] += 1


def test_kill_9_during_a_report_leaves_an_abandoned_run_not_a_running_one(tmp_path, capsys):
    from econmotor.store import Registry

    url = f"sqlite:///{tmp_path / 'reg.sqlite'}"

    def training_started() -> bool:
        if not (tmp_path / "reg.sqlite").exists():
            return False
        with Registry(url) as reg:
            return bool(reg.runs(status="running"))

    proc = _econmotor("report", "--task-id", "dishwashing", "--motor-backend", "dishwashing", "--max-steps",
                      "1000000", "--db-url", url, "--output-dir", "out", cwd=tmp_path)
    _kill_when(proc, training_started)
    # the next command: the run whose process is gone is abandoned, with the reason
    capsys.readouterr()
    assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--db-url", url,
                 "--run-id", "1"]) == 2
    err = capsys.readouterr().err
    assert "run(s) #1 were 'running' but their process is gone" in err  # said once, by the first open
    assert "run #1 is abandoned" in err and "ended without recording an outcome" in err, err
    with Registry(url) as reg:
        [run] = reg.runs()
        assert run.status == "abandoned" and reg.runs(status="running") == []
        assert reg.reports() == []  # no report row for files never written
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_live_run_is_not_marked_abandoned(tmp_path):
    from econmotor.store import Registry

    url = f"sqlite:///{tmp_path / 'reg.sqlite'}"
    with Registry(url) as reg:
        run_id = reg.start_run("train", "dishwashing", "dishwashing")
    with Registry(url) as reg:  # same (live) process: still running
        assert reg.run(run_id).status == "running" and reg.abandoned_run_ids == []


TRAIN = """
import sys
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.objectives import EconomicObjectiveSpec
MujocoBackend().train_policy("hopper_courier", EconomicObjectiveSpec(), [], 2, 10_000_000, 0,
    output_dir=sys.argv[1], eval_episodes=0, checkpoint_every_steps=256,
    hyperparameters={"n_steps": 64, "batch_size": 64, "n_epochs": 1})
"""


def test_kill_9_during_checkpoint_writes_then_resume_skips_truncated_checkpoints(tmp_path, capsys):
    from econmotor.motor_backend.mujoco.training import checkpoint_vecnormalize, find_checkpoint
    from econmotor.motor_backend.run_dir import read_run_config

    run_dir = tmp_path / "run"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen([sys.executable, "-c", TRAIN, str(run_dir)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    # checkpoints every 256 steps (~ every 0.2-0.5 s): a kill at a random moment lands in or near a write
    _kill_when(proc, lambda: (find_checkpoint(run_dir, True)[0] or (None, 0))[1] >= 1536)
    ckpts = run_dir / "checkpoints"
    (newest, _), skipped = find_checkpoint(run_dir, True)
    # atomic writes: a kill mid-write leaves at most a *.tmp<pid>.* file, never a damaged checkpoint
    assert skipped == [], skipped
    # what a crash without atomic writes (or a full disk) leaves: a truncated zip, a truncated VecNormalize file
    older = sorted(int(p.name.split("_")[1]) for p in ckpts.glob("ckpt_*_steps.zip"))
    assert len(older) >= 3
    newest.write_bytes(newest.read_bytes()[:200])
    second = ckpts / f"ckpt_{older[-2]}_steps.zip"
    stats = checkpoint_vecnormalize(second, older[-2])
    stats.write_bytes(stats.read_bytes()[:40])
    (_, intact_steps), skipped = find_checkpoint(run_dir, True)
    assert intact_steps == older[-3] and len(skipped) == 2

    capsys.readouterr()
    target = intact_steps + 256
    assert main(["train", "--task", "hopper_courier", "--num-envs", "2", "--max-steps", str(target),
                 "--output-dir", str(run_dir), "--resume", "--eval-episodes", "1"]) == 0
    err = capsys.readouterr().err
    assert err.count("skipped a damaged checkpoint") == 2 and f"ckpt_{intact_steps}_steps.zip" in err, err
    config = read_run_config(run_dir, "mujoco")
    assert config["resumed_from_steps"] == intact_steps and len(config["skipped_checkpoints"]) == 2
    assert (run_dir / "policy.zip").is_file()


def test_counts_for_the_closing_note(capsys):
    with capsys.disabled():
        print(f"\ncrash recovery: kill -9 {COUNTS['kills']} processes; runs left running: 0")
