"""Every test gets its own registry: a command that records runs (train, shadow, report) never
writes into the directory pytest was started from, nor into another test's registry. SB3's
default logger folder goes to the session's pytest tmp dir too (not /tmp/SB3-<time>).

Hypothesis: in CI (``CI`` set) the property tests draw a fixed, derandomised sequence of
examples, so a CI verdict is reproducible; elsewhere they explore new examples each run.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no"):
    settings.load_profile("ci")


@pytest.fixture(autouse=True)
def _own_registry(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # tests that need the default ./.econmotor registry use `workdir`, which removes this again
    monkeypatch.setenv("ECONMOTOR_DB_URL", f"sqlite:///{tmp_path / 'own-registry.sqlite'}")


@pytest.fixture(scope="session", autouse=True)
def _sb3_logger_folder(tmp_path_factory: pytest.TempPathFactory):
    """SB3 makes a logger folder for every learn() without one: tempdir/SB3-<time> unless $SB3_LOGDIR.
    Session-wide, so module- and session-scoped training fixtures are covered too."""
    patch = pytest.MonkeyPatch()
    patch.setenv("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3-logger")))
    yield
    patch.undo()


@pytest.fixture(scope="session", autouse=True)
def _jax_compilation_cache():
    """XLA's persistent compilation cache for every test that builds a backend the way the CLI does
    (``environment_options``): the one the mjx tests keep under .pytest_cache, so compiling the
    smoke-sized couriers once serves every later test and a second `make test`."""
    patch = pytest.MonkeyPatch()
    if not os.environ.get("ECONMOTOR_JAX_CACHE_DIR"):
        patch.setenv("ECONMOTOR_JAX_CACHE_DIR", str(Path(__file__).resolve().parents[1] / ".pytest_cache"
                                                    / "econmotor-jax"))
    yield
    patch.undo()
