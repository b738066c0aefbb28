"""Bad input to a sequential evaluation (Must-show 5 of issue 33): a cap below one batch, a negative cap,
``--eval-episodes 0`` with the sequential default, a cap beside a fixed count. Each exits 2 with one
line naming the flag, before anything is trained or written. In-process (``econmotor.cli.main``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from econmotor.cli import main

MUJOCO = ["report", "--task-id", "hopper_courier"]  # the mujoco backend: batches of 16 episodes
COMPARE = ["compare", "--task-id", "humanoid_locomotion_g1", "--policy", "a.onnx", "--policy", "b.onnx"]


@pytest.fixture(autouse=True)
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    return tmp_path


def refused(capsys: pytest.CaptureFixture[str], args: list[str], *words: str) -> str:
    capsys.readouterr()
    rc = main(args)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.mark.parametrize(("command", "backend"), [(MUJOCO, "mujoco"), (["demo"], "mjx")])
def test_a_cap_below_one_batch_names_the_flag_and_the_batch(capsys, workdir: Path, command: list[str],
                                                             backend: str) -> None:
    from econmotor.motor_backend.factory import make_motor_backend

    batch = make_motor_backend(backend).evaluation_batch("hopper_courier")  # the mjx hopper's: 48 on a CPU
    line = refused(capsys, [*command, "--eval-max-episodes", "8"], "--eval-max-episodes", "below one evaluation batch",
                   f"{batch} or more")
    assert "8" in line
    assert not (workdir / "runs").exists() and not (workdir / ".econmotor").exists()  # nothing trained or written


@pytest.mark.parametrize(("flag", "value"), [("--eval-max-episodes", "-5"), ("--eval-max-seconds", "-1"),
                                             ("--eval-max-seconds", "0")])
def test_a_negative_cap_is_refused(capsys, flag: str, value: str) -> None:
    refused(capsys, [*MUJOCO, flag, value], flag, "out of range")


@pytest.mark.parametrize("command", [MUJOCO, ["demo"], ["report", "--task-id", "humanoid_locomotion_g1", "--policy",
                                                       "holosoma:g1_29dof/ppo", "--motor-backend", "holosoma"],
                                     COMPARE])
def test_eval_episodes_0_says_to_give_a_count_or_leave_it_out(capsys, command: list[str]) -> None:
    refused(capsys, [*command, "--eval-episodes", "0"], "--eval-episodes", "leave --eval-episodes out",
            "sequential")


def test_a_cap_beside_a_fixed_count_is_refused(capsys) -> None:
    refused(capsys, [*MUJOCO, "--eval-episodes", "20", "--eval-max-episodes", "100"], "--eval-max-episodes",
            "drop --eval-episodes")
