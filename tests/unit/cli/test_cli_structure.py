"""The CLI reads top to bottom: no function in ``cli/`` over 60 lines, no command module importing another
(shared helpers live in modules that register no command), and the ``report`` flags and the
:class:`ReportArgs` that ``demo`` builds agree on every default."""

from __future__ import annotations

import ast
import dataclasses
import inspect
from pathlib import Path

import pytest
from typer.models import ParameterInfo

import econmotor.cli
from econmotor.cli.report import report_command
from econmotor.cli.reporting import ReportArgs

CLI = Path(econmotor.cli.__file__).resolve().parent
MAX_FUNCTION_LINES = 60


def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"), str(path))


def _registers_a_command(tree: ast.Module) -> bool:
    """A module with a function decorated ``@<app>.command(...)`` (``app``, ``datapacks_app``, ...)."""
    return any(isinstance(d, ast.Call) and isinstance(d.func, ast.Attribute) and d.func.attr == "command"
               for node in ast.walk(tree) if isinstance(node, ast.FunctionDef) for d in node.decorator_list)


def _cli_imports(tree: ast.Module) -> set[str]:
    """The ``econmotor.cli`` modules a module imports (at the top or inside functions)."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("econmotor.cli."):
            found.add(node.module.removeprefix("econmotor.cli."))
        elif isinstance(node, ast.ImportFrom) and node.module == "econmotor.cli":
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name.removeprefix("econmotor.cli.") for a in node.names
                         if a.name.startswith("econmotor.cli."))
    return found


def test_no_function_in_the_cli_is_longer_than_60_lines():
    long = []
    for path in sorted(CLI.glob("*.py")):
        for node in ast.walk(_tree(path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])  # decorators count
                lines = node.end_lineno - first + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{path.name}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, f"over {MAX_FUNCTION_LINES} lines: {long}"


def test_no_command_module_imports_another_command_module():
    trees = {path.stem: _tree(path) for path in CLI.glob("*.py") if path.stem != "__init__"}
    commands = {name for name, tree in trees.items() if _registers_a_command(tree)}
    assert {"report", "train", "compare", "demo", "solve", "sweep"} <= commands  # the finder sees them
    wrong = {name: sorted(_cli_imports(tree) & commands) for name, tree in trees.items() if name in commands}
    assert not any(wrong.values()), f"command modules importing command modules: {wrong}"


def test_the_finders_see_a_command_and_an_import_inside_a_function():
    tree = ast.parse("@app.command('x')\ndef f():\n    from econmotor.cli.report import g\n")
    assert _registers_a_command(tree) and _cli_imports(tree) == {"report"}


def test_report_args_defaults_are_the_report_flags_defaults():
    """``demo`` builds a :class:`ReportArgs` and leaves the rest to its defaults: they are ``report``'s."""
    fields = ReportArgs.__dataclass_fields__
    for name, param in inspect.signature(report_command).parameters.items():
        default = param.default.default if isinstance(param.default, ParameterInfo) else param.default
        if name == "more_datapacks":  # folded into ReportArgs.datapacks
            continue
        if default is ...:
            assert fields[name].default is dataclasses.MISSING, name  # required on both sides
            continue
        expected = tuple(default) if isinstance(default, list) else default
        assert fields[name].default == expected, name


@pytest.mark.parametrize("backend", ["mujoco", "dishwashing", "mjx"])
def test_command_speed_is_refused_for_a_backend_without_a_course(backend: str):
    from econmotor.cli.options import course_speed_options
    from econmotor.errors import ConfigError
    from econmotor.motor_backend.factory import backend_class

    assert course_speed_options(backend_class(backend), None) == {}
    with pytest.raises(ConfigError, match="--command-speed.*walks no course.*holosoma"):
        course_speed_options(backend_class(backend), 0.8)


def test_command_speed_goes_through_the_contract_keyword():
    from econmotor.cli.options import course_speed_options
    from econmotor.motor_backend.factory import backend_class

    assert course_speed_options(backend_class("holosoma"), 0.8) == {"course_speed_m_per_s": 0.8}
