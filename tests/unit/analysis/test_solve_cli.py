"""`econmotor solve` on JSONL input and its errors (exit 2, one line naming the problem)."""

import json

import numpy as np

from econmotor.analysis.episode_table import EpisodeTable, RunInfo, read_episodes_jsonl, write_episodes_jsonl
from econmotor.cli import main


def small_export(tmp_path):
    runs = [RunInfo("a", datapacks=("dp1",)), RunInfo("b", datapacks=("dp2",))]
    table = EpisodeTable.from_arrays(runs, np.array([0, 0, 1, 1]),
                                     mpl_units_per_hour=np.array([60.0, 62.0, 40.0, 42.0]),
                                     error_rate=np.array([0.1, 0.1, 0.01, 0.01]),
                                     energy_wh=np.array([10.0, 10.0, 5.0, 5.0]),
                                     energy_wh_per_unit=np.array([1.0, 1.0, 0.5, 0.5]),
                                     wage_parity=np.array([0.9, 0.9, 0.7, 0.7]))
    return write_episodes_jsonl(table, tmp_path / "ep.jsonl")


def test_solve_from_jsonl_with_vectors_grid_and_reference(tmp_path):
    path = small_export(tmp_path)
    sets = tmp_path / "sets.yaml"
    sets.write_text("constraint_sets:\n  careful: {max_error_rate: 0.05}\n  nobody: {min_wage_parity: 5}\n")
    out = tmp_path / "out"
    assert main(["solve", "--episodes-jsonl", str(path), "--constraints", str(sets), "--vector", "1,0,0,0,0",
                 "--grid", "2", "--reference-point", "energy=2", "--output-dir", str(out)]) == 0
    doc = json.loads((out / "objective_surface.json").read_text())
    assert doc["objectives"][0]["name"] == "w[1,0,0,0,0]" and len(doc["objectives"]) == 11
    cells = {(c["objective"], c["constraint_set"]): c for c in doc["cells"]}
    assert cells[("w[1,0,0,0,0]", "careful")]["best_run_id"] == "b"
    assert doc["constraint_sets_no_run_meets"] == ["nobody"]
    assert doc["pareto_front"]["reference_point"]["energy_wh_per_unit"] == 2.0
    assert doc["pareto_front"]["run_ids"] == ["a", "b"]


def test_solve_errors_are_one_line_and_exit_2(tmp_path, capsys):
    path = small_export(tmp_path)
    assert main(["solve", "--episodes-jsonl", str(path), "--reference-point", "speed=3"]) == 2
    assert "--reference-point" in capsys.readouterr().err
    assert main(["solve", "--episodes-jsonl", str(path), "--preset", "thruput"]) == 2
    assert "did you mean 'throughput'" in capsys.readouterr().err
    assert main(["solve", "--db-url", f"sqlite:///{tmp_path / 'none.sqlite'}"]) == 2
    assert "no registry" in capsys.readouterr().err
    assert main(["solve", "--episodes-jsonl", str(path), "--vector", "1,2"]) == 2
    assert "expected 5 numbers" in capsys.readouterr().err


def test_a_folder_reads_every_shadow_runs_episodes_below_it(tmp_path, capsys):
    """The README's `solve --episodes-jsonl runs/shadow`: each shadow run writes its own
    runs/shadow/<run>/shadow_episodes.jsonl, so a folder stands for all of them."""
    table = read_episodes_jsonl(small_export(tmp_path))
    shadow = tmp_path / "runs" / "shadow"
    for run_id in ("a", "b"):
        one = EpisodeTable.from_records([r for r in table.records() if r["run_id"] == run_id], run_id)
        (shadow / f"run-{run_id}").mkdir(parents=True)
        write_episodes_jsonl(one, shadow / f"run-{run_id}" / "shadow_episodes.jsonl")
    (shadow / "run-a" / "other.jsonl").write_text("not episodes\n")  # only the shadow runs' files are read
    out = tmp_path / "out"
    assert main(["solve", "--episodes-jsonl", str(shadow), "--output-dir", str(out)]) == 0
    doc = json.loads((out / "objective_surface.json").read_text())
    assert sorted(run["run_id"] for run in doc["runs"]) == ["a", "b"]
    capsys.readouterr()
    (tmp_path / "empty").mkdir()
    assert main(["solve", "--episodes-jsonl", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert "--episodes-jsonl" in err and "no shadow_episodes.jsonl below it" in err


def test_a_solve_without_output_dir_never_overwrites_another(tmp_path, monkeypatch):
    path = small_export(tmp_path)
    monkeypatch.chdir(tmp_path)
    surfaces = tmp_path / "runs" / "objective_surface"
    assert main(["solve", "--episodes-jsonl", str(path)]) == 0
    (first,) = surfaces.iterdir()
    before = (first / "objective_surface.json").read_text()
    pids = iter([111, 222])  # two processes (within one second, the UTC time alone would repeat)
    monkeypatch.setattr("econmotor.cli.solve.os.getpid", lambda: next(pids))
    assert main(["solve", "--episodes-jsonl", str(path), "--vector", "1,0,0,0,0"]) == 0
    assert main(["solve", "--episodes-jsonl", str(path), "--preset", "safety"]) == 0
    assert len(list(surfaces.iterdir())) == 3
    assert (first / "objective_surface.json").read_text() == before
