"""``econmotor tasks`` and ``tasks --show`` at 80 columns: ids, units and parameter names whole, nothing cut."""

from __future__ import annotations

import pytest

from econmotor.cli import main
from econmotor.cli._app import console
from econmotor.tasks import load_catalog


@pytest.fixture
def width_80(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(console, "_width", 80)  # as with COLUMNS=80 (read when the console is created)


def test_tasks_at_80_columns_cut_nothing(width_80, capsys) -> None:
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    assert "…" not in out and max(len(line) for line in out.splitlines()) <= 80
    catalog = load_catalog([])
    for task_id in catalog.ids(None):
        assert task_id in out
        assert all(word in out for word in catalog.get(task_id).unit.split())  # wrapped between words only
    assert "lift-and-carry" in out


@pytest.mark.parametrize("task_id", ["humanoid_locomotion_g1", "dishwashing"])
def test_tasks_show_at_80_columns_keeps_parameter_names_whole(width_80, capsys, task_id) -> None:
    assert main(["tasks", "--show", task_id]) == 0
    out = capsys.readouterr().out
    table = out.split("\nunit of work:")[0]
    assert "…" not in table
    assert max(len(line) for line in table.splitlines()[1:]) <= 80  # the title, not a tty here, is not wrapped
    for row in load_catalog([]).get(task_id).economics.parameters():
        assert row["name"] in table and row["unit"].split()[0] in table


def test_tasks_for_a_backend_that_runs_none_is_an_empty_table(width_80, capsys) -> None:
    assert main(["tasks", "--backend", "no_such_backend"]) == 0
    assert "task id" in capsys.readouterr().out
