import subprocess
import sys

from econmotor.cli import main


def test_tasks_lists_catalog(capsys):
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    assert "dishwashing" in out


def test_tasks_show_lists_every_parameter_with_source(capsys):
    assert main(["tasks", "--show", "dishwashing"]) == 0
    out = capsys.readouterr().out
    assert "robot_capex_usd" in out and "USD/h" in out


def test_unknown_task_is_one_clear_line_and_exit_2(capsys):
    assert main(["tasks", "--show", "dishwasher"]) == 2
    err = capsys.readouterr().err
    assert "unknown task id 'dishwasher'" in err and "dishwashing" in err


def test_bad_datapack_exit_2(tmp_path, capsys):
    bad = tmp_path / "dp.yaml"
    bad.write_text("id: x\nmotion_clip: []\n")
    assert main(["datapacks", "validate", str(bad)]) == 2
    assert "motion_clip" in capsys.readouterr().err


def test_console_script_runs():
    proc = subprocess.run([sys.executable, "-m", "econmotor", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "report" in proc.stdout or "tasks" in proc.stdout


def test_typer_exit_code_inside_a_command_is_returned():
    import typer

    from econmotor.cli import app

    @app.command("_exit_probe", hidden=True)
    def _probe() -> None:
        raise typer.Exit(3)

    try:
        assert main(["_exit_probe"]) == 3
    finally:
        app.registered_commands[:] = [c for c in app.registered_commands if c.name != "_exit_probe"]


def test_usage_errors_are_one_message_not_a_traceback(capsys):
    assert main(["tasks", "--no-such-flag"]) == 2
    err = capsys.readouterr().err
    assert "no-such-flag" in err.lower() and "Traceback" not in err
