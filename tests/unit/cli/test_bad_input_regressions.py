"""Named regressions for each bad input the hostile-input probe of issue 15 found, and a
path-escape test for each name that becomes a path. In-process (``econmotor.cli.main``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from econmotor.cli import main


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    return tmp_path


def refused(capsys: pytest.CaptureFixture[str], args: list[str], *names: str) -> str:
    """Run ``args``; assert exit 2 with one line naming ``names``, no traceback, nothing a run writes (refused
    before any work: no run directory, no registry); return the line."""
    capsys.readouterr()
    rc = main(args)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert err.startswith(lines[0]), err  # no blank line first (an unused progress display printed one)
    for name in names:
        assert name in lines[0], (name, lines[0])
    assert not Path("runs").exists() and not Path(".econmotor").exists()
    return lines[0]


REPORT = ["report", "--task-id", "dishwashing", "--motor-backend", "dishwashing"]


# ----------------------------------------------------------------------------- tracebacks before
@pytest.mark.parametrize("kind", ["objective", "datapack", "constraints", "tasks"])
def test_deeply_nested_yaml_is_a_clean_error(kind, workdir, capsys):
    for body in ("a: " + "[" * 5000 + "]" * 5000 + "\n",
                 "".join("  " * i + f"k{i}:\n" for i in range(200)) + "  " * 200 + "v: 1\n"):
        path = workdir / f"{kind}.yaml"
        path.write_text(body)
        (workdir / "e.jsonl").write_text("")
        args = {"objective": [*REPORT, "--objective-config", str(path)],
                "datapack": ["datapacks", "validate", str(path)],
                "constraints": ["solve", "--episodes-jsonl", "e.jsonl", "--constraints", str(path)],
                "tasks": ["tasks", "--tasks-file", str(path)]}[kind]
        refused(capsys, args, path.name, "nested")


@pytest.mark.parametrize("seed", ["-1", "18446744073709551616"])
def test_seed_out_of_range(seed, workdir, capsys):
    refused(capsys, [*REPORT, "--seed", seed], "--seed")
    refused(capsys, ["train", "--task", "dishwashing", "--backend", "dishwashing", "--seed", seed], "--seed")


def test_unsupported_db_url_lists_the_supported_schemes(workdir, capsys, monkeypatch):
    refused(capsys, [*REPORT, "--db-url", "notaurl://x"], "--db-url", "notaurl", "sqlite:///", "postgresql")
    monkeypatch.setenv("ECONMOTOR_DB_URL", "notaurl://x")
    refused(capsys, [*REPORT], "ECONMOTOR_DB_URL", "postgresql")
    refused(capsys, ["solve"], "ECONMOTOR_DB_URL", "postgresql")


def test_binary_episodes_jsonl(workdir, capsys):
    (workdir / "b.jsonl").write_bytes(b"\xff\xfe\x00\x81" * 64)
    refused(capsys, ["solve", "--episodes-jsonl", "b.jsonl"], "b.jsonl", "UTF-8")


def test_output_json_that_is_a_directory_and_output_dir_that_is_a_file(workdir, capsys):
    (workdir / "adir").mkdir()
    (workdir / "afile").write_text("x")
    refused(capsys, [*REPORT, "--output-json", "adir"], "--output-json", "directory")
    refused(capsys, [*REPORT, "--output-dir", "afile"], "--output-dir", "is a file")
    refused(capsys, [*REPORT, "--output-dir", "afile/below"], "--output-dir", "is a file")
    refused(capsys, ["solve", "--output-dir", "afile"], "--output-dir")


def test_cpus_per_cell_nan(workdir, capsys):
    refused(capsys, ["sweep", "--task-id", "dishwashing", "--cpus-per-cell", "nan"], "--cpus-per-cell", "finite")


def test_read_only_working_directory_with_the_default_registry(tmp_path, capsys, monkeypatch):
    """/proc refuses new files even to root (a chmod 555 directory would not stop root)."""
    monkeypatch.delenv("ECONMOTOR_DB_URL", raising=False)
    monkeypatch.chdir("/proc")
    refused(capsys, [*REPORT, "--output-dir", str(tmp_path / "out")], "default registry", "--db-url")
    from econmotor.errors import RegistryError
    from econmotor.store import Registry

    with pytest.raises(RegistryError, match="cannot create the registry directory"):
        Registry()


# ----------------------------------------------------------------------------- nonsense accepted before
@pytest.mark.parametrize(("flag", "value"), [("--num-envs", "-1"), ("--max-steps", "-5"), ("--eval-episodes", "-1")])
def test_negative_counts(flag, value, workdir, capsys):
    refused(capsys, [*REPORT, flag, value], flag)
    refused(capsys, ["train", "--task", "dishwashing", "--backend", "dishwashing", flag, value], flag)


def test_negative_learning_starts_and_unknown_constraint_mode(workdir, capsys):
    refused(capsys, ["shadow", "--learning-starts", "-5"], "--learning-starts")
    line = refused(capsys, ["shadow", "--constraint-mode", "lagrange"], "--constraint-mode", "lagrangian")
    assert "did you mean" in line


def test_all_zero_objective_vector(workdir, capsys):
    (workdir / "zero.yaml").write_text("objective_vector: [0, 0, 0, 0, 0]\n")
    refused(capsys, [*REPORT, "--objective-config", "zero.yaml"], "zero.yaml", "objective_vector", "all-zero")
    (workdir / "flat.yaml").write_text("mpl_weight: 0\nerror_weight: 0\n")
    refused(capsys, [*REPORT, "--objective-config", "flat.yaml"], "flat.yaml", "zero")
    refused(capsys, ["shadow", "--objective-vector", "0", "0", "0", "0", "0"], "all-zero")


def test_duplicated_yaml_key(workdir, capsys):
    (workdir / "dup.yaml").write_text("name: a\nmpl_weight: 1\nmpl_weight: 2\n")
    refused(capsys, [*REPORT, "--objective-config", "dup.yaml"], "dup.yaml", "duplicate key 'mpl_weight'", "line 3")


def test_broken_yaml_names_the_file_and_where_not_an_in_memory_string(workdir, capsys):
    (workdir / "broken.yaml").write_text("mpl_weight: 1.0\n  bad: [1, 2\n")
    line = refused(capsys, [*REPORT, "--objective-config", "broken.yaml"], "broken.yaml", "not valid YAML",
                   "line 2, column 6")
    assert "<unicode string>" not in line


def test_yaml_merge_keys_still_work():
    from econmotor.config.loading import load_yaml_text

    assert load_yaml_text("a: &x {k: 1}\nb:\n  <<: *x\n  k: 2\n", "t") == {"a": {"k": 1}, "b": {"k": 2}}


def test_datapack_ranges_no_backend_can_use_fail_validate(workdir, capsys):
    (workdir / "p.yaml").write_text("id: p\ndomain_randomization:\n  friction_range: [-1.0, 0.0]\n")
    refused(capsys, ["datapacks", "validate", "p.yaml"], "p.yaml", "friction_range")
    (workdir / "q.yaml").write_text("id: q\ndomain_randomization:\n  friction_range: [0.5, 1.5]\n")
    refused(capsys, ["datapacks", "validate", "--motor-backend", "dishwashing", "q.yaml"], "q.yaml", "friction_range")
    assert main(["datapacks", "validate", "q.yaml"]) == 0  # mujoco can use it


# ----------------------------------------------------------------------------- hangs before
def test_sizes_are_refused_before_work_with_size_and_limit(workdir, capsys):
    refused(capsys, [*REPORT, "--max-steps", "99999999999999999999999"], "--max-steps", "1,000,000,000")
    refused(capsys, ["sweep", "--task-id", "dishwashing", "--seeds", "0-100000000"],
            "--seeds", "100,000,001", "1,000")
    refused(capsys, ["sweep", "--task-id", "dishwashing", "--grid", "400"], "--grid", "10,827,401", "10,000")
    refused(capsys, ["solve", "--grid", "300"], "--grid", "4,590,551", "50,000")
    refused(capsys, ["sweep", "--task-id", "dishwashing", "--grid", "12", "--seeds", "0-99"],
            "--seeds", "46,100", "10,000")  # (455 grid + 6 presets) x 100 seeds
    assert not (workdir / ".econmotor").exists()


# ----------------------------------------------------------------------------- path escapes
def test_objective_name_flag_cannot_escape(workdir, capsys):
    refused(capsys, [*REPORT, "--objective-name", "x/../../NAME"], "--objective-name")
    refused(capsys, [*REPORT, "--objective-name", ".."], "--objective-name")


def test_objective_yaml_name_cannot_escape(workdir, capsys):
    (workdir / "o.yaml").write_text("name: ../../NAME\nmpl_weight: 1\n")
    refused(capsys, [*REPORT, "--objective-config", "o.yaml"], "o.yaml", "name")
    (workdir / "p.yaml").write_text("name: ../../NAME\nobjective_preset: throughput\n")
    refused(capsys, [*REPORT, "--objective-config", "p.yaml"], "p.yaml", "name")


def test_task_id_from_a_tasks_file_cannot_escape(workdir, capsys):
    (workdir / "t.yaml").write_text("tasks:\n  ../../NAME:\n    unit: dish\n    economics: {}\n    backends: {}\n")
    refused(capsys, ["tasks", "--tasks-file", "t.yaml"], "t.yaml", "tasks.../../NAME")
    refused(capsys, ["report", "--task-id", "../../NAME", "--tasks-file", "t.yaml"], "t.yaml")


def test_datapack_id_cannot_escape(workdir, capsys):
    (workdir / "d.yaml").write_text("id: ../../NAME\n")
    refused(capsys, ["datapacks", "validate", "d.yaml"], "d.yaml", "id")
    refused(capsys, ["datapacks", "record-clip", "--policy", "p", "--out", "c.npz", "--datapack-id", "a/b"],
            "--datapack-id")


def test_run_directory_names_cannot_escape(tmp_path):
    """The dishwashing backend's run directory is built from task id and objective name through path_name."""
    from econmotor.config.loading import path_name
    from econmotor.errors import ConfigError

    for bad in ("../x", "a/b", "a\\b", ".hidden", "", "x" * 500, "a\x00b"):
        with pytest.raises(ConfigError):
            path_name(bad, "<t>", "name")
    for good in ("throughput", "grid[0.25,0.25,0.5,0,0]", "my objective", "w[1,0,0,0,0]"):
        assert (tmp_path / path_name(good, "<t>", "name")).parent == tmp_path


