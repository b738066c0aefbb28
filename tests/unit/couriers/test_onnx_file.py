"""A file given as a policy that is not an ONNX model (corrupt, truncated, empty) is one error line naming
the file and exit 2, from ``report --policy`` and ``train --init-policy`` alike: every reader opens policy
files through :mod:`econmotor.couriers.onnx_file` (issue 52, item 7)."""

from __future__ import annotations

from pathlib import Path

import pytest

from econmotor.cli import main
from econmotor.couriers.policy_import import shipped_policy_path
from econmotor.errors import ConfigError
from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle

pytestmark = [pytest.mark.holosoma]  # the truncated file is cut from the shipped G1 walker


def corrupt_files(folder: Path) -> list[Path]:
    """Random bytes, the first half of the shipped G1 walker, and an empty file, each named ``*.onnx``."""
    shipped = shipped_policy_path("holosoma:g1_29dof/ppo").read_bytes()
    files = {"noise.onnx": bytes(range(256)) * 8, "truncated.onnx": shipped[: len(shipped) // 2], "empty.onnx": b""}
    for name, body in files.items():
        (folder / name).write_bytes(body)
    return [folder / name for name in files]


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    return tmp_path


@pytest.mark.parametrize("command", [
    ["report", "--task-id", "humanoid_locomotion_g1", "--motor-backend", "holosoma", "--eval-episodes", "1",
     "--policy"],
    ["train", "--task-id", "humanoid_locomotion_g1", "--motor-backend", "mujoco", "--max-steps", "100",
     "--init-policy"],
])
def test_a_corrupt_onnx_is_one_line_naming_the_file(command, workdir, capsys) -> None:
    for path in corrupt_files(workdir):
        capsys.readouterr()
        assert main([*command, str(path)]) == 2, path
        err = capsys.readouterr().err
        assert "Traceback" not in err and "DecodeError" not in err, err
        text = " ".join(err.split())
        assert str(path) in text and "not a readable ONNX model" in text, text
    assert not (workdir / "runs").exists() or not any((workdir / "runs").iterdir())


def test_the_deployed_policy_handle_names_a_corrupt_file(tmp_path: Path) -> None:
    for path in corrupt_files(tmp_path):
        with pytest.raises(ConfigError, match="not a readable ONNX model") as info:
            OnnxPolicyHandle(path)
        assert str(path) in str(info.value)
