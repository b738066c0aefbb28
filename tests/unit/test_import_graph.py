"""No import cycle in econmotor: every module's imports, those inside functions included, form a DAG.

The graph is read from the source (``ast``), so an import a function makes only when it runs counts
as much as one at the top of a module: a circle that only a run would show is caught here.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import econmotor

ROOT = Path(econmotor.__file__).resolve().parent


def module_files() -> dict[str, Path]:
    files = {}
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        files[".".join(parts)] = path
    return files


def import_graph(files: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the econmotor modules it imports (a ``from pkg import name`` counts ``pkg.name`` when
    that is a module, else ``pkg``)."""
    graph: dict[str, set[str]] = {name: set() for name in files}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                graph[name].update(alias.name for alias in node.names if alias.name in files)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(anchor + ([node.module] if node.module else []))
                for alias in node.names:
                    target = f"{base}.{alias.name}"
                    graph[name].add(target if target in files else base)
        graph[name] &= files.keys()
        graph[name].discard(name)
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` (as a path that returns to its start), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt):], nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start)):
            return cycle
    return None


def test_the_finder_sees_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_the_graph_sees_imports_inside_functions():
    graph = import_graph(module_files())
    # motor_backend/factory.py imports a backend module only through importlib; base.py imports the
    # task catalog at the top; the CLI's shared options import the selection module inside a function
    assert "econmotor.tasks.catalog" in graph["econmotor.motor_backend.base"]
    assert "econmotor.motor_backend.selection" in graph["econmotor.cli.options"]


def test_no_import_cycle():
    cycle = find_cycle(import_graph(module_files()))
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_every_module_imports():
    """Each module imports on its own (optional dependencies aside), in the order the graph allows."""
    skipped = []
    for name in sorted(n for n in module_files() if not n.endswith("__main__")):  # __main__ runs the CLI
        try:
            importlib.import_module(name)
        except ImportError as exc:  # an optional extra (ray, psycopg, holosoma) not installed here
            skipped.append(f"{name}: {exc}")
    assert len(skipped) < len(module_files()) // 4, skipped


BACKENDS = ("dishwashing", "mujoco", "mjx", "holosoma")
#: what the backends share and build on: these import no backend, nor anything of ``motor_backend`` (the
#: backend contract is above them)
SHARED = ("econmotor.couriers", "econmotor.locomotion", "econmotor.robots", "econmotor.economics",
          "econmotor.objectives", "econmotor.valuation", "econmotor.config", "econmotor.tasks")


def backend_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[1] == "motor_backend" and parts[2] in BACKENDS else None


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """Imports that cross the layers: a backend package into another, a shared package into any backend,
    holosoma's host side into its venv side (``holosoma.venv``, run only inside ``.venv-holosoma``)."""
    bad = []
    for module, targets in graph.items():
        for target in targets:
            mine, theirs = backend_of(module), backend_of(target)
            if theirs and mine and theirs != mine:
                bad.append(f"{module} -> {target} (backends are peers)")
            if theirs and module.startswith(SHARED):
                bad.append(f"{module} -> {target} (a shared package imports a backend)")
            elif target.startswith("econmotor.motor_backend") and module.startswith(SHARED):
                bad.append(f"{module} -> {target} (a shared package imports the backend contract above it)")
            venv = "econmotor.motor_backend.holosoma.venv"
            if target.startswith(venv) and not module.startswith(venv):
                bad.append(f"{module} -> {target} (holosoma's host side imports its venv side)")
    return sorted(bad)


def test_the_layer_rule_sees_a_crossing():
    graph = {"econmotor.motor_backend.mjx.backend": {"econmotor.motor_backend.holosoma.host.plan"},
             "econmotor.locomotion.course": {"econmotor.motor_backend.mjx.env"},
             "econmotor.motor_backend.holosoma.host.backend": {"econmotor.motor_backend.holosoma.venv.runner"},
             "econmotor.motor_backend.holosoma.venv.runner": {"econmotor.motor_backend.holosoma.job_specs"},
             "econmotor.couriers.datapack_mapping": {"econmotor.motor_backend.datapacks"}}
    assert len(layer_violations(graph)) == 4
    assert any("backend contract above it" in v for v in layer_violations(graph))


def test_backends_are_peers_and_shared_packages_import_none():
    assert layer_violations(import_graph(module_files())) == []
