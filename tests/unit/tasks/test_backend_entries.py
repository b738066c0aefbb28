"""A user task file's ``backends:`` entries are checked when a command loads the catalog
(``factory.load_checked_catalog``): an unknown backend name, or a key or value its backend cannot use,
is a ConfigError naming the file and the key. The catalog itself only parses (no import circle)."""

import pytest

from econmotor.errors import ConfigError
from econmotor.motor_backend.factory import (
    backend_class,
    check_backend_entries,
    known_backends,
    load_checked_catalog,
    make_motor_backend,
)
from econmotor.tasks.catalog import load_catalog

TASK = """tasks:
  my_task:
    unit: dish
    economics:
      wage_human_usd_per_hour: {{value: 18.0, source: "x"}}
    backends:
      {entry}
"""


def task_file(tmp_path, entry: str):
    path = tmp_path / "tasks.yaml"
    path.write_text(TASK.format(entry=entry))
    return path


@pytest.mark.parametrize(("entry", "key", "message"), [
    ("dishwashin: {}", "tasks.my_task.backends.dishwashin", "unknown motor backend (did you mean 'dishwashing'?)"),
    ("dishwashing: {econ_prest: toy}", "tasks.my_task.backends.dishwashing.econ_prest", "unknown key"),
    ("dishwashing: {econ_preset: luxury}", "tasks.my_task.backends.dishwashing.econ_preset", "not allowed"),
    ("dishwashing: {econ_overrides: {damage_cost: lots}}",
     "tasks.my_task.backends.dishwashing.econ_overrides.damage_cost", "expected a number"),
    ("dishwashing: {econ_overrides: {damage_cost: -1}}",
     "tasks.my_task.backends.dishwashing.econ_overrides.damage_cost", "must not be negative"),
    ("dishwashing: {econ_overrides: {wage: 3}}", "tasks.my_task.backends.dishwashing.econ_overrides.wage",
     "unknown key"),
    ("dishwashing: {overlay_normalization: 3}", "tasks.my_task.backends.dishwashing.overlay_normalization",
     "expected a string"),
    ("mujoco: {env_id: Hopper-v5, leg_distance_m: far}", "tasks.my_task.backends.mujoco.leg_distance_m",
     "expected a number"),
    ("mujoco: {leg_distance_m: 3}", "tasks.my_task.backends.mujoco.env_id", "missing required key"),
    ("holosoma: {progress_mode: fast}", "tasks.my_task.backends.holosoma.experiment", "name one"),
    ("holosoma: {experiment: x, progress_mode: time}", "tasks.my_task.backends.holosoma.robot", "name one"),
    ("holosoma: {experiment: x, robot: g1_29dof, drivetrain_efficiency: abc}",
     "tasks.my_task.backends.holosoma.drivetrain_efficiency", "expected a number"),
], ids=["unknown-backend", "unknown-key", "unknown-preset", "override-type", "override-negative",
        "override-name", "normalization-type", "mujoco-type", "mujoco-missing", "holosoma-no-preset",
        "holosoma-no-robot", "holosoma-efficiency-type"])
def test_bad_entry_is_refused_at_load(tmp_path, entry, key, message):
    path = task_file(tmp_path, entry)
    assert "my_task" in load_catalog([path])  # parsing alone accepts it
    with pytest.raises(ConfigError) as info:
        load_checked_catalog([path])
    assert info.value.source == str(path)
    assert info.value.key.startswith(key), info.value
    assert message in info.value.detail


def test_good_entries_load(tmp_path):
    path = task_file(tmp_path, "dishwashing: {econ_preset: realistic, econ_overrides: {damage_cost: 2.5}, "
                               "overlay_normalization: none}")
    spec = load_checked_catalog([path]).get("my_task")
    assert spec.backend_entry("dishwashing")["econ_overrides"] == {"damage_cost": 2.5}


def test_a_backend_built_without_a_catalog_checks_its_task_files(tmp_path):
    path = task_file(tmp_path, "dishwashing: {econ_preset: luxury}")
    with pytest.raises(ConfigError, match="not allowed"):
        make_motor_backend("dishwashing", task_files=[path])


def test_the_backend_uses_the_catalog_it_is_handed(tmp_path):
    path = task_file(tmp_path, "dishwashing: {econ_preset: realistic}")
    catalog = load_checked_catalog([path])
    backend = make_motor_backend("dishwashing", task_files=[path], catalog=catalog)
    assert backend.catalog is catalog


@pytest.mark.parametrize("backend", known_backends())
def test_every_shipped_entry_passes_its_backends_check(backend):
    """The shipped catalog is not re-checked on every load (that would import every backend): here instead."""
    cls = backend_class(backend)
    specs = [spec for spec in load_catalog() if backend in spec.backends]
    assert specs, f"no shipped task has a '{backend}' entry"
    for spec in specs:
        cls.check_task_entry(spec)
        check_backend_entries(spec)
