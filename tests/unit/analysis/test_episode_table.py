"""Episode tables from summaries and the JSONL export format."""

import json
import math

import numpy as np
import pytest

from econmotor.analysis.episode_table import (
    EPISODE_FORMAT,
    EpisodeTable,
    read_episodes_jsonl,
    write_episodes_jsonl,
)
from econmotor.config.task_economics import TaskEconomics
from econmotor.errors import ConfigError
from econmotor.motor_backend.results import summarize_episodes


def backend_summaries() -> list[dict]:
    raw = [{"units_completed": 10, "errors": 1, "episode_length_s": 600, "energy_wh": 5.0},
           {"units_completed": 0, "errors": 4, "episode_length_s": 600, "energy_wh": 2.0,
            "termination_reason": "catastrophic_error", "risk_score": 0.5}]
    _, _, episodes = summarize_episodes(raw, TaskEconomics())
    return episodes


def test_backend_episode_summaries_become_columns():
    records = [{**ep, "run_id": "7", "datapacks": "dp_a,dp_b", "seed": 3} for ep in backend_summaries()]
    table = EpisodeTable.from_records(records, default_price_usd_per_kwh=0.12)
    assert table.runs[0].datapacks == ("dp_a", "dp_b") and table.runs[0].seed == 3
    assert table.columns["mpl_units_per_hour"].tolist() == [60.0, 0.0]
    assert table.columns["error_rate"] == pytest.approx([1 / 11, 1.0])
    assert table.columns["energy_wh_per_unit"][0] == 0.5 and math.isinf(table.columns["energy_wh_per_unit"][1])
    assert table.catastrophic.tolist() == [False, True]
    assert table.columns["risk_score"].tolist() == [0.0, 0.5]
    assert table.energy_price_usd_per_kwh.tolist() == [0.12, 0.12]


def test_jsonl_round_trip_keeps_runs_metrics_and_infinite_energy(tmp_path):
    records = [{**ep, "run_id": run, "task_id": "dishwashing", "objective": "safety", "cell_key": "abc"}
               for run in ("r1", "r2") for ep in backend_summaries()]
    table = EpisodeTable.from_records(records)
    path = write_episodes_jsonl(table, tmp_path / "episodes.jsonl")
    lines = path.read_text().splitlines()
    assert len(lines) == 4 and json.loads(lines[1])["energy_wh_per_unit"] is None
    assert json.loads(lines[0])["format"] == EPISODE_FORMAT
    back = read_episodes_jsonl(path)
    assert back.runs == table.runs
    for name, column in table.columns.items():
        np.testing.assert_array_equal(back.columns[name], column)
    np.testing.assert_array_equal(back.catastrophic, table.catastrophic)


def test_bad_jsonl_lines_name_the_file_line_and_key(tmp_path):
    path = tmp_path / "bad.jsonl"
    path.write_text('{"run_id": "a", "mpl_units_per_hour": 1, "error_rate": 0, "energy_wh": 1}\n')
    with pytest.raises(ConfigError, match=r"bad.jsonl:1: key 'wage_parity'"):
        read_episodes_jsonl(path)
    path.write_text('{"mpl": 1}\n')
    with pytest.raises(ConfigError, match="run_id"):
        read_episodes_jsonl(path)
    path.write_text('{"format": "other/9", "run_id": "a"}\n')
    with pytest.raises(ConfigError, match="unsupported episode format"):
        read_episodes_jsonl(path)
    path.write_text("not json\n")
    with pytest.raises(ConfigError, match="not valid JSON"):
        read_episodes_jsonl(path)
    with pytest.raises(ConfigError, match="export-jsonl"):
        read_episodes_jsonl(tmp_path / "missing.jsonl")
