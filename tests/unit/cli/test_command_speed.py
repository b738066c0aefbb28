"""``--command-speed`` means the same in ``compare`` and ``sweep`` (issue 52, item 7): a speed that is not
finite, above 10 m/s, or beyond the forward command range its policy was trained for (``lin_vel_x`` in the
ONNX metadata; the walker would clip the command to it) is one error line naming the flag, exit 2, before any
episode. Each command also carries a flag refused later (an unknown datapack, ``--eval-episodes 0``), so a
speed let through fails fast on that instead of pricing for minutes."""

from __future__ import annotations

import json
from pathlib import Path

import onnx
import pytest

from econmotor.cli import main
from econmotor.couriers.policy_import import shipped_policy_path

pytestmark = [pytest.mark.holosoma]  # the shipped G1 walker, and a copy of it with a slower command range

G1 = "holosoma:g1_29dof/ppo"


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    return tmp_path


def slow_walker(path: Path, top_m_per_s: float) -> Path:
    """The shipped G1 walker with ``lin_vel_x`` up to ``top_m_per_s`` in its metadata, saved at ``path``."""
    model = onnx.load(str(shipped_policy_path(G1)))
    for prop in model.metadata_props:
        if prop.key == "command_ranges":
            ranges = json.loads(prop.value)
            ranges["lin_vel_x"] = [-top_m_per_s, top_m_per_s]
            prop.value = json.dumps(ranges)
    onnx.save(model, str(path))
    return path


def refused_speed(capsys: pytest.CaptureFixture[str], args: list[str], *names: str) -> None:
    capsys.readouterr()
    assert main(args) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert err.startswith("error: --command-speed") and "Traceback" not in err, err
    for name in names:
        assert name in err, (name, err)


def test_compare_and_sweep_refuse_the_same_speeds(workdir, capsys) -> None:
    slow = str(slow_walker(workdir / "slow.onnx", 0.5))
    compare = ["compare", "--task-id", "humanoid_locomotion_g1", "--policy", G1, "--policy", slow,
               "--eval-episodes", "1", "--datapacks", "no-such-pack", "--command-speed"]
    sweep = ["sweep", "--task-id", "humanoid_locomotion_g1", "--motor-backend", "holosoma", "--eval-episodes", "0",
             "--output-dir", "sweep", "--command-speed"]
    for args in ([*compare, "inf"], [*sweep[:-1], "--policy", G1, "--command-speed", "0.5,inf"]):
        refused_speed(capsys, args, "finite")
    for args in ([*compare, "50"], [*sweep[:-1], "--policy", G1, "--command-speed", "50"]):
        refused_speed(capsys, args, "50", "<= 10")
    # within 10 m/s but beyond what a policy was trained for: compare names the slower policy, sweep its own
    refused_speed(capsys, [*compare, "0.8"], "0.8 m/s", slow, "lin_vel_x up to 0.5 m/s")
    refused_speed(capsys, [*sweep[:-1], "--policy", G1, "--command-speed", "0.6,1.5"], "1.5 m/s", G1,
                  "lin_vel_x up to 1 m/s")
    refused_speed(capsys, [*sweep[:-1], "--policy", slow, "--command-speed", "0.8"], "0.8 m/s", slow)
    assert not (workdir / "reports").exists() and not (workdir / "sweep").exists()
