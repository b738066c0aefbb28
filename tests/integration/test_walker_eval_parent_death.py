"""A walker evaluation's worker processes end when their parent dies (issue 52, item 7): after ``kill -9``
of a G1 report its two evaluator workers kept stepping their episodes at full CPU (still there after 90 s).

The parent here is a Python process that prices the shipped G1 walker on two workers (episodes far longer
than the test); once both workers are stepping it is killed with SIGKILL, which runs no cleanup of its own,
and both workers must be gone within a few seconds. The parent runs in its own process group, which the test
kills whatever happens, so no process outlives it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = [pytest.mark.holosoma]  # the shipped G1 walker

PARENT = r"""
from econmotor.locomotion.course import CourseSettings
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.evaluation import WalkerEvaluation, evaluate
from econmotor.locomotion.task import MeterSettings

meter = MeterSettings(leg_distance_m=2.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.2,
                      fall_tilt_rad=0.8)
course = CourseSettings(leg_m=10.0, dwell_s=1.0, speed_m_per_s=0.8, legs=100)
ev = WalkerEvaluation(policy="holosoma:g1_29dof/ppo", course=course, meter=meter, stress=Stress(),
                      episode_s=3600.0, seed=0, slots=1)
evaluate(ev, 2, workers=2)
"""


def stat(pid: int) -> list[str] | None:
    """``/proc/<pid>/stat``'s fields after the command name (state first), or None for no such process."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text.rpartition(")")[2].split()


def alive(pid: int) -> bool:
    fields = stat(pid)
    return fields is not None and fields[0] != "Z"  # a zombie no one reaps yet runs nothing


def workers_of(parent: int) -> list[int]:
    """The multiprocessing workers (``spawn_main``) whose parent is ``parent``."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and (fields := stat(int(entry.name))) and int(fields[1]) == parent:
            try:
                if b"spawn_main" in (entry / "cmdline").read_bytes():
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


def cpu_s(pid: int) -> float:
    fields = stat(pid)
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK") if fields else 0.0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_the_workers_end_when_their_parent_is_killed() -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    parent = subprocess.Popen([sys.executable, "-c", PARENT], env=env, start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        kill_once_stepping(parent, 2, start_s=60)
    finally:
        try:
            os.killpg(parent.pid, signal.SIGKILL)  # the parent's group: it, its workers, their resource tracker
        except ProcessLookupError:
            pass
        parent.wait()
        parent.stderr.close()


def kill_once_stepping(parent: subprocess.Popen, count: int, start_s: float) -> None:
    """SIGKILL ``parent`` once its ``count`` workers step (started and past their imports: a second of CPU
    each, within ``start_s``); all of them must be gone within 5 s."""
    workers: list[int] = []
    deadline = time.monotonic() + start_s
    while not (len(workers) == count and all(cpu_s(w) > 1.0 for w in workers)):
        assert parent.poll() is None, parent.stderr.read().decode()
        assert time.monotonic() < deadline, f"the workers did not start stepping: {workers}"
        time.sleep(0.2)
        workers = workers_of(parent.pid)
    parent.kill()  # SIGKILL: no cleanup runs in the parent
    parent.wait()
    deadline = time.monotonic() + 5
    while any(alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [w for w in workers if alive(w)], "workers kept running after their parent was killed"
