"""Every test gets its own registry: a command that records runs (train, shadow, report) never
writes into the directory pytest was started from, nor into another test's registry."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _own_registry(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # tests that need the default ./.econmotor registry use `workdir`, which removes this again
    monkeypatch.setenv("ECONMOTOR_DB_URL", f"sqlite:///{tmp_path / 'own-registry.sqlite'}")
