"""The registry checks of tests/unit/store/registry_contract.py against a real PostgreSQL server.

The throwaway server (fixtures ``pg_server`` / ``pg_url``) is started by
tests/integration/conftest.py; in CI (``CI`` set) a server that cannot start fails the tests.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

pytestmark = pytest.mark.postgres

_spec = importlib.util.spec_from_file_location(
    "registry_contract", Path(__file__).parents[1] / "unit" / "store" / "registry_contract.py")
contract = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(contract)


@pytest.mark.parametrize("check", contract.CHECKS, ids=lambda c: c.__name__.removeprefix("check_"))
def test_registry_contract_on_postgresql(check, pg_url: str) -> None:
    check(pg_url)


def test_two_registries_creating_the_schema_at_once_on_postgresql(pg_url: str) -> None:
    from concurrent.futures import ThreadPoolExecutor

    from econmotor.store import Registry

    with ThreadPoolExecutor(2) as pool:
        regs = list(pool.map(lambda _: Registry(pg_url), range(2)))
    ids = [reg.start_run("train", "dishwashing", "dishwashing") for reg in regs]
    assert len(set(ids)) == 2 and len(regs[0].runs()) == 2
    for reg in regs:
        reg.close()


def test_report_from_a_postgresql_registry(pg_url: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import json

    from econmotor.cli import main
    from econmotor.motor_backend.results import MotorEvalResult, summarize_episodes
    from econmotor.store import Registry
    from econmotor.tasks import get_task

    monkeypatch.chdir(tmp_path)
    task = get_task("dishwashing")
    raw, econ, eps = summarize_episodes([{"units_completed": 50, "errors": 0, "episode_length_s": 3600,
                                          "energy_wh": 100}], task.economics)
    with Registry(pg_url) as reg:
        run_id = reg.record_run("eval", MotorEvalResult("p", "dishwashing", "dishwashing", raw, econ, eps))
    monkeypatch.setenv("ECONMOTOR_DB_URL", pg_url)  # read at the CLI edge
    assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--output-dir", "out"]) == 0
    doc = json.loads((tmp_path / "out" / f"dishwashing_run{run_id}.json").read_text())
    # 50 dishes/h, 0.1 kWh/h: unit cost (1.75 + 0.9 + 2.0 + 0.012)/50 = 0.09324
    assert doc["pricing"]["aggregate"]["robot_unit_cost_usd"] == pytest.approx(0.09324)
    assert doc["registry"]["db_url"].startswith("postgresql+psycopg://econ@127.0.0.1")
    assert not (tmp_path / ".econmotor").exists()
    with Registry(pg_url) as reg:
        assert [r.id for r in reg.reports("dishwashing")] == [doc["registry"]["report_id"]]
