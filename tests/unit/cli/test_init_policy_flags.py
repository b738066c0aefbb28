"""``--init-policy`` at the edge: a backend that cannot start from a policy, a missing file, an architecture
the mjx actor lacks, a policy for another robot, and flags it cannot go with are one clear line, exit 2,
and record nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

from econmotor.cli import main

pytestmark = [pytest.mark.holosoma]  # the shipped names resolve in .venv-holosoma's holosoma_inference


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    return tmp_path


def refused(capsys: pytest.CaptureFixture[str], args: list[str], *names: str) -> str:
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    text = " ".join(err.split())
    for name in names:
        assert name in text, (name, text)
    return text


@pytest.mark.parametrize(("extra", "names"), [
    # mujoco starts the card robots' walker tasks from a policy, not a Gymnasium courier: it names the ones it can
    (["--motor-backend", "mujoco", "--init-policy", "holosoma:g1_29dof/ppo"],
     ("--init-policy", "hopper_courier", "humanoid_locomotion_g1")),
    (["--motor-backend", "mjx", "--init-policy", "walker.onnx"], ("--init-policy", "walker.onnx", "no such ONNX")),
    (["--motor-backend", "mjx", "--init-policy", "holosoma:g1_29dof/fastsac"],
     ("FastSAC", "holosoma:g1_29dof/fastsac", "--motor-backend mujoco")),
    (["--motor-backend", "mjx", "--init-policy", "holosoma:h1_19dof/ppo"],
     ("--init-policy", "ppo_h1_19dof.onnx", "holosoma:g1_29dof/ppo")),
    (["--motor-backend", "mjx", "--init-policy", "holosoma:g1_29dof/ppo"],
     ("input 'actor_obs'", "100 values", "the env's 11")),
])
def test_train_refuses_an_init_policy_it_cannot_start_from(extra, names, workdir, capsys) -> None:
    refused(capsys, ["train", "--task-id", "hopper_courier", "--max-steps", "320", "--num-envs", "8", *extra], *names)
    assert not (workdir / "runs").exists() or not any((workdir / "runs").iterdir())
    assert not (workdir / ".econmotor").exists()  # no registry row


def test_report_refuses_init_policy_with_policy_or_no_backend(workdir, capsys) -> None:
    refused(capsys, ["report", "--task-id", "humanoid_locomotion_g1", "--motor-backend", "holosoma", "--policy",
                     "holosoma:g1_29dof/ppo", "--eval-episodes", "1", "--init-policy", "holosoma:g1_29dof/ppo"],
            "--init-policy", "--policy")
    refused(capsys, ["train", "--task-id", "hopper_courier", "--motor-backend", "mjx", "--resume", "--output-dir",
                     "run", "--init-policy", "holosoma:g1_29dof/ppo"], "--init-policy", "--resume")
