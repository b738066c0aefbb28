"""``econmotor compare`` end to end on Holosoma's shipped G1 policies (in .venv-holosoma): every policy is
evaluated on the same seeds and episode count (read back from the registry, not from compare's own
summary), the winner is the cheapest deployable policy and its line quotes what its report charges, and
bad requests (one policy, a policy twice, a bad shipped name, a missing ONNX file) are refused before
anything is evaluated or recorded.

A short course (one 4 m leg, a 1 s dwell) and an acceptance rule any upright walker meets (a tasks file,
as a user would write one) make a deployable report reachable in two episodes.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from econmotor.cli import main
from econmotor.motor_backend.run_dir import REPORT_EVAL_SEED_OFFSET
from econmotor.store import Registry

pytestmark = [pytest.mark.holosoma]
CATALOG = Path(__file__).resolve().parents[2] / "src" / "econmotor" / "tasks" / "holosoma.yaml"
POLICIES = ("holosoma:g1_29dof/ppo", "holosoma:g1_29dof/fastsac")
EPISODES, SEED = 2, 4


@pytest.fixture(scope="module")
def easy_tasks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    task = yaml.safe_load(CATALOG.read_text(encoding="utf-8"))["tasks"]["humanoid_locomotion_g1"]
    task["locomotion"].update(sim2sim_legs=1, unit_length_m=4.0, dwell_s=1.0, sim2sim_episode_s=20.0)
    task["acceptance"] = {"max_error_rate": {"value": 1.0, "source": "test: any fall rate"},
                          "min_units_per_hour": {"value": 0.0, "source": "test: any throughput"}, "error_name": "fall"}
    task["description"] = "G1 on a short course, accepted whenever it walks (test)"
    path = tmp_path_factory.mktemp("tasks") / "g1_easy.yaml"
    path.write_text(yaml.safe_dump({"tasks": {"g1_easy": task}}), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def compared(easy_tasks: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    work = tmp_path_factory.mktemp("compare")
    url = f"sqlite:///{work / 'registry.sqlite'}"
    args = ["compare", "--task-id", "g1_easy", "--tasks-file", str(easy_tasks), "--eval-episodes", str(EPISODES),
            "--seed", str(SEED), "--db-url", url, "--output-dir", str(work / "cmp")]
    for policy in POLICIES:
        args += ["--policy", policy]
    assert main(args) == 0
    with Registry(url, create=False) as reg:
        runs = reg.runs(task_id="g1_easy")
        episodes = reg.episodes(task_id="g1_easy")
        reports = reg.reports(task_id="g1_easy")
    return {"runs": runs, "episodes": episodes, "reports": reports,
            "result": json.loads((work / "cmp" / "compare.json").read_text(encoding="utf-8"))}


def test_every_policy_is_evaluated_on_the_same_seeds_and_episodes(compared: dict) -> None:
    runs = compared["runs"]
    assert sorted(r.policy_path for r in runs) == sorted(POLICIES) and all(r.kind == "eval" for r in runs)
    first = SEED + REPORT_EVAL_SEED_OFFSET
    for run in runs:  # what each evaluation was run with, as recorded
        assert run.config["backend_config"]["seed"] == first, run.policy_path
        assert [e.episode_index for e in compared["episodes"] if e.run_id == run.id] == list(range(EPISODES))
    assert len({run.seed for run in runs}) == 1
    assert compared["result"]["context"]["seeds"] == f"{first}-{first + EPISODES - 1}"


def test_the_winner_is_the_cheapest_deployable_policy_at_its_reports_price(compared: dict) -> None:
    reports = {r.document["runs"]["eval"]["policy_path"]: r.document for r in compared["reports"]}
    assert set(reports) == set(POLICIES) and all(doc["verdict"]["deployable"] for doc in reports.values())
    charge = {p: doc["recommendation"]["price_usd_per_unit"] for p, doc in reports.items()}
    point = {p: doc["pricing"]["aggregate"]["price_usd_per_unit"] for p, doc in reports.items()}
    winner = min(POLICIES, key=lambda p: point[p])
    summary = compared["result"]["summary"]
    assert summary.startswith(f"winner: {winner}, charging ")
    assert compared["result"]["ranking"][0]["policy"] == winner
    quoted = float(summary.split("charging ", 1)[1].split(" USD/unit", 1)[0])
    assert quoted == pytest.approx(charge[winner], rel=1e-3)  # the price the winner's own report charges
    assert charge[winner] >= point[winner]  # the cautious end of its intervals


@pytest.mark.parametrize(("policies", "said"), [
    (POLICIES[:1], "at least two policies, got 1"),
    ((POLICIES[0], POLICIES[0]), "a policy is named twice"),
    ((POLICIES[0], "holosoma:g1_29dof/nonesuch"), "holosoma:g1_29dof/nonesuch"),
    ((POLICIES[0], "missing/policy.onnx"), "no such ONNX file"),
], ids=["one", "twice", "bad-shipped-name", "missing-onnx"])
def test_bad_requests_are_refused_before_anything_is_evaluated(policies, said, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    url = f"sqlite:///{tmp_path / 'registry.sqlite'}"
    args = ["compare", "--task-id", "humanoid_locomotion_g1", "--db-url", url, "--output-dir", "cmp"]
    for policy in policies:
        args += ["--policy", policy]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "--policy" in err and said in err and "Traceback" not in err
    assert not (tmp_path / "cmp").exists() and not (tmp_path / "runs").exists()
    if (tmp_path / "registry.sqlite").exists():
        with Registry(url, create=False) as reg:
            assert reg.runs() == []
