"""No function in motor_backend/ is longer than 60 lines: what a backend does around learning is split into
parts a reader can hold (the training loops, the learners' updates, the backends' ``train_policy``)."""

from __future__ import annotations

import ast
from pathlib import Path

LIMIT = 60
ROOT = Path(__file__).resolve().parents[2] / "src" / "econmotor" / "motor_backend"


def test_no_function_in_motor_backend_is_longer_than_the_limit() -> None:
    long = []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > LIMIT:
                    long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, "longer than 60 lines: " + "; ".join(long)
