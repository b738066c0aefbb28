"""The mujoco backend's two kinds of task are declared in one place (``mujoco/task_kinds.py``).

The backend asks a task's (or a run's) kind and never tests which it is: no module of ``motor_backend``
but the declaring one compares against the walker kind's name or calls a predicate of it.
"""

from __future__ import annotations

import ast
from pathlib import Path

import econmotor.motor_backend as motor_backend
from econmotor.motor_backend.mujoco.task_kinds import COURIER, WALKER, run_kind, task_kind
from econmotor.tasks import get_task

DECLARING = Path(motor_backend.__file__).parent / "mujoco" / "task_kinds.py"


def test_each_task_and_run_has_its_declared_kind():
    assert task_kind(get_task("humanoid_locomotion_g1")) is WALKER
    assert task_kind(get_task("humanoid_locomotion_t1")) is WALKER
    assert task_kind(get_task("hopper_courier")) is COURIER
    assert run_kind({"trainer": "walker"}) is WALKER and run_kind({"algorithm": "ppo"}) is COURIER
    assert WALKER.starts_from_policies and not COURIER.starts_from_policies
    assert (WALKER.final_policy_file, COURIER.final_policy_file) == ("policy.onnx", "policy.zip")


def kind_tests(source: str) -> list[str]:
    """Comparisons against the literal ``"walker"`` and calls of an ``is_walker_*`` predicate in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare):
            parts = [node.left, *node.comparators]
            if any(isinstance(p, ast.Constant) and p.value == "walker" for p in parts):
                found.append(f"line {node.lineno}: compares with 'walker'")
        if isinstance(node, ast.Call):
            name = getattr(node.func, "id", None) or getattr(node.func, "attr", "")
            if name.startswith("is_walker"):
                found.append(f"line {node.lineno}: calls {name}")
    return found


def test_the_finder_sees_a_kind_test():
    assert len(kind_tests('if is_walker_task(spec):\n    pass\nx = config.get("trainer") == "walker"\n')) == 2


def test_no_backend_module_tests_the_task_kind_outside_its_declaration():
    root = Path(motor_backend.__file__).parent
    offenders = {str(p.relative_to(root)): found for p in sorted(root.rglob("*.py"))
                 if p != DECLARING and (found := kind_tests(p.read_text()))}
    assert offenders == {}


def test_a_walker_runs_held_out_looks_follow_env_steps_not_wall_time():
    """Two runs of one seed look at the same env steps (and so keep the same checkpoint), however fast
    the machine: the walker's default cadence has no wall-time share."""
    from econmotor.motor_backend.mujoco.walker_backend import WALKER_CADENCE, WALKER_SELECT_BATCH
    from econmotor.motor_backend.selection import HeldOutResult, selection_for
    from econmotor.objectives import EconomicObjectiveSpec

    selection = selection_for(get_task("humanoid_locomotion_g1"), EconomicObjectiveSpec(), None, None, False, 0,
                              WALKER_CADENCE, WALKER_SELECT_BATCH)
    assert selection is not None and selection.config.every_steps == 500_000
    assert selection.config.max_share is None
    # a look that cost 100 s ended at 200 s: a wall-time share would hold the next one back for 900 s
    selection.history.append(HeldOutResult(env_steps=500_000, wall_s=200.0, eval_s=100.0, episodes=16,
                                           episodes_planned=32, cut_short=True, deployable=False, j_mean=0.0,
                                           fall_rate_upper=1.0, units_per_hour=0.0, units_per_hour_low=0.0,
                                           errors=0.0))
    for now in (selection.started + 200.0, selection.started + 201.0, selection.started + 1e6):
        assert selection.due(1_000_000, 500_000, now=now)
        assert not selection.due(999_999, 500_000, now=now)
