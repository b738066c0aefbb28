"""The JAX backend imports no torch or gymnasium; the couriers' and locomotion packages no jax either; no generated
code in src/."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import econmotor

SRC = Path(econmotor.__file__).parent


def modules_after_import(module: str) -> set[str]:
    """Top-level package names in ``sys.modules`` after importing ``module`` in a fresh interpreter."""
    code = f"import sys, {module}; print(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300)
    return set(out.stdout.split())


@pytest.mark.parametrize("module", ["econmotor.motor_backend.mjx.backend", "econmotor.motor_backend.mjx.env"])
def test_the_jax_backend_imports_no_torch_or_gymnasium(module):
    loaded = modules_after_import(module)
    assert "jax" in loaded  # the import did run
    assert not loaded & {"torch", "gymnasium", "stable_baselines3"}


@pytest.mark.parametrize("package", ["couriers", "locomotion"])
def test_the_couriers_and_locomotion_packages_import_no_gymnasium_torch_or_jax(package):
    modules = [f"econmotor.{package}.{p.stem}" for p in (SRC / package).glob("*.py") if p.stem != "__init__"]
    loaded = modules_after_import(", ".join(modules))
    assert not loaded & {"torch", "gymnasium", "stable_baselines3", "jax"}


def test_no_source_file_calls_exec_or_compile():
    """The builtins exec / compile (generated code) appear nowhere in src/econmotor."""
    calls = []
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("exec", "compile"):
                calls.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert calls == []