def test_markdown_escapes_user_strings_like_html(workdir, capsys):
    from econmotor.motor_backend.results import MotorEvalResult, summarize_episodes
    from econmotor.store import Registry
    from econmotor.tasks import get_task

    task = get_task("dishwashing")
    raw, econ, eps = summarize_episodes([{"units_completed": 50, "errors": 0, "episode_length_s": 3600,
                                          "energy_wh": 100}], task.economics)
    with Registry() as reg:
        reg.record_run("eval", MotorEvalResult("p", "dishwashing", "dishwashing", raw, econ, eps),
                       objective={"name": "obj"})
    notes = "<script>alert(1)</script> <img src=x onerror=alert(2)> [link](javascript:alert(3))"
    assert main(["report", "--motor-backend", "none", "--task-id", "dishwashing", "--output-dir", "out",
                 "--notes", notes]) == 0
    md = next((workdir / "out").glob("*.md")).read_text()
    html_text = next((workdir / "out").glob("*.html")).read_text()
    for text in (md, html_text):
        assert "<script>" not in text and "<img src=x" not in text
    assert "&lt;script&gt;" in md and "\\[link\\]" in md


# ----------------------------------------------------------------------------- registry rows after files
def test_a_report_row_is_committed_only_after_its_files_exist(workdir):
    from econmotor.errors import RegistryError
    from econmotor.store import Registry

    with Registry() as reg:
        def fail(report_id):
            raise OSError("disk full")

        with pytest.raises(RegistryError):
            reg.record_report("dishwashing", {"a": 1}, {"json": "x.json"}, write_files=lambda rid: {"json": "nope"})
        with pytest.raises(OSError):
            reg.record_report("dishwashing", {"a": 1}, {"json": "x.json"}, write_files=fail)
        assert reg.reports() == []

        def write(report_id):
            path = workdir / f"r{report_id}.json"
            path.write_text(json.dumps({"id": report_id}))
            return {"json": str(path)}

        report_id = reg.record_report("dishwashing", {"a": 1}, {}, write_files=write)
        [row] = reg.reports()
        assert row.id == report_id and Path(row.files["json"]).is_file()


def test_a_missing_run_directory_is_one_line_with_nothing_before_it(workdir, capsys):
    refused(capsys, ["evaluate", "--task-id", "hopper_courier", "--policy", "runs/nothere"], "runs/nothere")
    refused(capsys, [*REPORT, "--objective-config", "nope.yaml"], "--objective-config", "nope.yaml: file not found")


def test_an_unknown_command_lists_the_commands_of_its_group(workdir, capsys):
    refused(capsys, ["price"], "No such command 'price'", "Commands: compare, datapacks, demo,", "report")
    refused(capsys, ["datapacks", "lst"], "No such command 'lst'", "Commands: record-clip, validate.")
