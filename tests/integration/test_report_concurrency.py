"""Two `econmotor report` processes writing one SQLite registry at the same time."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from econmotor.store import Registry

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_two_report_processes_share_one_registry_without_losing_rows(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'shared.sqlite'}"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "ECONMOTOR_DB_URL": url}  # the URL from the environment
    procs = []
    for worker in range(2):
        cmd = [sys.executable, "-c", "import sys; from econmotor.cli import main; sys.exit(main(sys.argv[1:]))",
               "report", "--task-id", "dishwashing", "--motor-backend", "dishwashing", "--seed", str(worker),
               "--max-steps", "300", "--eval-episodes", "2", "--objective-name", f"worker{worker}",
               "--datapacks", str(REPO / "configs" / "datapacks" / "dishwashing_varied_crockery.yaml"),
               "--output-dir", str(tmp_path / f"out{worker}")]
        procs.append(subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                      text=True))
    outputs = [p.communicate(timeout=300) for p in procs]
    for proc, (_, err) in zip(procs, outputs, strict=True):
        assert proc.returncode == 0, err[-3000:]
    reg = Registry(url, create=False)
    runs = reg.runs()
    assert sorted((r.objective_name, r.kind, r.status) for r in runs) == [
        ("worker0", "eval", "completed"), ("worker0", "train", "completed"),
        ("worker1", "eval", "completed"), ("worker1", "train", "completed")]
    for run in runs:  # every eval run belongs to its own worker's training run
        if run.kind == "eval":
            assert reg.run(run.parent_run_id).objective_name == run.objective_name
    assert len(reg.episodes(kind="train")) == 10 and len(reg.episodes(kind="eval")) == 4
    reports = reg.reports("dishwashing")
    assert sorted(r.document["objective"]["name"] for r in reports) == ["worker0", "worker1"]
    for worker in range(2):
        (doc,) = (tmp_path / f"out{worker}").glob("*.json")
        assert json.loads(doc.read_text())["objective"]["name"] == f"worker{worker}"
    assert not (tmp_path / ".econmotor").exists()  # ECONMOTOR_DB_URL was used, not the default file
