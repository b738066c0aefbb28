"""An imported ONNX policy whose Holosoma metadata is wrong: the importer refuses it naming the file, the
metadata key and what is wrong, and priced end to end (``econmotor report --policy``) that is one error line
and exit 2, with no report written.

The files are a shipped G1 policy with one metadata entry changed (written with the onnx package here);
the error comes from the importer in .venv-holosoma, through the evaluation job, to the command line.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import onnx
import pytest

from econmotor.cli import main
from econmotor.couriers.policy_import import find_holosoma_python, shipped_policy_path
from econmotor.motor_backend.holosoma.host.jobs import job_environment

pytestmark = [pytest.mark.holosoma]
REPO = Path(__file__).resolve().parents[2]


def altered(path: Path, change) -> Path:
    """The shipped G1 PPO policy with ``change(metadata dict)`` applied, saved at ``path``."""
    model = onnx.load(str(shipped_policy_path("holosoma:g1_29dof/ppo", find_holosoma_python(REPO / ".venv-holosoma"))))
    meta = {p.key: p.value for p in model.metadata_props}
    change(meta)
    del model.metadata_props[:]
    for key, value in meta.items():
        model.metadata_props.add(key=key, value=value)
    onnx.save(model, str(path))
    return path


def drop_kp(meta: dict) -> None:
    del meta["kp"]


def short_kd(meta: dict) -> None:
    meta["kd"] = json.dumps(json.loads(meta["kd"])[:28])


def swap_joints(meta: dict) -> None:
    names = json.loads(meta["dof_names"])
    meta["dof_names"] = json.dumps([names[1], names[0], *names[2:]])


CASES = {"no-kp": (drop_kp, "metadata", "lacks Holosoma export metadata ['kp']"),
         "short-kd": (short_kd, "kd", "28 gains for 29 dof_names"),
         "joints-reordered": (swap_joints, "dof_names", "the joints of robot card 'g1_29dof' in another order")}

RESOLVE = r"""
import sys
from econmotor.errors import ConfigError
from econmotor.couriers.policy_import import resolve_contract

for path in sys.argv[1:]:
    try:
        resolve_contract(path)
        print("@@accepted", path)
    except ConfigError as exc:
        print("@@refused", str(exc).replace("\n", " "))
"""


def test_the_importer_refuses_each_bad_metadata_naming_the_file_and_key(tmp_path: Path) -> None:
    """Every case in one .venv-holosoma process (the importer's imports cost seconds)."""
    files = {name: altered(tmp_path / f"{name}.onnx", change) for name, (change, _, _) in CASES.items()}
    python = find_holosoma_python(REPO / ".venv-holosoma")
    proc = subprocess.run([str(python), "-c", RESOLVE, *map(str, files.values())], capture_output=True, text=True,
                          env=job_environment(), timeout=300)
    said = [line for line in proc.stdout.splitlines() if line.startswith("@@")]
    assert len(said) == len(CASES), proc.stdout[-2000:] + proc.stderr[-3000:]
    for line, (name, (_, key, text)) in zip(said, CASES.items(), strict=True):
        assert line.startswith(f"@@refused {files[name]}: key '{key}': ") and text in line, (name, line)


def test_bad_export_metadata_is_one_error_line_on_the_command_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """End to end: the importer's ConfigError, raised in .venv-holosoma's job, is raised again here."""
    change, key, said = CASES["no-kp"]
    monkeypatch.chdir(tmp_path)
    policy = altered(tmp_path / "policy.onnx", change)
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    rc = main(["report", "--task-id", "humanoid_locomotion_g1", "--motor-backend", "holosoma", "--policy",
               str(policy), "--eval-episodes", "1", "--db-url", url, "--output-dir", "out"])
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert rc == 2, err
    assert len(errors) == 1 and "Traceback" not in err, err  # one line (after the evaluation's progress notes)
    assert str(policy) in errors[0] and f"key '{key}'" in errors[0] and said in errors[0], errors[0]
    assert not (tmp_path / "out").exists()
