"""The mjx backend's TensorBoard scalars: readable by TensorBoard, written without torch."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tensorboard.backend.event_processing.event_accumulator import EventAccumulator


def test_scalars_are_written_without_importing_torch(tmp_path: Path) -> None:
    code = ("import sys; from econmotor.motor_backend.mjx.training import ScalarWriter; "
            f"w = ScalarWriter({str(tmp_path / 'tb')!r}); w.add_scalar('held_out/J', 1.5, 800); "
            "w.add_scalar('held_out/J', 2.5, 1600); w.close(); "
            "assert 'torch' not in sys.modules and 'gymnasium' not in sys.modules, 'torch or gymnasium imported'")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    (events,) = (tmp_path / "tb").glob("events.*")
    scalars = EventAccumulator(str(events)).Reload().Scalars("held_out/J")
    assert [(s.step, s.value) for s in scalars] == [(800, 1.5), (1600, 2.5)]
