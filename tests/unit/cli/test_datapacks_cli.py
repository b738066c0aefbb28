"""``econmotor datapacks validate`` at 80 columns: ids, randomization keys and file paths whole, nothing cut."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console

from econmotor.cli import main
from econmotor.cli._app import console
from econmotor.cli.datapacks import COLUMNS, datapacks_table
from econmotor.config.datapacks import load_datapack_configs

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture
def width_80(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(console, "_width", 80)  # as with COLUMNS=80 (read when the console is created)


def test_validate_at_80_columns_cuts_nothing(width_80, monkeypatch, capsys) -> None:
    monkeypatch.chdir(REPO)
    paths = sorted(str(p.relative_to(REPO)) for p in (REPO / "configs" / "datapacks").glob("*.yaml"))
    assert main(["datapacks", "validate", *paths]) == 0
    out = capsys.readouterr().out
    assert "…" not in out and max(len(line) for line in out.splitlines()) <= 80
    for pack in load_datapack_configs([Path(p) for p in paths]):
        assert pack.id in out
        assert all(key in out for key in pack.domain_randomization)
        assert all(key in out for key in pack.curriculum)
    for path in paths:
        assert path in out


def test_a_wide_console_keeps_one_row_per_pack() -> None:
    rows = [("dishwashing_nominal", "0", "-", "-", "dishwashing", "configs/datapacks/dishwashing_nominal.yaml")]
    out = Console(width=200, record=True, file=io.StringIO())
    out.print(datapacks_table(rows, out))
    text = out.export_text()
    assert all(col in text for col in COLUMNS)
    assert any("dishwashing_nominal" in line and "configs/datapacks/dishwashing_nominal.yaml" in line
               for line in text.splitlines())


def test_a_missing_motion_clip_is_the_error_whichever_backend_is_asked(tmp_path, monkeypatch, capsys) -> None:
    """The clip is the pack's own problem: no backend accepts it, and the error says so (not that
    the dishwashing backend has no such randomization key); mujoco checks the file as holosoma does."""
    monkeypatch.chdir(tmp_path)
    pack = tmp_path / "pack.yaml"
    pack.write_text("id: clipped\nmotion_clips:\n  - path: mocap/missing.npz\n"
                    "domain_randomization:\n  friction_range: [0.5, 1.0]\n")
    for args in ([], ["--motor-backend", "mujoco"], ["--motor-backend", "holosoma"]):
        assert main(["datapacks", "validate", str(pack), *args]) == 2
        err = " ".join(capsys.readouterr().err.split())
        assert "pack.yaml" in err and "missing.npz" in err and "not found" in err, (args, err)
