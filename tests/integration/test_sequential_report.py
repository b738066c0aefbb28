"""A report without --eval-episodes evaluates sequentially (issue 33): its evaluation run stops at a look
of the plan once the acceptance rule is decided, records how and why, and the report says so in its
evidence line and judges as the look did. Real dishwashing backend, SQLite registry."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from econmotor.cli import main
from econmotor.store import Registry


def test_a_report_without_an_episode_count_evaluates_until_decided(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    assert main(["report", "--task-id", "dishwashing", "--motor-backend", "dishwashing", "--max-steps", "2000",
                 "--db-url", url, "--output-dir", "out", "--eval-max-episodes", "64"]) == 0
    doc = json.loads(next((tmp_path / "out").glob("*.json")).read_text(encoding="utf-8"))
    evaluation = doc["evaluation"]
    assert evaluation["rule"] == "sequential" and evaluation["plan"]["looks"] == [16, 32, 48, 64]
    assert evaluation["outcome"] in ("pass", "fail", "episode cap")
    assert evaluation["episodes"] == doc["uncertainty"]["evidence"]["episodes"] == evaluation["looks"][-1]["episodes"]
    assert doc["verdict"]["deployable"] == (evaluation["outcome"] == "pass")
    assert evaluation["confidence"] == pytest.approx(1 - 0.05 / 4)  # four looks share the bootstrap's 5%
    # the verdict quotes the error rate's confidence sequence (95% at every look) and the look's throughput bound
    assert "95% upper bound on the error rate" in doc["verdict"]["checks"][1]["text"]
    assert "98.8% lower bound on throughput" in doc["verdict"]["checks"][2]["text"]
    assert doc["uncertainty"]["confidence"] == 0.95  # the table's intervals stay at 95%
    markdown = next((tmp_path / "out").glob("*.md")).read_text(encoding="utf-8")
    assert "Episodes: sequential, until the acceptance rule was decided" in markdown
    assert f"stopped after {evaluation['episodes']} episodes" in markdown
    with Registry(url, create=False) as reg:
        (eval_run,) = [r for r in reg.runs(task_id="dishwashing") if r.kind == "eval"]
    assert eval_run.config["episodes_chosen"] == "sequential"
    assert eval_run.config["backend_config"]["sequential"]["outcome"] == evaluation["outcome"]
    assert len(list(reg.episodes(run_ids=[eval_run.id], status=None))) == evaluation["episodes"]
